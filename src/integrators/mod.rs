//! Integrators: one file per method family, all behind [`Integrator`].
//!
//! An integrator owns its step sizes and scratch buffers (sized once in
//! [`Integrator::setup`], so a step allocates nothing), advances the [`System`] state by
//! one outer step, and leaves the force-evaluation counts in the system's
//! [`ForceSplit`](crate::split::ForceSplit). Steps are named everywhere as `h` (the outer
//! step, at which the slowest forces are sampled) and `inner_steps` / `dt` (the inner step
//! `dt = h / inner_steps`) — never a bare "timestep".

pub mod verlet;

pub use verlet::VelocityVerlet;

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

/// The methods `--method` accepts, with a line of help each.
pub const METHODS: &[(&str, &str)] = &[(
    "verlet",
    "velocity Verlet: every force level at every step h (single time step)",
)];

/// A method's settings, from the scene's `[run]` table and the command line.
#[derive(Clone, Debug, Default)]
pub struct MethodSettings {
    pub method: String,
    /// Outer step.
    pub h: f64,
    /// Inner steps per outer step.
    pub inner_steps: Option<usize>,
    /// Inner step `h / inner_steps`, when given instead of `inner_steps`.
    pub dt: Option<f64>,
}

impl MethodSettings {
    /// The number of inner steps, from `inner_steps` or from `dt`, which must divide `h`.
    pub fn resolved_inner_steps(&self) -> Result<Option<usize>> {
        match (self.inner_steps, self.dt) {
            (Some(_), Some(_)) => Err(crate::error::Error::input(
                "give the inner step either as inner steps (--inner) or as dt (--dt), not both",
            )),
            (Some(0), None) => Err(crate::error::Error::input(
                "inner steps must be at least 1",
            )),
            (Some(k), None) => Ok(Some(k)),
            (None, Some(dt)) => {
                if !(dt.is_finite() && dt > 0.0) {
                    return Err(crate::error::Error::input(format!(
                        "inner step dt must be positive and finite, got {dt}"
                    )));
                }
                let ratio = self.h / dt;
                let k = ratio.round();
                if k < 1.0 || (ratio - k).abs() > 1e-9 * ratio {
                    return Err(crate::error::Error::input(format!(
                        "inner step dt = {dt} does not divide the outer step h = {} \
                         (h/dt = {ratio}); choose dt = h/k for a whole number k",
                        self.h
                    )));
                }
                Ok(Some(k as usize))
            }
            (None, None) => Ok(None),
        }
    }
}

/// Build the integrator a run asked for. `notices` collects what the user should know
/// (an option the method ignores).
pub fn build(settings: &MethodSettings, notices: &mut Vec<String>) -> Result<Box<dyn Integrator>> {
    let inner_steps = settings.resolved_inner_steps()?;
    match settings.method.as_str() {
        "verlet" => {
            if let Some(k) = inner_steps {
                notices.push(format!(
                    "verlet takes a single step h; the inner step setting ({k} inner steps) is ignored"
                ));
            }
            Ok(Box::new(VelocityVerlet::new(settings.h)?))
        }
        other => {
            let known: Vec<&str> = METHODS.iter().map(|(name, _)| *name).collect();
            Err(crate::error::Error::input(format!(
                "unknown method \"{other}\"; known methods: {}",
                known.join(", ")
            )))
        }
    }
}
