//! The bonded sections of the force field: the bond graph, bonds, angles and torsions.

use std::collections::{BTreeMap, BTreeSet};

use serde_json::Value;

use super::{
    ANGLE_TABLE, BOND_TABLE, Context, Group, Symmetry, Terms, angle_key, lookup, norm, range_text,
    sorted_key, source,
};
use crate::forces::angle::{AngleBend, HarmonicAngles};
use crate::forces::pair::{Pair, PairTerm};
use crate::forces::spring::HarmonicBond;
use crate::forces::torsion::{Cosine, Dihedral, Torsions};
use crate::forces::{Site, TermClass};
use crate::split::Assignment;

/// The bond graph: bonds (sorted, each once), angles `i-j-k` around every atom `j`, and
/// proper dihedrals `i-j-k-l` around every bond `j-k`.
pub(super) struct Topology {
    pub bonds: Vec<[usize; 2]>,
    pub angles: Vec<[usize; 3]>,
    pub dihedrals: Vec<[usize; 4]>,
}

impl Topology {
    pub fn new(listed: &[[usize; 2]], n: usize) -> Result<Self, String> {
        let mut neighbours: Vec<BTreeSet<usize>> = vec![BTreeSet::new(); n];
        for &[a, b] in listed {
            if a >= n || b >= n || a == b {
                return Err(format!(
                    "bond {a}-{b} does not join two atoms of the structure"
                ));
            }
            neighbours[a].insert(b);
            neighbours[b].insert(a);
        }
        let mut bonds: Vec<[usize; 2]> =
            listed.iter().map(|&[a, b]| [a.min(b), a.max(b)]).collect();
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
        Ok(Topology {
            bonds,
            angles,
            dihedrals,
        })
    }
}

/// A force constant: the scene's, else the built-in table's (`true` when given).
fn constant(given: Option<f64>, table: Option<f64>) -> Option<(f64, bool)> {
    match (given, table) {
        (Some(k), _) => Some((k, true)),
        (None, Some(k)) => Some((k, false)),
        (None, None) => None,
    }
}

/// One report line per kind of bond or angle: count, constant and its source, the rest
/// value (`rest`, in `unit`) given or the range of the geometric ones.
fn report_groups(
    report: &mut Vec<String>,
    what: &str,
    rest: &str,
    unit: &str,
    groups: &BTreeMap<String, Group>,
) {
    for (key, (count, k, from, given, values)) in groups {
        report.push(format!(
            "{what} {key} ×{count}: k = {k} ({from}), {rest} = {}",
            match given {
                Some(r) => format!("{r}{unit} (scene)"),
                None => format!("geometry ({}{unit})", range_text(values)),
            }
        ));
    }
}

/// Harmonic bonds `(k/2)(r − r₀)²`, `r₀` from the geometry unless given; returns the
/// dump `[a, b, k, r0]` per bond.
pub(super) fn bonds(
    ctx: &Context,
    bonds: &[[usize; 2]],
    terms: &mut Terms,
    report: &mut Vec<String>,
) -> Result<Vec<Value>, String> {
    let mut groups: BTreeMap<String, Group> = BTreeMap::new();
    let mut pairs = Vec::with_capacity(bonds.len());
    let mut dump = Vec::with_capacity(bonds.len());
    for &[a, b] in bonds {
        let (types, elems) = ctx.names(&[a, b]);
        let found = lookup(&ctx.input.spec.bonds, &types, &elems, Symmetry::Reversible);
        let table = BOND_TABLE
            .iter()
            .find(|(x, y, _)| {
                (*x == elems[0] && *y == elems[1]) || (*x == elems[1] && *y == elems[0])
            })
            .map(|t| t.2);
        let Some(k) = constant(found.and_then(|(_, s)| s.k), table) else {
            return Err(format!(
                "no force constant for bond {}: give [forcefield.bonds] \"{}-{}\" = {{ k = … }}",
                ctx.label(&[a, b]),
                types[0],
                types[1]
            ));
        };
        let length = norm(ctx.difference(a, b));
        let r0 = found.and_then(|(_, s)| s.r0);
        let key = found
            .map(|(key, _)| key.to_string())
            .unwrap_or_else(|| sorted_key(&elems));
        let entry = groups
            .entry(key)
            .or_insert((0, k.0, source(k.1), r0, Vec::new()));
        entry.0 += 1;
        entry.4.push(length);
        if k.0 < 0.0 || k.0.is_nan() || r0.is_some_and(|r| r < 0.0 || r.is_nan()) {
            return Err(format!("bond {}: k and r0 must be ≥ 0", ctx.label(&[a, b])));
        }
        pairs.push(Pair {
            a: Site::Particle(a),
            b: Site::Particle(b),
            potential: HarmonicBond {
                stiffness: k.0,
                rest_length: r0.unwrap_or(length),
            },
        });
        dump.push(serde_json::json!([a, b, k.0, r0.unwrap_or(length)]));
    }
    report_groups(report, "bond", "r0", "", &groups);
    if !pairs.is_empty() {
        let periodic_box = ctx.input.periodic_box;
        let term = PairTerm::new("bond", TermClass::Bonded, 3, pairs, periodic_box);
        terms.push(("bonds".into(), Box::new(term), Assignment::Default));
    }
    Ok(dump)
}

/// Harmonic angles `(k/2)(θ − θ₀)²`, `θ₀` from the geometry unless given; returns the
/// dump `[i, j, k, k, θ₀ rad]` per angle.
pub(super) fn angles(
    ctx: &Context,
    angles: &[[usize; 3]],
    terms: &mut Terms,
    report: &mut Vec<String>,
) -> Result<Vec<Value>, String> {
    let mut groups: BTreeMap<String, Group> = BTreeMap::new();
    let mut bends = Vec::with_capacity(angles.len());
    let mut dump = Vec::with_capacity(angles.len());
    for &[i, j, k] in angles {
        let (types, elems) = ctx.names(&[i, j, k]);
        let found = lookup(&ctx.input.spec.angles, &types, &elems, Symmetry::Reversible);
        let table = ANGLE_TABLE
            .iter()
            .find(|(x, c, y, _)| {
                *c == elems[1]
                    && ((*x == elems[0] && *y == elems[2]) || (*x == elems[2] && *y == elems[0]))
            })
            .map(|t| t.3);
        let Some(stiffness) = constant(found.and_then(|(_, s)| s.k), table) else {
            return Err(format!(
                "no force constant for angle {}: give [forcefield.angles] \"{}-{}-{}\" = {{ k = … }}",
                ctx.label(&[i, j, k]),
                types[0],
                types[1],
                types[2]
            ));
        };
        let geometry = ctx.angle(i, j, k);
        let theta0 = found.and_then(|(_, s)| s.theta0);
        let key = found
            .map(|(key, _)| key.to_string())
            .unwrap_or_else(|| angle_key(&elems));
        let entry =
            groups
                .entry(key)
                .or_insert((0, stiffness.0, source(stiffness.1), theta0, Vec::new()));
        entry.0 += 1;
        entry.4.push(geometry.to_degrees());
        let rest_angle = theta0.map_or(geometry, f64::to_radians);
        bends.push(AngleBend {
            sites: [Site::Particle(i), Site::Particle(j), Site::Particle(k)],
            stiffness: stiffness.0,
            rest_angle,
        });
        dump.push(serde_json::json!([i, j, k, stiffness.0, rest_angle]));
    }
    report_groups(report, "angle", "theta0", "°", &groups);
    if !bends.is_empty() {
        let term = HarmonicAngles::new(3, bends, ctx.input.periodic_box);
        terms.push(("angles".into(), Box::new(term), Assignment::Default));
    }
    Ok(dump)
}

/// Proper torsions `Σ k (1 + cos(nφ − δ))`, only when `[forcefield.torsions]` is given
/// (then every dihedral needs an entry); returns the dump `[[i, j, k, l], series]`.
pub(super) fn torsions(
    ctx: &Context,
    dihedrals: &[[usize; 4]],
    terms: &mut Terms,
    report: &mut Vec<String>,
) -> Result<Vec<Value>, String> {
    let Some(table) = &ctx.input.spec.torsions else {
        if !dihedrals.is_empty() {
            report.push(format!(
                "torsions: none — the {} proper dihedrals get no torsion term (no \
                 [forcefield.torsions] table; give one to include them)",
                dihedrals.len()
            ));
        }
        return Ok(Vec::new());
    };
    let mut list = Vec::with_capacity(dihedrals.len());
    let mut groups: BTreeMap<String, usize> = BTreeMap::new();
    for &[i, j, k, l] in dihedrals {
        let (types, elems) = ctx.names(&[i, j, k, l]);
        let Some((key, series)) = lookup(table, &types, &elems, Symmetry::Torsion) else {
            return Err(format!(
                "no torsion parameters for the dihedral {}: give [forcefield.torsions] \
                 \"{}-{}-{}-{}\" (or with X at the ends) = [{{ k = …, n = …, phase = … }}]",
                ctx.label(&[i, j, k, l]),
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
    let dump = list
        .iter()
        .map(|d| {
            let series: Vec<_> = d
                .series
                .iter()
                .map(|c| serde_json::json!([c.k, c.periodicity, c.phase]))
                .collect();
            serde_json::json!([d.atoms, series])
        })
        .collect();
    if !list.is_empty() {
        let term = Torsions::new(list, ctx.input.periodic_box);
        terms.push(("torsions".into(), Box::new(term), Assignment::Default));
    }
    Ok(dump)
}
