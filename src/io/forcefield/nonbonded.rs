//! The non-bonded sections of the force field: exclusions and 1-4 pairs, Lennard-Jones
//! mixing, Coulomb, the cutoff term and the separate 1-4 terms.

use std::collections::BTreeSet;

use super::atoms::AtomTable;
use super::bonded::Topology;
use super::{ForcefieldInput, ForcefieldSpec, InverseLength, Symmetry, Terms, lookup};
use crate::forces::coulomb::Coulomb;
use crate::forces::ewald::{EwaldParameters, EwaldRequest, PmeReciprocal, resolve};
use crate::forces::lennard_jones::LennardJones;
use crate::forces::nonbonded::{Electrostatics, LjPair, NonbondedSpec};
use crate::forces::pair::{Pair, PairTerm};
use crate::forces::{Site, TermClass};
use crate::split::Assignment;
use crate::units::{COULOMB_KCAL_ANGSTROM, Units, significant};

/// Which pairs the cutoff term leaves out, and the 1-4 pairs computed on their own.
pub(super) struct Exclusions {
    /// Pairs left out of the cutoff term.
    pub excluded: Vec<(usize, usize)>,
    pub pairs_14: BTreeSet<(usize, usize)>,
    /// The 1-4 pairs are scaled in their own terms (else they are ordinary pairs).
    pub separate_14: bool,
    pub scale_14_lj: f64,
    pub scale_14_coulomb: f64,
}

/// 1-2 and 1-3 pairs excluded or ordinary, 1-4 pairs scaled (AMBER defaults 0.5 and
/// 1/1.2); one report line.
pub(super) fn exclusions(
    spec: &ForcefieldSpec,
    graph: &Topology,
    report: &mut Vec<String>,
) -> Result<Exclusions, String> {
    let scale = |value: Option<f64>, default: f64, what: &str| -> Result<f64, String> {
        let v = value.unwrap_or(default);
        if !(0.0..=1.0).contains(&v) {
            return Err(format!(
                "[forcefield] {what} must be between 0 and 1, got {v}"
            ));
        }
        Ok(v)
    };
    let scale_12 = scale(spec.scale_12, 0.0, "scale_12")?;
    let scale_13 = scale(spec.scale_13, 0.0, "scale_13")?;
    for (what, v) in [("scale_12", scale_12), ("scale_13", scale_13)] {
        if v != 0.0 && v != 1.0 {
            return Err(format!(
                "[forcefield] {what} is 0 (excluded) or 1 (an ordinary pair), got {v}"
            ));
        }
    }
    let scale_14_lj = scale(spec.scale_14_lj, 0.5, "scale_14_lj")?;
    let scale_14_coulomb = scale(spec.scale_14_coulomb, 1.0 / 1.2, "scale_14_coulomb")?;
    let (pairs_12, pairs_13, pairs_14) = neighbour_pairs(graph);
    let separate_14 = !(scale_14_lj == 1.0 && scale_14_coulomb == 1.0);
    let mut excluded: Vec<(usize, usize)> = Vec::new();
    if scale_12 == 0.0 {
        excluded.extend(&pairs_12);
    }
    if scale_13 == 0.0 {
        excluded.extend(&pairs_13);
    }
    if separate_14 {
        excluded.extend(&pairs_14);
    }
    report.push(format!(
        "pairs: {} 1-2 ({}), {} 1-3 ({}), {} 1-4 ({})",
        pairs_12.len(),
        if scale_12 == 0.0 {
            "excluded"
        } else {
            "ordinary"
        },
        pairs_13.len(),
        if scale_13 == 0.0 {
            "excluded"
        } else {
            "ordinary"
        },
        pairs_14.len(),
        if separate_14 {
            format!(
                "LJ × {}, Coulomb × {}, no cutoff, terms \"lj-14\" and \"coulomb-14\"",
                significant(scale_14_lj, 10),
                significant(scale_14_coulomb, 10)
            )
        } else {
            "ordinary".into()
        }
    ));
    Ok(Exclusions {
        excluded,
        pairs_14,
        separate_14,
        scale_14_lj,
        scale_14_coulomb,
    })
}

type PairSet = BTreeSet<(usize, usize)>;

/// The 1-2, 1-3 and 1-4 pairs of the bond graph, each pair in the closest set only.
fn neighbour_pairs(graph: &Topology) -> (PairSet, PairSet, PairSet) {
    let mut pairs_12: PairSet = BTreeSet::new();
    for &[a, b] in &graph.bonds {
        pairs_12.insert((a, b));
    }
    let mut pairs_13: PairSet = BTreeSet::new();
    for &[i, _, k] in &graph.angles {
        let p = (i.min(k), i.max(k));
        if !pairs_12.contains(&p) {
            pairs_13.insert(p);
        }
    }
    let mut pairs_14: PairSet = BTreeSet::new();
    for &[i, _, _, l] in &graph.dihedrals {
        let p = (i.min(l), i.max(l));
        if !pairs_12.contains(&p) && !pairs_13.contains(&p) {
            pairs_14.insert(p);
        }
    }
    (pairs_12, pairs_13, pairs_14)
}

/// The cutoff term's settings.
pub(super) struct Settings {
    /// Infinite for none.
    pub cutoff: f64,
    pub skin: f64,
    pub inner_buffer: f64,
    pub electrostatics: Electrostatics,
    pub coulomb_constant: f64,
    pub lj_shift: bool,
    /// With `coulomb = "pme"`: its parameters.
    pub ewald: Option<EwaldParameters>,
    /// The scene's units, for the report's lengths and α.
    pub units: Units,
}

/// Cutoff, skin, Coulomb form and constant, LJ shift.
pub(super) fn settings(input: &ForcefieldInput, charges: &[f64]) -> Result<Settings, String> {
    let spec = input.spec;
    let cutoff = match spec.cutoff {
        Some(c) if c > 0.0 && c.is_finite() => c,
        Some(c) => return Err(format!("[forcefield] cutoff must be positive, got {c}")),
        None => f64::INFINITY,
    };
    if input.periodic_box.is_some() && !cutoff.is_finite() {
        return Err("[forcefield] a periodic box needs a cutoff (give cutoff = …)".into());
    }
    let skin = spec.skin.unwrap_or(2.0);
    if !(skin >= 0.0 && skin.is_finite()) {
        return Err(format!("[forcefield] skin must be ≥ 0, got {skin}"));
    }
    let inner_buffer = spec.inner_buffer.unwrap_or(skin / 2.0);
    if !(0.0..=skin).contains(&inner_buffer) {
        return Err(format!(
            "[forcefield] inner_buffer must be between 0 and the skin {skin}, got {inner_buffer}"
        ));
    }
    let mut electrostatics = coulomb(spec, charges)?;
    let ewald = match electrostatics {
        Electrostatics::Ewald { .. } => {
            let request = ewald_request(spec, input.units)?;
            let lengths = input.periodic_box.map(|b| b.lengths);
            let params =
                resolve(&request, cutoff, lengths).map_err(|e| format!("[forcefield] {e}"))?;
            electrostatics = Electrostatics::Ewald {
                alpha: params.alpha,
            };
            Some(params)
        }
        _ => None,
    };
    Ok(Settings {
        cutoff,
        skin,
        inner_buffer,
        electrostatics,
        ewald,
        coulomb_constant: match input.units {
            Units::Real => COULOMB_KCAL_ANGSTROM,
            Units::None => 1.0,
        },
        lj_shift: spec.lj_shift.unwrap_or(true),
        units: input.units,
    })
}

/// The Coulomb form: none without charges unless chosen, else DSF, reaction field or
/// plain.
fn coulomb(spec: &ForcefieldSpec, charges: &[f64]) -> Result<Electrostatics, String> {
    let any_charge = charges.iter().any(|&c| c != 0.0);
    Ok(match spec.coulomb.as_deref() {
        None if !any_charge => Electrostatics::None,
        None => {
            return Err(
                "the atoms carry charges: choose [forcefield] coulomb = \"dsf\", \
                 \"reaction-field\" (with a cutoff) or \"plain\" (without)"
                    .into(),
            );
        }
        Some("none") => Electrostatics::None,
        Some("plain") => Electrostatics::Plain,
        Some("dsf") => Electrostatics::DampedShiftedForce {
            alpha: spec.dsf_alpha.unwrap_or(0.0),
        },
        Some("reaction-field") => Electrostatics::ReactionField {
            dielectric: rf_dielectric(spec.rf_dielectric.unwrap_or(78.3))?,
        },
        // α is resolved with the box and cutoff (`settings`).
        Some("pme") => Electrostatics::Ewald { alpha: 0.0 },
        Some(other) => {
            return Err(format!(
                "unknown [forcefield] coulomb \"{other}\"; use pme, dsf, reaction-field, plain \
                 or none"
            ));
        }
    })
}

/// Lennard-Jones per type pair (`nt × nt`): `[forcefield.pairs]` when given, else
/// Lorentz–Berthelot mixing; one report line per given pair.
pub(super) fn lennard_jones(
    spec: &ForcefieldSpec,
    atoms: &AtomTable,
    settings: &Settings,
    report: &mut Vec<String>,
) -> Vec<LjPair> {
    let nt = atoms.kinds.len();
    let mut lj = vec![LjPair::default(); nt * nt];
    for a in 0..nt {
        for b in 0..nt {
            let key_types = [atoms.kinds[a].as_str(), atoms.kinds[b].as_str()];
            let key_elements = [
                atoms.elements[atoms.first_of_kind[a]].as_str(),
                atoms.elements[atoms.first_of_kind[b]].as_str(),
            ];
            let (epsilon, sigma) =
                match lookup(&spec.pairs, &key_types, &key_elements, Symmetry::Reversible) {
                    Some((_, p)) => (p.epsilon, p.sigma),
                    None => {
                        let (ea, sa) = atoms.lj_params[a];
                        let (eb, sb) = atoms.lj_params[b];
                        ((ea * eb).sqrt(), 0.5 * (sa + sb))
                    }
                };
            lj[a * nt + b] = LjPair::new(epsilon, sigma, settings.cutoff, settings.lj_shift);
        }
    }
    for key in spec.pairs.keys() {
        report.push(format!("LJ pair {key}: ε, σ (scene, no mixing)"));
    }
    lj
}

/// The report line of the cutoff term.
pub(super) fn report_line(settings: &Settings) -> String {
    let cutoff = settings.cutoff;
    format!(
        "nonbonded: cutoff {}, skin {}, LJ {}Lorentz–Berthelot, Coulomb {}",
        if cutoff.is_finite() {
            settings.units.length(cutoff)
        } else {
            "none".into()
        },
        settings.units.length(settings.skin),
        if settings.lj_shift && cutoff.is_finite() {
            "energy-shifted, "
        } else {
            ""
        },
        settings.electrostatics.describe(settings.units)
    )
}

/// What the cutoff term over every pair not excluded is built from (the term itself, or
/// its distance split: `super::distance_split`).
pub(super) fn cutoff_spec(
    input: &ForcefieldInput,
    atoms: &AtomTable,
    settings: &Settings,
    lj: &[LjPair],
    excluded: &[(usize, usize)],
) -> NonbondedSpec {
    NonbondedSpec {
        cutoff: settings.cutoff,
        skin: settings.skin,
        inner_buffer: Some(settings.inner_buffer),
        electrostatics: settings.electrostatics,
        coulomb_constant: settings.coulomb_constant,
        box_lengths: input.periodic_box.map(|b| b.lengths),
        types: atoms.kind_of.clone(),
        lj: lj.to_vec(),
        charges: atoms.charges.clone(),
        excluded: excluded.to_vec(),
    }
}

/// The 1-4 pairs in their own terms, scaled, without cutoff, plain Coulomb ("lj-14",
/// "coulomb-14"), as OpenMM computes `NonbondedForce` exceptions.
pub(super) fn pairs_14_terms(
    input: &ForcefieldInput,
    atoms: &AtomTable,
    settings: &Settings,
    lj: &[LjPair],
    exclusions: &Exclusions,
    terms: &mut Terms,
) {
    if !exclusions.separate_14 || exclusions.pairs_14.is_empty() {
        return;
    }
    let nt = atoms.kinds.len();
    let (scale_lj, scale_coulomb) = (exclusions.scale_14_lj, exclusions.scale_14_coulomb);
    let mut lj_pairs = Vec::new();
    let mut coulomb_pairs = Vec::new();
    for &(i, l) in &exclusions.pairs_14 {
        let (a, b) = (atoms.kind_of[i] as usize, atoms.kind_of[l] as usize);
        let p = lj[a * nt + b];
        // Back from c12, c6 to ε, σ of the pair (σ⁶ = c12/c6, ε = c6²/(4 c12)).
        if scale_lj > 0.0 && p.c12 > 0.0 && p.c6 > 0.0 {
            let sigma = (p.c12 / p.c6).powf(1.0 / 6.0);
            let epsilon = p.c6 * p.c6 / (4.0 * p.c12);
            lj_pairs.push(Pair {
                a: Site::Particle(i),
                b: Site::Particle(l),
                potential: LennardJones::new(scale_lj * epsilon, sigma, f64::INFINITY, false),
            });
        }
        if settings.electrostatics != Electrostatics::None && scale_coulomb > 0.0 {
            let qq =
                scale_coulomb * settings.coulomb_constant * atoms.charges[i] * atoms.charges[l];
            if qq != 0.0 {
                coulomb_pairs.push(Pair {
                    a: Site::Particle(i),
                    b: Site::Particle(l),
                    potential: Coulomb { charge_product: qq },
                });
            }
        }
    }
    let periodic_box = input.periodic_box;
    if !lj_pairs.is_empty() {
        let kind = "lennard-jones-14";
        let term = PairTerm::new(kind, TermClass::Nonbonded, 3, lj_pairs, periodic_box);
        terms.push(("lj-14".into(), Box::new(term), Assignment::Default));
    }
    if !coulomb_pairs.is_empty() {
        let kind = "coulomb-14";
        let term = PairTerm::new(kind, TermClass::Nonbonded, 3, coulomb_pairs, periodic_box);
        terms.push(("coulomb-14".into(), Box::new(term), Assignment::Default));
    }
}

/// The PME keys of `[forcefield]`, checked where a value alone can be wrong; keys that
/// need `coulomb = "pme"` are an error without it.
fn ewald_request(spec: &ForcefieldSpec, units: Units) -> Result<EwaldRequest, String> {
    let alpha = match &spec.ewald_alpha {
        None => None,
        Some(value) => Some(
            inverse_length(value, units).map_err(|e| format!("[forcefield] ewald_alpha {e}"))?,
        ),
    };
    Ok(EwaldRequest {
        tolerance: spec.ewald_tolerance,
        spacing: spec.fourier_spacing,
        alpha,
        grid: spec.pme_grid,
        order: spec.pme_order,
    })
}

/// Keys that only PME reads, when given without it: an error naming the first.
pub(super) fn stray_pme_keys(spec: &ForcefieldSpec) -> Result<(), String> {
    if spec.coulomb.as_deref() == Some("pme") {
        return Ok(());
    }
    let given = [
        ("ewald_tolerance", spec.ewald_tolerance.is_some()),
        ("fourier_spacing", spec.fourier_spacing.is_some()),
        ("ewald_alpha", spec.ewald_alpha.is_some()),
        ("pme_grid", spec.pme_grid.is_some()),
        ("pme_order", spec.pme_order.is_some()),
        ("pme_level", spec.pme_level.is_some()),
    ];
    match given.iter().find(|(_, set)| *set) {
        Some((key, _)) => Err(format!(
            "[forcefield] {key} is a PME setting: it needs coulomb = \"pme\""
        )),
        None => Ok(()),
    }
}

/// An inverse length in the scene's unit from a number (already in it) or text such as
/// `"0.347/Å"` or `"3.47/nm"` (real units only).
pub fn inverse_length(value: &InverseLength, units: Units) -> Result<f64, String> {
    let text = match value {
        InverseLength::Number(x) => return Ok(*x),
        InverseLength::Text(text) => text.trim(),
    };
    let Some((number, unit)) = text.split_once('/') else {
        return text
            .parse::<f64>()
            .map_err(|_| format!("\"{text}\" is no number (write 0.347 or \"0.347/Å\")"));
    };
    let number: f64 = number
        .trim()
        .parse()
        .map_err(|_| format!("\"{text}\": \"{}\" is no number", number.trim()))?;
    // Length of the unit in Å.
    let length = match unit.trim() {
        "Å" | "A" | "angstrom" | "Angstrom" => 1.0,
        "nm" => 10.0,
        "pm" => 0.01,
        other => {
            return Err(format!(
                "\"{text}\": unknown length unit \"{other}\" (use Å, A, angstrom, nm or pm)"
            ));
        }
    };
    match units {
        Units::Real => Ok(number / length),
        Units::None => Err(format!(
            "\"{text}\" has a unit, but the scene has none: give a plain number"
        )),
    }
}

/// With `coulomb = "pme"`: the `"pme-reciprocal"` term (mesh, exclusion correction, self
/// and background), on `pme_level` or the slowest level; report lines, with a notice for a
/// charged box.
pub(super) fn pme_term(
    input: &ForcefieldInput,
    atoms: &AtomTable,
    settings: &Settings,
    exclusions: &Exclusions,
    terms: &mut Terms,
    report: &mut Vec<String>,
) -> Result<(), String> {
    let (Some(params), Some(periodic_box)) = (settings.ewald, input.periodic_box) else {
        return Ok(());
    };
    let term = PmeReciprocal::new(
        params,
        periodic_box.lengths,
        settings.coulomb_constant,
        atoms.charges.clone(),
        &exclusions.excluded,
    )?;
    report.push(format!(
        "pme-reciprocal: {}; {} excluded pairs corrected; level {}",
        params.describe(settings.units),
        exclusions.excluded.len(),
        match input.spec.pme_level {
            Some(level) => level.to_string(),
            None => "slowest (default)".into(),
        }
    ));
    let net = term.net_charge();
    if net.abs() > 1e-6 {
        report.push(format!(
            "notice: the box carries a net charge of {net:.6} e; PME adds the neutralising \
             background -pi Q^2/(2 V alpha^2) (energy component ewald-background)"
        ));
    }
    let assignment = match input.spec.pme_level {
        Some(level) => Assignment::Level(level),
        None => Assignment::Default,
    };
    terms.push(("pme-reciprocal".into(), Box::new(term), assignment));
    Ok(())
}

/// A reaction field's dielectric ε_rf: at least 1 (the vacuum's) and finite (78.3 for
/// water), else an error naming it.
pub fn rf_dielectric(epsilon_rf: f64) -> Result<f64, String> {
    if epsilon_rf.is_finite() && epsilon_rf >= 1.0 {
        return Ok(epsilon_rf);
    }
    Err(format!(
        "epsilon_rf = {epsilon_rf}: the reaction field's dielectric constant must be at least \
         1 (vacuum) and finite (water: 78.3)"
    ))
}
