//! Holonomic distance constraints: rigid bonds and rigid three-site waters.
//!
//! A constraint `|qᵢ − qⱼ| = d` (minimum image in a periodic box) acts through a force
//! along the bond. Rigid waters are solved analytically by SETTLE (MK92, [`settle`]); every
//! other constrained bond by SHAKE for positions (RCB77) and RATTLE for velocities (And83,
//! [`rattle`]), iterated Gauss–Seidel in a fixed order to a relative tolerance.
//!
//! **Positions** ([`Constraints::constrain_positions`]): after a drift `q_new = q_old +
//! dt M⁻¹ p` the positions are moved along the *old* bond vectors until every constraint
//! holds, and the momenta get the matching change `Δp = M Δq / dt`, so `q_new = q_old + dt
//! M⁻¹ p` still holds afterwards (And83 (2.4)–(2.6)).
//! **Velocities** ([`Constraints::constrain_velocities`]): after a kick the momenta are
//! projected so that every constrained pair's relative velocity is perpendicular to its
//! bond, `rᵢⱼ·(vᵢ − vⱼ) = 0` (And83 (2.7)–(2.9)); SETTLE's three conditions are linear
//! in the three multipliers and are solved exactly (a 3×3 system: MK92's analytic velocity
//! step), the other bonds by RATTLE iterations.
//!
//! **Tolerances.** A distance holds when `|r² − d²| ≤ 2 tol d²` (`|r − d|/d ≤ tol` to first
//! order); a velocity when `|r̂·(vᵢ − vⱼ)| ≤ tol v_rms`, with `v_rms` the root-mean-square
//! velocity per coordinate at the call (a scale with the units of a velocity that does not
//! vanish as the projection converges). SETTLE is exact to round-off. A SHAKE or RATTLE
//! sweep that has not converged in `max_iterations` sweeps is a [`ConstraintFailure`].
//!
//! **Cost.** SETTLE: ~200 flops per water, its constants computed once
//! ([`settle::Settle`]), a register of SIMD lanes of waters at a time (8 with AVX-512; the
//! same bits as one at a time, on every instruction set). SHAKE/RATTLE: `O(iterations × constraints)`;
//! bonds to hydrogen are decoupled except around a heavy atom, a handful of sweeps.
//! Nothing is allocated per call: the old bond vectors live in a buffer sized once. The
//! loops run on one thread in a fixed order, so the bits do not depend on the thread
//! count (the work is a few percent of a force evaluation and does not pay for threads).
//!
//! **Sets** ([`ConstraintSet`]): as OpenMM's `constraints=HBonds|AllBonds` and
//! `rigidWater`: a water's O–H bonds and its H–H distance (from the H–H bond, else from
//! the H–O–H rest angle) are SETTLE'd when `rigid_water`, else they are ordinary bonds.
//! Each constraint length is the bond's force-field rest length.

pub mod linear;
pub mod rattle;
pub mod settle;

use std::fmt;

use super::PeriodicBox;
use super::topology::BondedTopology;
use crate::error::{Error, Result};
use crate::forces::scratch::Scratch;
pub use crate::settings::ConstraintSet;

/// The relative constraint tolerance used when none is given.
pub const DEFAULT_TOLERANCE: f64 = 1e-8;

/// SHAKE/RATTLE sweeps before a step is declared failed. A sweep over decoupled bonds
/// converges in one; coupled all-bond networks of organic molecules in tens to hundreds.
pub const DEFAULT_MAX_ITERATIONS: usize = 1000;

/// One constrained distance `|qᵢ − qⱼ| = length`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DistanceConstraint {
    pub i: usize,
    pub j: usize,
    pub length: f64,
}

/// A rigid three-site water: `|O − Hₖ| = oh`, `|H₁ − H₂| = hh`, solved by SETTLE.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigidWater {
    pub oxygen: usize,
    pub hydrogens: [usize; 2],
    pub oh: f64,
    pub hh: f64,
}

/// A step whose constraints could not be satisfied (SHAKE/RATTLE did not converge, or a
/// water was displaced beyond what SETTLE can solve). The integrator turns it into a step
/// failure with the time.
#[derive(Clone, Debug, PartialEq)]
pub struct ConstraintFailure(pub String);

impl fmt::Display for ConstraintFailure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for ConstraintFailure {}

/// A set of constraints with the scratch its solvers need.
#[derive(Clone, Debug)]
pub struct Constraints {
    dim: usize,
    periodic_box: Option<PeriodicBox>,
    pairs: Vec<DistanceConstraint>,
    waters: Vec<RigidWater>,
    tolerance: f64,
    max_iterations: usize,
    /// The old bond vector of every pair, `dim` numbers each (SHAKE's directions).
    reference: Vec<f64>,
    /// Every water's SETTLE constants, refitted when the masses are not those they were
    /// computed for (the first call).
    settle: Vec<settle::Settle>,
    /// Every pair's SHAKE/RATTLE record, refitted likewise.
    fitted: Vec<rattle::Pair>,
    /// The waters' changes of a parallel SETTLE pass, sized here.
    settle_changes: Scratch<settle::Change>,
}

impl Constraints {
    /// A set of pair constraints and rigid waters among `n_particles` particles in `dim`
    /// dimensions. No particle may be in two waters or in a water and a pair (SETTLE
    /// solves each water alone); waters need `dim = 3`.
    pub fn new(
        dim: usize,
        n_particles: usize,
        pairs: Vec<DistanceConstraint>,
        waters: Vec<RigidWater>,
        periodic_box: Option<PeriodicBox>,
    ) -> Result<Self> {
        check_pairs(n_particles, &pairs)?;
        check_waters(dim, n_particles, &pairs, &waters)?;
        let reference = vec![0.0; pairs.len() * dim];
        let fitted = pairs
            .iter()
            .map(|c| rattle::Pair::unfitted(c, dim))
            .collect();
        let settle = waters
            .iter()
            .map(|w| settle::Settle::with_masses(w, f64::NAN, f64::NAN))
            .collect();
        let settle_changes = Scratch::with_len(waters.len());
        Ok(Constraints {
            dim,
            periodic_box,
            pairs,
            waters,
            tolerance: DEFAULT_TOLERANCE,
            max_iterations: DEFAULT_MAX_ITERATIONS,
            reference,
            settle,
            fitted,
            settle_changes,
        })
    }

    /// The constraints of `set` (and SETTLE for every water when `rigid_water`) on a 3-D
    /// system with this topology.
    pub fn from_topology(
        topology: &BondedTopology,
        set: ConstraintSet,
        rigid_water: bool,
        periodic_box: Option<PeriodicBox>,
    ) -> Result<Self> {
        let water_list = if rigid_water {
            topology.waters()
        } else {
            Vec::new()
        };
        let mut in_water = vec![false; topology.len()];
        let mut waters = Vec::with_capacity(water_list.len());
        for &[o, h1, h2] in &water_list {
            waters.push(rigid_water_geometry(topology, o, h1, h2)?);
            for a in [o, h1, h2] {
                in_water[a] = true;
            }
        }
        let pairs = topology
            .bonds
            .iter()
            .filter(|b| !in_water[b.i] && !in_water[b.j])
            .filter(|b| match set {
                ConstraintSet::None => false,
                ConstraintSet::HBonds => topology.is_hydrogen(b.i) || topology.is_hydrogen(b.j),
                ConstraintSet::AllBonds => true,
            })
            .map(|b| DistanceConstraint {
                i: b.i,
                j: b.j,
                length: b.length,
            })
            .collect();
        Constraints::new(3, topology.len(), pairs, waters, periodic_box)
    }

    /// This set with relative tolerance `tolerance` (> 0, < 1).
    pub fn with_tolerance(mut self, tolerance: f64) -> Result<Self> {
        if !(tolerance > 0.0 && tolerance < 1.0) {
            return Err(Error::setting(
                "constraint_tolerance",
                "constraint_tolerance must lie between 0 and 1 (a relative error)",
            )
            .expected("a number in (0, 1)")
            .got(tolerance.to_string()));
        }
        self.tolerance = tolerance;
        Ok(self)
    }

    /// This set with at most `max_iterations` (≥ 1) SHAKE/RATTLE sweeps per call.
    pub fn with_max_iterations(mut self, max_iterations: usize) -> Result<Self> {
        if max_iterations == 0 {
            return Err(Error::input(
                "the constraint iteration cap must be at least 1",
            ));
        }
        self.max_iterations = max_iterations;
        Ok(self)
    }

    pub fn tolerance(&self) -> f64 {
        self.tolerance
    }

    pub fn pairs(&self) -> &[DistanceConstraint] {
        &self.pairs
    }

    pub fn waters(&self) -> &[RigidWater] {
        &self.waters
    }

    /// The number of scalar constraints (each removes one degree of freedom): one per pair,
    /// three per rigid water.
    pub fn count(&self) -> usize {
        self.pairs.len() + 3 * self.waters.len()
    }

    pub fn is_empty(&self) -> bool {
        self.count() == 0
    }

    /// SETTLE needs the two hydrogens of a water to weigh the same, and every constrained
    /// particle a finite positive mass: checked once when a run is set up.
    pub fn check_masses(&self, inverse_mass: &[f64]) -> Result<()> {
        let dim = self.dim;
        let w = |i: usize| inverse_mass[i * dim];
        for water in &self.waters {
            let [h1, h2] = water.hydrogens;
            if w(h1) != w(h2) {
                return Err(Error::input(format!(
                    "rigid water {}-{}-{}: SETTLE needs its two hydrogens to have the same \
                     mass, got {} and {}",
                    water.oxygen,
                    h1,
                    h2,
                    1.0 / w(h1),
                    1.0 / w(h2)
                )));
            }
        }
        let particles = self.pairs.iter().flat_map(|c| [c.i, c.j]).chain(
            self.waters
                .iter()
                .flat_map(|x| [x.oxygen, x.hydrogens[0], x.hydrogens[1]]),
        );
        for i in particles {
            if !(w(i).is_finite() && w(i) > 0.0) {
                return Err(Error::input(format!(
                    "constrained particle {i} needs a finite positive mass"
                )));
            }
        }
        Ok(())
    }

    /// Constrain the positions `q_new` reached from `q_old` (which satisfy the constraints)
    /// by a drift of length `dt`, and correct the momenta `p` by `M Δq / dt` to match.
    pub fn constrain_positions(
        &mut self,
        q_old: &[f64],
        q_new: &mut [f64],
        p: &mut [f64],
        inverse_mass: &[f64],
        dt: f64,
    ) -> Result<(), ConstraintFailure> {
        self.fit_settle(inverse_mass);
        let pbc = self.periodic_box.as_ref();
        let scratch = &self.settle_changes;
        settle::positions_all(&self.settle, pbc, q_old, q_new, p, dt, scratch)?;
        if !self.pairs.is_empty() {
            rattle::shake(self, q_old, q_new, p, inverse_mass, dt)?;
        }
        Ok(())
    }

    /// Refit the SETTLE constants of the waters whose masses are not `inverse_mass`'s.
    fn fit_settle(&mut self, inverse_mass: &[f64]) {
        for (s, water) in self.settle.iter_mut().zip(&self.waters) {
            if !s.fits(inverse_mass) {
                *s = settle::Settle::new(water, inverse_mass);
            }
        }
    }

    /// Project the momenta `p` at positions `q` (which satisfy the constraints) so that no
    /// constrained distance changes: `rᵢⱼ·(vᵢ − vⱼ) = 0` for every constraint.
    pub fn constrain_velocities(
        &mut self,
        q: &[f64],
        p: &mut [f64],
        inverse_mass: &[f64],
    ) -> Result<(), ConstraintFailure> {
        // The velocity pass reads the masses itself: no refit here.
        let pbc = self.periodic_box.as_ref();
        let scratch = &self.settle_changes;
        settle::velocities_all(&self.settle, pbc, q, p, inverse_mass, scratch)?;
        if !self.pairs.is_empty() {
            rattle::rattle(self, q, p, inverse_mass)?;
        }
        Ok(())
    }

    /// Move positions `q` that need not satisfy the constraints onto them (a start from a
    /// flexible structure, as OpenMM's `applyConstraints`): SHAKE on every constrained
    /// distance, a water's three included, along the bonds as they are, then SETTLE on
    /// each water so that it is rigid to round-off. Allocates (it is
    /// done once, before a run); the momenta are left alone (project them afterwards with
    /// [`Constraints::constrain_velocities`]).
    pub fn project_positions(
        &self,
        q: &mut [f64],
        inverse_mass: &[f64],
    ) -> Result<(), ConstraintFailure> {
        let mut all = self.pairs.clone();
        for w in &self.waters {
            let [h1, h2] = w.hydrogens;
            all.extend([
                DistanceConstraint {
                    i: w.oxygen,
                    j: h1,
                    length: w.oh,
                },
                DistanceConstraint {
                    i: w.oxygen,
                    j: h2,
                    length: w.oh,
                },
                DistanceConstraint {
                    i: h1,
                    j: h2,
                    length: w.hh,
                },
            ]);
        }
        let q_start = q.to_vec();
        let mut reference = vec![0.0; all.len() * self.dim];
        let mut unused_momenta = vec![0.0; q.len()];
        let solver = rattle::Solver::of(self);
        // A start can be far from the constraints (a flexible water's angle off by degrees):
        // the sweeps converge linearly, so give them room.
        let solver = rattle::Solver {
            max_iterations: solver.max_iterations.max(10_000),
            ..solver
        };
        let mut fitted: Vec<_> = all
            .iter()
            .map(|c| rattle::Pair::unfitted(c, self.dim))
            .collect();
        rattle::fit(&all, &mut fitted, self.dim, inverse_mass);
        rattle::shake_pairs(
            solver,
            &all,
            &fitted,
            &mut reference,
            &q_start,
            q,
            &mut unused_momenta,
            1.0,
        )?;
        // SETTLE with no drift rebuilds each water as the exact rigid triangle (the
        // iteration left it within the tolerance), so the waters start rigid to round-off.
        let q_near = q.to_vec();
        for water in &self.waters {
            let water = settle::Settle::new(water, inverse_mass);
            let pbc = self.periodic_box.as_ref();
            settle::positions(&water, pbc, &q_near, q, &mut unused_momenta, 1.0)?;
        }
        Ok(())
    }

    /// The largest relative violation `|r − d| / d` of any constraint at `q`.
    pub fn max_violation(&self, q: &[f64]) -> f64 {
        let mut worst: f64 = 0.0;
        let mut check = |i: usize, j: usize, d: f64| {
            let r = self.separation(q, i, j);
            let r = r[..self.dim].iter().map(|x| x * x).sum::<f64>().sqrt();
            worst = worst.max((r - d).abs() / d);
        };
        for c in &self.pairs {
            check(c.i, c.j, c.length);
        }
        for w in &self.waters {
            let [h1, h2] = w.hydrogens;
            check(w.oxygen, h1, w.oh);
            check(w.oxygen, h2, w.oh);
            check(h1, h2, w.hh);
        }
        worst
    }

    /// The largest `|r̂ᵢⱼ·(vᵢ − vⱼ)|` over all constraints at `q` with momenta `p`: zero
    /// when the velocities are tangent to the constraint manifold.
    pub fn max_velocity_violation(&self, q: &[f64], p: &[f64], inverse_mass: &[f64]) -> f64 {
        let dim = self.dim;
        let mut worst: f64 = 0.0;
        let mut check = |i: usize, j: usize| {
            let r = self.separation(q, i, j);
            let mut dot = 0.0;
            let mut r2 = 0.0;
            for a in 0..dim {
                let v = inverse_mass[i * dim + a] * p[i * dim + a]
                    - inverse_mass[j * dim + a] * p[j * dim + a];
                dot += r[a] * v;
                r2 += r[a] * r[a];
            }
            worst = worst.max(dot.abs() / r2.sqrt());
        };
        for c in &self.pairs {
            check(c.i, c.j);
        }
        for w in &self.waters {
            let [h1, h2] = w.hydrogens;
            check(w.oxygen, h1);
            check(w.oxygen, h2);
            check(h1, h2);
        }
        worst
    }

    /// `qᵢ − qⱼ` (minimum image), in the first `dim` entries.
    fn separation(&self, q: &[f64], i: usize, j: usize) -> [f64; 3] {
        separation(self.dim, self.periodic_box, q, i, j)
    }
}

/// `qᵢ − qⱼ` in `dim` dimensions, the minimum image in a periodic box.
#[inline]
fn separation(
    dim: usize,
    periodic_box: Option<PeriodicBox>,
    q: &[f64],
    i: usize,
    j: usize,
) -> [f64; 3] {
    let mut r = [0.0; 3];
    for a in 0..dim {
        let d = q[i * dim + a] - q[j * dim + a];
        r[a] = match periodic_box {
            Some(b) => b.wrap(a, d),
            None => d,
        };
    }
    r
}

/// The geometry of the rigid water `o, h1, h2`: the O–H rest length of its bonds (they
/// must agree), the H–H one from an H–H bond or else from the H–O–H rest angle.
fn rigid_water_geometry(
    topology: &BondedTopology,
    o: usize,
    h1: usize,
    h2: usize,
) -> Result<RigidWater> {
    let (Some(oh), Some(oh2)) = (topology.bond_length(o, h1), topology.bond_length(o, h2)) else {
        return Err(Error::input(format!(
            "water {o}-{h1}-{h2}: its O-H bonds have no rest length"
        )));
    };
    if (oh - oh2).abs() > 1e-12 * oh {
        return Err(Error::input(format!(
            "water {o}-{h1}-{h2}: rigid water needs equal O-H rest lengths, got {oh} and {oh2}"
        )));
    }
    let hh = match topology.bond_length(h1, h2) {
        Some(hh) => hh,
        None => match topology.rest_angle(h1, o, h2) {
            Some(theta0) => 2.0 * oh * (0.5 * theta0).sin(),
            None => {
                return Err(Error::input(format!(
                    "water {o}-{h1}-{h2}: rigid water needs an H-O-H rest angle or an H-H \
                     bond to fix the H-H distance"
                )));
            }
        },
    };
    if !(hh > 0.0 && hh < 2.0 * oh) {
        return Err(Error::input(format!(
            "water {o}-{h1}-{h2}: H-H distance {hh} does not make a triangle with O-H {oh}"
        )));
    }
    Ok(RigidWater {
        oxygen: o,
        hydrogens: [h1, h2],
        oh,
        hh,
    })
}

fn check_pairs(n: usize, pairs: &[DistanceConstraint]) -> Result<()> {
    for c in pairs {
        if c.i >= n || c.j >= n || c.i == c.j {
            return Err(Error::input(format!(
                "constraint {}-{} does not join two of the {n} particles",
                c.i, c.j
            )));
        }
        if !(c.length.is_finite() && c.length > 0.0) {
            return Err(Error::input(format!(
                "constraint {}-{} has length {}; it must be positive",
                c.i, c.j, c.length
            )));
        }
    }
    Ok(())
}

fn check_waters(
    dim: usize,
    n: usize,
    pairs: &[DistanceConstraint],
    waters: &[RigidWater],
) -> Result<()> {
    if waters.is_empty() {
        return Ok(());
    }
    if dim != 3 {
        return Err(Error::input("rigid water (SETTLE) needs dim = 3"));
    }
    let mut owner = vec![false; n];
    for c in pairs {
        owner[c.i] = true;
        owner[c.j] = true;
    }
    for w in waters {
        let [h1, h2] = w.hydrogens;
        for a in [w.oxygen, h1, h2] {
            if a >= n {
                return Err(Error::input(format!(
                    "rigid water atom {a} is beyond the {n} particles"
                )));
            }
            if owner[a] {
                return Err(Error::input(format!(
                    "particle {a} is in a rigid water and in another constraint; SETTLE \
                     solves each water alone"
                )));
            }
            owner[a] = true;
        }
        if !(w.oh > 0.0 && w.hh > 0.0 && w.hh < 2.0 * w.oh) {
            return Err(Error::input(format!(
                "rigid water {}-{h1}-{h2}: O-H {} and H-H {} make no triangle",
                w.oxygen, w.oh, w.hh
            )));
        }
    }
    Ok(())
}
