//! Energy minimisation by FIRE (Bitzek, Koskinen, Gähler, Moseler, Gumbsch, PRL 97, 170201,
//! 2006): damped dynamics that turns the velocity towards the force while the power F·v is
//! positive and stops dead when it is not. XYZ files are rarely at a minimum of longstep's
//! force field, and normal modes are only meaningful at one.
//!
//! Positions move with unit masses (the minimum does not depend on the masses); momenta of
//! the system are left as they were. Cost: one gradient of every level per iteration, plus a
//! few Hessian-vector products to choose the step.

use serde::Serialize;

use crate::system::System;
use crate::units::Units;

#[derive(Clone, Debug)]
pub struct MinimizeOptions {
    /// Stop when the largest force component is below this.
    pub force_tolerance: f64,
    pub max_iterations: usize,
}

impl Default for MinimizeOptions {
    fn default() -> Self {
        MinimizeOptions {
            force_tolerance: 1e-6,
            max_iterations: 100_000,
        }
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct MinimizeReport {
    pub iterations: usize,
    pub energy_before: f64,
    pub energy_after: f64,
    pub max_force: f64,
    pub converged: bool,
}

impl MinimizeReport {
    /// The one-line report: energies to 10 significant digits and the largest force, with
    /// their units in a real scene (`E -1.234567890e1 kcal/mol -> …, max force 6.4e-7
    /// kcal/mol/Å`).
    pub fn text(&self, units: Units) -> String {
        let (energy, force) = match units {
            Units::None => (String::new(), String::new()),
            _ => (
                format!(" {}", units.energy_name()),
                format!(" {}/{}", units.energy_name(), units.length_name()),
            ),
        };
        format!(
            "{} iterations, E {:.9e}{energy} -> {:.9e}{energy}, max force {:.2e}{force}{}",
            self.iterations,
            self.energy_before,
            self.energy_after,
            self.max_force,
            if self.converged {
                ""
            } else {
                " (not converged)"
            }
        )
    }
}

impl std::fmt::Display for MinimizeReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.text(Units::None))
    }
}

/// The largest curvature of the potential (unit masses), by power iteration with
/// Hessian-vector products of every level.
fn largest_curvature(system: &mut System) -> f64 {
    let n = system.n_dofs();
    let q = system.state.q.clone();
    let mut v: Vec<f64> = (0..n)
        .map(|k| 1.0 + 0.1 * ((k * 7919) % 13) as f64)
        .collect();
    let mut hv = vec![0.0; n];
    let mut total = vec![0.0; n];
    let mut estimate = 0.0;
    for _ in 0..30 {
        let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        if norm == 0.0 {
            break;
        }
        v.iter_mut().for_each(|x| *x /= norm);
        total.fill(0.0);
        for level in 0..system.forces.n_levels() {
            system.forces.hessian_vector(level, &q, &v, &mut hv);
            total.iter_mut().zip(&hv).for_each(|(t, h)| *t += h);
        }
        estimate = v.iter().zip(&total).map(|(a, b)| a * b).sum::<f64>().abs();
        std::mem::swap(&mut v, &mut total);
    }
    estimate
}

/// Minimise the total potential energy over the positions.
pub fn minimize(system: &mut System, options: &MinimizeOptions) -> MinimizeReport {
    const N_MIN: usize = 5;
    const F_INC: f64 = 1.1;
    const F_DEC: f64 = 0.5;
    const ALPHA_START: f64 = 0.1;
    const F_ALPHA: f64 = 0.99;
    let n = system.n_dofs();
    let energy_before = system.forces.total_energy(&system.state.q);
    // Explicit Euler dynamics is stable for dt < 2/√λ_max; FIRE may grow dt tenfold.
    let curvature = largest_curvature(system).max(f64::MIN_POSITIVE);
    let dt_max = 1.0 / curvature.sqrt();
    let mut dt = 0.1 * dt_max;
    let mut alpha = ALPHA_START;
    let mut since_negative = 0;
    let mut velocity = vec![0.0; n];
    let mut gradient = vec![0.0; n];
    let mut iterations = 0;
    let mut max_force;
    loop {
        system.forces.total_gradient(&system.state.q, &mut gradient);
        max_force = gradient.iter().fold(0.0f64, |m, g| m.max(g.abs()));
        if max_force < options.force_tolerance
            || iterations == options.max_iterations
            || !max_force.is_finite()
        {
            break;
        }
        iterations += 1;
        let power: f64 = -velocity
            .iter()
            .zip(&gradient)
            .map(|(v, g)| v * g)
            .sum::<f64>();
        if power > 0.0 {
            let v_norm = velocity.iter().map(|v| v * v).sum::<f64>().sqrt();
            let f_norm = gradient.iter().map(|g| g * g).sum::<f64>().sqrt();
            for (v, g) in velocity.iter_mut().zip(&gradient) {
                *v = (1.0 - alpha) * *v - alpha * v_norm * g / f_norm;
            }
            since_negative += 1;
            if since_negative > N_MIN {
                dt = (dt * F_INC).min(dt_max);
                alpha *= F_ALPHA;
            }
        } else {
            velocity.fill(0.0);
            dt *= F_DEC;
            alpha = ALPHA_START;
            since_negative = 0;
        }
        for ((x, v), g) in system.state.q.iter_mut().zip(&mut velocity).zip(&gradient) {
            *v -= dt * g;
            *x += dt * *v;
        }
    }
    MinimizeReport {
        iterations,
        energy_before,
        energy_after: system.forces.total_energy(&system.state.q),
        max_force,
        converged: max_force < options.force_tolerance,
    }
}
