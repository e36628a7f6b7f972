//! The [`Integrator`] trait every method implements, and the two operations every method
//! is made of: the kick `p -= s ∇V` and the drift `q += dt M⁻¹p`.

use crate::error::Result;
use crate::system::System;

/// A step the method could not take (a solver that did not converge, a step-size floor
/// reached). The run stops and reports it with the time.
#[derive(Debug, Clone, PartialEq)]
pub struct StepFailure(pub String);

pub trait Integrator {
    /// The method's name as given on the command line (`"verlet"`).
    fn name(&self) -> &'static str;

    /// The method's parameters for the run header (`"h = 0.05"`).
    fn describe(&self) -> String;

    /// The outer step `h`.
    fn outer_step(&self) -> f64;

    /// Size buffers, check that the method can apply every force level of the system,
    /// and evaluate what the first step needs.
    fn setup(&mut self, system: &mut System) -> Result<()>;

    /// Advance the state, time included, by one outer step.
    fn step(&mut self, system: &mut System) -> Result<(), StepFailure>;

    /// Whether every step is exactly `h` long; the run loop then sets `t = t₀ + n h`
    /// instead of letting rounding accumulate over many `t += h`.
    fn fixed_step(&self) -> bool {
        true
    }

    /// Names of method-specific columns for `energy.csv` (an invariant, a step size).
    fn extra_columns(&self) -> Vec<&'static str> {
        Vec::new()
    }

    /// Values for [`Integrator::extra_columns`] at the current state.
    fn extra_values(&self, _system: &System, _out: &mut Vec<f64>) {}

    /// Whether the method integrates velocity-dependent (magnetic) terms, whose force is
    /// no gradient ([`ForceTerm::magnetic`](crate::forces::ForceTerm::magnetic)); the run
    /// refuses such a system for every other method.
    fn handles_magnetic(&self) -> bool {
        false
    }

    /// Whether the method solves with a non-diagonal mass matrix
    /// ([`System::mass_matrix`]); the run refuses a system with one otherwise.
    fn supports_mass_matrix(&self) -> bool {
        false
    }

    /// What the user should know about this method on this system before the run (a
    /// fallback to another scheme, a costly split).
    fn notices(&self, _system: &System) -> Vec<String> {
        Vec::new()
    }

    /// A method-specific object for the run summary, under its key (MEMM18's pseudo-energy
    /// statistics are `("pseudo_energy", {...})`).
    fn report(&self) -> Option<(&'static str, serde_json::Value)> {
        None
    }
}

/// `p -= scale · gradient`: a kick by the force `−gradient` over time `scale`.
#[inline]
pub fn kick(p: &mut [f64], gradient: &[f64], scale: f64) {
    for (pi, gi) in p.iter_mut().zip(gradient) {
        *pi -= scale * gi;
    }
}

/// `q += dt · M⁻¹ p`: free flight over `dt`.
#[inline]
pub fn drift(q: &mut [f64], p: &[f64], inverse_mass: &[f64], dt: f64) {
    for ((qi, pi), wi) in q.iter_mut().zip(p).zip(inverse_mass) {
        *qi += dt * (wi * pi);
    }
}
