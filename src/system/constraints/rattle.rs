//! SHAKE positions (RCB77) and RATTLE velocities (And83) for pair constraints, by
//! Gauss–Seidel sweeps over the constraints in their fixed order.
//!
//! **SHAKE** (And83 (2.5)–(2.6)): for a constraint `i–j` with old bond vector `r⁰` and
//! current one `s`, the correction along `r⁰` that satisfies it to first order is
//! `g = (d² − |s|²) / (2 (s·r⁰)(wᵢ + wⱼ))`, `qᵢ += g wᵢ r⁰`, `qⱼ −= g wⱼ r⁰`, and the momenta
//! take `±g r⁰ / dt` (`w = 1/m`). Sweeps repeat until `|d² − |s|²| ≤ 2 tol d²` for all.
//! **RATTLE** (And83 (2.8)–(2.9)): `k = −r·(vᵢ − vⱼ) / ((wᵢ + wⱼ)|r|²)`, `pᵢ += k r`,
//! `pⱼ −= k r`, until `|r̂·(vᵢ − vⱼ)| ≤ tol v_rms` for all.
//! Cost per sweep: ~30 flops per constraint.

use super::{ConstraintFailure, Constraints, DistanceConstraint, PeriodicBox, separation};

/// SHAKE the positions `q_new` (drifted by `dt` from `q_old`) onto the pair constraints,
/// with the matching momentum change.
pub(super) fn shake(
    set: &mut Constraints,
    q_old: &[f64],
    q_new: &mut [f64],
    p: &mut [f64],
    inverse_mass: &[f64],
    dt: f64,
) -> Result<(), ConstraintFailure> {
    let solver = Solver::of(set);
    shake_pairs(
        solver,
        &set.pairs,
        &mut set.reference,
        q_old,
        q_new,
        p,
        inverse_mass,
        dt,
    )
}

/// What a sweep needs to know besides the constraints.
#[derive(Clone, Copy)]
pub(super) struct Solver {
    pub dim: usize,
    pub pbc: Option<PeriodicBox>,
    pub tolerance: f64,
    pub max_iterations: usize,
}

impl Solver {
    pub fn of(set: &Constraints) -> Self {
        Solver {
            dim: set.dim,
            pbc: set.periodic_box,
            tolerance: set.tolerance,
            max_iterations: set.max_iterations,
        }
    }
}

/// SHAKE `pairs` with `reference` (`dim` numbers per pair) as scratch for the old bonds.
#[allow(clippy::too_many_arguments)]
pub(super) fn shake_pairs(
    solver: Solver,
    pairs: &[DistanceConstraint],
    reference: &mut [f64],
    q_old: &[f64],
    q_new: &mut [f64],
    p: &mut [f64],
    inverse_mass: &[f64],
    dt: f64,
) -> Result<(), ConstraintFailure> {
    let Solver { dim, pbc, .. } = solver;
    for (c, r0) in pairs.iter().zip(reference.chunks_exact_mut(dim)) {
        r0.copy_from_slice(&separation(dim, pbc, q_old, c.i, c.j)[..dim]);
    }
    let mut worst = 0.0;
    for _ in 0..solver.max_iterations {
        worst = 0.0;
        for (c, r0) in pairs.iter().zip(reference.chunks_exact(dim)) {
            let s = separation(dim, pbc, q_new, c.i, c.j);
            let d2 = c.length * c.length;
            let s2: f64 = s[..dim].iter().map(|x| x * x).sum();
            let diff = d2 - s2;
            if diff.abs() <= 2.0 * solver.tolerance * d2 {
                continue;
            }
            worst = f64::max(worst, diff.abs() / (2.0 * d2));
            let dot: f64 = s[..dim].iter().zip(r0).map(|(x, y)| x * y).sum();
            if dot <= 0.0 || dot.is_nan() {
                return Err(ConstraintFailure(format!(
                    "SHAKE: bond {}-{} turned by 90° or more in one drift (|r| = {:.6} for \
                     length {}); the step is too long",
                    c.i,
                    c.j,
                    s2.sqrt(),
                    c.length
                )));
            }
            let (wi, wj) = (inverse_mass[c.i * dim], inverse_mass[c.j * dim]);
            let g = diff / (2.0 * dot * (wi + wj));
            for (a, &r) in r0.iter().enumerate() {
                q_new[c.i * dim + a] += g * wi * r;
                q_new[c.j * dim + a] -= g * wj * r;
                p[c.i * dim + a] += g * r / dt;
                p[c.j * dim + a] -= g * r / dt;
            }
        }
        if worst == 0.0 {
            return Ok(());
        }
    }
    Err(ConstraintFailure(format!(
        "SHAKE did not converge to relative tolerance {} in {} sweeps (a violation of \
         {worst:.3e} in the last)",
        solver.tolerance, solver.max_iterations
    )))
}

/// The root-mean-square velocity per coordinate, `√(Σ (w p)² / n)`: RATTLE's scale.
fn rms_velocity(p: &[f64], inverse_mass: &[f64]) -> f64 {
    if p.is_empty() {
        return 0.0;
    }
    let sum: f64 = p
        .iter()
        .zip(inverse_mass)
        .map(|(pk, w)| (w * pk).powi(2))
        .sum();
    (sum / p.len() as f64).sqrt()
}

/// RATTLE the momenta `p` at positions `q` onto the pair constraints' tangent space.
pub(super) fn rattle(
    set: &mut Constraints,
    q: &[f64],
    p: &mut [f64],
    inverse_mass: &[f64],
) -> Result<(), ConstraintFailure> {
    let dim = set.dim;
    let pbc = set.periodic_box;
    let threshold = set.tolerance * rms_velocity(p, inverse_mass);
    for (c, r) in set.pairs.iter().zip(set.reference.chunks_exact_mut(dim)) {
        r.copy_from_slice(&separation(dim, pbc, q, c.i, c.j)[..dim]);
    }
    for _ in 0..set.max_iterations {
        let mut converged = true;
        for (c, r) in set.pairs.iter().zip(set.reference.chunks_exact(dim)) {
            let (wi, wj) = (inverse_mass[c.i * dim], inverse_mass[c.j * dim]);
            let mut dot = 0.0;
            let mut r2 = 0.0;
            for (a, &ra) in r.iter().enumerate() {
                dot += ra * (wi * p[c.i * dim + a] - wj * p[c.j * dim + a]);
                r2 += ra * ra;
            }
            if dot.abs() <= threshold * r2.sqrt() {
                continue;
            }
            converged = false;
            let k = -dot / ((wi + wj) * r2);
            for (a, &ra) in r.iter().enumerate() {
                p[c.i * dim + a] += k * ra;
                p[c.j * dim + a] -= k * ra;
            }
        }
        if converged {
            return Ok(());
        }
    }
    Err(ConstraintFailure(format!(
        "RATTLE did not converge to relative tolerance {} in {} sweeps",
        set.tolerance, set.max_iterations
    )))
}
