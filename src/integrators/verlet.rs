//! Velocity Verlet (Störmer–Verlet), the single-time-step baseline: every force level is
//! evaluated at every step.
//!
//! `p ← p − (h/2)∇V(q); q ← q + h M⁻¹p; p ← p − (h/2)∇V(q)`. Second order, symplectic,
//! time-reversible; stable for `hω < 2` on the fastest frequency ω. Cost per step: one
//! evaluation of every level (the end-of-step gradient is the next step's first).

use super::integrator::{Integrator, StepFailure, drift, kick};
use crate::error::{Error, Result};
use crate::system::System;

pub struct VelocityVerlet {
    h: f64,
    gradient: Vec<f64>,
}

impl VelocityVerlet {
    pub fn new(h: f64) -> Result<Self> {
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::setting("h", "step h must be positive and finite")
                .expected("a positive finite step")
                .got(h.to_string()));
        }
        Ok(VelocityVerlet {
            h,
            gradient: Vec::new(),
        })
    }
}

impl Integrator for VelocityVerlet {
    fn name(&self) -> &'static str {
        "verlet"
    }

    fn describe(&self) -> String {
        format!("h = {}", self.h)
    }

    fn outer_step(&self) -> f64 {
        self.h
    }

    fn setup(&mut self, system: &mut System) -> Result<()> {
        self.gradient = vec![0.0; system.n_dofs()];
        system
            .forces
            .total_gradient(&system.state.q, &mut self.gradient);
        Ok(())
    }

    fn step(&mut self, system: &mut System) -> Result<(), StepFailure> {
        let half = 0.5 * self.h;
        let state = &mut system.state;
        kick(&mut state.p, &self.gradient, half);
        drift(&mut state.q, &state.p, &system.inverse_mass, self.h);
        system.forces.total_gradient(&state.q, &mut self.gradient);
        kick(&mut state.p, &self.gradient, half);
        state.t += self.h;
        Ok(())
    }
}
