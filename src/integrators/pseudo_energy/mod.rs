//! The explicit pseudo-energy conserving scheme of MEMM18 section 2 (synchronous).
//!
//! Knowing `p^{n−1/2}`, `q^n` and `p^{n+1/2}` (the two-step form (6), equivalent to the
//! jump form (3a)–(3c)):
//!
//! * free flight (4): `q̂(t) = q^n + (t − t^n) M⁻¹ p^{n+1/2}`, so `q^{n+1} = q̂(t^{n+1})` (3b);
//! * forces integrated along it by a symmetric quadrature (9):
//!   `Q_n = h_n Σ w_i ∇V(q^n + τ_i h_n M⁻¹ p^{n+1/2})`;
//! * momentum (6b)/(10): `p^{n+3/2} = p^{n−1/2} − 2 Q_n`, i.e. the jump
//!   `[p]^{n+1} = p^{n+3/2} − p^{n+1/2}` satisfies `([p]^{n+1} + [p]^n)/2 = −Q_n`.
//!
//! Initialisation (5)/(7): `p^{−1/2} = p^{1/2} = p(t⁰)`, i.e. `[p]^0 = 0`.
//!
//! With exact force integration the pseudo-energy (13)
//! `H̃^n = V(q^n) + ½ (p^{n−1/2})ᵀ M⁻¹ p^{n+1/2}` is conserved for any step sequence
//! (Theorem 1), and equals `H(q⁰, p⁰)`. The discrete energy of Remark 8,
//! `H^n = V(q^n) + ⅛ |M^{−1/2}(p^{n−1/2} + p^{n+1/2})|²`, satisfies (17)
//! `H^n = H̃^n + ⅛ |M^{−1/2}[p]^n|² ≥ H̃^n`. The state's momentum is the average
//! `(p^{n−1/2} + p^{n+1/2})/2`, so the run's "total" energy is exactly `H^n`.
//!
//! Second order (Theorem 5), time-reversible for a symmetric rule (Prop. 4), conserves
//! linear momentum of an isolated system (Remark 3), linearly stable for
//! `h ≤ 2 √(μ/λ)` (Prop. 6). A non-diagonal mass matrix is used as is (one banded solve
//! per step for `M⁻¹ p`).
//!
//! Adaptive halving (Remark 8, `--adaptive ε`): a step whose new jump has
//! `⅛ |M^{−1/2}[p]^{n+1}|² > ε |H̃^n|` is rejected and retried with half the step, down
//! to the floor `h_min` (default `h/1024`); every step starts from the nominal `h`.
//! Reaching the floor with the bound still violated stops the run with a message.
//!
//! Cost per step: `n` gradient evaluations of every level for an `n`-node rule, `n − 1`
//! for a Gauss–Lobatto rule (its last node is the next step's first), plus one
//! (uncounted) energy evaluation for the pseudo-energy monitor; rejected attempts cost
//! the same again.

pub mod staggered;

use super::integrator::{Integrator, StepFailure, state_from_json, state_to_json};
use super::quadrature::Quadrature;
use crate::error::{Error, Result};
use crate::settings::MethodSettings;
use crate::system::System;
pub use staggered::StaggeredMomenta;

/// Running statistics of the pseudo-energy at the nodes where it is conserved.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct PseudoEnergyMonitor {
    pub initial: f64,
    pub last: f64,
    pub last_discrete: f64,
    pub max_abs_error: f64,
    /// `|H̃⁰|`, or the energy scale `K₀ + |V₀|` when `H̃⁰` is (nearly) zero.
    pub reference: f64,
    /// Largest `H^n − H̃^n = ⅛|M^{−1/2}[p]^n|²` seen.
    pub max_discrete_gap: f64,
}

impl PseudoEnergyMonitor {
    pub fn new(pseudo: f64, scale: f64) -> Self {
        let reference = if pseudo.abs() > 1e-12 * scale {
            pseudo.abs()
        } else if scale > 0.0 {
            scale
        } else {
            1.0
        };
        PseudoEnergyMonitor {
            initial: pseudo,
            last: pseudo,
            last_discrete: pseudo,
            max_abs_error: 0.0,
            reference,
            max_discrete_gap: 0.0,
        }
    }

    pub fn record(&mut self, pseudo: f64, discrete: f64) {
        self.last = pseudo;
        self.last_discrete = discrete;
        self.max_abs_error = self.max_abs_error.max((pseudo - self.initial).abs());
        self.max_discrete_gap = self.max_discrete_gap.max(discrete - pseudo);
    }

    pub fn max_relative_error(&self) -> f64 {
        self.max_abs_error / self.reference
    }

    pub fn to_json(&self) -> serde_json::Map<String, serde_json::Value> {
        let mut map = serde_json::Map::new();
        map.insert("initial".into(), self.initial.into());
        map.insert("final".into(), self.last.into());
        map.insert("max_abs_error".into(), self.max_abs_error.into());
        map.insert(
            "max_relative_error".into(),
            self.max_relative_error().into(),
        );
        map.insert("max_discrete_gap".into(), self.max_discrete_gap.into());
        map
    }
}

/// `V(q) + ½ p_minus · v_plus` and `V(q) + ⅛ (p_minus + p_plus)·(v_minus + v_plus)`:
/// MEMM18 (13) and Remark 8, with `v = M⁻¹ p` already computed.
pub fn pseudo_and_discrete_energy(
    potential: f64,
    p_minus: &[f64],
    p_plus: &[f64],
    v_minus: &[f64],
    v_plus: &[f64],
) -> (f64, f64) {
    let mut cross = 0.0;
    let mut mean = 0.0;
    for i in 0..p_minus.len() {
        cross += p_minus[i] * v_plus[i];
        mean += (p_minus[i] + p_plus[i]) * (v_minus[i] + v_plus[i]);
    }
    (potential + 0.5 * cross, potential + 0.125 * mean)
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Adaptive {
    pub epsilon: f64,
    pub h_min: f64,
}

pub struct PseudoEnergy {
    /// Nominal step; every step starts from it (adaptive halving may shorten one).
    h: f64,
    quadrature: Quadrature,
    adaptive: Option<Adaptive>,
    /// Whether [`PseudoEnergy::set_step`] changed the step: then `t` accumulates.
    variable: bool,
    /// Compute `H̃` at every node (one energy evaluation per step).
    track: bool,
    /// `p^{n∓1/2}`, their velocities and the pseudo-energy monitor.
    staggered: StaggeredMomenta,
    p_next: Vec<f64>,
    v_next: Vec<f64>,
    integral: Vec<f64>,
    gradient: Vec<f64>,
    scratch: Vec<f64>,
    /// `∇V(q^n)` when the rule has end nodes and it is known.
    start_gradient: Vec<f64>,
    end_gradient: Vec<f64>,
    start_valid: bool,
    last_h: f64,
    smallest_h: f64,
    largest_h: f64,
    rejected: u64,
}

impl PseudoEnergy {
    pub fn new(h: f64, quadrature: Quadrature) -> Result<Self> {
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::setting("h", "step h must be positive and finite")
                .expected("a positive finite step")
                .got(h.to_string()));
        }
        Ok(PseudoEnergy {
            h,
            quadrature,
            adaptive: None,
            variable: false,
            track: true,
            staggered: StaggeredMomenta::default(),
            p_next: Vec::new(),
            v_next: Vec::new(),
            integral: Vec::new(),
            gradient: Vec::new(),
            scratch: Vec::new(),
            start_gradient: Vec::new(),
            end_gradient: Vec::new(),
            start_valid: false,
            last_h: h,
            smallest_h: f64::INFINITY,
            largest_h: 0.0,
            rejected: 0,
        })
    }

    /// From `--h`, `--quadrature` (default midpoint), `--adaptive`, `--h-min`.
    pub fn from_settings(settings: &MethodSettings) -> Result<Self> {
        let quadrature = Quadrature::by_name(settings.quadrature.as_deref().unwrap_or("midpoint"))?;
        let mut method = Self::new(settings.h, quadrature)?;
        if let Some(epsilon) = settings.adaptive {
            let h_min = settings.h_min.unwrap_or(settings.h / 1024.0);
            method = method.with_adaptive(epsilon, h_min)?;
        } else if settings.h_min.is_some() {
            return Err(Error::setting(
                "h_min",
                "h_min is the floor of adaptive halving: give --adaptive EPS with it",
            )
            .expected("--adaptive EPS with it"));
        }
        Ok(method)
    }

    /// Halve a step whose jump has `⅛|M^{−1/2}[p]|² > ε |H̃|` (Remark 8), not below `h_min`.
    pub fn with_adaptive(mut self, epsilon: f64, h_min: f64) -> Result<Self> {
        if !(epsilon.is_finite() && epsilon > 0.0) {
            return Err(
                Error::setting("adaptive", "adaptive tolerance must be positive")
                    .expected("a positive number")
                    .got(epsilon.to_string()),
            );
        }
        if !(h_min.is_finite() && h_min > 0.0 && h_min <= self.h) {
            return Err(Error::setting(
                "h_min",
                format!("h_min must be positive and at most h = {}", self.h),
            )
            .expected(format!("a positive step of at most h = {}", self.h))
            .got(h_min.to_string()));
        }
        self.adaptive = Some(Adaptive { epsilon, h_min });
        Ok(self)
    }

    /// Whether to compute the pseudo-energy at every node (default on; adaptive halving
    /// needs it). Off saves one energy evaluation per step, for timing.
    pub fn with_monitor(mut self, track: bool) -> Self {
        self.track = track;
        self
    }

    /// The step of the following steps (variable step sequences).
    pub fn set_step(&mut self, h: f64) {
        debug_assert!(h.is_finite() && h > 0.0);
        self.h = h;
        self.variable = true;
    }

    pub fn quadrature(&self) -> &Quadrature {
        &self.quadrature
    }

    pub fn monitor(&self) -> &PseudoEnergyMonitor {
        &self.staggered.monitor
    }

    /// The step last taken (after any halving).
    pub fn last_step(&self) -> f64 {
        self.last_h
    }

    /// `p^{n−1/2}` and `p^{n+1/2}`.
    pub fn half_step_momenta(&self) -> (&[f64], &[f64]) {
        (&self.staggered.p_minus, &self.staggered.p_plus)
    }

    /// Reverse time (MEMM18 Prop. 4, [`StaggeredMomenta::reverse`]). Stepping on then
    /// retraces the trajectory backwards.
    pub fn reverse(&mut self, system: &mut System) {
        self.staggered.reverse(system);
    }

    /// The scheme's state `Z = (q, p^{n−1/2}, p^{n+1/2})` (length `3 n_dofs`), as in the
    /// proof of MEMM18 Prop. 6.
    pub fn state_vector(&self, system: &System, z: &mut [f64]) {
        self.staggered.state_vector(system, z);
    }

    /// Replace the scheme's state by `Z` (see [`PseudoEnergy::state_vector`]).
    pub fn set_state_vector(&mut self, system: &mut System, z: &[f64]) {
        self.staggered.set_state_vector(system, z);
        self.start_valid = false;
    }

    /// `integral = Q_n / h = Σ w_i ∇V(q^n + τ_i h v^{n+1/2})`, reusing `∇V(q^n)` for a
    /// rule with end nodes and keeping `∇V(q^{n+1})` for the next step.
    fn integrate_forces(&mut self, system: &mut System, h: f64) {
        let ends = self.quadrature.has_end_nodes();
        self.integral.fill(0.0);
        let q = &system.state.q;
        for (&tau, &w) in self
            .quadrature
            .nodes()
            .iter()
            .zip(self.quadrature.weights())
        {
            let gradient = if tau == 0.0 && ends && self.start_valid {
                &self.start_gradient
            } else {
                let s = tau * h;
                let v_plus = &self.staggered.v_plus;
                for ((x, qi), vi) in self.scratch.iter_mut().zip(q).zip(v_plus) {
                    *x = qi + s * vi;
                }
                system
                    .forces
                    .total_gradient(&self.scratch, &mut self.gradient);
                &self.gradient
            };
            for (acc, g) in self.integral.iter_mut().zip(gradient) {
                *acc += w * g;
            }
            if tau == 1.0 && ends {
                std::mem::swap(&mut self.end_gradient, &mut self.gradient);
            }
        }
    }
}

impl Integrator for PseudoEnergy {
    fn name(&self) -> &'static str {
        "pseudo-energy"
    }

    fn describe(&self) -> String {
        let mut text = format!("h = {}, quadrature {}", self.h, self.quadrature.name());
        if let Some(a) = self.adaptive {
            text.push_str(&format!(
                ", adaptive ε = {}, h_min = {}",
                a.epsilon, a.h_min
            ));
        }
        text
    }

    fn outer_step(&self) -> f64 {
        self.h
    }

    /// The staggered momenta `p^{n∓½}` of (6) and their velocities, the pseudo-energy
    /// statistics and the step-size history; `∇V(qⁿ)` is recomputed by `setup`.
    fn save_state(&self) -> Result<serde_json::Value> {
        let state = PseudoEnergyState {
            staggered: self.staggered.clone(),
            last_h: self.last_h,
            smallest_h: self.smallest_h.is_finite().then_some(self.smallest_h),
            largest_h: self.largest_h,
            rejected: self.rejected,
        };
        state_to_json(self.name(), &state)
    }

    fn restore_state(&mut self, state: &serde_json::Value) -> Result<()> {
        let name = self.name();
        let saved: PseudoEnergyState = state_from_json(name, state)?;
        self.staggered.restore(name, saved.staggered)?;
        self.last_h = saved.last_h;
        self.smallest_h = saved.smallest_h.unwrap_or(f64::INFINITY);
        self.largest_h = saved.largest_h;
        self.rejected = saved.rejected;
        Ok(())
    }

    fn setup(&mut self, system: &mut System) -> Result<()> {
        let n = system.n_dofs();
        self.staggered.start(system);
        self.p_next = vec![0.0; n];
        self.v_next = vec![0.0; n];
        self.integral = vec![0.0; n];
        self.gradient = vec![0.0; n];
        self.scratch = vec![0.0; n];
        self.start_gradient = vec![0.0; n];
        self.end_gradient = vec![0.0; n];
        self.start_valid = false;
        if self.quadrature.has_end_nodes() {
            system
                .forces
                .total_gradient(&system.state.q, &mut self.start_gradient);
            self.start_valid = true;
        }
        self.staggered.start_monitor(system);
        self.smallest_h = f64::INFINITY;
        self.largest_h = 0.0;
        self.rejected = 0;
        Ok(())
    }

    fn step(&mut self, system: &mut System) -> Result<(), StepFailure> {
        let mut h = self.h;
        loop {
            self.integrate_forces(system, h);
            let staggered = &self.staggered;
            // (6b): p^{n+3/2} = p^{n−1/2} − 2 Q_n.
            for ((next, minus), integral) in self
                .p_next
                .iter_mut()
                .zip(&staggered.p_minus)
                .zip(&self.integral)
            {
                *next = minus - 2.0 * h * integral;
            }
            system.velocity(&self.p_next, &mut self.v_next);
            let Some(adaptive) = self.adaptive else {
                break;
            };
            // ⅛|M^{−1/2}[p]^{n+1}|² = ⅛ [p]·M⁻¹[p], with M⁻¹[p] = v_next − v_plus.
            let (p_plus, v_plus) = (&staggered.p_plus, &staggered.v_plus);
            let gap: f64 = 0.125
                * (0..self.p_next.len())
                    .map(|i| (self.p_next[i] - p_plus[i]) * (self.v_next[i] - v_plus[i]))
                    .sum::<f64>();
            let bound = adaptive.epsilon * staggered.monitor.last.abs();
            if gap <= bound {
                break;
            }
            if h <= adaptive.h_min {
                return Err(StepFailure(format!(
                    "adaptive halving reached the floor h_min = {} with the jump bound still \
                     violated: |M^-1/2 [p]|^2/8 = {gap:.3e} > eps |H~| = {bound:.3e}; lower \
                     --h-min or raise --adaptive",
                    adaptive.h_min
                )));
            }
            h = (0.5 * h).max(adaptive.h_min);
            self.rejected += 1;
        }
        // (3b): q^{n+1} = q^n + h M⁻¹ p^{n+1/2}.
        let staggered = &mut self.staggered;
        for (qi, vi) in system.state.q.iter_mut().zip(&staggered.v_plus) {
            *qi += h * vi;
        }
        std::mem::swap(&mut staggered.p_minus, &mut staggered.p_plus);
        std::mem::swap(&mut staggered.p_plus, &mut self.p_next);
        std::mem::swap(&mut staggered.v_minus, &mut staggered.v_plus);
        std::mem::swap(&mut staggered.v_plus, &mut self.v_next);
        if self.quadrature.has_end_nodes() {
            std::mem::swap(&mut self.start_gradient, &mut self.end_gradient);
            self.start_valid = true;
        }
        self.staggered.sync_state(system);
        system.state.t += h;
        self.last_h = h;
        self.smallest_h = self.smallest_h.min(h);
        self.largest_h = self.largest_h.max(h);
        if self.track || self.adaptive.is_some() {
            self.staggered.record(system);
        }
        Ok(())
    }

    fn fixed_step(&self) -> bool {
        self.adaptive.is_none() && !self.variable
    }

    fn extra_columns(&self) -> Vec<&'static str> {
        let mut columns = vec!["pseudo_energy", "discrete_energy"];
        if self.adaptive.is_some() {
            columns.push("h");
        }
        columns
    }

    fn extra_values(&self, system: &System, out: &mut Vec<f64>) {
        let (pseudo, discrete) = self.staggered.energies(system);
        out.extend([pseudo, discrete]);
        if self.adaptive.is_some() {
            out.push(self.last_h);
        }
    }

    fn supports_mass_matrix(&self) -> bool {
        true
    }

    fn report(&self) -> Option<(&'static str, serde_json::Value)> {
        let mut map = self.staggered.monitor.to_json();
        map.insert("quadrature".into(), self.quadrature.name().into());
        map.insert(
            "evaluations_per_step".into(),
            self.quadrature.evaluations_per_step().into(),
        );
        if self.adaptive.is_some() {
            map.insert("h_smallest".into(), self.smallest_h.into());
            map.insert("h_largest".into(), self.largest_h.into());
            map.insert("rejected_steps".into(), self.rejected.into());
        }
        Some(("pseudo_energy", serde_json::Value::Object(map)))
    }
}

/// What a checkpoint holds of the MEMM18 (6) scheme.
#[derive(serde::Serialize, serde::Deserialize)]
struct PseudoEnergyState {
    /// Its keys stand beside the others, as before the shared type.
    #[serde(flatten)]
    staggered: StaggeredMomenta,
    last_h: f64,
    /// `None` before the first step.
    smallest_h: Option<f64>,
    largest_h: f64,
    rejected: u64,
}
