//! Exact solutions that scenes can provide, for error measurement: `longstep run` reports
//! `max_i |q_i(t) − q_i^exact(t)|` at the end of the run (summary key `exact_error`).
//!
//! A scene gives one in its `[exact]` table (docs/scenes.md):
//!
//! * `type = "expression"`: one expression per axis in `t`, the particle index `i` and the
//!   scene's parameters, e.g. `position = ["sin(t)^4 + 1"]`;
//! * `type = "two-media-wave"`: the d'Alembert solution of MEMM18 4.3.2 for
//!   `u_tt = (c(x)² u_x)_x` on `(0, L)` with `c = c1` left of the interface `ξ` and `c2`
//!   right of it, a fixed end at 0, and an initial pulse `u₀` (zero outside `support`)
//!   moving right, `v₀ = −c1 u₀′`. With `r = (c2 − c1)/(c1 + c2)`:
//!   `u(x, t) = Σ_k r^k (u₀(x + 2ξk − c1 t) − u₀(2ξk − x − c1 t))` for `x < ξ` and
//!   `u(x, t) = 2c1/(c1 + c2) Σ_k r^k u₀((c1/c2)(x − ξ) + 2ξk + ξ − c1 t)` for `x > ξ`
//!   (MEMM18's formula with `ξ = 1/2`), valid until the transmitted wave reaches the far
//!   end. Particle `i` sits at `x = node(i)`.
//!
//! New kinds implement [`ExactSolution`].

use std::collections::BTreeMap;

use super::State;
use crate::error::{Error, Result};
use crate::expr;

/// Exact positions of a scene as functions of time.
pub trait ExactSolution: Send + Sync {
    /// One line for the run summary.
    fn describe(&self) -> String;

    /// `q = q^exact(t)` over all coordinates.
    fn positions(&self, t: f64, q: &mut [f64]) -> Result<()>;
}

/// The error of a state against an exact solution.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ExactError {
    pub t: f64,
    /// `max_i |q_i − q_i^exact|`.
    pub max_abs: f64,
    /// `max_i |q_i^exact|`, for scale.
    pub max_exact: f64,
    pub solution: String,
}

/// The position error of `state` at its time.
pub fn position_error(exact: &dyn ExactSolution, state: &State) -> Result<ExactError> {
    let mut q = vec![0.0; state.q.len()];
    exact.positions(state.t, &mut q)?;
    let max_abs = state
        .q
        .iter()
        .zip(&q)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    let max_exact = q.iter().map(|x| x.abs()).fold(0.0, f64::max);
    Ok(ExactError {
        t: state.t,
        max_abs,
        max_exact,
        solution: exact.describe(),
    })
}

/// Positions given by expressions in `t`, `i` and the scene's parameters, one per axis.
pub struct ExpressionSolution {
    pub dim: usize,
    pub position: Vec<String>,
    pub parameters: BTreeMap<String, f64>,
}

impl ExactSolution for ExpressionSolution {
    fn describe(&self) -> String {
        format!("expression [{}]", self.position.join(", "))
    }

    fn positions(&self, t: f64, q: &mut [f64]) -> Result<()> {
        let mut local = self.parameters.clone();
        local.insert("t".into(), t);
        for (i, chunk) in q.chunks_mut(self.dim).enumerate() {
            local.insert("i".into(), i as f64);
            for (x, text) in chunk.iter_mut().zip(&self.position) {
                *x = expr::evaluate(text, &local)
                    .map_err(|e| Error::input(format!("exact solution: {e}")))?;
            }
        }
        Ok(())
    }
}

/// MEMM18 4.3.2's transmitted-and-reflected pulse (see the module documentation).
pub struct TwoMediaWave {
    pub c1: f64,
    pub c2: f64,
    pub interface: f64,
    /// `u₀(x)`, an expression in `x` and the parameters.
    pub pulse: String,
    /// `u₀ = 0` outside `[support.0, support.1]`.
    pub support: (f64, f64),
    /// The rest position of particle `i`, an expression in `i` and the parameters.
    pub node: String,
    pub parameters: BTreeMap<String, f64>,
}

impl TwoMediaWave {
    fn pulse_at(&self, x: f64, local: &mut BTreeMap<String, f64>) -> Result<f64> {
        if x < self.support.0 || x > self.support.1 {
            return Ok(0.0);
        }
        local.insert("x".into(), x);
        expr::evaluate(&self.pulse, local).map_err(|e| Error::input(format!("exact pulse: {e}")))
    }

    /// `u(x, t)`.
    pub fn displacement(&self, x: f64, t: f64) -> Result<f64> {
        let mut local = self.parameters.clone();
        let (c1, c2, xi) = (self.c1, self.c2, self.interface);
        let r = (c2 - c1) / (c1 + c2);
        // Terms with 2ξk − (distance travelled) beyond the support vanish; one more for safety.
        let reach = c1 * t + (c1 / c2) * (1.0 + xi) + self.support.1.abs() + self.support.0.abs();
        let k_max = (reach / (2.0 * xi)).ceil() as usize + 1;
        let mut u = 0.0;
        let mut weight = 1.0;
        for k in 0..=k_max {
            let shift = 2.0 * xi * k as f64 - c1 * t;
            if x < xi {
                u += weight
                    * (self.pulse_at(x + shift, &mut local)?
                        - self.pulse_at(shift - x, &mut local)?);
            } else {
                u += weight
                    * (2.0 * c1 / (c1 + c2))
                    * self.pulse_at((c1 / c2) * (x - xi) + xi + shift, &mut local)?;
            }
            weight *= r;
        }
        Ok(u)
    }
}

impl ExactSolution for TwoMediaWave {
    fn describe(&self) -> String {
        format!(
            "two-media wave c1 = {}, c2 = {}, interface {}",
            self.c1, self.c2, self.interface
        )
    }

    fn positions(&self, t: f64, q: &mut [f64]) -> Result<()> {
        let mut local = self.parameters.clone();
        for (i, x) in q.iter_mut().enumerate() {
            local.insert("i".into(), i as f64);
            let node = expr::evaluate(&self.node, &local)
                .map_err(|e| Error::input(format!("exact solution node: {e}")))?;
            *x = self.displacement(node, t)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wave() -> TwoMediaWave {
        TwoMediaWave {
            c1: 10.0,
            c2: 1.0,
            interface: 0.5,
            pulse: "0.01*exp(-(20*(x-0.2))^2)".into(),
            support: (0.0, 0.5),
            node: "i/100".into(),
            parameters: BTreeMap::new(),
        }
    }

    #[test]
    fn starts_from_the_pulse_and_satisfies_the_fixed_end() {
        let w = wave();
        for x in [0.1, 0.2, 0.33] {
            let u0 = 0.01 * (-(20.0 * (x - 0.2f64)).powi(2)).exp();
            assert!((w.displacement(x, 0.0).unwrap() - u0).abs() < 1e-15);
        }
        for t in [0.05, 0.1, 0.23, 0.5] {
            assert!(w.displacement(0.0, t).unwrap().abs() < 1e-15);
        }
    }

    #[test]
    fn displacement_is_continuous_across_the_interface() {
        // Both formulas at ξ ∓ 1e-9: the difference is the slope times 2e-9, the slope
        // being at most |u₀′| c1/c2 ≈ 0.09·10.
        let w = wave();
        for t in [0.03, 0.035, 0.12, 0.31] {
            let left = w.displacement(0.5 - 1e-9, t).unwrap();
            let right = w.displacement(0.5 + 1e-9, t).unwrap();
            assert!((left - right).abs() < 1e-8, "t = {t}: {left} vs {right}");
        }
    }
}
