//! The innermost step of the r-RESPA recursion ([`super::impulse`]): what happens at the
//! fastest level between two evaluations of its force, and how every level kicks.
//!
//! One innermost step of length `dt` is, for every implementation,
//! `B(dt/2) · kick₀(dt/2) · flight(dt) · [∇V₀] · kick₀(dt/2) · B(dt/2)`,
//! where `kick` is [`InnermostStep::kick`] (used by the outer levels' kicks too), `flight`
//! is [`InnermostStep::flight`] and `B` is [`InnermostStep::bracket`] (empty except for
//! SIN(R)). The implementations:
//! - [`VerletStep`]: velocity Verlet, `flight = drift(dt)` (impulse and the mollified
//!   methods; GSS98 after eq. (1));
//! - [`Baoab`](super::langevin::Baoab): BAOAB (LM13), `flight = A(dt/2) O(dt) A(dt/2)`
//!   (`langevin-respa`, OpenMM's `MTSLangevinIntegrator`);
//! - [`Sinr`](super::sinr::Sinr): SIN(R)'s `N(dt/2) V(dt/2) X(dt) OU(dt) V(dt/2) N(dt/2)`
//!   with isokinetic kicks (LMT13).
//!
//! Cost: one gradient of level 0 per innermost step, whatever the implementation.

use super::integrator::{StepFailure, drift, kick};
use crate::error::Result;
use crate::system::System;

pub trait InnermostStep: Send {
    /// The method's name when this step makes it another method (`"langevin-respa"`);
    /// `None` for plain velocity Verlet.
    fn method_name(&self) -> Option<&'static str> {
        None
    }

    /// The run header's part (`", kT = …, friction = …"`).
    fn describe(&self) -> String {
        String::new()
    }

    /// Size buffers and noise for innermost steps of `dt`.
    fn setup(&mut self, _dt: f64, _system: &mut System) -> Result<()> {
        Ok(())
    }

    /// `p -= scale · gradient`, the kick every level gives through this step.
    fn kick(&mut self, system: &mut System, gradient: &[f64], scale: f64) {
        kick(&mut system.state.p, gradient, scale);
    }

    /// What comes before the first kick and after the last one, over `delta = dt/2`.
    fn bracket(&mut self, _system: &mut System, _delta: f64) {}

    /// The motion between the two kicks of level 0, over `dt`.
    fn flight(&mut self, system: &mut System, dt: f64) -> Result<(), StepFailure>;

    /// After every outer step (a thermostat's health check; the constrained step's owed
    /// velocity projection).
    fn after_outer_step(&mut self, _system: &mut System) -> Result<(), StepFailure> {
        Ok(())
    }

    /// What the user should know before the run.
    fn notices(&self, _system: &System) -> Vec<String> {
        Vec::new()
    }

    /// The summary's object for this step, under its key.
    fn report(&self) -> Option<(&'static str, serde_json::Value)> {
        None
    }

    /// Whether this step is plain velocity Verlet, so the fast level may run block by
    /// block in parallel ([`super::impulse`]).
    fn is_plain_verlet(&self) -> bool {
        false
    }

    /// The step's hidden state for a checkpoint ([`Integrator::save_state`]); `Null`
    /// for none.
    ///
    /// [`Integrator::save_state`]: super::Integrator::save_state
    fn save_state(&self) -> Result<serde_json::Value> {
        Ok(serde_json::Value::Null)
    }

    /// Restore what [`InnermostStep::save_state`] saved, after `setup`.
    fn restore_state(&mut self, state: &serde_json::Value) -> Result<()> {
        super::integrator::expect_no_state(self.method_name().unwrap_or("verlet"), state)
    }
}

/// Velocity Verlet: kick `dt/2`, drift `dt`, kick `dt/2`.
#[derive(Clone, Copy, Debug, Default)]
pub struct VerletStep;

impl InnermostStep for VerletStep {
    fn flight(&mut self, system: &mut System, dt: f64) -> Result<(), StepFailure> {
        let state = &mut system.state;
        drift(&mut state.q, &state.p, &system.inverse_mass, dt);
        Ok(())
    }

    fn is_plain_verlet(&self) -> bool {
        true
    }
}
