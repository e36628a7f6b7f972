//! SHAKE positions (RCB77) and RATTLE velocities (And83) for pair constraints, by
//! Gauss–Seidel sweeps over the constraints in their fixed order.
//!
//! **SHAKE** (And83 (2.5)–(2.6)): for a constraint `i–j` with old bond vector `r⁰` and
//! current one `s`, the correction along `r⁰` that satisfies it to first order is
//! `g = (d² − |s|²) / (2 (s·r⁰)(wᵢ + wⱼ))`, `qᵢ += g wᵢ r⁰`, `qⱼ −= g wⱼ r⁰`, and the momenta
//! take `±g r⁰ / dt` (`w = 1/m`). Sweeps repeat until `|d² − |s|²| ≤ 2 tol d²` for all.
//! **RATTLE** (And83 (2.8)–(2.9)): `k = −r·(vᵢ − vⱼ) / ((wᵢ + wⱼ)|r|²)`, `pᵢ += k r`,
//! `pⱼ −= k r`, until `|r̂·(vᵢ − vⱼ)| ≤ tol v_rms` for all.
//! Cost per sweep: ~30 flops per constraint. Each pair's first coordinates, inverse masses,
//! `1/(wᵢ + wⱼ)` and `d²` are computed once ([`Pair`], refitted only when the masses change),
//! so a sweep is one tight loop over flat records.

use super::{ConstraintFailure, Constraints, DistanceConstraint, PeriodicBox};

/// One pair constraint with what a sweep needs of it, for given masses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Pair {
    /// The first coordinates of the two particles (`dim · i`, `dim · j`).
    i: usize,
    j: usize,
    wi: f64,
    wj: f64,
    /// `1 / (wᵢ + wⱼ)`.
    reduced: f64,
    /// The squared length `d²`.
    d2: f64,
}

impl Pair {
    fn new(c: &DistanceConstraint, dim: usize, inverse_mass: &[f64]) -> Self {
        let (wi, wj) = (inverse_mass[c.i * dim], inverse_mass[c.j * dim]);
        Pair {
            i: c.i * dim,
            j: c.j * dim,
            wi,
            wj,
            reduced: 1.0 / (wi + wj),
            d2: c.length * c.length,
        }
    }

    /// A record that fits no masses (refitted on first use).
    pub(super) fn unfitted(c: &DistanceConstraint, dim: usize) -> Self {
        Pair {
            i: c.i * dim,
            j: c.j * dim,
            wi: f64::NAN,
            wj: f64::NAN,
            reduced: f64::NAN,
            d2: c.length * c.length,
        }
    }
}

/// Refit the records `fitted` of `pairs` whose masses are not `inverse_mass`'s.
pub(super) fn fit(pairs: &[DistanceConstraint], fitted: &mut [Pair], dim: usize, w: &[f64]) {
    for (c, f) in pairs.iter().zip(fitted.iter_mut()) {
        if w[f.i] != f.wi || w[f.j] != f.wj {
            *f = Pair::new(c, dim, w);
        }
    }
}

/// `q[i..i+dim] − q[j..j+dim]` (first coordinates `i`, `j`), the minimum image in a box.
#[inline(always)]
fn bond(dim: usize, pbc: Option<&PeriodicBox>, q: &[f64], i: usize, j: usize) -> [f64; 3] {
    let mut r = [0.0; 3];
    let (qi, qj) = (&q[i..i + dim], &q[j..j + dim]);
    for a in 0..dim {
        r[a] = qi[a] - qj[a];
    }
    if let Some(b) = pbc {
        for (a, x) in r.iter_mut().enumerate().take(dim) {
            *x = b.wrap(a, *x);
        }
    }
    r
}

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
    fit(&set.pairs, &mut set.fitted, set.dim, inverse_mass);
    shake_pairs(
        solver,
        &set.pairs,
        &set.fitted,
        &mut set.reference,
        q_old,
        q_new,
        p,
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

/// SHAKE `pairs` (their records `fitted` for these masses) with `reference` (`dim` numbers
/// per pair) as scratch for the old bonds.
#[allow(clippy::too_many_arguments)]
pub(super) fn shake_pairs(
    solver: Solver,
    pairs: &[DistanceConstraint],
    fitted: &[Pair],
    reference: &mut [f64],
    q_old: &[f64],
    q_new: &mut [f64],
    p: &mut [f64],
    dt: f64,
) -> Result<(), ConstraintFailure> {
    let Solver { dim, pbc, .. } = solver;
    let pbc = pbc.as_ref();
    for (c, r0) in fitted.iter().zip(reference.chunks_exact_mut(dim)) {
        r0.copy_from_slice(&bond(dim, pbc, q_old, c.i, c.j)[..dim]);
    }
    let bound = 2.0 * solver.tolerance;
    let inverse_dt = 1.0 / dt;
    let mut worst = 0.0;
    for _ in 0..solver.max_iterations {
        worst = 0.0;
        for (k, (c, r0)) in fitted.iter().zip(reference.chunks_exact(dim)).enumerate() {
            let s = bond(dim, pbc, q_new, c.i, c.j);
            let s2: f64 = s[..dim].iter().map(|x| x * x).sum();
            let diff = c.d2 - s2;
            if diff.abs() <= bound * c.d2 {
                continue;
            }
            worst = f64::max(worst, diff.abs() / (2.0 * c.d2));
            let dot: f64 = s[..dim].iter().zip(r0).map(|(x, y)| x * y).sum();
            if dot <= 0.0 || dot.is_nan() {
                return Err(turned(&pairs[k], s2));
            }
            let g = 0.5 * diff / dot * c.reduced;
            let (gi, gj, gp) = (g * c.wi, g * c.wj, g * inverse_dt);
            let (qi, qj) = (c.i, c.j);
            for (a, &r) in r0.iter().enumerate() {
                q_new[qi + a] += gi * r;
                q_new[qj + a] -= gj * r;
                p[qi + a] += gp * r;
                p[qj + a] -= gp * r;
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

/// A bond that turned by 90° or more in one drift, at `|r|² = s2`.
fn turned(c: &DistanceConstraint, s2: f64) -> ConstraintFailure {
    ConstraintFailure(format!(
        "SHAKE: bond {}-{} turned by 90° or more in one drift (|r| = {:.6} for \
         length {:.6}); the step is too long",
        c.i,
        c.j,
        s2.sqrt(),
        c.length
    ))
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
    let pbc = set.periodic_box.as_ref();
    let threshold = set.tolerance * rms_velocity(p, inverse_mass);
    // `|dot| ≤ threshold |r|` compared squared: no square root per pair and sweep.
    let threshold2 = threshold * threshold;
    fit(&set.pairs, &mut set.fitted, dim, inverse_mass);
    for (c, r) in set.fitted.iter().zip(set.reference.chunks_exact_mut(dim)) {
        r.copy_from_slice(&bond(dim, pbc, q, c.i, c.j)[..dim]);
    }
    let sweep = match dim {
        1 => rattle_sweep::<1>,
        2 => rattle_sweep::<2>,
        _ => rattle_sweep::<3>,
    };
    for _ in 0..set.max_iterations {
        if sweep(&set.fitted, &set.reference, p, threshold2) {
            return Ok(());
        }
    }
    Err(ConstraintFailure(format!(
        "RATTLE did not converge to relative tolerance {} in {} sweeps",
        set.tolerance, set.max_iterations
    )))
}

/// One Gauss–Seidel RATTLE sweep in `D` dimensions (fixed-size, so the coordinate loops
/// unroll); whether every pair already met `dot² ≤ threshold2 · |r|²`.
fn rattle_sweep<const D: usize>(
    fitted: &[Pair],
    reference: &[f64],
    p: &mut [f64],
    threshold2: f64,
) -> bool {
    let mut converged = true;
    for (c, r) in fitted.iter().zip(reference.chunks_exact(D)) {
        let r: &[f64; D] = r.try_into().expect("chunks of D");
        let (i, j) = (c.i, c.j);
        let pi: [f64; D] = p[i..i + D].try_into().expect("D coordinates");
        let pj: [f64; D] = p[j..j + D].try_into().expect("D coordinates");
        let mut dot = 0.0;
        let mut r2 = 0.0;
        for a in 0..D {
            dot += r[a] * (c.wi * pi[a] - c.wj * pj[a]);
            r2 += r[a] * r[a];
        }
        if dot * dot <= threshold2 * r2 {
            continue;
        }
        converged = false;
        let k = -dot / r2 * c.reduced;
        for a in 0..D {
            p[i + a] += k * r[a];
            p[j + a] -= k * r[a];
        }
    }
    converged
}
