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

use std::collections::{BTreeMap, BTreeSet};

use serde::Deserialize;

use crate::forces::angle::{AngleBend, HarmonicAngles};
use crate::forces::coulomb::Coulomb;
use crate::forces::lennard_jones::LennardJones;
use crate::forces::neighbour_list::NeighbourList;
use crate::forces::nonbonded::{Electrostatics, LjPair, Nonbonded, NonbondedSpec};
use crate::forces::pair::{Pair, PairTerm};
use crate::forces::spring::HarmonicBond;
use crate::forces::torsion::{Cosine, Dihedral, Torsions};
use crate::forces::{ForceTerm, Site, TermClass};
use crate::split::Assignment;
use crate::system::PeriodicBox;
use crate::units::{COULOMB_KCAL_ANGSTROM, Units};

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ForcefieldSpec {
    /// Non-bonded cutoff (length); none: every pair (no periodic box).
    pub cutoff: Option<f64>,
    /// Neighbour-list skin (length), default 2 (rebuilds against list length: fastest of
    /// 1, 1.5, 2, 2.5 Å on 5184 water atoms at 4 fs).
    pub skin: Option<f64>,
    /// `"dsf"`, `"reaction-field"`, `"plain"` or `"none"`.
    pub coulomb: Option<String>,
    pub dsf_alpha: Option<f64>,
    pub rf_dielectric: Option<f64>,
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

/// Build the force-field terms. Errors are messages for the scene to locate.
pub fn build_forcefield(input: &ForcefieldInput) -> Result<BuiltForcefield, String> {
    let spec = input.spec;
    let n = input.atoms.len();
    let q = input.q;
    let mut report = Vec::new();
    let box_lengths = input.periodic_box.map(|b| b.lengths);
    let wrap = |d: [f64; 3]| -> [f64; 3] {
        match &input.periodic_box {
            Some(b) => std::array::from_fn(|a| b.wrap(a, d[a])),
            None => d,
        }
    };
    let position = |i: usize| -> [f64; 3] { [q[3 * i], q[3 * i + 1], q[3 * i + 2]] };
    let difference = |a: usize, b: usize| -> [f64; 3] {
        let (ra, rb) = (position(a), position(b));
        wrap(std::array::from_fn(|k| ra[k] - rb[k]))
    };
    let norm = |d: [f64; 3]| (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();

    // --- atoms: element, mass, charge, LJ ------------------------------------------------
    for key in spec.atoms.keys() {
        if !input
            .atoms
            .iter()
            .any(|a| &a.type_name == key || &a.element == key)
        {
            return Err(format!(
                "[forcefield.atoms] has \"{key}\", but no atom of the structure has that type \
                 or element"
            ));
        }
    }
    let atom_spec = |atom: &FfAtom| -> (Option<&AtomSpec>, Option<&AtomSpec>) {
        (
            spec.atoms.get(&atom.type_name),
            spec.atoms.get(&atom.element),
        )
    };
    let mut elements = Vec::with_capacity(n);
    let mut masses = Vec::with_capacity(n);
    let mut type_charges = Vec::with_capacity(n);
    for (i, atom) in input.atoms.iter().enumerate() {
        let (by_type, by_element) = atom_spec(atom);
        let element = by_type
            .and_then(|s| s.element.clone())
            .unwrap_or_else(|| atom.element.clone());
        let mass = by_type
            .and_then(|s| s.mass)
            .or_else(|| by_element.and_then(|s| s.mass));
        let mass = match mass {
            Some(m) if m > 0.0 && m.is_finite() => m,
            Some(m) => {
                return Err(format!(
                    "atom {i} ({}): mass {m} must be positive",
                    atom.type_name
                ));
            }
            None if atom.element_mass > 0.0 => atom.element_mass,
            None => {
                return Err(format!(
                    "atom {i} has type \"{}\", which is no element: give its element or mass in \
                     [forcefield.atoms] \"{}\"",
                    atom.type_name, atom.type_name
                ));
            }
        };
        let charge = by_type
            .and_then(|s| s.charge)
            .or_else(|| by_element.and_then(|s| s.charge))
            .unwrap_or(0.0);
        elements.push(element);
        masses.push(mass);
        type_charges.push(charge);
    }
    let charges = match &spec.charges {
        Some(list) => {
            if list.len() != n {
                return Err(format!(
                    "[forcefield] charges lists {} charges for {n} atoms",
                    list.len()
                ));
            }
            list.clone()
        }
        None => type_charges,
    };
    if let Some(bad) = charges.iter().position(|c| !c.is_finite()) {
        return Err(format!("atom {bad} has a non-finite charge"));
    }

    // Atom kinds for reports and LJ types: distinct type names in order of appearance.
    let mut kinds: Vec<String> = Vec::new();
    let mut kind_of = vec![0u32; n];
    for (i, atom) in input.atoms.iter().enumerate() {
        let index = match kinds.iter().position(|k| k == &atom.type_name) {
            Some(index) => index,
            None => {
                kinds.push(atom.type_name.clone());
                kinds.len() - 1
            }
        };
        kind_of[i] = index as u32;
    }
    let first_of_kind: Vec<usize> = (0..kinds.len())
        .map(|k| kind_of.iter().position(|&x| x as usize == k).unwrap_or(0))
        .collect();
    let mut lj_params = Vec::with_capacity(kinds.len());
    for (k, name) in kinds.iter().enumerate() {
        let i = first_of_kind[k];
        let atom = &input.atoms[i];
        let (by_type, by_element) = atom_spec(atom);
        let element = &elements[i];
        let given = |f: fn(&AtomSpec) -> Option<f64>| {
            by_type.and_then(f).or_else(|| by_element.and_then(f))
        };
        let table = LJ_TABLE.iter().find(|(e, _, _)| e == element);
        let epsilon = given(|s| s.epsilon);
        let sigma = given(|s| s.sigma);
        let (epsilon, sigma, from) = match (epsilon, sigma, table) {
            (Some(e), Some(s), _) => (e, s, "scene"),
            (None, None, Some(&(_, e, s))) => (e, s, "built-in table (AMBER parm99)"),
            (Some(_), None, _) | (None, Some(_), _) => {
                return Err(format!(
                    "[forcefield.atoms] \"{name}\" gives only one of epsilon and sigma; give both"
                ));
            }
            (None, None, None) => {
                return Err(format!(
                    "no Lennard-Jones parameters for atom type \"{name}\" (element \"{element}\", \
                     first at atom {i}): give epsilon and sigma in [forcefield.atoms] \"{name}\""
                ));
            }
        };
        if !(epsilon >= 0.0 && sigma > 0.0) {
            return Err(format!(
                "atom type \"{name}\": epsilon must be ≥ 0 and sigma > 0, got {epsilon} and {sigma}"
            ));
        }
        let count = kind_of.iter().filter(|&&x| x as usize == k).count();
        report.push(format!(
            "atom {name} ×{count}: element {element}, mass {} ({}), charge {} ({}), LJ ε = {epsilon}, σ = {sigma} ({from})",
            masses[i],
            if by_type.and_then(|s| s.mass).or(by_element.and_then(|s| s.mass)).is_some() {
                "scene"
            } else {
                "element"
            },
            charges[i],
            if spec.charges.is_some() {
                "per-atom list"
            } else if by_type.and_then(|s| s.charge).or(by_element.and_then(|s| s.charge)).is_some() {
                "scene"
            } else {
                "default 0"
            },
        ));
        lj_params.push((epsilon, sigma));
    }

    // --- bond graph -----------------------------------------------------------------------
    let mut neighbours: Vec<BTreeSet<usize>> = vec![BTreeSet::new(); n];
    for &[a, b] in input.bonds {
        if a >= n || b >= n || a == b {
            return Err(format!(
                "bond {a}-{b} does not join two atoms of the structure"
            ));
        }
        neighbours[a].insert(b);
        neighbours[b].insert(a);
    }
    let mut bonds: Vec<[usize; 2]> = input
        .bonds
        .iter()
        .map(|&[a, b]| [a.min(b), a.max(b)])
        .collect();
    bonds.sort_unstable();
    bonds.dedup();
    let mut angles = Vec::new();
    for (j, around) in neighbours.iter().enumerate() {
        let list: Vec<usize> = around.iter().copied().collect();
        for (x, &i) in list.iter().enumerate() {
            for &k in &list[x + 1..] {
                angles.push([i, j, k]);
            }
        }
    }
    let mut dihedrals = Vec::new();
    for &[j, k] in &bonds {
        for &i in &neighbours[j] {
            if i == k {
                continue;
            }
            for &l in &neighbours[k] {
                if l == j || l == i {
                    continue;
                }
                dihedrals.push([i, j, k, l]);
            }
        }
    }

    let names = |atoms: &[usize]| -> (Vec<&str>, Vec<&str>) {
        (
            atoms
                .iter()
                .map(|&a| input.atoms[a].type_name.as_str())
                .collect(),
            atoms.iter().map(|&a| elements[a].as_str()).collect(),
        )
    };
    let label = |atoms: &[usize]| -> String {
        atoms
            .iter()
            .map(|&a| format!("{} {}", input.atoms[a].type_name, a))
            .collect::<Vec<_>>()
            .join(" - ")
    };

    // --- bonds ----------------------------------------------------------------------------
    let mut terms: Vec<(String, Box<dyn ForceTerm>, Assignment)> = Vec::new();
    let mut bond_groups: BTreeMap<String, Group> = BTreeMap::new();
    let mut bond_pairs = Vec::with_capacity(bonds.len());
    let mut bond_dump = Vec::with_capacity(bonds.len());
    for &[a, b] in &bonds {
        let (types, elems) = names(&[a, b]);
        let found = lookup(&spec.bonds, &types, &elems, Symmetry::Reversible);
        let table = BOND_TABLE
            .iter()
            .find(|(x, y, _)| {
                (*x == elems[0] && *y == elems[1]) || (*x == elems[1] && *y == elems[0])
            })
            .map(|t| t.2);
        let k = match (found.and_then(|(_, s)| s.k), table) {
            (Some(k), _) => (k, true),
            (None, Some(k)) => (k, false),
            (None, None) => {
                return Err(format!(
                    "no force constant for bond {}: give [forcefield.bonds] \"{}-{}\" = {{ k = … }}",
                    label(&[a, b]),
                    types[0],
                    types[1]
                ));
            }
        };
        let length = norm(difference(a, b));
        let r0 = found.and_then(|(_, s)| s.r0);
        let key = found
            .map(|(key, _)| key.to_string())
            .unwrap_or_else(|| sorted_key(&elems));
        let entry = bond_groups
            .entry(key)
            .or_insert((0, k.0, source(k.1), r0, Vec::new()));
        entry.0 += 1;
        entry.4.push(length);
        if k.0 < 0.0 || k.0.is_nan() || r0.is_some_and(|r| r < 0.0 || r.is_nan()) {
            return Err(format!("bond {}: k and r0 must be ≥ 0", label(&[a, b])));
        }
        bond_pairs.push(Pair {
            a: Site::Particle(a),
            b: Site::Particle(b),
            potential: HarmonicBond {
                stiffness: k.0,
                rest_length: r0.unwrap_or(length),
            },
        });
        bond_dump.push(serde_json::json!([a, b, k.0, r0.unwrap_or(length)]));
    }
    for (key, (count, k, from, r0, lengths)) in &bond_groups {
        report.push(format!(
            "bond {key} ×{count}: k = {k} ({from}), r0 = {}",
            match r0 {
                Some(r) => format!("{r} (scene)"),
                None => format!("geometry ({})", range_text(lengths)),
            }
        ));
    }
    if !bond_pairs.is_empty() {
        terms.push((
            "bonds".into(),
            Box::new(PairTerm::new(
                "bond",
                TermClass::Bonded,
                3,
                bond_pairs,
                input.periodic_box,
            )),
            Assignment::Default,
        ));
    }

    // --- angles ---------------------------------------------------------------------------
    let mut angle_groups: BTreeMap<String, Group> = BTreeMap::new();
    let mut bends = Vec::with_capacity(angles.len());
    let mut angle_dump = Vec::with_capacity(angles.len());
    for &[i, j, k] in &angles {
        let (types, elems) = names(&[i, j, k]);
        let found = lookup(&spec.angles, &types, &elems, Symmetry::Reversible);
        let table = ANGLE_TABLE
            .iter()
            .find(|(x, c, y, _)| {
                *c == elems[1]
                    && ((*x == elems[0] && *y == elems[2]) || (*x == elems[2] && *y == elems[0]))
            })
            .map(|t| t.3);
        let stiffness = match (found.and_then(|(_, s)| s.k), table) {
            (Some(k), _) => (k, true),
            (None, Some(k)) => (k, false),
            (None, None) => {
                return Err(format!(
                    "no force constant for angle {}: give [forcefield.angles] \"{}-{}-{}\" = {{ k = … }}",
                    label(&[i, j, k]),
                    types[0],
                    types[1],
                    types[2]
                ));
            }
        };
        let (u, w) = (difference(i, j), difference(k, j));
        let cross = [
            u[1] * w[2] - u[2] * w[1],
            u[2] * w[0] - u[0] * w[2],
            u[0] * w[1] - u[1] * w[0],
        ];
        let geometry = norm(cross).atan2(u[0] * w[0] + u[1] * w[1] + u[2] * w[2]);
        let theta0 = found.and_then(|(_, s)| s.theta0);
        let key = found
            .map(|(key, _)| key.to_string())
            .unwrap_or_else(|| angle_key(&elems));
        let entry = angle_groups.entry(key).or_insert((
            0,
            stiffness.0,
            source(stiffness.1),
            theta0,
            Vec::new(),
        ));
        entry.0 += 1;
        entry.4.push(geometry.to_degrees());
        bends.push(AngleBend {
            sites: [Site::Particle(i), Site::Particle(j), Site::Particle(k)],
            stiffness: stiffness.0,
            rest_angle: theta0.map_or(geometry, f64::to_radians),
        });
        angle_dump.push(serde_json::json!([
            i,
            j,
            k,
            stiffness.0,
            theta0.map_or(geometry, f64::to_radians)
        ]));
    }
    for (key, (count, k, from, theta0, values)) in &angle_groups {
        report.push(format!(
            "angle {key} ×{count}: k = {k} ({from}), theta0 = {}",
            match theta0 {
                Some(t) => format!("{t}° (scene)"),
                None => format!("geometry ({}°)", range_text(values)),
            }
        ));
    }
    if !bends.is_empty() {
        terms.push((
            "angles".into(),
            Box::new(HarmonicAngles::new(3, bends, input.periodic_box)),
            Assignment::Default,
        ));
    }

    // --- torsions -------------------------------------------------------------------------
    let mut torsion_dump = Vec::new();
    if let Some(table) = &spec.torsions {
        let mut list = Vec::with_capacity(dihedrals.len());
        let mut groups: BTreeMap<String, usize> = BTreeMap::new();
        for &[i, j, k, l] in &dihedrals {
            let (types, elems) = names(&[i, j, k, l]);
            let Some((key, series)) = lookup(table, &types, &elems, Symmetry::Torsion) else {
                return Err(format!(
                    "no torsion parameters for the dihedral {}: give [forcefield.torsions] \
                     \"{}-{}-{}-{}\" (or with X at the ends) = [{{ k = …, n = …, phase = … }}]",
                    label(&[i, j, k, l]),
                    types[0],
                    types[1],
                    types[2],
                    types[3]
                ));
            };
            *groups.entry(key.to_string()).or_insert(0) += 1;
            list.push(Dihedral {
                atoms: [i, j, k, l],
                series: series
                    .iter()
                    .map(|c| Cosine {
                        k: c.k,
                        periodicity: c.n,
                        phase: c.phase.to_radians(),
                    })
                    .collect(),
            });
        }
        for (key, count) in &groups {
            report.push(format!("torsion {key} ×{count} (scene)"));
        }
        for d in &list {
            let series: Vec<_> = d
                .series
                .iter()
                .map(|c| serde_json::json!([c.k, c.periodicity, c.phase]))
                .collect();
            torsion_dump.push(serde_json::json!([d.atoms, series]));
        }
        if !list.is_empty() {
            terms.push((
                "torsions".into(),
                Box::new(Torsions::new(list, input.periodic_box)),
                Assignment::Default,
            ));
        }
    }

    // --- exclusions and 1-4 pairs ----------------------------------------------------------
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
    let mut pairs_12: BTreeSet<(usize, usize)> = BTreeSet::new();
    for &[a, b] in &bonds {
        pairs_12.insert((a, b));
    }
    let mut pairs_13: BTreeSet<(usize, usize)> = BTreeSet::new();
    for &[i, _, k] in &angles {
        let p = (i.min(k), i.max(k));
        if !pairs_12.contains(&p) {
            pairs_13.insert(p);
        }
    }
    let mut pairs_14: BTreeSet<(usize, usize)> = BTreeSet::new();
    for &[i, _, _, l] in &dihedrals {
        let p = (i.min(l), i.max(l));
        if !pairs_12.contains(&p) && !pairs_13.contains(&p) {
            pairs_14.insert(p);
        }
    }
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
        if scale_12 == 0.0 { "excluded" } else { "ordinary" },
        pairs_13.len(),
        if scale_13 == 0.0 { "excluded" } else { "ordinary" },
        pairs_14.len(),
        if separate_14 {
            format!(
                "LJ × {scale_14_lj}, Coulomb × {scale_14_coulomb}, no cutoff, terms \"lj-14\" and \"coulomb-14\""
            )
        } else {
            "ordinary".into()
        }
    ));

    // --- non-bonded -----------------------------------------------------------------------
    let cutoff = match spec.cutoff {
        Some(c) if c > 0.0 && c.is_finite() => c,
        Some(c) => return Err(format!("[forcefield] cutoff must be positive, got {c}")),
        None => f64::INFINITY,
    };
    if box_lengths.is_some() && !cutoff.is_finite() {
        return Err("[forcefield] a periodic box needs a cutoff (give cutoff = …)".into());
    }
    let skin = spec.skin.unwrap_or(2.0);
    if !(skin >= 0.0 && skin.is_finite()) {
        return Err(format!("[forcefield] skin must be ≥ 0, got {skin}"));
    }
    let any_charge = charges.iter().any(|&c| c != 0.0);
    let electrostatics = match spec.coulomb.as_deref() {
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
            dielectric: spec.rf_dielectric.unwrap_or(78.3),
        },
        Some(other) => {
            return Err(format!(
                "unknown [forcefield] coulomb \"{other}\"; use dsf, reaction-field, plain or none"
            ));
        }
    };
    let coulomb_constant = match input.units {
        Units::Real => COULOMB_KCAL_ANGSTROM,
        Units::None => 1.0,
    };
    let lj_shift = spec.lj_shift.unwrap_or(true);
    let nt = kinds.len();
    let mut lj = vec![LjPair::default(); nt * nt];
    for a in 0..nt {
        for b in 0..nt {
            let key_types = [kinds[a].as_str(), kinds[b].as_str()];
            let key_elements = [
                elements[first_of_kind[a]].as_str(),
                elements[first_of_kind[b]].as_str(),
            ];
            let (epsilon, sigma) =
                match lookup(&spec.pairs, &key_types, &key_elements, Symmetry::Reversible) {
                    Some((_, p)) => (p.epsilon, p.sigma),
                    None => {
                        let (ea, sa) = lj_params[a];
                        let (eb, sb) = lj_params[b];
                        ((ea * eb).sqrt(), 0.5 * (sa + sb))
                    }
                };
            lj[a * nt + b] = LjPair::new(epsilon, sigma, cutoff, lj_shift);
        }
    }
    for key in spec.pairs.keys() {
        report.push(format!("LJ pair {key}: ε, σ (scene, no mixing)"));
    }
    report.push(format!(
        "nonbonded: cutoff {}, skin {skin}, LJ {}Lorentz–Berthelot, Coulomb {}",
        if cutoff.is_finite() {
            cutoff.to_string()
        } else {
            "none".into()
        },
        if lj_shift && cutoff.is_finite() {
            "energy-shifted, "
        } else {
            ""
        },
        electrostatics.describe()
    ));
    let (coulomb_name, alpha, dielectric) = match electrostatics {
        Electrostatics::None => ("none", None, None),
        Electrostatics::Plain => ("plain", None, None),
        Electrostatics::DampedShiftedForce { alpha } => ("dsf", Some(alpha), None),
        Electrostatics::ReactionField { dielectric } => ("reaction-field", None, Some(dielectric)),
    };
    let parameters = serde_json::json!({
        "units": input.units.name(),
        "elements": elements,
        "masses": masses,
        "charges": charges,
        "types": kinds,
        "type_of": kind_of,
        "lj_epsilon": (0..nt).map(|a| (0..nt).map(|b| {
            let p = lj[a * nt + b];
            if p.c12 > 0.0 && p.c6 > 0.0 { p.c6 * p.c6 / (4.0 * p.c12) } else { 0.0 }
        }).collect::<Vec<_>>()).collect::<Vec<_>>(),
        "lj_sigma": (0..nt).map(|a| (0..nt).map(|b| {
            let p = lj[a * nt + b];
            if p.c12 > 0.0 && p.c6 > 0.0 { (p.c12 / p.c6).powf(1.0 / 6.0) } else { 1.0 }
        }).collect::<Vec<_>>()).collect::<Vec<_>>(),
        "bonds": bond_dump,
        "angles": angle_dump,
        "torsions": torsion_dump,
        "exclusions": excluded,
        "pairs_14": if separate_14 { pairs_14.iter().collect::<Vec<_>>() } else { Vec::new() },
        "scale_14_lj": scale_14_lj,
        "scale_14_coulomb": scale_14_coulomb,
        "nonbonded": {
            "cutoff": if cutoff.is_finite() { Some(cutoff) } else { None },
            "coulomb": coulomb_name,
            "dsf_alpha": alpha,
            "rf_dielectric": dielectric,
            "lj_shift": lj_shift && cutoff.is_finite(),
            "coulomb_constant": coulomb_constant,
        },
        "box": box_lengths,
        "doc": "bonds [i, j, k, r0] (E = k/2 (r - r0)^2); angles [i, j, k, k, theta0 rad] \
                (E = k/2 (theta - theta0)^2); torsions [[i, j, k, l], [[k, n, phase rad], ...]] \
                (E = sum k (1 + cos(n phi - phase))); exclusions: pairs left out of the \
                cutoff term; pairs_14: scaled, no cutoff, plain Coulomb",
    });
    let nonbonded = Nonbonded::new(
        NonbondedSpec {
            cutoff,
            skin,
            electrostatics,
            coulomb_constant,
            box_lengths,
            types: kind_of.clone(),
            lj: lj.clone(),
            charges: charges.clone(),
            excluded: excluded.clone(),
        },
        q,
    )?;
    terms.push(("nonbonded".into(), Box::new(nonbonded), Assignment::Default));

    if separate_14 && !pairs_14.is_empty() {
        let mut lj_pairs = Vec::new();
        let mut coulomb_pairs = Vec::new();
        for &(i, l) in &pairs_14 {
            let (a, b) = (kind_of[i] as usize, kind_of[l] as usize);
            let p = lj[a * nt + b];
            // Back from c12, c6 to ε, σ of the pair (σ⁶ = c12/c6, ε = c6²/(4 c12)).
            if scale_14_lj > 0.0 && p.c12 > 0.0 && p.c6 > 0.0 {
                let sigma = (p.c12 / p.c6).powf(1.0 / 6.0);
                let epsilon = p.c6 * p.c6 / (4.0 * p.c12);
                lj_pairs.push(Pair {
                    a: Site::Particle(i),
                    b: Site::Particle(l),
                    potential: LennardJones::new(
                        scale_14_lj * epsilon,
                        sigma,
                        f64::INFINITY,
                        false,
                    ),
                });
            }
            if electrostatics != Electrostatics::None && scale_14_coulomb > 0.0 {
                let qq = scale_14_coulomb * coulomb_constant * charges[i] * charges[l];
                if qq != 0.0 {
                    coulomb_pairs.push(Pair {
                        a: Site::Particle(i),
                        b: Site::Particle(l),
                        potential: Coulomb { charge_product: qq },
                    });
                }
            }
        }
        if !lj_pairs.is_empty() {
            terms.push((
                "lj-14".into(),
                Box::new(PairTerm::new(
                    "lennard-jones-14",
                    TermClass::Nonbonded,
                    3,
                    lj_pairs,
                    input.periodic_box,
                )),
                Assignment::Default,
            ));
        }
        if !coulomb_pairs.is_empty() {
            terms.push((
                "coulomb-14".into(),
                Box::new(PairTerm::new(
                    "coulomb-14",
                    TermClass::Nonbonded,
                    3,
                    coulomb_pairs,
                    input.periodic_box,
                )),
                Assignment::Default,
            ));
        }
    }

    Ok(BuiltForcefield {
        terms,
        masses,
        charges,
        elements,
        report,
        parameters,
    })
}

/// The closest pair of atoms nearer than `limit`, if any (`q` is `n × 3`).
pub fn closest_overlap(
    q: &[f64],
    periodic_box: Option<PeriodicBox>,
    limit: f64,
) -> Option<(usize, usize, f64)> {
    let n = q.len() / 3;
    let mut list = NeighbourList::new(n, limit, 0.0, periodic_box.map(|b| b.lengths));
    list.build(q, |_, _| Some(0));
    let mut wrapped = vec![0.0; q.len()];
    list.wrap_positions(q, &mut wrapped);
    let mut worst: Option<(usize, usize, f64)> = None;
    for chunk in &list.chunks {
        for (row, i) in chunk.rows.clone().enumerate() {
            let range = chunk.starts[0][row] as usize..chunk.starts[0][row + 1] as usize;
            for &entry in &chunk.entries[0][range] {
                let (j, s) = crate::forces::neighbour_list::unpack(entry);
                let shift = list.shifts[s];
                let d: [f64; 3] =
                    std::array::from_fn(|a| wrapped[3 * j + a] + shift[a] - wrapped[3 * i + a]);
                let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                if r < limit && worst.is_none_or(|w| r < w.2) {
                    worst = Some((i.min(j), i.max(j), r));
                }
            }
        }
    }
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
