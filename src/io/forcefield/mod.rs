//! The `[forcefield]` section of a molecule scene: a small, explicit molecular force field
//! built from a structure's atoms and bond graph. Units are the scene's (`units = "real"`:
//! Å, kcal/mol, e, degrees for angles in the file).
//!
//! * bonds `(k/2)(r − r₀)²` for every bond of the structure; `k` and `r₀` from
//!   `[forcefield.bonds] "A-B" = { k, r0 }`, else `k` from the built-in table per element
//!   pair; `r₀` from the starting geometry unless given;
//! * angles `(k/2)(θ − θ₀)²` for every pair of bonds sharing an atom, same rules
//!   (`[forcefield.angles] "A-B-C" = { k, theta0 }`, θ₀ in degrees);
//! * proper torsions `Σ k (1 + cos(nφ − δ))` only when `[forcefield.torsions]` is given:
//!   then every proper dihedral of the bond graph needs an entry (`"A-B-C-D"`, either
//!   direction, `X` a wildcard at the ends);
//! * Lennard-Jones 12-6 with Lorentz–Berthelot mixing (`σ = (σ_a + σ_b)/2`, `ε = √(ε_a ε_b)`)
//!   from `[forcefield.atoms] A = { epsilon, sigma }` or the built-in per-element table, or
//!   per type pair from `[forcefield.pairs] "A-B" = { epsilon, sigma }`;
//! * Coulomb with charges from `[forcefield.atoms] A = { charge }` or the per-atom list
//!   `charges`, default 0, as DSF or reaction field with a cutoff, or plain without one;
//! * 1-2 and 1-3 pairs excluded (`scale_12`, `scale_13` = 0; 1 makes them ordinary pairs),
//!   1-4 pairs scaled by `scale_14_lj` and `scale_14_coulomb` (defaults 0.5 and 1/1.2, the
//!   AMBER convention) and computed without cutoff in their own terms, as OpenMM computes
//!   `NonbondedForce` exceptions; with both scales 1 they are ordinary pairs.
//!
//! Atom types are the atom names of the structure file; a type that is no element name
//! gives its `element` (or mass) in `[forcefield.atoms]`. Every lookup tries the type names
//! first, then the element names, then the built-in table; an explicit value always wins.
//! Missing parameters are an error naming the atoms. The builder reports which value came
//! from where; runs print that report.
//!
//! The built-in tables are generic (one value per element pair or triple): bond and angle
//! constants from AMBER ff94 (Cornell et al., J. Am. Chem. Soc. 117, 5179 (1995); their
//! `K(r − r₀)²` doubled to this `(k/2)` form) and Lennard-Jones from AMBER parm99
//! (σ = 2R*/2^{1/6}). They make a molecule run; they are no validated force field.

use std::collections::BTreeMap;

use serde::Deserialize;

use crate::forces::ForceTerm;
use crate::forces::clusters::ClusterList;
use crate::forces::nonbonded::{Electrostatics, LjPair, Nonbonded};
use crate::split::Assignment;
use crate::system::PeriodicBox;
use crate::units::Units;

mod atoms;
mod bonded;
pub(crate) mod distance_split;
mod nonbonded;

pub use nonbonded::{inverse_length, rf_dielectric};

pub use distance_split::SplitSection;

use atoms::AtomTable;
use bonded::Topology;
use nonbonded::{Exclusions, Settings};

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ForcefieldSpec {
    /// Non-bonded cutoff (length); none: every pair (no periodic box).
    pub cutoff: Option<f64>,
    /// Neighbour-list skin (length), default 2 (rebuilds against list length: fastest of
    /// 1, 1.5, 2, 2.5 Å on 5184 water atoms at 4 fs).
    pub skin: Option<f64>,
    /// The pruned inner list's buffer (length, at most the skin), default half the skin.
    pub inner_buffer: Option<f64>,
    /// `"dsf"`, `"reaction-field"`, `"plain"` or `"none"`.
    pub coulomb: Option<String>,
    pub dsf_alpha: Option<f64>,
    pub rf_dielectric: Option<f64>,
    /// PME (`coulomb = "pme"`): `erfc(α r_c)` = this, GROMACS `ewald-rtol` (default 1e-5).
    pub ewald_tolerance: Option<f64>,
    /// PME grid spacing (length), default 1.2 Å (GROMACS `fourier-spacing`).
    pub fourier_spacing: Option<f64>,
    /// PME splitting coefficient α: a number in the scene's inverse length unit, or text
    /// with its unit (`"0.347/Å"`, `"3.47/nm"`); overrides `ewald_tolerance`.
    pub ewald_alpha: Option<InverseLength>,
    /// PME grid points per axis; overrides `fourier_spacing`.
    pub pme_grid: Option<[usize; 3]>,
    /// PME B-spline order, 4 to 6 (default 5).
    pub pme_order: Option<usize>,
    /// The level of the `pme-reciprocal` term (default: the slowest).
    pub pme_level: Option<usize>,
    /// The level of the cutoff (real-space) term, `"nonbonded"` (default: the slowest);
    /// not with `[forcefield.split]`, which places its two parts itself.
    pub nonbonded_level: Option<usize>,
    pub lj_shift: Option<bool>,
    pub scale_12: Option<f64>,
    pub scale_13: Option<f64>,
    pub scale_14_lj: Option<f64>,
    pub scale_14_coulomb: Option<f64>,
    /// Per-atom charges, overriding the per-type ones.
    pub charges: Option<Vec<f64>>,
    #[serde(default)]
    pub atoms: BTreeMap<String, AtomSpec>,
    #[serde(default)]
    pub pairs: BTreeMap<String, PairSpec>,
    #[serde(default)]
    pub bonds: BTreeMap<String, BondSpec>,
    #[serde(default)]
    pub angles: BTreeMap<String, AngleSpec>,
    pub torsions: Option<BTreeMap<String, Vec<CosineSpec>>>,
    /// The cutoff term split by distance across two levels (`[forcefield.split]`).
    pub split: Option<SplitSection>,
}

/// Electrostatics settings that replace a scene's `[forcefield]` keys (the command line's
/// `--coulomb`, `--ewald-alpha`, …): each given value overrides its key.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ElectrostaticsOverrides {
    pub coulomb: Option<String>,
    pub ewald_tolerance: Option<f64>,
    pub fourier_spacing: Option<f64>,
    pub ewald_alpha: Option<InverseLength>,
    pub pme_grid: Option<[usize; 3]>,
    pub pme_order: Option<usize>,
    pub pme_level: Option<usize>,
    pub nonbonded_level: Option<usize>,
    /// The cutoff term split by distance (`--split`): replaces the scene's split section.
    pub split: Option<SplitSection>,
}

impl ElectrostaticsOverrides {
    pub fn is_empty(&self) -> bool {
        *self == ElectrostaticsOverrides::default()
    }

    /// The given keys into a `[topology]` table (the command line over a topology file).
    pub fn write_to(&self, table: &mut toml::Table) {
        let mut put = |key: &str, value: Option<toml::Value>| {
            if let Some(value) = value {
                table.insert(key.into(), value);
            }
        };
        let whole = |n: usize| toml::Value::Integer(n as i64);
        put("coulomb", self.coulomb.clone().map(toml::Value::String));
        put(
            "ewald_tolerance",
            self.ewald_tolerance.map(toml::Value::Float),
        );
        put(
            "fourier_spacing",
            self.fourier_spacing.map(toml::Value::Float),
        );
        put(
            "ewald_alpha",
            self.ewald_alpha.as_ref().map(|a| match a {
                InverseLength::Number(x) => toml::Value::Float(*x),
                InverseLength::Text(t) => toml::Value::String(t.clone()),
            }),
        );
        put(
            "pme_grid",
            self.pme_grid
                .map(|g| toml::Value::Array(g.iter().map(|&n| whole(n)).collect())),
        );
        put("pme_order", self.pme_order.map(whole));
        put("pme_level", self.pme_level.map(whole));
        put("nonbonded_level", self.nonbonded_level.map(whole));
        put(
            "split",
            self.split
                .as_ref()
                .and_then(|s| toml::Value::try_from(s).ok()),
        );
    }

    /// Replace the keys of `spec` that are given here. Switching to PME drops the DSF and
    /// reaction-field keys, and switching away drops the PME keys, so the scene's other
    /// model does not trip the check of stray keys.
    pub fn apply(&self, spec: &mut ForcefieldSpec) {
        if let Some(coulomb) = &self.coulomb {
            if coulomb == "pme" {
                spec.dsf_alpha = None;
                spec.rf_dielectric = None;
            } else {
                spec.ewald_tolerance = None;
                spec.fourier_spacing = None;
                spec.ewald_alpha = None;
                spec.pme_grid = None;
                spec.pme_order = None;
                spec.pme_level = None;
            }
            spec.coulomb = Some(coulomb.clone());
        }
        let set = |target: &mut Option<f64>, value: Option<f64>| {
            if value.is_some() {
                *target = value;
            }
        };
        set(&mut spec.ewald_tolerance, self.ewald_tolerance);
        set(&mut spec.fourier_spacing, self.fourier_spacing);
        if let Some(alpha) = &self.ewald_alpha {
            spec.ewald_alpha = Some(alpha.clone());
        }
        if let Some(grid) = self.pme_grid {
            spec.pme_grid = Some(grid);
        }
        if let Some(level) = self.pme_level {
            spec.pme_level = Some(level);
        }
        if let Some(level) = self.nonbonded_level {
            spec.nonbonded_level = Some(level);
        }
        if let Some(order) = self.pme_order {
            spec.pme_order = Some(order);
        }
        if let Some(split) = &self.split {
            spec.split = Some(split.clone());
        }
    }
}

/// An inverse length: a plain number in the scene's unit, or text with a unit.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum InverseLength {
    Number(f64),
    Text(String),
}

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AtomSpec {
    pub element: Option<String>,
    pub mass: Option<f64>,
    pub charge: Option<f64>,
    pub epsilon: Option<f64>,
    pub sigma: Option<f64>,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PairSpec {
    pub epsilon: f64,
    pub sigma: f64,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BondSpec {
    pub k: Option<f64>,
    pub r0: Option<f64>,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AngleSpec {
    pub k: Option<f64>,
    /// Degrees.
    pub theta0: Option<f64>,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CosineSpec {
    pub k: f64,
    pub n: f64,
    /// Degrees.
    #[serde(default)]
    pub phase: f64,
}

/// Built-in bond constants `k` (kcal/mol/Å², `(k/2)(r − r₀)²`): AMBER ff94 `K` × 2.
const BOND_TABLE: &[(&str, &str, f64)] = &[
    ("C", "C", 620.0),
    ("C", "H", 680.0),
    ("C", "N", 674.0),
    ("C", "O", 640.0),
    ("C", "S", 454.0),
    ("H", "N", 868.0),
    ("H", "O", 1106.0),
    ("H", "S", 548.0),
];

/// Built-in angle constants `k` (kcal/mol/rad², `(k/2)(θ − θ₀)²`), by (end, centre, end):
/// AMBER ff94 `K` × 2.
const ANGLE_TABLE: &[(&str, &str, &str, f64)] = &[
    ("C", "C", "C", 80.0),
    ("H", "C", "H", 70.0),
    ("C", "C", "H", 100.0),
    ("C", "C", "N", 160.0),
    ("C", "C", "O", 100.0),
    ("H", "C", "N", 100.0),
    ("H", "C", "O", 100.0),
    ("N", "C", "O", 160.0),
    ("C", "C", "S", 100.0),
    ("H", "C", "S", 100.0),
    ("C", "N", "C", 100.0),
    ("C", "N", "H", 100.0),
    ("H", "N", "H", 70.0),
    ("C", "O", "H", 110.0),
    ("H", "O", "H", 110.0),
    ("C", "S", "H", 86.0),
];

/// Built-in Lennard-Jones (ε kcal/mol, σ Å) per element: AMBER parm99 CT, HC, N, OH, S
/// (σ = 2R*/2^{1/6}) and argon.
const LJ_TABLE: &[(&str, f64, f64)] = &[
    ("H", 0.0157, 2.649_533),
    ("C", 0.1094, 3.399_669),
    ("N", 0.17, 3.249_999),
    ("O", 0.2104, 3.066_469),
    ("S", 0.25, 3.563_595),
    ("Ar", 0.2381, 3.405),
];

/// One atom as the force field sees it.
#[derive(Clone, Debug)]
pub struct FfAtom {
    /// The name in the structure file (the atom type).
    pub type_name: String,
    /// Element symbol as chemfiles reads it (may be empty for an unknown type).
    pub element: String,
    /// Mass from the element table (0 when unknown), in the scene's unit.
    pub element_mass: f64,
}

/// What the builder produces.
pub struct BuiltForcefield {
    pub terms: Vec<(String, Box<dyn ForceTerm>, Assignment)>,
    /// Per-atom masses in the scene's unit.
    pub masses: Vec<f64>,
    pub charges: Vec<f64>,
    /// Element symbol per atom (after `[forcefield.atoms] element` overrides).
    pub elements: Vec<String>,
    /// Which parameter came from where, one line each.
    pub report: Vec<String>,
    /// Every parameter of every interaction, for `longstep forces --parameters` (peer codes
    /// build the same system from it: `scripts/compare_openmm.py`).
    pub parameters: serde_json::Value,
}

/// Report of one kind of bond or angle: count, constant, its source, the given rest value
/// and the geometric ones.
type Group = (usize, f64, &'static str, Option<f64>, Vec<f64>);

/// Where a parameter came from.
fn source(given: bool) -> &'static str {
    if given { "scene" } else { "built-in table" }
}

pub struct ForcefieldInput<'a> {
    pub spec: &'a ForcefieldSpec,
    pub units: Units,
    pub atoms: &'a [FfAtom],
    /// Positions, `n × 3`.
    pub q: &'a [f64],
    pub bonds: &'a [[usize; 2]],
    pub periodic_box: Option<PeriodicBox>,
}

/// The force-field terms, in the order the sections add them.
type Terms = Vec<(String, Box<dyn ForceTerm>, Assignment)>;

/// What the sections read: the input and every atom's resolved parameters.
struct Context<'a> {
    input: &'a ForcefieldInput<'a>,
    atoms: &'a AtomTable,
}

impl Context<'_> {
    fn position(&self, i: usize) -> [f64; 3] {
        let q = self.input.q;
        [q[3 * i], q[3 * i + 1], q[3 * i + 2]]
    }

    /// `r_a − r_b`, the nearest image in a periodic box.
    fn difference(&self, a: usize, b: usize) -> [f64; 3] {
        let (ra, rb) = (self.position(a), self.position(b));
        let d: [f64; 3] = std::array::from_fn(|k| ra[k] - rb[k]);
        match &self.input.periodic_box {
            Some(b) => std::array::from_fn(|a| b.wrap(a, d[a])),
            None => d,
        }
    }

    /// The angle `i-j-k` at `j` (radians).
    fn angle(&self, i: usize, j: usize, k: usize) -> f64 {
        let (u, w) = (self.difference(i, j), self.difference(k, j));
        let cross = [
            u[1] * w[2] - u[2] * w[1],
            u[2] * w[0] - u[0] * w[2],
            u[0] * w[1] - u[1] * w[0],
        ];
        norm(cross).atan2(u[0] * w[0] + u[1] * w[1] + u[2] * w[2])
    }

    /// Type names and elements of some atoms, for table lookups.
    fn names(&self, atoms: &[usize]) -> (Vec<&str>, Vec<&str>) {
        (
            atoms
                .iter()
                .map(|&a| self.input.atoms[a].type_name.as_str())
                .collect(),
            atoms
                .iter()
                .map(|&a| self.atoms.elements[a].as_str())
                .collect(),
        )
    }

    /// `"CT 0 - HC 1"`, for messages.
    fn label(&self, atoms: &[usize]) -> String {
        atoms
            .iter()
            .map(|&a| format!("{} {}", self.input.atoms[a].type_name, a))
            .collect::<Vec<_>>()
            .join(" - ")
    }
}

fn norm(d: [f64; 3]) -> f64 {
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

/// Build the force-field terms. Errors are messages for the scene to locate.
pub fn build_forcefield(input: &ForcefieldInput) -> Result<BuiltForcefield, String> {
    let mut report = Vec::new();
    let atoms = atoms::resolve(input, &mut report)?;
    let graph = Topology::new(input.bonds, input.atoms.len())?;
    let ctx = Context {
        input,
        atoms: &atoms,
    };
    let mut terms = Terms::new();
    let dumps = [
        bonded::bonds(&ctx, &graph.bonds, &mut terms, &mut report)?,
        bonded::angles(&ctx, &graph.angles, &mut terms, &mut report)?,
        bonded::torsions(&ctx, &graph.dihedrals, &mut terms, &mut report)?,
    ];
    nonbonded::stray_pme_keys(input.spec)?;
    let exclusions = nonbonded::exclusions(input.spec, &graph, &mut report)?;
    let settings = nonbonded::settings(input, &atoms.charges)?;
    let lj = nonbonded::lennard_jones(input.spec, &atoms, &settings, &mut report);
    report.push(nonbonded::report_line(&settings));
    if settings.electrostatics == Electrostatics::None && atoms.charges.iter().any(|&c| c != 0.0) {
        report.push(
            "notice: the atoms carry charges, but [forcefield] coulomb = \"none\": the charges \
             are ignored (no electrostatics at all)"
                .into(),
        );
    }
    let parameters = parameters(&ctx, &settings, &lj, &exclusions, dumps);
    let cutoff_spec = nonbonded::cutoff_spec(input, &atoms, &settings, &lj, &exclusions.excluded);
    match (&input.spec.split, input.spec.nonbonded_level) {
        (None, level) => terms.push((
            "nonbonded".into(),
            Box::new(Nonbonded::new(cutoff_spec, input.q)?),
            level.map_or(Assignment::Default, Assignment::Level),
        )),
        (Some(_), Some(_)) => {
            return Err(
                "[forcefield] nonbonded_level places the whole cutoff term; with \
                        [forcefield.split] give its short_level and remainder_level instead"
                    .into(),
            );
        }
        (Some(section), None) => {
            distance_split::terms(input, &atoms, section, cutoff_spec, &mut terms, &mut report)?
        }
    }
    nonbonded::pme_term(
        input,
        &atoms,
        &settings,
        &exclusions,
        &mut terms,
        &mut report,
    )?;
    nonbonded::pairs_14_terms(input, &atoms, &settings, &lj, &exclusions, &mut terms);
    Ok(BuiltForcefield {
        terms,
        masses: atoms.masses,
        charges: atoms.charges,
        elements: atoms.elements,
        report,
        parameters,
    })
}

/// Every parameter of every interaction as JSON (`longstep forces --parameters`); `dumps`
/// are the bonds, angles and torsions.
fn parameters(
    ctx: &Context,
    settings: &Settings,
    lj: &[LjPair],
    exclusions: &Exclusions,
    [bonds, angles, torsions]: [Vec<serde_json::Value>; 3],
) -> serde_json::Value {
    let atoms = ctx.atoms;
    let nt = atoms.kinds.len();
    let cutoff = settings.cutoff;
    let (coulomb_name, alpha, dielectric) = match settings.electrostatics {
        Electrostatics::None => ("none", None, None),
        Electrostatics::Plain => ("plain", None, None),
        Electrostatics::DampedShiftedForce { alpha } => ("dsf", Some(alpha), None),
        Electrostatics::ReactionField { dielectric } => ("reaction-field", None, Some(dielectric)),
        Electrostatics::Ewald { .. } => ("pme", None, None),
    };
    let ewald = settings
        .ewald
        .map(|p| serde_json::json!({"alpha": p.alpha, "grid": p.grid, "order": p.order}));
    serde_json::json!({
        "units": ctx.input.units.name(),
        "elements": atoms.elements,
        "masses": atoms.masses,
        "charges": atoms.charges,
        "types": atoms.kinds,
        "type_of": atoms.kind_of,
        "lj_epsilon": (0..nt).map(|a| (0..nt).map(|b| {
            let p = lj[a * nt + b];
            if p.c12 > 0.0 && p.c6 > 0.0 { p.c6 * p.c6 / (4.0 * p.c12) } else { 0.0 }
        }).collect::<Vec<_>>()).collect::<Vec<_>>(),
        "lj_sigma": (0..nt).map(|a| (0..nt).map(|b| {
            let p = lj[a * nt + b];
            if p.c12 > 0.0 && p.c6 > 0.0 { (p.c12 / p.c6).powf(1.0 / 6.0) } else { 1.0 }
        }).collect::<Vec<_>>()).collect::<Vec<_>>(),
        "bonds": bonds,
        "angles": angles,
        "torsions": torsions,
        "exclusions": exclusions.excluded,
        "pairs_14": if exclusions.separate_14 {
            exclusions.pairs_14.iter().collect::<Vec<_>>()
        } else {
            Vec::new()
        },
        "scale_14_lj": exclusions.scale_14_lj,
        "scale_14_coulomb": exclusions.scale_14_coulomb,
        "nonbonded": {
            "cutoff": if cutoff.is_finite() { Some(cutoff) } else { None },
            "coulomb": coulomb_name,
            "dsf_alpha": alpha,
            "rf_dielectric": dielectric,
            "pme": ewald,
            "lj_shift": settings.lj_shift && cutoff.is_finite(),
            "coulomb_constant": settings.coulomb_constant,
        },
        "box": ctx.input.periodic_box.map(|b| b.lengths),
        "doc": "bonds [i, j, k, r0] (E = k/2 (r - r0)^2); angles [i, j, k, k, theta0 rad] \
                (E = k/2 (theta - theta0)^2); torsions [[i, j, k, l], [[k, n, phase rad], ...]] \
                (E = sum k (1 + cos(n phi - phase))); exclusions: pairs left out of the \
                cutoff term (with PME, corrected by -q_i q_j erf(alpha r)/r); pairs_14: scaled, \
                no cutoff, plain Coulomb; nonbonded.pme: alpha (1/length), grid, order",
    })
}

/// The scene's `box` against `[forcefield] cutoff`, for a scene to check before it looks
/// for overlapping atoms: a box too small for the cutoff wraps the structure onto itself,
/// and the overlap it causes is not what the user must fix. Every box length must exceed
/// 2 × cutoff (the minimum-image convention, as [`Nonbonded::new`] requires); the message
/// names the keys and says how far the structure (`q`, `n × 3`) spans, for comparison.
pub fn check_box(
    spec: &ForcefieldSpec,
    periodic_box: Option<PeriodicBox>,
    q: &[f64],
) -> Result<(), String> {
    let (Some(cutoff), Some(pb)) = (spec.cutoff, periodic_box) else {
        return Ok(());
    };
    let shortest = pb.lengths.iter().cloned().fold(f64::INFINITY, f64::min);
    if 2.0 * cutoff < shortest {
        return Ok(());
    }
    let span: Vec<String> = (0..3)
        .map(|axis| {
            let along = q.iter().skip(axis).step_by(3);
            let lo = along.clone().cloned().fold(f64::INFINITY, f64::min);
            let hi = along.cloned().fold(f64::NEG_INFINITY, f64::max);
            crate::io::number::Num(if hi >= lo { hi - lo } else { 0.0 }).to_string()
        })
        .collect();
    let lengths: Vec<String> = pb
        .lengths
        .iter()
        .map(|&l| crate::io::number::Num(l).to_string())
        .collect();
    Err(format!(
        "box = [{}] is too small for [forcefield] cutoff = {}: every box length must be \
         larger than 2 × cutoff = {} (the minimum-image convention); the structure's atoms \
         span [{}] — give the box the structure was made in, or a shorter cutoff",
        lengths.join(", "),
        crate::io::number::Num(cutoff),
        crate::io::number::Num(2.0 * cutoff),
        span.join(", ")
    ))
}

/// The closest pair of atoms nearer than `limit`, if any (`q` is `n × 3`).
pub fn closest_overlap(
    q: &[f64],
    periodic_box: Option<PeriodicBox>,
    limit: f64,
) -> Option<(usize, usize, f64)> {
    let n = q.len() / 3;
    let none = vec![0u32; n + 1];
    let mut list = ClusterList::new(
        limit,
        0.0,
        periodic_box.map(|b| b.lengths),
        none,
        Vec::new(),
        vec![0.0; n],
    );
    list.update(q);
    let mut worst: Option<(usize, usize, f64)> = None;
    list.for_each_pair(false, |i, j, d| {
        let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        if r < limit && worst.is_none_or(|w| r < w.2) {
            worst = Some((i.min(j), i.max(j), r));
        }
    });
    worst
}

fn range_text(values: &[f64]) -> String {
    let lo = values.iter().cloned().fold(f64::INFINITY, f64::min);
    let hi = values.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    if (hi - lo).abs() <= 1e-9 * hi.abs().max(1.0) {
        format!("{lo:.4}")
    } else {
        format!("{lo:.4} to {hi:.4}")
    }
}

fn sorted_key(names: &[&str]) -> String {
    let mut v = names.to_vec();
    v.sort_unstable();
    v.join("-")
}

fn angle_key(names: &[&str]) -> String {
    let (a, c) = if names[0] <= names[2] {
        (names[0], names[2])
    } else {
        (names[2], names[0])
    };
    format!("{a}-{}-{c}", names[1])
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Symmetry {
    /// `A-B` = `B-A`, `A-B-C` = `C-B-A`.
    Reversible,
    /// `A-B-C-D` = `D-C-B-A`, and `X` matches any type at the two ends.
    Torsion,
}

/// The table entry for the atoms with these type names or, failing that, elements.
fn lookup<'a, T>(
    table: &'a BTreeMap<String, T>,
    types: &[&str],
    elements: &[&str],
    symmetry: Symmetry,
) -> Option<(&'a str, &'a T)> {
    let matches = |key: &str, names: &[&str]| -> bool {
        let parts: Vec<&str> = key.split('-').map(str::trim).collect();
        if parts.len() != names.len() {
            return false;
        }
        let fits = |order: &mut dyn Iterator<Item = &&str>| -> bool {
            order
                .zip(&parts)
                .enumerate()
                .all(|(position, (name, part))| {
                    *part == *name
                        || (symmetry == Symmetry::Torsion
                            && *part == "X"
                            && (position == 0 || position + 1 == parts.len()))
                })
        };
        fits(&mut names.iter()) || fits(&mut names.iter().rev())
    };
    // Exact keys before wildcard ones, types before elements.
    for names in [types, elements] {
        for exact in [true, false] {
            for (key, value) in table {
                let has_wildcard = key.split('-').any(|p| p.trim() == "X");
                if has_wildcard == exact {
                    continue;
                }
                if matches(key, names) {
                    return Some((key.as_str(), value));
                }
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(cutoff: f64) -> ForcefieldSpec {
        ForcefieldSpec {
            cutoff: Some(cutoff),
            ..ForcefieldSpec::default()
        }
    }

    #[test]
    fn a_box_not_larger_than_twice_the_cutoff_is_named() {
        let q = [0.0, 0.0, 0.0, 18.5, 1.0, 2.0];
        let small = PeriodicBox {
            lengths: [10.0, 10.0, 10.0],
        };
        let message = check_box(&spec(9.0), Some(small), &q).unwrap_err();
        assert!(
            message.starts_with("box = [10, 10, 10] is too small for [forcefield] cutoff = 9")
                && message.contains("2 × cutoff = 18")
                && message.contains("span [18.5, 1, 2]"),
            "{message}"
        );
        // Exactly 2 × cutoff is refused (Nonbonded::new's `2 cutoff >= shortest`).
        let edge = PeriodicBox {
            lengths: [30.0, 18.0, 30.0],
        };
        assert!(check_box(&spec(9.0), Some(edge), &q).is_err());
        let fine = PeriodicBox {
            lengths: [18.6, 18.6, 18.6],
        };
        assert_eq!(check_box(&spec(9.0), Some(fine), &q), Ok(()));
        assert_eq!(check_box(&spec(9.0), None, &q), Ok(()));
        let no_cutoff = ForcefieldSpec::default();
        assert_eq!(check_box(&no_cutoff, Some(small), &q), Ok(()));
    }
}
