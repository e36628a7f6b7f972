//! Constrained innermost steps: velocity Verlet with RATTLE (And83) and BAOAB with
//! constraints (LM13's constrained BAOAB), as the innermost step of the r-RESPA recursion
//! ([`super::impulse`]), so that `verlet`, `impulse` (endpoint), the mollified impulse
//! methods (`short-average`, `long-average`, `linear-average`, `equilibrium-molly`) and
//! `langevin-respa` (with or without `--mollifier`) run with rigid bonds and rigid water
//! ([`crate::system::constraints`]).
//!
//! **Mollified slow forces.** The mollified impulse `A_q(q)ᵀ∇U(A(q))` (GSS98 eq. (4)) is a
//! kick of the slow level like any other, so it is projected onto the constraints' tangent
//! space with the others (below). The GSS98 averages integrate their auxiliary problem
//! under the same constraints and differentiate through them
//! ([`super::mollified`]'s `constrained`); the equilibrium projection (IRS99,
//! [`super::equilibrium_molly`]) is a function of `q` whose exact Jacobian needs no
//! change. Either way the kick is the gradient of `U(A(q))` restricted to the manifold,
//! and the method conserves `K + W(q) + U(A(q))`.
//!
//! **Where the constraints act.** A kick of any level ([`InnermostStep::kick`]) only
//! changes the momenta and leaves the velocity projection onto the constraints' tangent
//! space (RATTLE's velocity step) owed; it is done once, when the momenta are next used:
//! before a drift (and its position constraint) and at the end of the outer step. Kicks
//! with no drift between them (the slow kicks of every level around the inner kicks, the
//! last inner kick of one inner step and the first of the next) thus share one projection:
//! the projection `P` at fixed `q` is linear and idempotent, `P(P p + k) = P(p + k)`, so
//! one projection of their sum is the projection after each, to round-off (to the RATTLE
//! tolerance for pair constraints, which meet it either way).
//!
//! The flight of level 0:
//! - velocity Verlet: `drift(dt)`, then SHAKE/SETTLE of the positions with the matching
//!   momentum change `Δp = M Δq / dt` (And83 (2.4)–(2.6));
//! - BAOAB: `A(dt/2)` + position constraint, `O(dt)`, `A(dt/2)` + position constraint, as
//!   OpenMM's `LangevinMiddleIntegrator` with constraints (which constrains the positions
//!   once after both drifts; here after each, as the issue asks).
//!
//! With all levels' substeps 1 the recursion is plain velocity Verlet, so the constrained
//! `verlet` is this step with one inner step per level.
//!
//! A constraint that does not converge (SHAKE/RATTLE beyond the iteration cap, SETTLE
//! beyond reach) is a step failure with the time (exit 3).
//!
//! Cost besides Verlet's or BAOAB's: one position constraint per drift, one velocity
//! projection before each drift that follows a kick or an O step, and one at the end of the
//! outer step: with `K` innermost Verlet steps per outer step, `K` position constraints and
//! `K + 1` projections, whatever the number of levels (the former scheme projected after
//! every kick: `2K + 2(levels − 1)`).

use super::impulse::Impulse;
use super::innermost::InnermostStep;
use super::integrator::{Integrator, StepFailure, drift, kick};
use super::langevin::Langevin;
use super::mollified::SlowMollifier;
use crate::error::{Error, Result};
use crate::settings::{ConstraintSet, MethodSettings};
use crate::system::System;
use crate::system::constraints::ConstraintFailure;

/// The methods that run with constraints.
pub const CONSTRAINED_METHODS: [&str; 7] = [
    "verlet",
    "impulse",
    "short-average",
    "long-average",
    "linear-average",
    "equilibrium-molly",
    "langevin-respa",
];

/// The motion between the two kicks of level 0.
enum Flight {
    Verlet,
    Baoab(Langevin),
}

/// The constrained innermost step of `verlet`, `impulse` or `langevin-respa`.
pub struct Constrained {
    name: &'static str,
    flight: Flight,
    /// The positions before a drift (SHAKE's reference).
    q_old: Vec<f64>,
    /// Whether the momenta changed (a kick, an O step) since the last projection.
    owed: bool,
}

/// Build `method` with constraints: `verlet`, `impulse` and the mollified methods with
/// [`Constrained`] velocity Verlet, `langevin-respa` with constrained BAOAB; every other
/// method refuses. `mollifier` is the slow-force mollifier the registry built for a
/// mollified method or `langevin-respa --mollifier`.
pub fn build(
    settings: &MethodSettings,
    mollifier: Option<Box<dyn SlowMollifier>>,
) -> Result<Box<dyn Integrator>> {
    let name = settings.method.as_str();
    let step = |name, flight| Box::new(Constrained::new(name, flight));
    match name {
        "verlet" => {
            let one_step_per_level = MethodSettings {
                inner_steps: Some(1),
                level_steps: None,
                ..settings.clone()
            };
            let method =
                Impulse::with_innermost(&one_step_per_level, None, step("verlet", Flight::Verlet))?;
            Ok(Box::new(method))
        }
        "impulse" => Ok(Box::new(Impulse::with_innermost(
            settings,
            None,
            step("impulse", Flight::Verlet),
        )?)),
        "short-average" | "long-average" | "linear-average" | "equilibrium-molly" => {
            let Some(mollifier) = mollifier else {
                return Err(Error::input(format!(
                    "{name} was built without its mollifier"
                )));
            };
            let name = mollifier.name();
            Ok(Box::new(Impulse::with_innermost(
                settings,
                Some(mollifier),
                step(name, Flight::Verlet),
            )?))
        }
        "langevin-respa" => {
            let langevin = Langevin::from_settings(settings)?;
            Ok(Box::new(Impulse::with_innermost(
                settings,
                mollifier,
                step("langevin-respa", Flight::Baoab(langevin)),
            )?))
        }
        other => Err(refusal(settings, other)),
    }
}

/// Why `method` refuses the constraints `settings` ask for: SIN(R) for its own reason, every
/// other method because only [`CONSTRAINED_METHODS`] have a constrained innermost step.
fn refusal(settings: &MethodSettings, method: &str) -> Error {
    let mut asked = Vec::new();
    if settings.constraints != ConstraintSet::None {
        asked.push(format!("constraints = {}", settings.constraints.name()));
    }
    if settings.rigid_water {
        asked.push("rigid_water".to_string());
    }
    let why = if method == "sinr" {
        format!(
            "its isokinetic constraint holds each Cartesian degree of freedom's kinetic energy \
             at L kT (docs/thermostats.md), and the velocity projection of bond constraints \
             mixes the coordinates it joins, breaking that per-coordinate constraint (no \
             constrained SIN(R) is built); run sinr flexible (LMT13's protocol: flexible \
             water; --hydrogen-mass is allowed), or {} with the constraints",
            CONSTRAINED_METHODS.join(", ")
        )
    } else {
        format!(
            "constraints act on the innermost level of {} only; run one of those, or drop the \
             constraints",
            CONSTRAINED_METHODS.join(", ")
        )
    };
    Error::setting(
        "method",
        format!(
            "{method} does not run with constraints ({}): {why}",
            asked.join(", ")
        ),
    )
    .expected(CONSTRAINED_METHODS.join(", "))
    .got_named(method)
}

impl Constrained {
    fn new(name: &'static str, flight: Flight) -> Self {
        Constrained {
            name,
            flight,
            q_old: Vec::new(),
            owed: false,
        }
    }

    /// RATTLE's velocity projection at the current positions, if one is owed (see the
    /// module's doc).
    fn project_velocities(&mut self, system: &mut System) -> Result<(), StepFailure> {
        if !std::mem::take(&mut self.owed) {
            return Ok(());
        }
        let Some(constraints) = system.constraints.as_mut() else {
            return Ok(());
        };
        let state = &mut system.state;
        constraints
            .constrain_velocities(&state.q, &mut state.p, &system.inverse_mass)
            .map_err(|e| failure(state.t, e))
    }

    /// The owed projection, `drift(dt)` and the position constraint with its momentum change.
    fn constrained_drift(&mut self, system: &mut System, dt: f64) -> Result<(), StepFailure> {
        self.project_velocities(system)?;
        let state = &mut system.state;
        self.q_old.copy_from_slice(&state.q);
        drift(&mut state.q, &state.p, &system.inverse_mass, dt);
        if let Some(constraints) = system.constraints.as_mut() {
            constraints
                .constrain_positions(
                    &self.q_old,
                    &mut state.q,
                    &mut state.p,
                    &system.inverse_mass,
                    dt,
                )
                .map_err(|e| failure(state.t, e))?;
        }
        Ok(())
    }
}

/// A constraint failure as a step failure, with the time of the step it happened in.
fn failure(t: f64, e: ConstraintFailure) -> StepFailure {
    // Ten digits: a sum of steps reads 123220, not 123220.00000000001.
    let t = crate::units::significant(t, 10);
    StepFailure(format!("constraints failed (outer step at t = {t}): {e}"))
}

impl InnermostStep for Constrained {
    fn method_name(&self) -> Option<&'static str> {
        Some(self.name)
    }

    fn describe(&self) -> String {
        let flight = match &self.flight {
            Flight::Verlet => String::new(),
            Flight::Baoab(langevin) => langevin.describe(),
        };
        format!("{flight}, constrained (RATTLE/SETTLE on the innermost level)")
    }

    fn setup(&mut self, dt: f64, system: &mut System) -> Result<()> {
        let Some(constraints) = &system.constraints else {
            return Err(Error::input(format!(
                "{} was built with constraints, but the system has none attached (they are \
                 built from the scene by Scene::apply_molecular_settings)",
                self.name
            )));
        };
        constraints.check_masses(&system.inverse_mass)?;
        self.q_old = vec![0.0; system.n_dofs()];
        self.owed = false;
        if let Flight::Baoab(langevin) = &mut self.flight {
            langevin.setup(dt, &system.inverse_mass);
        }
        Ok(())
    }

    /// The kick alone: its projection is owed (done before the next drift or at the end of
    /// the outer step).
    fn kick(&mut self, system: &mut System, gradient: &[f64], scale: f64) {
        kick(&mut system.state.p, gradient, scale);
        self.owed = true;
    }

    fn flight(&mut self, system: &mut System, dt: f64) -> Result<(), StepFailure> {
        if matches!(self.flight, Flight::Verlet) {
            return self.constrained_drift(system, dt);
        }
        let half = 0.5 * dt;
        self.constrained_drift(system, half)?;
        if let Flight::Baoab(langevin) = &mut self.flight {
            langevin.apply(&mut system.state.p);
            self.owed = true;
        }
        self.constrained_drift(system, half)
    }

    /// The projection owed by the kicks since the last drift.
    fn after_outer_step(&mut self, system: &mut System) -> Result<(), StepFailure> {
        self.project_velocities(system)
    }

    /// The Langevin generator of a constrained BAOAB step; a constrained Verlet step keeps
    /// nothing between outer steps (the owed projection is done at their end).
    fn save_state(&self) -> Result<serde_json::Value> {
        match &self.flight {
            Flight::Baoab(langevin) => langevin.save_state(),
            Flight::Verlet => Ok(serde_json::Value::Null),
        }
    }

    fn restore_state(&mut self, state: &serde_json::Value) -> Result<()> {
        match &mut self.flight {
            Flight::Baoab(langevin) => langevin.restore_state(state),
            Flight::Verlet => super::integrator::expect_no_state(self.name, state),
        }
    }

    fn report(&self) -> Option<(&'static str, serde_json::Value)> {
        match &self.flight {
            Flight::Baoab(langevin) => Some(("langevin", langevin.report())),
            Flight::Verlet => None,
        }
    }
}
