//! Start velocities at a temperature, and the degrees of freedom a temperature is counted
//! over.
//!
//! **Degrees of freedom.** A system whose forces are translation invariant (every
//! molecule scene, periodic or not, and any scene without anchors or external fields)
//! conserves its total momentum: the centre of mass moves uniformly and carries no
//! heat, so the start momenta have it removed and the temperature is counted over
//! `n_dof = dim·N − dim`. A system with fixed anchors or an external field does not
//! conserve momentum; nothing is removed and `n_dof = dim·N`. Which case holds is
//! decided from the forces themselves ([`momentum_is_conserved`]). An open (non-periodic)
//! system also conserves its angular momentum; it is not removed and its rotation stays
//! counted, so an isolated molecule keeps the rotation its draw gave it (on average
//! `k_B T / 2` per axis, a small part of `n_dof k_B T / 2` for all but the smallest).
//!
//! **Constraints** ([`super::constraints`]) each remove one more degree of freedom:
//! `n_dof = dim·N − N_c − dim`, and a start at a temperature is projected onto them.
//!
//! **The kinetic temperature** is `T = 2K / (n_dof k_B)` (`k_B = 1` in a dimensionless
//! scene, where a temperature is the number `k_B T`).

use rand::rngs::Xoshiro256PlusPlus;
use rand::{RngExt, SeedableRng};
use rand_distr::StandardNormal;

use super::System;
use super::constraints::Constraints;
use crate::error::{Error, Result};

/// The seed used when none is given (`--seed`, `[run] seed`), so a run is reproducible by
/// default; give different seeds for independent starts. The stochastic methods use the
/// same default for their noise (`integrators::langevin::DEFAULT_SEED`, salted there so
/// the noise is not the stream of the start velocities; `tests/temperature.rs` checks
/// that the two agree).
pub const DEFAULT_SEED: u64 = 2013;

/// The generator of a draw: rand's `Xoshiro256PlusPlus`, one of its *portable* generators
/// (the same stream for the same seed across releases and platforms, which `StdRng` does
/// not promise). Numbers are drawn on one thread in a fixed order, so the same seed gives
/// the same bits at any thread count.
pub fn generator(seed: u64) -> Xoshiro256PlusPlus {
    Xoshiro256PlusPlus::seed_from_u64(seed)
}

/// Fill `out` with standard normal deviates (rand_distr's `StandardNormal`), in order.
pub fn fill_normal(rng: &mut Xoshiro256PlusPlus, out: &mut [f64]) {
    for x in out {
        *x = rng.sample(StandardNormal);
    }
}

/// The degrees of freedom a kinetic temperature is counted over.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DegreesOfFreedom {
    /// `dim·N − N_c − dim` when the total momentum is conserved (and removed), else
    /// `dim·N − N_c`, with `N_c` scalar constraints.
    pub count: usize,
    /// Whether the forces conserve the total momentum (no anchors, no external field).
    pub momentum_conserved: bool,
    /// The scalar constraints `N_c` (one per rigid bond, three per rigid water).
    pub constraints: usize,
}

impl DegreesOfFreedom {
    /// `dim·N − N_c − dim` or `dim·N − N_c`, with the system's constraints (if any).
    pub fn of(system: &System) -> Self {
        let n_constraints = system.constraints.as_ref().map_or(0, |c| c.count());
        Self::constrained(system, n_constraints)
    }

    /// With `constraints` scalar constraints ([`Constraints::count`]), each removing one
    /// degree of freedom: `dim·N − N_c − dim` (or `dim·N − N_c`). Constraint forces are
    /// internal, so they conserve the total momentum and do not change which case holds.
    pub fn constrained(system: &System, constraints: usize) -> Self {
        let momentum_conserved = momentum_is_conserved(system);
        let all = system.n_dofs().saturating_sub(constraints);
        let count = if momentum_conserved {
            all.saturating_sub(system.dim)
        } else {
            all
        };
        DegreesOfFreedom {
            count,
            momentum_conserved,
            constraints,
        }
    }

    /// The kinetic temperature `2K / (n_dof k_B)` of a kinetic energy `kinetic` (0 without
    /// degrees of freedom).
    pub fn temperature(&self, kinetic: f64, boltzmann: f64) -> f64 {
        if self.count == 0 {
            return 0.0;
        }
        2.0 * kinetic / (self.count as f64 * boltzmann)
    }

    /// How they are counted, for the run header.
    pub fn describe(&self, dim: usize, n_particles: usize) -> String {
        let constraints = match self.constraints {
            0 => String::new(),
            n => format!(" − {n} constraints"),
        };
        if self.momentum_conserved {
            format!(
                "{} degrees of freedom ({dim}·{n_particles}{constraints} − {dim}: centre-of-mass \
                 momentum removed)",
                self.count
            )
        } else {
            format!(
                "{} degrees of freedom ({dim}·{n_particles}{constraints}: anchors or external \
                 fields, the momentum is not conserved and is not removed)",
                self.count
            )
        }
    }
}

/// Whether the forces are translation invariant, so the total momentum is conserved: the
/// net force `Σᵢ ∇ᵢV` and the response to a uniform displacement `∇²V·eₐ` vanish along every
/// axis `a`. Both are sums whose terms cancel pair by pair when the forces are invariant,
/// leaving round-off of order `ε·N` times the sum of their magnitudes; an anchor or an
/// external field leaves a whole interaction's worth (at least ~1/N of the total). The
/// threshold 1e-8 of the scale lies between the two for any N up to 10⁷. A
/// velocity-dependent (magnetic) term counts as breaking the invariance; a term invariant
/// by construction though not to round-off (PME's reciprocal sum, whose B-spline mesh
/// leaves a net force ~1e-3 of its forces) is left out of the sums.
pub fn momentum_is_conserved(system: &System) -> bool {
    let all = system.forces.terms();
    if all.iter().any(|t| t.term.magnetic().is_some()) {
        return false;
    }
    // Terms invariant by construction whose numbers are not (PME's mesh) are left out.
    let terms: Vec<_> = all
        .iter()
        .filter(|t| !t.term.invariant_by_construction())
        .collect();
    let q = &system.state.q;
    let dim = system.dim;
    let n = q.len();
    let mut gradient = vec![0.0; n];
    for t in &terms {
        t.term.add_gradient(q, &mut gradient);
    }
    // A fixed pseudo-random probe direction sets the scale of a Hessian product.
    let mut probe = vec![0.0; n];
    fill_normal(&mut generator(0x5EED), &mut probe);
    let hessian = |v: &[f64]| {
        let mut out = vec![0.0; n];
        for t in &terms {
            t.term.add_hessian_vector(q, v, &mut out);
        }
        out
    };
    let hessian_scale: f64 = hessian(&probe).iter().map(|x| x.abs()).sum();
    const RELATIVE: f64 = 1e-8;
    (0..dim).all(|a| {
        let along = |x: &[f64]| x.iter().skip(a).step_by(dim).copied().collect::<Vec<f64>>();
        let g = along(&gradient);
        let net: f64 = g.iter().sum();
        let magnitude: f64 = g.iter().map(|x| x.abs()).sum();
        let mut uniform = vec![0.0; n];
        uniform
            .iter_mut()
            .skip(a)
            .step_by(dim)
            .for_each(|x| *x = 1.0);
        let response: f64 = hessian(&uniform).iter().map(|x| x.abs()).sum();
        net.abs() <= RELATIVE * magnitude && response <= RELATIVE * hessian_scale
    })
}

/// What [`maxwell_boltzmann`] did, for the run header.
#[derive(Clone, Debug, PartialEq)]
pub struct ThermalStart {
    pub degrees_of_freedom: DegreesOfFreedom,
    pub seed: u64,
}

/// Replace the momenta with a Maxwell–Boltzmann draw at `kt` (`k_B T` in the scene's
/// energy unit): `pᵢₐ = √(mᵢ kT) ξ` with standard normal `ξ` from the seeded generator,
/// drawn in particle order on one thread; then the centre-of-mass momentum is removed
/// when the forces conserve it, and the momenta are rescaled so the kinetic temperature
/// is exactly `T` over [`DegreesOfFreedom::count`].
/// With the system's own constraints ([`System::constraints`]) the draw is put on them as
/// [`maxwell_boltzmann_constrained`] does.
pub fn maxwell_boltzmann(system: &mut System, kt: f64, seed: u64) -> Result<ThermalStart> {
    match system.constraints.take() {
        Some(mut constraints) => {
            let start = thermal_start(system, Some(&mut constraints), kt, seed);
            system.constraints = Some(constraints);
            start
        }
        None => thermal_start(system, None, kt, seed),
    }
}

/// [`maxwell_boltzmann`] on the constraint manifold: the draw, with the centre-of-mass
/// momentum removed, is projected onto the velocities that keep every constraint
/// ([`Constraints::constrain_velocities`], the RATTLE projection, which leaves the total
/// momentum alone), then rescaled to exactly `T` over the `dim·N − N_c (− dim)` degrees of
/// freedom left. The positions must satisfy the constraints (see
/// [`Constraints::constrain_positions`]).
pub fn maxwell_boltzmann_constrained(
    system: &mut System,
    constraints: &mut Constraints,
    kt: f64,
    seed: u64,
) -> Result<ThermalStart> {
    thermal_start(system, Some(constraints), kt, seed)
}

fn thermal_start(
    system: &mut System,
    constraints: Option<&mut Constraints>,
    kt: f64,
    seed: u64,
) -> Result<ThermalStart> {
    if !(kt.is_finite() && kt > 0.0) {
        return Err(
            Error::setting("temperature", "a temperature must be positive and finite")
                .expected("a positive finite temperature")
                .got(format!("k_B T = {kt}")),
        );
    }
    if system.mass_matrix.is_some() {
        return Err(Error::input(
            "start velocities at a temperature need a diagonal mass matrix; this scene has a \
             non-diagonal one (lump it with lump = true in [mass_matrix], or give its momenta)",
        ));
    }
    let n_constraints = constraints.as_ref().map_or(0, |c| c.count());
    let dofs = DegreesOfFreedom::constrained(system, n_constraints);
    if dofs.count == 0 {
        return Err(Error::input(format!(
            "a temperature needs degrees of freedom to heat, and this scene has none ({} \
             particle(s) whose only motion, the centre of mass, carries no temperature)",
            system.n_particles()
        )));
    }
    let dim = system.dim;
    let masses = &system.particles.masses;
    let p = &mut system.state.p;
    fill_normal(&mut generator(seed), p);
    for (i, &m) in masses.iter().enumerate() {
        let sigma = (m * kt).sqrt();
        p[i * dim..(i + 1) * dim]
            .iter_mut()
            .for_each(|x| *x *= sigma);
    }
    if dofs.momentum_conserved {
        remove_centre_of_mass_momentum(p, masses, dim);
    }
    if let Some(constraints) = constraints {
        constraints
            .constrain_velocities(&system.state.q, p, &system.inverse_mass)
            .map_err(|e| Error::input(format!("start velocities on the constraints: {e}")))?;
    }
    let kinetic = super::kinetic_energy(p, &system.inverse_mass);
    let target = 0.5 * dofs.count as f64 * kt;
    let scale = (target / kinetic).sqrt();
    p.iter_mut().for_each(|x| *x *= scale);
    Ok(ThermalStart {
        degrees_of_freedom: dofs,
        seed,
    })
}

/// `pᵢ −= (mᵢ / M) P`: the centre of mass at rest, the relative motion unchanged.
pub fn remove_centre_of_mass_momentum(p: &mut [f64], masses: &[f64], dim: usize) {
    let total_mass: f64 = masses.iter().sum();
    let mut momentum = [0.0; 3];
    for pi in p.chunks_exact(dim) {
        for a in 0..dim {
            momentum[a] += pi[a];
        }
    }
    for (pi, &m) in p.chunks_exact_mut(dim).zip(masses) {
        for a in 0..dim {
            pi[a] -= m / total_mass * momentum[a];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_deviates_have_unit_variance_and_zero_mean() {
        // n = 200 000 deviates: the sample mean has standard error 1/√n ≈ 2.2e-3 and the
        // sample variance √(2/n) ≈ 3.2e-3; we allow 5 standard errors.
        let mut rng = generator(42);
        let mut x = vec![0.0; 200_001];
        fill_normal(&mut rng, &mut x);
        let n = x.len() as f64;
        let mean = x.iter().sum::<f64>() / n;
        let variance = x.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (n - 1.0);
        assert!(mean.abs() < 5.0 / n.sqrt(), "mean {mean}");
        assert!(
            (variance - 1.0).abs() < 5.0 * (2.0 / n).sqrt(),
            "variance {variance}"
        );
        // The fourth moment of a normal is 3 (a uniform would give 1.8): var ≈ √(96/n).
        let fourth = x.iter().map(|v| v.powi(4)).sum::<f64>() / n;
        assert!((fourth - 3.0).abs() < 5.0 * (96.0 / n).sqrt(), "{fourth}");
    }

    #[test]
    fn the_same_seed_gives_the_same_numbers() {
        let draw = |seed| {
            let mut x = vec![0.0; 7];
            fill_normal(&mut generator(seed), &mut x);
            x
        };
        assert_eq!(draw(3), draw(3));
        assert_ne!(draw(3), draw(4));
    }
}
