//! Which distances the equilibrium mollifier holds at rest, grouped into molecules, and the
//! ordering of each molecule's KKT system.
//!
//! Bonds are the fast level's springs of positive rest length (anchored ones included).
//! With angles, each harmonic angle `i–j–k` of the fast level whose two arms are held bonds
//! becomes the 1–3 distance `d² = r₁² + r₂² − 2 r₁ r₂ cos θ₀` (law of cosines). A centre
//! with `k` bonded neighbours has at most `2k − 3` independent 1–3 distances (k = 2: 1,
//! 3: 3, 4: 5) when non-planar, `k − 1` when planar; rings add further dependencies. The
//! set is made non-redundant by a numerical rank check at the start positions (Gram–Schmidt
//! on the constraint gradients, bonds first), plus two rules the start positions cannot
//! show: a centre with three neighbours whose rest angles sum to 360° is planar at rest
//! (one of its three 1–3 distances is dropped), and a linear angle (θ₀ within 5° of 180°)
//! cannot be a 1–3 distance (its gradient vanishes against the bonds' at rest): skipped.

use std::collections::{BTreeMap, VecDeque};

use crate::error::{Error, Result};
use crate::forces::components::Components;
use crate::forces::{RestGeometry, Site};
use crate::system::{PeriodicBox, System};

/// What the mollifier holds at rest (`--molly-constraints`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConstraintSet {
    Bonds,
    BondsAngles,
}

impl ConstraintSet {
    pub fn parse(text: Option<&str>) -> Result<Self> {
        match text {
            None | Some("bonds-angles") => Ok(ConstraintSet::BondsAngles),
            Some("bonds") => Ok(ConstraintSet::Bonds),
            Some(other) => Err(Error::setting(
                "molly_constraints",
                format!("unknown molly_constraints \"{other}\"; use bonds or bonds-angles"),
            )
            .expected("bonds or bonds-angles")
            .got_named(other)),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            ConstraintSet::Bonds => "bonds",
            ConstraintSet::BondsAngles => "bonds-angles",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConstraintKind {
    Bond,
    Angle,
}

/// `g = |A_a − A_b|² − length²` in molecule-local atom numbers; `b = None` is a fixed
/// anchor at `anchor`.
#[derive(Clone, Debug)]
pub struct Constraint {
    pub a: usize,
    pub b: Option<usize>,
    pub anchor: [f64; 3],
    pub length2: f64,
    /// Its row in the molecule's KKT system.
    pub row: usize,
    pub kind: ConstraintKind,
}

/// One molecule: a connected component of the constraint graph.
#[derive(Clone, Debug)]
pub struct MoleculePlan {
    /// Particle indices, in breadth-first order (the KKT order).
    pub atoms: Vec<usize>,
    /// Breadth-first parent of each atom (local numbers; the root is its own), along which
    /// positions are unwrapped by minimum image.
    pub parent: Vec<usize>,
    /// First KKT row of each atom (its `dim` coordinates are consecutive rows).
    pub atom_row: Vec<usize>,
    pub constraints: Vec<Constraint>,
    /// First non-zero column of each KKT row (the skyline).
    pub first: Vec<usize>,
    /// The longest held distance: the length scale of the convergence test.
    pub length_scale: f64,
}

impl MoleculePlan {
    pub fn kkt_size(&self) -> usize {
        self.first.len()
    }
}

/// What was left out, for the notice.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Skipped {
    pub linear: usize,
    pub without_arm: usize,
    pub anchored: usize,
    pub planar: usize,
    pub redundant_angles: usize,
    pub dependent_bonds: usize,
}

#[derive(Clone, Debug)]
pub struct Selection {
    pub molecules: Vec<MoleculePlan>,
    pub bonds: usize,
    pub angles: usize,
    pub skipped: Skipped,
}

/// The end of a bond that is not its first particle.
#[derive(Clone, Copy, Debug, PartialEq)]
enum End {
    Particle(usize),
    Fixed([f64; 3]),
}

#[derive(Clone, Copy, Debug)]
struct Candidate {
    a: usize,
    b: End,
    length: f64,
    kind: ConstraintKind,
}

/// A row is dependent when less than this fraction of its length lies outside the span of
/// the rows kept before it: a 1–3 distance within about 3° of planar or linear dependence
/// would make the KKT matrix nearly singular once projected to rest.
const RANK_TOLERANCE: f64 = 0.05;

/// Rest angles of a planar three-neighbour centre sum to 2π; within this, a centre counts
/// as planar (degrees 1.5 each on average).
const PLANAR_SUM_TOLERANCE: f64 = 4.5 * std::f64::consts::PI / 180.0;

/// θ₀ within this of 0 or π cannot be a 1–3 distance.
const LINEAR_TOLERANCE: f64 = 5.0 * std::f64::consts::PI / 180.0;

/// Choose the constraints of `set` from the fast level of `system`, group them into
/// molecules and lay out each molecule's KKT system.
pub fn select(system: &System, set: ConstraintSet) -> Result<Selection> {
    let mut skipped = Skipped::default();
    let (bonds, angles) = rest_geometry(system, &mut skipped)?;
    let mut candidates = bonds.clone();
    if set == ConstraintSet::BondsAngles {
        candidates.extend(angle_candidates(&bonds, &angles, &mut skipped));
    }
    let n = system.n_particles();
    let mut molecules = Vec::new();
    for component in components(n, &candidates) {
        let plan = molecule(system, &component, &candidates, &mut skipped);
        if !plan.constraints.is_empty() {
            molecules.push(plan);
        }
    }
    let count = |kind| {
        molecules
            .iter()
            .flat_map(|m| &m.constraints)
            .filter(|c| c.kind == kind)
            .count()
    };
    Ok(Selection {
        bonds: count(ConstraintKind::Bond),
        angles: count(ConstraintKind::Angle),
        molecules,
        skipped,
    })
}

/// An angle `(i, j, k, θ₀)` between particles, `j` the centre.
type Angle = (usize, usize, usize, f64);

/// The fast level's bonds (deduplicated; conflicting rest lengths are an error) and angles
/// between particles.
fn rest_geometry(system: &System, skipped: &mut Skipped) -> Result<(Vec<Candidate>, Vec<Angle>)> {
    let mut pairs: BTreeMap<(usize, usize), f64> = BTreeMap::new();
    let mut anchored: Vec<(usize, [f64; 3], f64)> = Vec::new();
    let mut angles = Vec::new();
    for labelled in system.forces.terms().iter().filter(|t| t.level == 0) {
        for geometry in labelled.term.rest_geometry() {
            match geometry {
                RestGeometry::Distance { sites, length } => match (sites[0], sites[1]) {
                    (Site::Particle(a), Site::Particle(b)) if a != b => {
                        let key = (a.min(b), a.max(b));
                        if let Some(&old) = pairs.get(&key)
                            && (old - length).abs() > 1e-12 * old
                        {
                            return Err(Error::input(format!(
                                "equilibrium-molly: particles {a} and {b} are bonded twice on \
                                 the fast level with different rest lengths ({old} and \
                                 {length}); it cannot hold both"
                            )));
                        }
                        pairs.insert(key, length);
                    }
                    (Site::Particle(a), Site::Fixed(x)) | (Site::Fixed(x), Site::Particle(a))
                        if !anchored.iter().any(|&(b, y, _)| b == a && y == x) =>
                    {
                        anchored.push((a, x, length));
                    }
                    _ => {}
                },
                RestGeometry::Angle { sites, angle } => match sites {
                    [Site::Particle(i), Site::Particle(j), Site::Particle(k)] => {
                        angles.push((i, j, k, angle))
                    }
                    _ => skipped.anchored += 1,
                },
            }
        }
    }
    if pairs.is_empty() && anchored.is_empty() {
        return Err(Error::input(
            "equilibrium-molly holds fast bonds at their rest length; this scene's fast level \
             has none (no harmonic spring of positive rest length and stiffness on level 0)",
        ));
    }
    let bond = |a, b, length| Candidate {
        a,
        b,
        length,
        kind: ConstraintKind::Bond,
    };
    let mut bonds: Vec<Candidate> = pairs
        .iter()
        .map(|(&(a, b), &length)| bond(a, End::Particle(b), length))
        .collect();
    bonds.extend(anchored.iter().map(|&(a, x, l)| bond(a, End::Fixed(x), l)));
    Ok((bonds, angles))
}

/// 1–3 distances of the angles whose arms are both held bonds, at most one per atom pair.
fn angle_candidates(
    bonds: &[Candidate],
    angles: &[Angle],
    skipped: &mut Skipped,
) -> Vec<Candidate> {
    let mut lengths: BTreeMap<(usize, usize), f64> = BTreeMap::new();
    for bond in bonds {
        if let End::Particle(b) = bond.b {
            lengths.insert((bond.a.min(b), bond.a.max(b)), bond.length);
        }
    }
    let arm = |x: usize, y: usize| lengths.get(&(x.min(y), x.max(y))).copied();
    let mut seen: BTreeMap<(usize, usize), ()> = BTreeMap::new();
    let mut by_centre: BTreeMap<usize, Vec<(Candidate, f64)>> = BTreeMap::new();
    for &(i, j, k, theta) in angles {
        let (Some(r1), Some(r2)) = (arm(i, j), arm(j, k)) else {
            skipped.without_arm += 1;
            continue;
        };
        if theta.sin().abs() < LINEAR_TOLERANCE.sin() || i == k {
            skipped.linear += 1;
            continue;
        }
        let key = (i.min(k), i.max(k));
        if lengths.contains_key(&key) || seen.insert(key, ()).is_some() {
            skipped.redundant_angles += 1;
            continue;
        }
        let length = (r1 * r1 + r2 * r2 - 2.0 * r1 * r2 * theta.cos()).sqrt();
        let candidate = Candidate {
            a: key.0,
            b: End::Particle(key.1),
            length,
            kind: ConstraintKind::Angle,
        };
        by_centre.entry(j).or_default().push((candidate, theta));
    }
    let mut chosen = Vec::new();
    for (_, mut list) in by_centre {
        let total: f64 = list.iter().map(|(_, theta)| theta).sum();
        if list.len() == 3 && (total - std::f64::consts::TAU).abs() < PLANAR_SUM_TOLERANCE {
            // Planar at rest: the third 1–3 distance follows from the other two in-plane
            // and constrains nothing out of plane to first order.
            list.pop();
            skipped.planar += 1;
        }
        chosen.extend(list.into_iter().map(|(c, _)| c));
    }
    chosen
}

/// Connected components of the constraint graph (particles that no constraint touches are
/// left out: the mollifier leaves them where they are).
fn components(n: usize, candidates: &[Candidate]) -> Vec<Vec<usize>> {
    let mut components = Components::new(n);
    let mut touched = vec![false; n];
    for c in candidates {
        touched[c.a] = true;
        if let End::Particle(b) = c.b {
            touched[b] = true;
            components.join(c.a, b);
        }
    }
    components.groups((0..n).filter(|&i| touched[i]))
}

/// Breadth-first order of a component from a pseudo-peripheral atom (the last one reached
/// from its lowest-numbered atom), so a chain is numbered from one end along its backbone;
/// with each atom's breadth-first parent.
fn breadth_first(
    component: &[usize],
    adjacency: &BTreeMap<usize, Vec<usize>>,
) -> Vec<(usize, usize)> {
    let walk = |root: usize| -> Vec<(usize, usize)> {
        let mut order = vec![(root, root)];
        let mut seen: BTreeMap<usize, ()> = BTreeMap::new();
        seen.insert(root, ());
        let mut queue = VecDeque::from([root]);
        while let Some(u) = queue.pop_front() {
            for &v in adjacency.get(&u).map(Vec::as_slice).unwrap_or(&[]) {
                if seen.insert(v, ()).is_none() {
                    order.push((v, u));
                    queue.push_back(v);
                }
            }
        }
        order
    };
    let first = walk(component[0]);
    let far = first.last().map_or(component[0], |&(v, _)| v);
    walk(far)
}

/// The plan of one molecule: order, kept constraints (rank check at the start positions),
/// KKT layout.
fn molecule(
    system: &System,
    component: &[usize],
    candidates: &[Candidate],
    skipped: &mut Skipped,
) -> MoleculePlan {
    let in_component: BTreeMap<usize, ()> = component.iter().map(|&i| (i, ())).collect();
    let mine: Vec<Candidate> = candidates
        .iter()
        .filter(|c| in_component.contains_key(&c.a))
        .copied()
        .collect();
    let mut adjacency: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for c in mine.iter().filter(|c| c.kind == ConstraintKind::Bond) {
        if let End::Particle(b) = c.b {
            adjacency.entry(c.a).or_default().push(b);
            adjacency.entry(b).or_default().push(c.a);
        }
    }
    let order = breadth_first(component, &adjacency);
    let local: BTreeMap<usize, usize> = order
        .iter()
        .enumerate()
        .map(|(k, &(v, _))| (v, k))
        .collect();
    let atoms: Vec<usize> = order.iter().map(|&(v, _)| v).collect();
    let parent: Vec<usize> = order.iter().map(|&(_, p)| local[&p]).collect();
    let dim = system.dim;
    let positions = unwrap_start(system, &atoms, &parent);
    let kept = independent(&mine, &local, &positions, dim, skipped);
    let constraints: Vec<Constraint> = kept
        .iter()
        .map(|c| Constraint {
            a: local[&c.a],
            b: match c.b {
                End::Particle(b) => Some(local[&b]),
                End::Fixed(_) => None,
            },
            anchor: match c.b {
                End::Fixed(x) => x,
                End::Particle(_) => [0.0; 3],
            },
            length2: c.length * c.length,
            row: 0,
            kind: c.kind,
        })
        .collect();
    let length_scale = kept.iter().map(|c| c.length).fold(0.0, f64::max);
    layout(atoms, parent, constraints, dim, length_scale)
}

/// Start positions of the molecule's atoms, unwrapped along the breadth-first tree.
fn unwrap_start(system: &System, atoms: &[usize], parent: &[usize]) -> Vec<f64> {
    let dim = system.dim;
    let q = &system.state.q;
    let mut x = vec![0.0; atoms.len() * dim];
    for (k, &atom) in atoms.iter().enumerate().skip(1) {
        let p = parent[k];
        for axis in 0..dim {
            let d = q[atom * dim + axis] - q[atoms[p] * dim + axis];
            let d = wrap(system.periodic_box.as_ref(), axis, d);
            x[k * dim + axis] = x[p * dim + axis] + d;
        }
    }
    if let Some(&root) = atoms.first() {
        for k in 0..atoms.len() {
            for axis in 0..dim {
                x[k * dim + axis] += q[root * dim + axis];
            }
        }
    }
    x
}

#[inline]
pub fn wrap(periodic_box: Option<&PeriodicBox>, axis: usize, d: f64) -> f64 {
    match periodic_box {
        Some(b) => b.wrap(axis, d),
        None => d,
    }
}

/// The candidates whose gradients at the start positions are independent of those kept
/// before them (bonds first, then angles), by modified Gram–Schmidt.
fn independent(
    candidates: &[Candidate],
    local: &BTreeMap<usize, usize>,
    x: &[f64],
    dim: usize,
    skipped: &mut Skipped,
) -> Vec<Candidate> {
    let n = x.len();
    let mut basis: Vec<Vec<f64>> = Vec::new();
    let mut kept = Vec::new();
    let mut sorted: Vec<&Candidate> = candidates.iter().collect();
    sorted.sort_by_key(|c| c.kind == ConstraintKind::Angle);
    for c in sorted {
        let a = local[&c.a];
        let mut row = vec![0.0; n];
        for axis in 0..dim {
            let xa = x[a * dim + axis];
            match c.b {
                End::Particle(b) => {
                    let d = xa - x[local[&b] * dim + axis];
                    row[a * dim + axis] = d;
                    row[local[&b] * dim + axis] = -d;
                }
                End::Fixed(anchor) => row[a * dim + axis] = xa - anchor[axis],
            }
        }
        let norm = row.iter().map(|v| v * v).sum::<f64>().sqrt();
        if norm == 0.0 {
            // Its two atoms coincide at the start: nothing to judge it by. Kept, so the
            // projection reports the crushed molecule instead of silently freeing it.
            kept.push(*c);
            continue;
        }
        row.iter_mut().for_each(|v| *v /= norm);
        for e in &basis {
            let projection: f64 = row.iter().zip(e).map(|(r, e)| r * e).sum();
            row.iter_mut()
                .zip(e)
                .for_each(|(r, e)| *r -= projection * e);
        }
        let rest = row.iter().map(|v| v * v).sum::<f64>().sqrt();
        if rest < RANK_TOLERANCE {
            count_dependent(c.kind, skipped);
            continue;
        }
        row.iter_mut().for_each(|v| *v /= rest);
        basis.push(row);
        kept.push(*c);
    }
    kept
}

fn count_dependent(kind: ConstraintKind, skipped: &mut Skipped) {
    match kind {
        ConstraintKind::Bond => skipped.dependent_bonds += 1,
        ConstraintKind::Angle => skipped.redundant_angles += 1,
    }
}

/// KKT rows: each atom's coordinates in breadth-first order, each constraint right after
/// the last of its atoms; the skyline of each row from the couplings (`M + H_μ` couples the
/// two atoms of a constraint, `G` a constraint with its atoms).
fn layout(
    atoms: Vec<usize>,
    parent: Vec<usize>,
    mut constraints: Vec<Constraint>,
    dim: usize,
    length_scale: f64,
) -> MoleculePlan {
    let n = atoms.len();
    let last_atom = |c: &Constraint| c.b.map_or(c.a, |b| b.max(c.a));
    constraints.sort_by_key(|c| (last_atom(c), c.a.min(c.b.unwrap_or(c.a))));
    let mut atom_row = vec![0; n];
    let mut first = Vec::new();
    let mut next = 0;
    let mut rows_of: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (index, c) in constraints.iter().enumerate() {
        rows_of[last_atom(c)].push(index);
    }
    for u in 0..n {
        atom_row[u] = next;
        next += dim;
        for &index in &rows_of[u] {
            constraints[index].row = next;
            next += 1;
        }
    }
    first.resize(next, usize::MAX);
    for u in 0..n {
        for axis in 0..dim {
            first[atom_row[u] + axis] = atom_row[u];
        }
    }
    for c in &constraints {
        let low = c.b.map_or(c.a, |b| b.min(c.a));
        first[c.row] = atom_row[low];
        let high = last_atom(c);
        for axis in 0..dim {
            let row = atom_row[high] + axis;
            first[row] = first[row].min(atom_row[low]);
        }
    }
    MoleculePlan {
        atoms,
        parent,
        atom_row,
        constraints,
        first,
        length_scale,
    }
}
