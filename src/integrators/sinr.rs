//! SIN(R): the stochastic isokinetic Nosé–Hoover RESPA method (LMT13: Leimkuhler, Margul
//! & Tuckerman, Mol. Phys. 111:3579, 2013), run by the r-RESPA recursion of
//! [`super::impulse`] with [`Sinr`] as its [`InnermostStep`].
//!
//! **Equations of motion** (LMT13; per Cartesian degree of freedom with position x,
//! momentum p = m v, and L thermostat pairs `(v1_k, v2_k)`, `Q1 = Q2 = kT τ²`):
//! `ẋ = v`, `v̇ = F/m − λ v`, `v̇1_k = −λ v1_k − v2_k v1_k`,
//! `dv2_k = [(Q1 v1_k² − kT)/Q2 − γ v2_k] dt + √(2γ kT/Q2) dW`,
//! `λ = (F v − L/(L+1) Σ_k Q1 v2_k v1_k²)/(L kT)`. They keep the isokinetic constraint
//! `m v² + L/(L+1) Σ_k Q1 v1_k² = L kT` on every degree of freedom, so no kinetic energy can
//! pile up in one mode (the resonance of impulse needs exactly that), and the positions are
//! canonical at T. The kinetic temperature is `L/(L+1)·T`, not T.
//!
//! **Splitting** (LMT13's XI-RESPA form, as Tinker's `stochisok.f`): the recursion of
//! impulse with every kick replaced by the isokinetic force operator `V_ℓ(h_ℓ/2)`, and the
//! innermost step (`dt`) `N(dt/2) V_0(dt/2) X(dt) OU(dt) V_0(dt/2) N(dt/2)`:
//! - `V(t)`, force part solved exactly ([`Sinr::isokinetic_kick`]): with `κ = √(L kT m)`
//!   (the bound of |p|), `â = sgn(F) p/κ`, `x = |F| t/κ`:
//!   `p ← sgn(F) κ (tanh x + â)/(1 + â tanh x)`, `v1_k ← v1_k sech x/(1 + â tanh x)`.
//!   This is the textbook `v ← (v + (F/m) s)/ṡ`, `v1_k ← v1_k/ṡ` with
//!   `s = sinh(√b t)/√b + (a/b)(cosh(√b t) − 1)`, `ṡ = cosh(√b t) + (a/√b) sinh(√b t)`,
//!   `a = F v/(L kT)`, `b = F²/(m L kT)` (so `√b t = x`, `a/√b = â`), divided through by
//!   cosh: bounded, no overflow, and for `â < 0` the differences `1 − |â|` (from the
//!   thermostat share, below) and `1 − tanh x = 2/(e^{2x} + 1)` are computed without
//!   cancellation. The textbook form divides by an `ṡ` that cancels to 0 when `F·v < 0`
//!   near the bound and overflows for `x > 710`.
//! - `N(δ)`, the thermostat flow ([`Sinr::thermostat_flow`]) in Suzuki–Yoshida sub-steps
//!   (fourth order, weights `w1 = w3 = 1/(2 − 2^{1/3})`, `w2 = 1 − 2 w1`; sub-step `t = w_j δ`):
//!   `v2_k += (t/2)(Q1 v1_k² − kT)/Q2`; per degree of freedom
//!   `H = √(L kT/(m v² + L/(L+1) Σ_k Q1 v1_k² e^{−2 t v2_k}))`, `v ← H v`,
//!   `v1_k ← H e^{−t v2_k} v1_k`; the same half-kick of `v2_k` again. The rescale is per
//!   degree of freedom (a global H, as in ParmEd's `SINRMTSIntegrator`, breaks the
//!   constraint).
//! - `X(dt)`: `x += dt v`. `OU(dt)`: `v2_k ← v2_k e^{−γ dt} + √(kT (1 − e^{−2γ dt})/Q2) ξ`.
//!
//! **Cost** per outer step: the force evaluations of impulse (one gradient of each level
//! per step of that level). Per innermost step, besides the fast gradient: two thermostat
//! flows of 3 sub-steps, each one `exp` per thermostat variable and one `sqrt` per degree
//! of freedom (`6 L n` exps), `2 n` isokinetic updates (one `expm1` each), `n L` normal
//! numbers; the outer levels' kicks add `n` `expm1` each. All O(n L). With L = 1 the kick
//! and the flow are branch-free loops over the coordinates with `exp`/`expm1` of
//! [`super::lane_exp`], so they run in SIMD lanes (AVX-512, AVX2 or portable, the same bits;
//! on the 1728-water box this cut their share of a 50 fs SIN(R) step from a third to a
//! tenth).
//!
//! **Start.** The given momenta keep their direction: each degree of freedom draws
//! `v1_k ~ N(0, kT/Q1)` and `v2_k ~ N(0, kT/Q2)` (the stationary law of the OU part) from
//! the seed, then `(p, v1)` is rescaled by one factor `H` onto the constraint.
//!
//! **Watches.** After every outer step the largest relative violation of the constraint,
//! `|m v² + L/(L+1) Σ Q1 v1² − L kT|/(L kT)`, and the smallest thermostat share
//! `L/(L+1) Σ Q1 v1²/(L kT) = 1 − m v²/(L kT)` are recorded for the summary. A share below
//! [`COLLAPSE_SHARE`] is a collapsed thermostat: a slow kick of many thermal momenta pinned
//! v at its bound and drove v1 to zero, after which the update is 0/0. The operators leave
//! such a degree of freedom untouched and the step fails with the time and the coordinate,
//! before anything turns into NaN.

use super::innermost::InnermostStep;
use super::integrator::{StepFailure, drift};
use super::lane_exp;
use super::langevin::{Gaussian, required_kt};
use crate::error::{Error, Result};
use crate::forces::simd::Isa;
use crate::settings::MethodSettings;
use crate::system::System;
use crate::units::Units;

/// L when `--thermostats` is not given: 1, with [`DEFAULT_TAU_FS`] the configuration
/// docs/thermostats.md shows sampling the 15 Å water box correctly at 48 and 96 fs (PE and
/// O–O peak pass, mean of three seeds ± 2σ), and the one the production study runs.
/// Tinker's default L = 4 with τ = 5 fs is undecided on the 9 Å box and fails the peak
/// with PME.
pub const DEFAULT_THERMOSTATS: usize = 1;
/// The most thermostat pairs per degree of freedom (memory is `2 L n` numbers).
pub const MAX_THERMOSTATS: usize = 16;
/// τ in a real scene when `--tau` is not given: 3 fs (see [`DEFAULT_THERMOSTATS`]).
/// Tinker's `TAU-TEMPERATURE 0.01 ps` (10 fs) samples the 9 Å box 0.33 kcal/mol/molecule
/// high at 50 fs; a 3 fs middle step needs τ = 3 fs.
pub const DEFAULT_TAU_FS: f64 = 3.0;
/// A thermostat share `1 − m v²/(L kT)` below this is a collapse. With L = 1 the share
/// is near 0 with probability ~√share at equilibrium, so 1e-100 (probability ~1e-50 per
/// sample) is reached only by a kick that pins the velocity, never by fluctuation.
pub const COLLAPSE_SHARE: f64 = 1e-100;

/// Whether a thermostat share means a collapse (NaN counts).
#[inline]
fn collapsed(share: f64) -> bool {
    share.is_nan() || share < COLLAPSE_SHARE
}

/// "SINRSINR" in ASCII: the salt of SIN(R)'s stream.
const SALT: u64 = 0x5349_4e52_5349_4e52;

/// Fourth-order Suzuki–Yoshida weights.
fn suzuki_yoshida() -> [f64; 3] {
    let w1 = 1.0 / (2.0 - 2f64.powf(1.0 / 3.0));
    [w1, 1.0 - 2.0 * w1, w1]
}

#[derive(Clone)]
pub struct Sinr {
    thermostats: usize,
    tau: f64,
    friction: f64,
    seed: u64,
    /// `Q2` (equal to `Q1`; kept for the start and the OU step, which divide by it).
    q2: f64,
    /// kT, `Q1`, `L kT`, `L/(L+1)`, `1/Q2`: what the kick and the flow read.
    c: Constants,
    weights: [f64; 3],
    /// The instruction set the kick and the flow are compiled for (the widest there is).
    isa: Isa,
    gaussian: Gaussian,
    /// `v1[i L + k]`, `v2[i L + k]`: thermostat pair k of coordinate i.
    v1: Vec<f64>,
    v2: Vec<f64>,
    inverse_mass: Vec<f64>,
    /// `κ = √(L kT m)`, the largest |p| the constraint allows.
    kappa: Vec<f64>,
    ou_decay: f64,
    ou_noise: f64,
    max_violation: f64,
    min_share: f64,
    collapsed: Option<usize>,
}

impl Sinr {
    /// SIN(R) with L pairs, time scale τ and thermostat friction γ at `kt`.
    pub fn new(kt: f64, thermostats: usize, tau: f64, friction: f64, seed: u64) -> Result<Self> {
        if !(1..=MAX_THERMOSTATS).contains(&thermostats) {
            return Err(Error::setting(
                "thermostats",
                format!("sinr: thermostats (L) must be between 1 and {MAX_THERMOSTATS}"),
            )
            .expected(format!("1 to {MAX_THERMOSTATS}"))
            .got(thermostats.to_string()));
        }
        let q = kt * tau * tau;
        Ok(Sinr {
            thermostats,
            tau,
            friction,
            seed,
            q2: q,
            c: Constants {
                q1: q,
                kt,
                ratio: thermostats as f64 / (thermostats + 1) as f64,
                lkt: thermostats as f64 * kt,
                over_q2: 1.0 / q,
            },
            weights: suzuki_yoshida(),
            isa: Isa::best(),
            gaussian: Gaussian::new(seed, SALT),
            v1: Vec::new(),
            v2: Vec::new(),
            inverse_mass: Vec::new(),
            kappa: Vec::new(),
            ou_decay: 1.0,
            ou_noise: 0.0,
            max_violation: 0.0,
            min_share: f64::INFINITY,
            collapsed: None,
        })
    }

    /// SIN(R) from a method's settings: `--temperature` (required), `--thermostats`
    /// (default 1), `--tau` (default 3 fs in a real scene, required in a dimensionless
    /// one), `--friction` on the thermostat variables (default 1/τ), `--seed`.
    pub fn from_settings(settings: &MethodSettings) -> Result<Self> {
        let kt = required_kt(settings)?;
        let tau = match (settings.tau, settings.units) {
            (Some(tau), _) => tau,
            (None, Units::Real) => DEFAULT_TAU_FS,
            (None, Units::None) => {
                return Err(Error::setting(
                    "tau",
                    "sinr needs the thermostat time scale in a dimensionless scene: give --tau \
                     (thermostat masses Q = kT τ²)",
                )
                .expected("a time scale τ"));
            }
        };
        Sinr::new(
            kt,
            settings.thermostats.unwrap_or(DEFAULT_THERMOSTATS),
            tau,
            settings.friction.unwrap_or(1.0 / tau),
            settings.seed.unwrap_or(super::langevin::DEFAULT_SEED),
        )
    }

    pub fn thermostats(&self) -> usize {
        self.thermostats
    }

    /// The thermostat velocities v1 (`[i L + k]`).
    pub fn v1(&self) -> &[f64] {
        &self.v1
    }

    /// The thermostat velocities v2 (`[i L + k]`).
    pub fn v2(&self) -> &[f64] {
        &self.v2
    }

    /// The largest relative constraint violation seen after any outer step.
    pub fn max_violation(&self) -> f64 {
        self.max_violation
    }

    /// The smallest thermostat share seen after any outer step.
    pub fn min_share(&self) -> f64 {
        self.min_share
    }

    /// Draw the thermostat variables, put `(p, v1)` on the constraint, and size the OU step
    /// for the innermost step `dt`.
    fn start(&mut self, dt: f64, system: &mut System) -> Result<()> {
        if system.mass_matrix.is_some() {
            return Err(Error::input(
                "sinr needs a diagonal mass matrix (its constraint is per coordinate)",
            ));
        }
        let n = system.n_dofs();
        let l = self.thermostats;
        self.gaussian = Gaussian::new(self.seed, SALT);
        self.inverse_mass = system.inverse_mass.clone();
        self.kappa = self
            .inverse_mass
            .iter()
            .map(|w| (self.c.lkt / w).sqrt())
            .collect();
        let v1_scale = (self.c.kt / self.c.q1).sqrt();
        let v2_scale = (self.c.kt / self.q2).sqrt();
        self.v1 = (0..n * l)
            .map(|_| v1_scale * self.gaussian.normal())
            .collect();
        self.v2 = (0..n * l)
            .map(|_| v2_scale * self.gaussian.normal())
            .collect();
        let p = &mut system.state.p;
        for (i, pi) in p.iter_mut().enumerate() {
            let thermo = &mut self.v1[i * l..(i + 1) * l];
            let bath: f64 = self.c.ratio * self.c.q1 * thermo.iter().map(|v| v * v).sum::<f64>();
            let scale = (self.c.lkt / (*pi * *pi * self.inverse_mass[i] + bath)).sqrt();
            *pi *= scale;
            thermo.iter_mut().for_each(|v| *v *= scale);
        }
        self.ou_decay = (-self.friction * dt).exp();
        self.ou_noise = (-self.c.kt * (-2.0 * self.friction * dt).exp_m1() / self.q2).sqrt();
        self.max_violation = 0.0;
        self.min_share = f64::INFINITY;
        self.collapsed = None;
        self.watch(p);
        Ok(())
    }

    /// `L/(L+1) Σ_k Q1 v1_k² / (L kT)` of coordinate i: its thermostat's share of `L kT`.
    #[inline]
    fn share(&self, i: usize) -> f64 {
        let l = self.thermostats;
        self.c.share(&self.v1[i * l..(i + 1) * l])
    }

    /// The isokinetic force operator `V(t)` with the force `−gradient` (bounded form, see
    /// the module doc). Coordinates with a collapsed thermostat are left as they are.
    pub fn isokinetic_kick(&mut self, p: &mut [f64], gradient: &[f64], t: f64) {
        let c = self.c;
        let (v1, kappa) = (&mut self.v1, &self.kappa);
        let any_collapsed = match self.thermostats {
            1 => self.isa.run(
                #[inline(always)]
                || lanes::kick::<1>(c, t, p, gradient, v1, kappa),
            ),
            4 => self.isa.run(
                #[inline(always)]
                || lanes::kick::<4>(c, t, p, gradient, v1, kappa),
            ),
            l => kick_general(c, t, l, p, gradient, v1, kappa),
        };
        if any_collapsed && self.collapsed.is_none() {
            // Rare: find the first one (its v1 was left as it was, so its share still shows).
            self.collapsed = (0..p.len()).find(|&i| gradient[i] != 0.0 && collapsed(self.share(i)));
        }
    }

    /// The thermostat flow `N(δ)`: three Suzuki–Yoshida sub-steps per coordinate (the
    /// coordinates' thermostats are independent, so each runs its sub-steps in turn).
    pub fn thermostat_flow(&mut self, p: &mut [f64], delta: f64) {
        let c = self.c;
        let steps = self.weights.map(|w| w * delta);
        let (v1, v2, w) = (&mut self.v1, &mut self.v2, &self.inverse_mass);
        match self.thermostats {
            1 => self.isa.run(
                #[inline(always)]
                || lanes::flow::<1>(c, steps, p, w, v1, v2),
            ),
            4 => self.isa.run(
                #[inline(always)]
                || lanes::flow::<4>(c, steps, p, w, v1, v2),
            ),
            l => flow_general(c, steps, l, p, w, v1, v2),
        }
    }

    /// The Ornstein–Uhlenbeck step on every v2 over the innermost step.
    pub fn ornstein_uhlenbeck(&mut self) {
        for v in self.v2.iter_mut() {
            *v = self.ou_decay * *v + self.ou_noise * self.gaussian.normal();
        }
    }

    /// Record the constraint violation and the smallest share; note a collapse.
    fn watch(&mut self, p: &[f64]) {
        for (i, pi) in p.iter().enumerate() {
            let share = self.share(i);
            let kinetic = pi * pi * self.inverse_mass[i] / self.c.lkt;
            let violation = (kinetic + share - 1.0).abs();
            self.max_violation = self.max_violation.max(violation);
            self.min_share = self.min_share.min(share);
            if collapsed(share) {
                self.collapsed.get_or_insert(i);
            }
        }
    }

    /// After an outer step: watch the constraint and the thermostats; a collapse (or a
    /// thermostat that is no longer finite) fails the step.
    pub fn check(&mut self, p: &[f64], t: f64) -> Result<(), StepFailure> {
        self.watch(p);
        if let Some(i) = self.collapsed {
            return Err(StepFailure(format!(
                "the SIN(R) thermostat of coordinate {i} collapsed by t = {t}: its share of \
                 L kT fell below {COLLAPSE_SHARE:e} (a kick pinned the velocity at its bound \
                 and drove v1 to zero); take a smaller outer step or move force to a faster \
                 level (a distance split)"
            )));
        }
        if let Some(k) = self.v2.iter().position(|v| !v.is_finite()) {
            return Err(StepFailure(format!(
                "the SIN(R) thermostat variable v2 of coordinate {} is not finite at t = {t}",
                k / self.thermostats
            )));
        }
        Ok(())
    }

    /// What the user should know before the run: the kinetic temperature is not T.
    pub fn notice(&self) -> String {
        format!(
            "sinr bounds each degree of freedom's kinetic energy by L kT: its kinetic \
             temperature is L/(L+1) = {:.4} of the target (L = {}); its positions sample the \
             target temperature, so judge it by configurational quantities (longstep analyze)",
            self.c.ratio, self.thermostats
        )
    }

    /// The run header's part.
    fn header(&self) -> String {
        format!(
            ", kT = {}, L = {}, tau = {}, friction = {} (on v2), seed = {}",
            self.c.kt, self.thermostats, self.tau, self.friction, self.seed
        )
    }

    /// The summary's `sinr` object.
    fn summary(&self) -> serde_json::Value {
        serde_json::json!({
            "kT": self.c.kt,
            "thermostats": self.thermostats,
            "tau": self.tau,
            "friction": self.friction,
            "seed": self.seed,
            "kinetic_temperature_factor": self.c.ratio,
            "kinetic_temperature_note": "SIN(R)'s kinetic temperature is L/(L+1) T by construction; judge it by configurational quantities",
            "constraint_max_violation": self.max_violation,
            "smallest_thermostat_share": self.min_share,
        })
    }
}

/// SIN(R) as the innermost step: isokinetic kicks at every level, the thermostat flow
/// `N(dt/2)` around the step, `X(dt) OU(dt)` between the kicks.
impl InnermostStep for Sinr {
    fn method_name(&self) -> Option<&'static str> {
        Some("sinr")
    }

    fn describe(&self) -> String {
        self.header()
    }

    fn setup(&mut self, dt: f64, system: &mut System) -> Result<()> {
        self.start(dt, system)
    }

    /// The generator, the thermostat variables `v1`, `v2` (LMT13's auxiliary velocities)
    /// and the health statistics the summary reports.
    fn save_state(&self) -> Result<serde_json::Value> {
        let state = SinrState {
            gaussian: self.gaussian.clone(),
            v1: self.v1.clone(),
            v2: self.v2.clone(),
            max_violation: self.max_violation,
            min_share: self.min_share.is_finite().then_some(self.min_share),
            collapsed: self.collapsed,
        };
        super::integrator::state_to_json("sinr", &state)
    }

    fn restore_state(&mut self, state: &serde_json::Value) -> Result<()> {
        use super::integrator::{restore_vector, state_from_json};
        let saved: SinrState = state_from_json("sinr", state)?;
        saved.gaussian.check("sinr")?;
        restore_vector("sinr", "thermostat variables v1", &saved.v1, &mut self.v1)?;
        restore_vector("sinr", "thermostat variables v2", &saved.v2, &mut self.v2)?;
        self.gaussian = saved.gaussian;
        self.max_violation = saved.max_violation;
        self.min_share = saved.min_share.unwrap_or(f64::INFINITY);
        self.collapsed = saved.collapsed;
        Ok(())
    }

    fn kick(&mut self, system: &mut System, gradient: &[f64], scale: f64) {
        self.isokinetic_kick(&mut system.state.p, gradient, scale);
    }

    fn bracket(&mut self, system: &mut System, delta: f64) {
        self.thermostat_flow(&mut system.state.p, delta);
    }

    fn flight(&mut self, system: &mut System, dt: f64) -> Result<(), StepFailure> {
        let state = &mut system.state;
        drift(&mut state.q, &state.p, &system.inverse_mass, dt);
        self.ornstein_uhlenbeck();
        Ok(())
    }

    fn after_outer_step(&mut self, system: &mut System) -> Result<(), StepFailure> {
        self.check(&system.state.p, system.state.t)
    }

    fn notices(&self, _system: &System) -> Vec<String> {
        vec![self.notice()]
    }

    fn report(&self) -> Option<(&'static str, serde_json::Value)> {
        Some(("sinr", self.summary()))
    }
}

/// What the kick and the flow need besides the arrays.
#[derive(Clone, Copy)]
struct Constants {
    /// `Q1 = kT τ²`.
    q1: f64,
    kt: f64,
    /// `L/(L+1)`.
    ratio: f64,
    /// `L kT`.
    lkt: f64,
    /// `1/Q2`.
    over_q2: f64,
}

impl Constants {
    /// `L/(L+1) Σ_k Q1 v1_k² / (L kT)` of one coordinate's thermostats: their share of `L kT`.
    #[inline(always)]
    fn share(&self, thermo: &[f64]) -> f64 {
        let sum: f64 = thermo.iter().map(|v| v * v).sum();
        self.ratio * self.q1 * sum / self.lkt
    }
}

/// One coordinate's isokinetic kick from its force, momentum, bound κ and share; returns
/// the new momentum and the factor for its v1 (the module doc's bounded form; the caller
/// skips coordinates with no force or a collapsed thermostat).
#[inline(always)]
fn kick_one(force: f64, p: f64, kappa: f64, share: f64, t: f64) -> (f64, f64) {
    let sign = force.signum();
    let a = sign * p / kappa;
    let x = force.abs() * t / kappa;
    // e^{−x} − 1 exactly for small x; tanh x = (1 − e^{−2x})/(1 + e^{−2x}).
    let m = lane_exp::exp_m1(-x);
    let e1 = 1.0 + m;
    let e2 = e1 * e1;
    let tanh = -m * (1.0 + e1) / (1.0 + e2);
    let sech = 2.0 * e1 / (1.0 + e2);
    // For â < 0: 1 − |â| = share/(1 + |â|) (the constraint), 1 − tanh x = 2e^{−2x}/(1 + e^{−2x}).
    let gap = share / (1.0 - a);
    let one_minus_tanh = 2.0 * e2 / (1.0 + e2);
    let (numerator, denominator) = if a >= 0.0 {
        (tanh + a, 1.0 + a * tanh)
    } else {
        (gap - one_minus_tanh, gap - a * one_minus_tanh)
    };
    (sign * kappa * numerator / denominator, sech / denominator)
}

/// The kick with L thermostats per coordinate; true if a coordinate with a force has a
/// collapsed thermostat (left untouched).
#[inline(always)]
fn kick_general(
    c: Constants,
    t: f64,
    l: usize,
    p: &mut [f64],
    gradient: &[f64],
    v1: &mut [f64],
    kappa: &[f64],
) -> bool {
    let mut any_collapsed = false;
    let rows = p
        .iter_mut()
        .zip(gradient)
        .zip(v1.chunks_exact_mut(l))
        .zip(kappa);
    for (((pi, gi), thermo), &kappa) in rows {
        let force = -gi;
        let share = c.share(thermo);
        let stuck = collapsed(share);
        any_collapsed |= stuck && force != 0.0;
        if force == 0.0 || stuck {
            continue;
        }
        let (new_p, factor) = kick_one(force, *pi, kappa, share, t);
        *pi = new_p;
        thermo.iter_mut().for_each(|v| *v *= factor);
    }
    any_collapsed
}

/// The flow with L thermostats per coordinate: for each Suzuki–Yoshida sub-step `t`, half
/// a push of every `v2_k`, the rescale, the other half push.
#[inline(always)]
fn flow_general(
    c: Constants,
    steps: [f64; 3],
    l: usize,
    p: &mut [f64],
    inverse_mass: &[f64],
    v1: &mut [f64],
    v2: &mut [f64],
) {
    let mut decay = [0.0; MAX_THERMOSTATS];
    let rows = p.iter_mut().zip(inverse_mass);
    let thermostats = v1.chunks_exact_mut(l).zip(v2.chunks_exact_mut(l));
    for ((pi, &w), (v1, v2)) in rows.zip(thermostats) {
        // A collapsed thermostat (v1 = 0) leaves m v² = L kT, so H = 1: no 0/0 here.
        for t in steps {
            let push = 0.5 * t * c.over_q2;
            for (b, a) in v2.iter_mut().zip(v1.iter()) {
                *b += push * (c.q1 * a * a - c.kt);
            }
            let mut kinetic = *pi * *pi * w;
            for ((d, a), b) in decay.iter_mut().zip(v1.iter()).zip(v2.iter()) {
                *d = lane_exp::exp(-t * b);
                kinetic += c.ratio * c.q1 * a * a * *d * *d;
            }
            let scale = (c.lkt / kinetic).sqrt();
            *pi *= scale;
            for (a, d) in v1.iter_mut().zip(&decay) {
                *a *= scale * d;
            }
            for (b, a) in v2.iter_mut().zip(v1.iter()) {
                *b += push * (c.q1 * a * a - c.kt);
            }
        }
    }
}

/// The kick and the flow for L fixed at compile time, inlined into the copy for the chosen
/// instruction set by [`Isa::run`]. L = 1 (the usual choice) has its own loops: the same
/// arithmetic as [`kick_general`] and [`flow_general`], bit for bit, written without
/// branches so each loop over coordinates runs in SIMD lanes. Other L run the general loops
/// with L a constant, so a coordinate's thermostats are one vector. No fused multiply-add
/// anywhere: every instruction set gives the same bits.
mod lanes {
    use super::{Constants, collapsed, kick_one, lane_exp};

    /// The kick with L thermostats per coordinate; true if a coordinate with a force has a
    /// collapsed thermostat.
    #[inline(always)]
    pub(super) fn kick<const L: usize>(
        c: Constants,
        t: f64,
        p: &mut [f64],
        gradient: &[f64],
        v1: &mut [f64],
        kappa: &[f64],
    ) -> bool {
        if L != 1 {
            return super::kick_general(c, t, L, p, gradient, v1, kappa);
        }
        let mut any_collapsed = false;
        let rows = p.iter_mut().zip(gradient).zip(v1.iter_mut()).zip(kappa);
        for (((pi, gi), a), &kappa) in rows {
            let force = -gi;
            let share = c.ratio * c.q1 * (*a * *a) / c.lkt;
            let stuck = collapsed(share);
            any_collapsed |= stuck & (force != 0.0);
            let (new_p, factor) = kick_one(force, *pi, kappa, share, t);
            let skip = (force == 0.0) | stuck;
            *pi = if skip { *pi } else { new_p };
            *a = if skip { *a } else { *a * factor };
        }
        any_collapsed
    }

    /// The thermostat flow with L thermostats per coordinate.
    #[inline(always)]
    pub(super) fn flow<const L: usize>(
        c: Constants,
        steps: [f64; 3],
        p: &mut [f64],
        inverse_mass: &[f64],
        v1: &mut [f64],
        v2: &mut [f64],
    ) {
        if L != 1 {
            return super::flow_general(c, steps, L, p, inverse_mass, v1, v2);
        }
        let rows = p
            .iter_mut()
            .zip(inverse_mass)
            .zip(v1.iter_mut())
            .zip(v2.iter_mut());
        for (((pi, &w), a), b) in rows {
            let (mut p, mut a_, mut b_) = (*pi, *a, *b);
            for t in steps {
                let push = 0.5 * t * c.over_q2;
                b_ += push * (c.q1 * a_ * a_ - c.kt);
                let d = lane_exp::exp(-t * b_);
                let kinetic = p * p * w + c.ratio * c.q1 * a_ * a_ * d * d;
                let scale = (c.lkt / kinetic).sqrt();
                p *= scale;
                a_ *= scale * d;
                b_ += push * (c.q1 * a_ * a_ - c.kt);
            }
            (*pi, *a, *b) = (p, a_, b_);
        }
    }
}

/// What a checkpoint holds of SIN(R): everything its step reads that positions and momenta
/// do not give.
#[derive(serde::Serialize, serde::Deserialize)]
struct SinrState {
    gaussian: Gaussian,
    v1: Vec<f64>,
    v2: Vec<f64>,
    max_violation: f64,
    /// `None` before the first kick (the share's minimum is then infinite).
    min_share: Option<f64>,
    collapsed: Option<usize>,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A spread of coordinates for L = 1 at kT = 0.6, τ = 5: momenta on and off the bound,
    /// both signs of force, a coordinate without force and one with a collapsed thermostat.
    fn coordinates() -> (Sinr, Vec<f64>, Vec<f64>) {
        let mut sinr = Sinr::new(0.6, 1, 5.0, 0.2, 1).expect("valid settings");
        let n = 203; // not a multiple of any vector width: the loops' remainders run too
        sinr.inverse_mass = (0..n)
            .map(|i| 1.0 / (1.0 + (i % 3) as f64 * 14.0))
            .collect();
        sinr.kappa = sinr
            .inverse_mass
            .iter()
            .map(|w| (sinr.c.lkt / w).sqrt())
            .collect();
        let mut gaussian = Gaussian::new(3, 4);
        let mut p = Vec::with_capacity(n);
        for i in 0..n {
            // (p, v1) on the constraint, the momentum's share between 0 and 1.
            let share = (i as f64 + 0.5) / n as f64;
            let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
            p.push(sign * sinr.kappa[i] * (1.0 - share).sqrt());
            sinr.v1.push(
                gaussian.normal().signum()
                    * (share * sinr.c.lkt / (sinr.c.ratio * sinr.c.q1)).sqrt(),
            );
            sinr.v2.push(0.3 * gaussian.normal());
        }
        sinr.v1[7] = 0.0; // collapsed
        p[7] = sinr.kappa[7];
        let mut gradient: Vec<f64> = (0..n).map(|_| 5.0 * gaussian.normal()).collect();
        gradient[11] = 0.0;
        (sinr, p, gradient)
    }

    fn bits(x: &[f64]) -> Vec<u64> {
        x.iter().map(|v| v.to_bits()).collect()
    }

    /// The vectorised L = 1 loops do the general loops' arithmetic in the same order: the
    /// same bits, on whichever instruction set this machine picks.
    #[test]
    fn the_single_thermostat_lanes_match_the_general_loops_bit_for_bit() {
        let (mut sinr, p, gradient) = coordinates();
        let c = sinr.c;
        let steps = sinr.weights.map(|w| w * 0.5);
        let (mut p1, mut v1a, mut v2a) = (p.clone(), sinr.v1.clone(), sinr.v2.clone());
        let (mut p2, mut v1b, mut v2b) = (p.clone(), sinr.v1.clone(), sinr.v2.clone());
        let collapsed_lanes = lanes::kick::<1>(c, 2.0, &mut p1, &gradient, &mut v1a, &sinr.kappa);
        let collapsed_loop = kick_general(c, 2.0, 1, &mut p2, &gradient, &mut v1b, &sinr.kappa);
        assert!(collapsed_lanes && collapsed_loop);
        lanes::flow::<1>(c, steps, &mut p1, &sinr.inverse_mass, &mut v1a, &mut v2a);
        flow_general(c, steps, 1, &mut p2, &sinr.inverse_mass, &mut v1b, &mut v2b);
        assert_eq!(bits(&p1), bits(&p2));
        assert_eq!(bits(&v1a), bits(&v1b));
        assert_eq!(bits(&v2a), bits(&v2b));
        // The coordinate without force and the collapsed one were not kicked; the rest were.
        assert_eq!(p1[7], p[7]);
        sinr.v1 = v1a;
        assert_eq!(sinr.share(7), 0.0);
        let mut again = p.clone();
        sinr.isokinetic_kick(&mut again, &gradient, 2.0);
        assert_eq!(sinr.collapsed, Some(7));
        assert_eq!(again[11], p[11]);
        assert_ne!(again[12], p[12]);
    }

    /// Every instruction set this machine has gives the portable path's bits, for L = 1
    /// (the branch-free loops) and L = 4 (the general loops with L constant).
    #[test]
    fn every_instruction_set_gives_the_portable_bits() {
        fn run(sinr: &Sinr, p: &[f64], gradient: &[f64], isa: Isa) -> Vec<u64> {
            let mut sinr = sinr.clone();
            sinr.isa = isa;
            let mut p = p.to_vec();
            sinr.isokinetic_kick(&mut p, gradient, 2.0);
            sinr.thermostat_flow(&mut p, 0.5);
            bits(&p)
                .into_iter()
                .chain(bits(&sinr.v1))
                .chain(bits(&sinr.v2))
                .collect()
        }
        let (one, p, gradient) = coordinates();
        let mut four = Sinr::new(0.6, 4, 5.0, 0.2, 1).expect("valid settings");
        four.inverse_mass = one.inverse_mass.clone();
        four.kappa = one
            .inverse_mass
            .iter()
            .map(|w| (four.c.lkt / w).sqrt())
            .collect();
        four.v1 = one
            .v1
            .iter()
            .flat_map(|v| [0.5 * v, -0.5 * v, 0.3 * v, 0.1])
            .collect();
        four.v2 = one.v2.iter().flat_map(|v| [*v, -v, 0.5 * v, 0.0]).collect();
        let portable_one = run(&one, &p, &gradient, Isa::Portable);
        let portable_four = run(&four, &p, &gradient, Isa::Portable);
        let others: Vec<Isa> = Isa::available()
            .into_iter()
            .filter(|&isa| isa != Isa::Portable)
            .collect();
        for &isa in &others {
            assert_eq!(
                run(&one, &p, &gradient, isa),
                portable_one,
                "{}",
                isa.name()
            );
            assert_eq!(
                run(&four, &p, &gradient, isa),
                portable_four,
                "{}",
                isa.name()
            );
        }
        eprintln!(
            "SIMD builds checked against the portable one: {}",
            others.len()
        );
    }

    /// Kick and flow keep every coordinate on its constraint to round-off.
    #[test]
    fn kick_and_flow_keep_the_constraint() {
        let (mut sinr, mut p, gradient) = coordinates();
        for _ in 0..50 {
            sinr.isokinetic_kick(&mut p, &gradient, 2.0);
            sinr.thermostat_flow(&mut p, 0.5);
        }
        sinr.collapsed = None;
        sinr.max_violation = 0.0;
        sinr.watch(&p);
        // A few roundings per operation, 100 operations: 1e-13 is far above round-off
        // (~1e-16 each) and far below any real violation.
        assert!(
            sinr.max_violation < 1e-13,
            "violation {}",
            sinr.max_violation
        );
    }
}
