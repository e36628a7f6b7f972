//! The impulse method (Verlet-I / r-RESPA) and the mollified impulse methods.
//!
//! **Impulse, endpoint version** (GSS98 after eq. (1)): kick `(h/2)F(q_n)`; oscillate with the
//! h-flow of the reduced problem `dp/dt = −W_q(q), dq/dt = M⁻¹p`, integrated by velocity
//! Verlet with `inner_steps` steps of `dt = h/inner_steps`; kick `(h/2)F(q_{n+1})`. The second
//! kick's force is the next step's first. With more than two force levels the scheme
//! recurses (recursive r-RESPA, level 0 innermost, as LAMMPS `run_style respa` and OpenMM
//! `MTSIntegrator`): each level kicks with its own force around `level_steps` steps of the
//! level below, and level 0 is plain Verlet. Cost per outer step: one gradient of each level
//! per step of that level (the slow level once per `h`, the fast level `inner_steps` times).
//!
//! **Impulse, midpoint version** (GSS98 section 2): oscillate `h/2`, kick `h F(q_{n+1/2})`,
//! oscillate `h/2` (an even number of inner steps); same cost.
//!
//! **Mollified impulse** (GSS98 eq. (4)): the endpoint method with the impulse `F(q_n)`
//! of the outermost level replaced by `A_q(q_n)ᵀ F(A(q_n))`, from a [`SlowMollifier`]: a
//! time average and its Jacobian ([`super::mollified`], GSS98; two levels; cost per outer
//! step `inner_steps` fast gradients for the oscillation, one averaging — ⌈μ·inner_steps⌉ − 1
//! fast gradients and the Hessian-vector products of the chosen Jacobian mode — and one
//! slow gradient, at `A(h; q)`), or the equilibrium projection of IRS99
//! ([`super::equilibrium_molly`]; no extra force evaluation).
//!
//! Mollification is a hook around the slow-force call; the rest of the integrator does not
//! know which kind it is.
//!
//! **Threads.** With more than one thread the inner loop of the endpoint form (impulse and
//! the mollified methods) runs block by block: whole molecules per block ([`Blocks`]), each
//! block's `K` Verlet steps on its own thread, the same bits as one thread.
//!
//! **Thermostatted r-RESPA** ([`InnermostStep`], `super::innermost`): the same recursion
//! with another innermost step and, for SIN(R), another kick. `langevin-respa` (BAOAB-RESPA, OpenMM's
//! `MTSLangevinIntegrator`): the innermost step is BAOAB (LM13), kick `dt/2`, drift `dt/2`,
//! O step ([`super::langevin`]), drift `dt/2`, kick `dt/2`; the outer levels kick as impulse
//! does. With one force level it is plain BAOAB. `sinr`: every kick goes through the
//! isokinetic operator and the innermost step carries the thermostat ([`super::sinr`]).
//! Same cost in force evaluations as impulse.

use super::innermost::{InnermostStep, VerletStep};
use super::integrator::{Integrator, StepFailure, drift, kick};
use super::mollified::{MollifyAt, SlowMollifier};
use crate::error::{Error, Result};
use crate::settings::MethodSettings;
use crate::split::{Blocks, ForceSplit};
use crate::system::System;

/// From this many particles on, with more than one thread, the inner loop of plain impulse
/// runs block by block in parallel ([`Blocks`]; the same bits as one thread).
const BLOCKS_MIN_PARTICLES: usize = 256;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variant {
    Endpoint,
    Midpoint,
}

pub struct Impulse {
    name: &'static str,
    h: f64,
    variant: Variant,
    inner_steps: Option<usize>,
    level_steps_setting: Option<Vec<usize>>,
    /// `substeps[ℓ]`: steps of level ℓ − 1 per step of level ℓ (ℓ ≥ 1; `substeps[0]` unused).
    substeps: Vec<usize>,
    /// `∇V_ℓ` at the current positions (for the slow level of a mollified method,
    /// `A_qᵀ ∇U(A)`), one buffer per level.
    gradients: Vec<Vec<f64>>,
    empty: Vec<bool>,
    mollifier: Option<Box<dyn SlowMollifier>>,
    /// The innermost step, through which every level kicks ([`InnermostStep`]).
    step: Box<dyn InnermostStep>,
    /// A mollified force that could not be computed at the start: the first step reports
    /// it, so the run stops at t₀ with its outputs written (exit 3), not as bad input.
    pending_failure: Option<StepFailure>,
    /// The fast level cut into blocks that no fast interaction crosses, when the inner
    /// loop runs block by block ([`Impulse::inner_blocks`]).
    blocks: Option<Blocks>,
}

impl Impulse {
    /// r-RESPA impulse (`mollifier = None`) or a mollified impulse method.
    pub fn new(
        settings: &MethodSettings,
        variant: Variant,
        mollifier: Option<Box<dyn SlowMollifier>>,
    ) -> Result<Self> {
        let h = settings.h;
        if !(h.is_finite() && h > 0.0) {
            return Err(
                Error::setting("h", "outer step h must be positive and finite")
                    .expected("a positive finite step")
                    .got(h.to_string()),
            );
        }
        let name = match (&mollifier, variant) {
            (Some(mollifier), _) => mollifier.name(),
            (None, Variant::Endpoint) => "impulse",
            (None, Variant::Midpoint) => "impulse-midpoint",
        };
        if settings.inner_steps.is_none() && settings.level_steps.is_none() {
            return Err(Error::setting(
                "inner_steps",
                format!("{name} needs the inner step: give --inner K (dt = h/K) or --dt"),
            )
            .expected("--inner K or --dt"));
        }
        Ok(Impulse {
            name,
            h,
            variant,
            inner_steps: settings.inner_steps,
            level_steps_setting: settings.level_steps.clone(),
            substeps: Vec::new(),
            gradients: Vec::new(),
            empty: Vec::new(),
            mollifier,
            step: Box::new(VerletStep),
            pending_failure: None,
            blocks: None,
        })
    }

    /// The endpoint recursion around another innermost step (a thermostatted r-RESPA
    /// method: BAOAB, SIN(R)), optionally with a mollified slow force. The method takes the
    /// step's name.
    pub fn with_innermost(
        settings: &MethodSettings,
        mollifier: Option<Box<dyn SlowMollifier>>,
        step: Box<dyn InnermostStep>,
    ) -> Result<Self> {
        let mut method = Impulse::new(settings, Variant::Endpoint, mollifier)?;
        if let Some(name) = step.method_name() {
            method.name = name;
        }
        method.step = step;
        Ok(method)
    }

    /// The blocks the fast level's inner loop runs in, if it runs block by block (for
    /// tests).
    pub fn fast_blocks(&self) -> Option<&Blocks> {
        self.blocks.as_ref()
    }

    /// The mollifier of a mollified method (for tests and studies).
    pub fn mollifier(&self) -> Option<&dyn SlowMollifier> {
        self.mollifier.as_deref()
    }

    fn top(&self) -> usize {
        self.gradients.len() - 1
    }

    /// Recompute the force of `level` at the current positions.
    fn refresh(&mut self, level: usize, system: &mut System) -> Result<(), StepFailure> {
        if self.empty[level] {
            return Ok(());
        }
        let top = self.top();
        let (lower, upper) = self.gradients.split_at_mut(level);
        let gradient = &mut upper[0];
        match (&mut self.mollifier, level == top) {
            (Some(mollifier), true) => {
                let at = MollifyAt {
                    forces: &mut system.forces,
                    inverse_mass: &system.inverse_mass,
                    q: &system.state.q,
                    fast_gradient_at_q: Some(&lower[0]),
                    slow_level: level,
                    constraints: system.constraints.as_mut(),
                };
                mollifier.mollified_gradient(at, gradient)
            }
            _ => {
                system.forces.gradient(level, &system.state.q, gradient);
                Ok(())
            }
        }
    }

    fn kick(&mut self, level: usize, system: &mut System, scale: f64) {
        if self.empty[level] {
            return;
        }
        self.step.kick(system, &self.gradients[level], scale);
    }

    /// One step of length `h_level` of `level` (endpoint form).
    fn advance(
        &mut self,
        level: usize,
        h_level: f64,
        system: &mut System,
    ) -> Result<(), StepFailure> {
        if level == 0 {
            return self.innermost(h_level, system);
        }
        let n = self.substeps[level];
        let h_sub = h_level / n as f64;
        match self.variant {
            Variant::Endpoint => {
                self.kick(level, system, 0.5 * h_level);
                match &self.blocks {
                    Some(blocks) if level == 1 => {
                        inner_blocks(blocks, n, h_sub, system, &mut self.gradients[0]);
                    }
                    _ => {
                        for _ in 0..n {
                            self.advance(level - 1, h_sub, system)?;
                        }
                    }
                }
                self.refresh(level, system)?;
                self.kick(level, system, 0.5 * h_level);
            }
            Variant::Midpoint => {
                for _ in 0..n / 2 {
                    self.advance(level - 1, h_sub, system)?;
                }
                self.refresh(level, system)?;
                self.kick(level, system, h_level);
                for _ in 0..n / 2 {
                    self.advance(level - 1, h_sub, system)?;
                }
            }
        }
        Ok(())
    }

    /// Size the innermost step for `dt = h / Π level_steps` (SIN(R) also starts its
    /// thermostat variables and puts the momenta on its constraint).
    fn setup_innermost(&mut self, system: &mut System) -> Result<()> {
        let dt = self.h / self.substeps[1..].iter().product::<usize>() as f64;
        self.step.setup(dt, system)
    }

    /// The fast level's blocks, where the inner loop of plain endpoint impulse pays to run
    /// in parallel: more than one thread, at least [`BLOCKS_MIN_PARTICLES`] particles, and
    /// at least two blocks.
    fn find_fast_blocks(&self, system: &System) -> Option<Blocks> {
        let threads = rayon::current_num_threads();
        let n = system.n_dofs() / system.dim;
        let plain = self.step.is_plain_verlet() && self.variant == Variant::Endpoint;
        if !plain || self.empty[0] || threads < 2 || n < BLOCKS_MIN_PARTICLES {
            return None;
        }
        system
            .forces
            .blocks(0, n, threads)
            .filter(|blocks| blocks.len() > 1)
    }

    /// The innermost step ([`InnermostStep`]): bracket, kick, flight, the level-0 force,
    /// kick, bracket.
    fn innermost(&mut self, dt: f64, system: &mut System) -> Result<(), StepFailure> {
        let half = 0.5 * dt;
        self.step.bracket(system, half);
        self.kick(0, system, half);
        self.step.flight(system, dt)?;
        self.refresh(0, system)?;
        self.kick(0, system, half);
        self.step.bracket(system, half);
        Ok(())
    }
}

impl Integrator for Impulse {
    fn name(&self) -> &'static str {
        self.name
    }

    fn describe(&self) -> String {
        let mut text = format!("h = {}", self.h);
        if self.substeps.len() == 2 {
            let k = self.substeps[1];
            text += &format!(", inner_steps = {k}, dt = {}", self.h / k as f64);
        } else if self.substeps.len() > 2 {
            let outer_first: Vec<String> = self.substeps[1..]
                .iter()
                .rev()
                .map(|s| s.to_string())
                .collect();
            text += &format!(", level_steps = {}", outer_first.join(","));
        }
        if let Some(mollifier) = &self.mollifier {
            text += &format!(", {}", mollifier.describe());
        }
        text += &self.step.describe();
        text
    }

    fn outer_step(&self) -> f64 {
        self.h
    }

    fn setup(&mut self, system: &mut System) -> Result<()> {
        let levels = system.forces.n_levels();
        self.substeps = vec![1; levels];
        match (&self.level_steps_setting, self.inner_steps) {
            (Some(steps), _) => {
                if steps.len() != levels - 1 {
                    return Err(Error::setting(
                        "level_steps",
                        format!(
                            "the scene has {levels} force levels, so level_steps needs {} numbers \
                         (steps of each level per step of the level above, outermost first)",
                            levels - 1
                        ),
                    )
                    .expected(format!("{} numbers", levels - 1))
                    .got(steps.len().to_string()));
                }
                for (i, &s) in steps.iter().enumerate() {
                    self.substeps[levels - 1 - i] = s;
                }
            }
            (None, Some(k)) => self.substeps[1..].fill(k),
            (None, None) => unreachable!("checked in new"),
        }
        if self.variant == Variant::Midpoint
            && let Some(odd) = self.substeps[1..].iter().find(|&&s| s % 2 == 1)
        {
            return Err(Error::setting(
                "level_steps",
                format!(
                    "{} oscillates h/2 on each side of the kick, so it needs an even number of \
                 inner steps per level",
                    self.name
                ),
            )
            .expected("an even number of inner steps per level")
            .got(odd.to_string()));
        }
        if let Some(mollifier) = &mut self.mollifier {
            mollifier.setup(system)?;
        }
        self.setup_innermost(system)?;
        let n = system.n_dofs();
        self.gradients = vec![vec![0.0; n]; levels];
        self.empty = (0..levels)
            .map(|level| system.forces.level_is_empty(level))
            .collect();
        self.blocks = self.find_fast_blocks(system);
        // Level 0 first: a mollified slow level reuses ∇W(q). The midpoint form evaluates
        // the outer levels where it kicks, so only level 0 is needed at the start.
        let needed = match self.variant {
            Variant::Endpoint => levels,
            Variant::Midpoint => 1,
        };
        self.pending_failure = None;
        for level in 0..needed {
            if let Err(failure) = self.refresh(level, system) {
                self.pending_failure = Some(failure);
                break;
            }
        }
        Ok(())
    }

    fn step(&mut self, system: &mut System) -> Result<(), StepFailure> {
        if let Some(failure) = self.pending_failure.take() {
            return Err(failure);
        }
        self.advance(self.top(), self.h, system)?;
        system.state.t += self.h;
        self.step.after_outer_step(system)
    }

    fn notices(&self, system: &System) -> Vec<String> {
        let mut notices = match &self.mollifier {
            Some(mollifier) => mollifier.notices(system),
            None => Vec::new(),
        };
        notices.extend(self.step.notices(system));
        notices
    }

    /// The innermost step's state (a thermostat's generator and variables); the
    /// gradients are recomputed by `setup`.
    fn save_state(&self) -> Result<serde_json::Value> {
        if let Some(mollifier) = &self.mollifier {
            mollifier.check_checkpoint()?;
        }
        self.step.save_state()
    }

    fn restore_state(&mut self, state: &serde_json::Value) -> Result<()> {
        self.step.restore_state(state)
    }

    fn report(&self) -> Option<(&'static str, serde_json::Value)> {
        match self.step.report() {
            Some(report) => Some(report),
            None => Some(("mollifier", self.mollifier.as_ref()?.report()?)),
        }
    }

    /// A mollified method is the impulse method for the mollified potential
    /// `W(q) + U(A(q))` (GSS98 section 2; IRS99 for the equilibrium projection):
    /// `mollified_total = K + W(q) + U(A(q))` is the energy it conserves (up to O(h²)
    /// oscillation, with no drift while stable).
    fn extra_columns(&self) -> Vec<&'static str> {
        let mut columns = Vec::new();
        if self.mollifier.is_some() {
            columns.push("mollified_total");
        }
        columns
    }

    fn extra_values(&self, system: &System, out: &mut Vec<f64>) {
        if let Some(mollifier) = &self.mollifier {
            let top = self.top();
            let mut energy = system.kinetic_energy();
            for level in 0..top {
                energy += system.forces.energy(level, &system.state.q);
            }
            energy += system.forces.energy(top, mollifier.mollified_positions());
            out.push(energy);
        }
    }
}

/// `steps` velocity-Verlet steps of the fast level, block by block in parallel: per block,
/// [`Impulse::innermost`]'s operations without a thermostat (kick `dt/2`, drift `dt`, the
/// block's fast gradient, kick `dt/2`) on its particles alone, which no fast interaction
/// couples to another block's. The same operations per coordinate in the same order as
/// `steps` calls of `innermost`, so the same bits; one parallel region per outer step
/// instead of several per inner step.
fn inner_blocks(blocks: &Blocks, steps: usize, dt: f64, system: &mut System, gradient: &mut [f64]) {
    let dim = system.dim;
    let state = &mut system.state;
    let part = Part {
        q: &mut state.q,
        p: &mut state.p,
        gradient,
        inverse_mass: &system.inverse_mass,
    };
    run_blocks(
        &system.forces,
        blocks,
        0..blocks.len(),
        dim,
        part,
        steps,
        dt,
    );
    system.forces.count_block_gradients(blocks, steps as u64);
}

/// The coordinates of a run of consecutive blocks.
struct Part<'a> {
    q: &'a mut [f64],
    p: &'a mut [f64],
    gradient: &'a mut [f64],
    inverse_mass: &'a [f64],
}

impl<'a> Part<'a> {
    fn split_at(self, at: usize) -> (Part<'a>, Part<'a>) {
        let (q0, q1) = self.q.split_at_mut(at);
        let (p0, p1) = self.p.split_at_mut(at);
        let (g0, g1) = self.gradient.split_at_mut(at);
        let (w0, w1) = self.inverse_mass.split_at(at);
        (
            Part {
                q: q0,
                p: p0,
                gradient: g0,
                inverse_mass: w0,
            },
            Part {
                q: q1,
                p: p1,
                gradient: g1,
                inverse_mass: w1,
            },
        )
    }
}

/// The blocks `range` (whose coordinates `part` holds), halved recursively over rayon.
fn run_blocks(
    forces: &ForceSplit,
    blocks: &Blocks,
    range: std::ops::Range<usize>,
    dim: usize,
    part: Part,
    steps: usize,
    dt: f64,
) {
    if range.len() == 1 {
        let b = range.start;
        let half = 0.5 * dt;
        for _ in 0..steps {
            kick(part.p, part.gradient, half);
            drift(part.q, part.p, part.inverse_mass, dt);
            forces.block_gradient(blocks, b, part.q, part.gradient);
            kick(part.p, part.gradient, half);
        }
        return;
    }
    let mid = range.start + range.len() / 2;
    let at = (blocks.particles[mid].start - blocks.particles[range.start].start) * dim;
    let (left, right) = part.split_at(at);
    rayon::join(
        || run_blocks(forces, blocks, range.start..mid, dim, left, steps, dt),
        || run_blocks(forces, blocks, mid..range.end, dim, right, steps, dt),
    );
}
