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

    /// The method's hidden state for a checkpoint: what cannot be recomputed bit for bit
    /// from the positions and momenta (a random-number generator, thermostat variables,
    /// staggered momenta, the adaptive step's history). `Null` for a method with none
    /// (the default); an error for a method whose state cannot be saved yet. Cached forces
    /// are not saved: [`Integrator::setup`] recomputes them.
    fn save_state(&self) -> Result<serde_json::Value> {
        Ok(serde_json::Value::Null)
    }

    /// Restore what [`Integrator::save_state`] saved, after [`Integrator::setup`]; an
    /// error names what is missing or malformed.
    fn restore_state(&mut self, state: &serde_json::Value) -> Result<()> {
        expect_no_state(self.name(), state)
    }
}

/// The default [`Integrator::restore_state`]: a method with no hidden state accepts only
/// `null`.
pub fn expect_no_state(method: &str, state: &serde_json::Value) -> Result<()> {
    if state.is_null() {
        Ok(())
    } else {
        Err(crate::error::Error::input(format!(
            "the checkpoint holds integrator state, but {method} keeps none"
        )))
    }
}

/// A method's hidden state as JSON (f64 as shortest round-trip decimals, which
/// `serde_json`'s `float_roundtrip` parsing reads back to the same bits).
pub fn state_to_json<T: serde::Serialize>(method: &str, state: &T) -> Result<serde_json::Value> {
    serde_json::to_value(state)
        .map_err(|e| crate::error::Error::input(format!("cannot save the state of {method}: {e}")))
}

/// The inverse of [`state_to_json`]; the error names the method and what is malformed.
pub fn state_from_json<T: serde::de::DeserializeOwned>(
    method: &str,
    state: &serde_json::Value,
) -> Result<T> {
    T::deserialize(state).map_err(|e| {
        crate::error::Error::input(format!(
            "the checkpoint's state of {method} is malformed: {e}"
        ))
    })
}

/// Copy a saved vector into a buffer sized by `setup`, refusing another length.
pub fn restore_vector(method: &str, what: &str, saved: &[f64], into: &mut [f64]) -> Result<()> {
    if saved.len() != into.len() {
        return Err(crate::error::Error::input(format!(
            "the checkpoint's {what} of {method} has {} values, this system {}",
            saved.len(),
            into.len()
        )));
    }
    into.copy_from_slice(saved);
    Ok(())
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
