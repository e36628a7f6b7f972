//! A [`Topology`] as longstep's force terms: `bonds` (harmonic pairs, [`PairTerm`] of
//! [`HarmonicBond`]), `angles` ([`HarmonicAngles`]), `torsions` and `impropers`
//! ([`Torsions`], a cosine series per quartet), `harmonic-impropers`
//! ([`HarmonicDihedrals`], GROMACS improper function 2), `nonbonded` (the cluster-pair
//! [`Nonbonded`] term with the topology's per-type-pair Lennard-Jones table and its
//! exclusions), `lj-14` and `coulomb-14` (the scaled 1-4 pairs, no cutoff, plain Coulomb,
//! as OpenMM computes `NonbondedForce` exceptions). Bonded terms are fast by default,
//! non-bonded ones slow.
//!
//! Electrostatics of the non-bonded term: plain Coulomb over every pair without a box (a
//! molecule in vacuum, OpenMM `NoCutoff`); with a box, or a cutoff, reaction field (OpenMM
//! `CutoffPeriodic`/`CutoffNonPeriodic`, ε_rf 78.3 by default) or damped shifted force.
//! Lennard-Jones is cut at the cutoff, neither shifted nor switched, without a long-range
//! correction (OpenMM's `NonbondedForce` with its defaults off); `lj_shift` shifts its energy
//! to zero at the cutoff, so the total energy no longer jumps as pairs cross it.

use std::collections::BTreeMap;

use super::Topology;
use crate::forces::angle::{AngleBend, HarmonicAngles};
use crate::forces::coulomb::Coulomb as CoulombPair;
use crate::forces::distance_split::SwitchBy;
use crate::forces::ewald::{EwaldParameters, EwaldRequest, PmeReciprocal, resolve};
use crate::forces::harmonic_dihedral::{HarmonicDihedral, HarmonicDihedrals};
use crate::forces::lennard_jones::LennardJones;
use crate::forces::nonbonded::{Electrostatics, LjPair, Nonbonded, NonbondedSpec};
use crate::forces::pair::{Pair, PairTerm};
use crate::forces::spring::HarmonicBond;
use crate::forces::torsion::{Cosine, Dihedral, Torsions};
use crate::forces::{ForceTerm, PeriodicBox, Site, TermClass};
use crate::io::forcefield::distance_split::{SplitAtoms, split_terms};
use crate::io::forcefield::{SplitSection, rf_dielectric};
use crate::split::Assignment;
use crate::units::{COULOMB_KCAL_ANGSTROM, Units, significant};

/// The pair-list skin when none is given (Å): the list holds pairs within cutoff + skin and
/// is rebuilt when two atoms may have closed it. With constraints and 4 fs steps a topology's
/// water hydrogens close 2 Å within a few dozen steps; 4 Å was 9–11 % faster than 2 Å with
/// HMR at 4 fs on the solvated dipeptide and Trp-cage (`scripts/skin_sitting.py`,
/// docs/data/sittings/topology-skin-2026-11-26.*), and 6 Å with a 2 Å inner buffer took
/// 3.3 % less process CPU time than 4 / 2 on Trp-cage, in all 5 interleaved pairs (56 list
/// builds to 22, 207 prunings to 195: docs/data/sittings/lists-2026-11-29-e.txt, part 4).
pub const DEFAULT_SKIN: f64 = 6.0;

/// The inner (pruned) list's buffer when none is given, as a fraction of the skin (2 Å of
/// the default 6): the kernel runs over the pairs within cutoff + this buffer, pruned again
/// when two atoms may have closed it.
pub const DEFAULT_INNER_FRACTION: f64 = 1.0 / 3.0;

/// The cutoff when none is given but one is needed (Å).
pub const DEFAULT_CUTOFF: f64 = 9.0;
/// OpenMM's default reaction-field dielectric.
pub const DEFAULT_EPSILON_RF: f64 = 78.3;

/// The Coulomb form of the non-bonded term.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Coulomb {
    /// `k_e q_i q_j / r` over every pair, no cutoff, no box.
    Plain,
    ReactionField,
    Dsf,
    /// Smooth PME: Ewald real space in the cutoff term and the `pme-reciprocal` term.
    Pme,
}

impl Coulomb {
    /// `plain` (or `none`: no cutoff, the vacuum form), `reaction-field`, `dsf`.
    pub fn parse(name: &str) -> Result<Coulomb, String> {
        match name {
            "plain" | "none" => Ok(Coulomb::Plain),
            "reaction-field" => Ok(Coulomb::ReactionField),
            "dsf" => Ok(Coulomb::Dsf),
            "pme" => Ok(Coulomb::Pme),
            other => Err(format!(
                "coulomb \"{other}\" is not one of none (plain Coulomb without cutoff), \
                 reaction-field, dsf, pme"
            )),
        }
    }
}

/// How the non-bonded term is computed; `None` takes the default.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NonbondedOptions {
    /// Å; default none in vacuum with plain Coulomb, else [`DEFAULT_CUTOFF`].
    pub cutoff: Option<f64>,
    /// Default plain without a box or cutoff, else reaction field.
    pub coulomb: Option<Coulomb>,
    pub epsilon_rf: Option<f64>,
    /// 1/Å, default 0 (shifted force).
    pub dsf_alpha: Option<f64>,
    /// Neighbour-list skin (Å), default [`DEFAULT_SKIN`].
    pub skin: Option<f64>,
    /// The inner list's buffer (Å), default [`DEFAULT_INNER_FRACTION`] of the skin.
    pub inner_buffer: Option<f64>,
    /// Shift the Lennard-Jones energy to zero at the cutoff (the force is unchanged), so
    /// the energy does not jump as pairs cross it; default false, as OpenMM.
    pub lj_shift: Option<bool>,
    /// PME's parameters (with `coulomb = pme`; the defaults of [`crate::forces::ewald`]).
    pub ewald: EwaldRequest,
    /// The level of the `pme-reciprocal` term (default: the slowest).
    pub pme_level: Option<usize>,
    /// The level of the cutoff term (default: the slowest).
    pub nonbonded_level: Option<usize>,
    /// The cutoff term split by distance into a short-range part and a remainder
    /// (`[topology.split]`), by atom pair unless `by = "molecule"`.
    pub split: Option<SplitSection>,
}

/// The terms with what the scene needs besides them.
pub struct BuiltTopology {
    pub terms: Vec<(String, Box<dyn ForceTerm>, Assignment)>,
    /// amu.
    pub masses: Vec<f64>,
    pub charges: Vec<f64>,
    pub elements: Vec<String>,
    pub names: Vec<String>,
    /// What was read and built, one line each (`longstep check` prints it).
    pub report: Vec<String>,
}

type Terms = Vec<(String, Box<dyn ForceTerm>, Assignment)>;

/// Build the force terms of `topology` at positions `q` (`n × 3`, Å).
pub fn build_terms(
    topology: &Topology,
    q: &[f64],
    options: &NonbondedOptions,
) -> Result<BuiltTopology, String> {
    let n = topology.atoms.len();
    if q.len() != 3 * n {
        return Err(format!(
            "{} atoms in the topology, {} in the coordinates",
            n,
            q.len() / 3
        ));
    }
    let periodic_box = topology.periodic_box.map(|lengths| PeriodicBox { lengths });
    let mut terms = Terms::new();
    let mut report = vec![summary_line(topology)];
    bonds(topology, periodic_box, &mut terms, &mut report);
    angles(topology, periodic_box, &mut terms, &mut report);
    torsions(topology, periodic_box, &mut terms, &mut report);
    harmonic_dihedrals(topology, periodic_box, &mut terms, &mut report);
    if !topology.settles.is_empty() {
        report.push(format!(
            "rigid waters: {} ([ settles ]), no bonded terms: a run holds them by SETTLE \
             (rigid water, on by default)",
            topology.settles.len()
        ));
    }
    let electrostatics = nonbonded(topology, q, options, &mut terms, &mut report)?;
    report.extend(charge_notices(topology, electrostatics));
    // With a distance split the 1-4 pairs, short-range by construction, go with its
    // short part; otherwise with the non-bonded terms (the slowest level by default).
    let level_14 = options.split.as_ref().map_or(Assignment::Default, |s| {
        Assignment::Level(s.short_level.unwrap_or(1))
    });
    pairs_14(
        topology,
        electrostatics,
        (periodic_box, level_14),
        &mut terms,
        &mut report,
    );
    report.extend(topology.notes.iter().cloned());
    Ok(BuiltTopology {
        terms,
        masses: topology.atoms.iter().map(|a| a.mass).collect(),
        charges: topology.atoms.iter().map(|a| a.charge).collect(),
        elements: topology
            .atoms
            .iter()
            .map(|a| {
                if a.element.is_empty() {
                    a.name.clone()
                } else {
                    a.element.clone()
                }
            })
            .collect(),
        names: topology.atoms.iter().map(|a| a.name.clone()).collect(),
        report,
    })
}

/// A 1-4 scale factor for the report: ten significant digits (0.8333333333, not
/// 0.8333333333333334), in exponent form when tiny (an AMBER SCNB of 1e10 gives 1e-10).
fn scale_text(x: f64) -> String {
    if x != 0.0 && x.abs() < 1e-5 {
        format!("{:e}", significant(x, 10).parse::<f64>().unwrap_or(x))
    } else {
        significant(x, 10)
    }
}

fn summary_line(topology: &Topology) -> String {
    // A sum of rounded charges a few 1e-7 below zero prints 0.000000, not -0.000000.
    let charge = match topology.total_charge() {
        q if q.abs() < 5e-7 => 0.0,
        q => q,
    };
    format!(
        "topology: {} ({}), {} atoms in {} residues, total charge {:.6} e, box {}",
        topology.source.display(),
        topology.format,
        topology.atoms.len(),
        topology.residues.len(),
        charge,
        match topology.periodic_box {
            Some(b) => {
                // To 10 significant digits: 45.981, not the 45.980999999999995 of nm × 10.
                let side = |x: f64| crate::io::summary::significant(x, 10);
                format!("{} × {} × {} Å", side(b[0]), side(b[1]), side(b[2]))
            }
            None => "none".into(),
        }
    )
}

fn bonds(
    topology: &Topology,
    periodic_box: Option<PeriodicBox>,
    terms: &mut Terms,
    report: &mut Vec<String>,
) {
    let pairs: Vec<_> = topology
        .bonds
        .iter()
        .map(|b| Pair {
            a: Site::Particle(b.atoms[0]),
            b: Site::Particle(b.atoms[1]),
            potential: HarmonicBond {
                stiffness: b.k,
                rest_length: b.r0,
            },
        })
        .collect();
    report.push(format!(
        "bonds: {} ({} with hydrogen), (k/2)(r − r0)², term \"bonds\"",
        pairs.len(),
        topology.bonds_with_hydrogen
    ));
    if !pairs.is_empty() {
        let term = PairTerm::new("bond", TermClass::Bonded, 3, pairs, periodic_box);
        terms.push(("bonds".into(), Box::new(term), Assignment::Default));
    }
}

fn angles(
    topology: &Topology,
    periodic_box: Option<PeriodicBox>,
    terms: &mut Terms,
    report: &mut Vec<String>,
) {
    let bends: Vec<_> = topology
        .angles
        .iter()
        .map(|a| AngleBend {
            sites: a.atoms.map(Site::Particle),
            stiffness: a.k,
            rest_angle: a.theta0,
        })
        .collect();
    report.push(format!(
        "angles: {}, (k/2)(θ − θ0)², term \"angles\"",
        bends.len()
    ));
    if !bends.is_empty() {
        let term = HarmonicAngles::new(3, bends, periodic_box);
        terms.push(("angles".into(), Box::new(term), Assignment::Default));
    }
}

/// Proper and improper dihedrals, each quartet's cosines in one series, in two terms.
fn torsions(
    topology: &Topology,
    periodic_box: Option<PeriodicBox>,
    terms: &mut Terms,
    report: &mut Vec<String>,
) {
    for (improper, name, what) in [
        (false, "torsions", "proper dihedrals"),
        (true, "impropers", "improper dihedrals"),
    ] {
        let mut quartets: BTreeMap<[usize; 4], Vec<Cosine>> = BTreeMap::new();
        let mut count = 0;
        for d in topology.dihedrals.iter().filter(|d| d.improper == improper) {
            count += 1;
            quartets.entry(d.atoms).or_default().push(Cosine {
                k: d.k,
                periodicity: d.periodicity,
                phase: d.phase,
            });
        }
        report.push(format!(
            "{what}: {} quartets, {count} cosine terms, k (1 + cos(nφ − δ)), term \"{name}\"",
            quartets.len()
        ));
        if quartets.is_empty() {
            continue;
        }
        let list = quartets
            .into_iter()
            .map(|(atoms, series)| Dihedral { atoms, series })
            .collect();
        let term = Torsions::new(list, periodic_box);
        terms.push((name.into(), Box::new(term), Assignment::Default));
    }
}

/// Harmonic dihedrals (GROMACS improper function 2), in one term.
fn harmonic_dihedrals(
    topology: &Topology,
    periodic_box: Option<PeriodicBox>,
    terms: &mut Terms,
    report: &mut Vec<String>,
) {
    if topology.harmonic_dihedrals.is_empty() {
        return;
    }
    let list: Vec<HarmonicDihedral> = topology
        .harmonic_dihedrals
        .iter()
        .map(|d| HarmonicDihedral {
            atoms: d.atoms,
            k: d.k,
            xi0: d.xi0,
        })
        .collect();
    report.push(format!(
        "harmonic dihedrals: {}, (k/2)(ξ − ξ0)², term \"harmonic-impropers\"",
        list.len()
    ));
    let term = HarmonicDihedrals::new(list, periodic_box);
    terms.push((
        "harmonic-impropers".into(),
        Box::new(term),
        Assignment::Default,
    ));
}

/// The electrostatics and cutoff the options ask for.
fn electrostatics(
    topology: &Topology,
    options: &NonbondedOptions,
) -> Result<(Electrostatics, f64, Option<EwaldParameters>), String> {
    let periodic = topology.periodic_box.is_some();
    let coulomb = options
        .coulomb
        .unwrap_or(if periodic || options.cutoff.is_some() {
            Coulomb::ReactionField
        } else {
            Coulomb::Plain
        });
    if let Some(c) = options.cutoff
        && !(c > 0.0 && c.is_finite())
    {
        return Err(format!("cutoff must be a positive length, got {c}"));
    }
    let cutoff = match coulomb {
        Coulomb::Plain if periodic => {
            return Err(
                "plain Coulomb (coulomb = none) is for a molecule in vacuum; the \
                        topology has a periodic box: choose reaction-field or dsf"
                    .into(),
            );
        }
        Coulomb::Plain if options.cutoff.is_some() => {
            return Err(
                "plain Coulomb (coulomb = none) has no cutoff: leave cutoff out, or \
                        choose reaction-field or dsf"
                    .into(),
            );
        }
        Coulomb::Plain => f64::INFINITY,
        Coulomb::Pme if !periodic => {
            return Err("PME (coulomb = pme) needs a periodic box: the topology has none".into());
        }
        _ => options.cutoff.unwrap_or(DEFAULT_CUTOFF),
    };
    let pme_only = options.ewald != EwaldRequest::default() || options.pme_level.is_some();
    if coulomb != Coulomb::Pme && pme_only {
        return Err(
            "ewald_tolerance, fourier_spacing, ewald_alpha, pme_grid, pme_order and \
                    pme_level are PME settings: they need coulomb = pme"
                .into(),
        );
    }
    let ewald = match coulomb {
        Coulomb::Pme => Some(resolve(&options.ewald, cutoff, topology.periodic_box)?),
        _ => None,
    };
    let form = match coulomb {
        Coulomb::Plain => Electrostatics::Plain,
        Coulomb::ReactionField => Electrostatics::ReactionField {
            dielectric: rf_dielectric(options.epsilon_rf.unwrap_or(DEFAULT_EPSILON_RF))?,
        },
        Coulomb::Dsf => Electrostatics::DampedShiftedForce {
            alpha: options.dsf_alpha.unwrap_or(0.0),
        },
        Coulomb::Pme => Electrostatics::Ewald {
            alpha: ewald.map_or(0.0, |p| p.alpha),
        },
    };
    Ok((form, cutoff, ewald))
}

/// The cutoff term over every pair not excluded; returns its electrostatics.
fn nonbonded(
    topology: &Topology,
    q: &[f64],
    options: &NonbondedOptions,
    terms: &mut Terms,
    report: &mut Vec<String>,
) -> Result<Electrostatics, String> {
    let (electrostatics, cutoff, ewald) = electrostatics(topology, options)?;
    let skin = options.skin.unwrap_or(DEFAULT_SKIN);
    if !(skin >= 0.0 && skin.is_finite()) {
        return Err(format!("skin must be ≥ 0, got {skin}"));
    }
    let inner_buffer = options
        .inner_buffer
        .unwrap_or(DEFAULT_INNER_FRACTION * skin);
    if !(0.0..=skin).contains(&inner_buffer) {
        return Err(format!(
            "inner_buffer must be between 0 and the skin {skin}, got {inner_buffer}"
        ));
    }
    let lj = &topology.lj;
    let shifted = options.lj_shift.unwrap_or(false) && cutoff.is_finite();
    let inv6 = if shifted { cutoff.powi(-6) } else { 0.0 };
    let table = (0..lj.c12.len())
        .map(|k| LjPair {
            c12: lj.c12[k],
            c6: lj.c6[k],
            shift: inv6 * (lj.c12[k] * inv6 - lj.c6[k]),
        })
        .collect();
    let spec = NonbondedSpec {
        cutoff,
        skin,
        inner_buffer: Some(inner_buffer),
        electrostatics,
        coulomb_constant: COULOMB_KCAL_ANGSTROM,
        box_lengths: topology.periodic_box,
        types: topology.atoms.iter().map(|a| a.lj_type as u32).collect(),
        lj: table,
        charges: topology.atoms.iter().map(|a| a.charge).collect(),
        excluded: topology.exclusions.clone(),
    };
    report.push(format!(
        "Lennard-Jones: {} atom types, c12/r¹² − c6/r⁶ per type pair from the file (no \
         mixing rule), cut at the cutoff, {}",
        lj.n_types,
        if shifted {
            "energy shifted to zero there"
        } else {
            "not shifted"
        }
    ));
    report.push(format!(
        "exclusions: {} pairs left out of the non-bonded term (1-2, 1-3, 1-4)",
        topology.exclusions.len()
    ));
    report.push(format!(
        "nonbonded: cutoff {}, skin {} (inner list {}), Coulomb {}, term \"nonbonded\"",
        if cutoff.is_finite() {
            Units::Real.length(cutoff)
        } else {
            "none".into()
        },
        Units::Real.length(skin),
        Units::Real.length(inner_buffer),
        electrostatics.describe(Units::Real)
    ));
    cutoff_terms(topology, spec, q, options, terms, report)?;
    if let (Some(params), Some(lengths)) = (ewald, topology.periodic_box) {
        pme_reciprocal(topology, (params, lengths), options, terms, report)?;
    }
    Ok(electrostatics)
}

/// The reciprocal-space PME term of `params` in the box `lengths`, on `pme_level`.
fn pme_reciprocal(
    topology: &Topology,
    (params, lengths): (EwaldParameters, [f64; 3]),
    options: &NonbondedOptions,
    terms: &mut Terms,
    report: &mut Vec<String>,
) -> Result<(), String> {
    let level = |l: Option<usize>| l.map_or(Assignment::Default, Assignment::Level);
    let charges = topology.atoms.iter().map(|a| a.charge).collect();
    let term = PmeReciprocal::new(
        params,
        lengths,
        COULOMB_KCAL_ANGSTROM,
        charges,
        &topology.exclusions,
    )?;
    report.push(format!(
        "pme-reciprocal: {}; {} excluded pairs corrected (1-2, 1-3, 1-4: the 1-4 pairs' \
         scaled Coulomb is in coulomb-14); term \"pme-reciprocal\"",
        params.describe(Units::Real),
        topology.exclusions.len()
    ));
    terms.push((
        "pme-reciprocal".into(),
        Box::new(term),
        level(options.pme_level),
    ));
    Ok(())
}

/// The cutoff term `spec` whole on `nonbonded_level`, or split by distance.
fn cutoff_terms(
    topology: &Topology,
    spec: NonbondedSpec,
    q: &[f64],
    options: &NonbondedOptions,
    terms: &mut Terms,
    report: &mut Vec<String>,
) -> Result<(), String> {
    let Some(section) = &options.split else {
        let level = options
            .nonbonded_level
            .map_or(Assignment::Default, Assignment::Level);
        terms.push((
            "nonbonded".into(),
            Box::new(Nonbonded::new(spec, q)?),
            level,
        ));
        return Ok(());
    };
    if options.nonbonded_level.is_some() {
        return Err(
            "nonbonded_level places the whole cutoff term; with a split give its \
                    short_level and remainder_level instead"
                .into(),
        );
    }
    // A rigid water's O–H pairs hold it together as bonds would.
    let bonds: Vec<[usize; 2]> = (topology.bonds.iter().map(|b| b.atoms))
        .chain(topology.settles.iter().flat_map(|s| {
            let [o, h1, h2] = s.atoms;
            [[o, h1], [o, h2]]
        }))
        .collect();
    let masses: Vec<f64> = topology.atoms.iter().map(|a| a.mass).collect();
    let is_named = |i: usize, name: &str| {
        let atom = &topology.atoms[i];
        atom.element == name || atom.name == name
    };
    let atoms = SplitAtoms {
        bonds: &bonds,
        masses: &masses,
        is_named: &is_named,
        table: "[topology.split]",
        default_by: SwitchBy::AtomPair,
    };
    split_terms(section, &atoms, spec, q, terms, report)
}

/// A total charge off a whole number by more than 1e-3 e (a charge lost or mistyped: the
/// files print charges to 1e-8 e, and their round-off over 10⁵ atoms stays below 1e-5 e);
/// with PME a box's net charge above 1e-4 e, which PME neutralises with a uniform
/// background (as the scenes' `[forcefield]` says, `nonbonded::pme_term`).
fn charge_notices(topology: &Topology, electrostatics: Electrostatics) -> Vec<String> {
    let net = topology.total_charge();
    let mut notices = Vec::new();
    if (net - net.round()).abs() > 1e-3 {
        notices.push(format!(
            "warning: the total charge is {net:.6} e, not a whole number: a charge may be \
             missing or mistyped in {}",
            topology.source.display()
        ));
    }
    if matches!(electrostatics, Electrostatics::Ewald { .. }) && net.abs() > 1e-4 {
        notices.push(format!(
            "notice: the box carries a net charge of {net:.6} e; PME adds the neutralising \
             background -pi Q^2/(2 V alpha^2) (energy component ewald-background)"
        ));
    }
    notices
}

/// The scaled 1-4 pairs, without cutoff, plain Coulomb: `lj-14` and `coulomb-14`.
fn pairs_14(
    topology: &Topology,
    electrostatics: Electrostatics,
    (periodic_box, level): (Option<PeriodicBox>, Assignment),
    terms: &mut Terms,
    report: &mut Vec<String>,
) {
    let mut lj_pairs = Vec::new();
    let mut coulomb_pairs = Vec::new();
    let mut scales: BTreeMap<String, usize> = BTreeMap::new();
    for pair in &topology.pairs_14 {
        let [i, j] = pair.atoms;
        let ((c12, c6), lj_scale, lj_key) = match pair.lj {
            Some(own) => (own, 1.0, "own LJ".to_string()),
            None => {
                let (a, b) = (topology.atoms[i].lj_type, topology.atoms[j].lj_type);
                let key = format!("LJ × {}", scale_text(pair.lj_scale));
                (topology.lj.pair(a, b), pair.lj_scale, key)
            }
        };
        let key = format!("Coulomb × {}, {lj_key}", scale_text(pair.coulomb_scale));
        *scales.entry(key).or_insert(0) += 1;
        if lj_scale != 0.0 && c12 > 0.0 && c6 > 0.0 {
            // ε and σ of the pair: σ⁶ = c12/c6, ε = c6²/(4 c12).
            let sigma = (c12 / c6).powf(1.0 / 6.0);
            let epsilon = c6 * c6 / (4.0 * c12);
            lj_pairs.push(Pair {
                a: Site::Particle(i),
                b: Site::Particle(j),
                potential: LennardJones::new(lj_scale * epsilon, sigma, f64::INFINITY, false),
            });
        }
        let qq = pair.coulomb_scale
            * COULOMB_KCAL_ANGSTROM
            * topology.atoms[i].charge
            * topology.atoms[j].charge;
        if electrostatics != Electrostatics::None && qq != 0.0 {
            coulomb_pairs.push(Pair {
                a: Site::Particle(i),
                b: Site::Particle(j),
                potential: CoulombPair { charge_product: qq },
            });
        }
    }
    let scales: Vec<String> = scales
        .iter()
        .map(|(key, count)| format!("{count} with {key}"))
        .collect();
    report.push(format!(
        "1-4 pairs: {} ({}), no cutoff, plain Coulomb, terms \"lj-14\" and \"coulomb-14\"",
        topology.pairs_14.len(),
        if scales.is_empty() {
            "none".into()
        } else {
            scales.join("; ")
        }
    ));
    for (name, kind, list) in [("lj-14", "lennard-jones-14", lj_pairs)] {
        if !list.is_empty() {
            let term = PairTerm::new(kind, TermClass::Nonbonded, 3, list, periodic_box);
            terms.push((name.into(), Box::new(term), level));
        }
    }
    if !coulomb_pairs.is_empty() {
        let kind = "coulomb-14";
        let term = PairTerm::new(kind, TermClass::Nonbonded, 3, coulomb_pairs, periodic_box);
        terms.push(("coulomb-14".into(), Box::new(term), level));
    }
}
