//! SIN(R): the stochastic isokinetic Nosé–Hoover RESPA method (LMT13: Leimkuhler, Margul
//! & Tuckerman, Mol. Phys. 111:3579, 2013), run by the r-RESPA recursion of
//! [`super::impulse`] with [`Thermostat::Sinr`](super::impulse::Thermostat).
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
//! numbers; the outer levels' kicks add `n` `expm1` each. All O(n L).
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

use super::StepFailure;
use super::langevin::{Gaussian, required_kt};
use crate::error::{Error, Result};
use crate::settings::MethodSettings;
use crate::system::System;
use crate::units::Units;

/// L when `--thermostats` is not given: Tinker's (and its SIN(R) author's) default.
pub const DEFAULT_THERMOSTATS: usize = 4;
/// The most thermostat pairs per degree of freedom (memory is `2 L n` numbers).
pub const MAX_THERMOSTATS: usize = 16;
/// τ in a real scene when `--tau` is not given: 10 fs, the value recommended for water by
/// the SIN(R) code of LMT13's second author (Tinker `TAU-TEMPERATURE 0.01 ps`).
pub const DEFAULT_TAU_FS: f64 = 10.0;
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

pub struct Sinr {
    thermostats: usize,
    kt: f64,
    tau: f64,
    friction: f64,
    seed: u64,
    q1: f64,
    q2: f64,
    /// `L kT`.
    lkt: f64,
    /// `L/(L+1)`.
    ratio: f64,
    weights: [f64; 3],
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
            return Err(Error::input(format!(
                "sinr: thermostats (L) must be between 1 and {MAX_THERMOSTATS}, got {thermostats}"
            )));
        }
        let q = kt * tau * tau;
        Ok(Sinr {
            thermostats,
            kt,
            tau,
            friction,
            seed,
            q1: q,
            q2: q,
            lkt: thermostats as f64 * kt,
            ratio: thermostats as f64 / (thermostats + 1) as f64,
            weights: suzuki_yoshida(),
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
    /// (default 4), `--tau` (default 10 fs in a real scene, required in a dimensionless
    /// one), `--friction` on the thermostat variables (default 1/τ), `--seed`.
    pub fn from_settings(settings: &MethodSettings) -> Result<Self> {
        let kt = required_kt(settings)?;
        let tau = match (settings.tau, settings.units) {
            (Some(tau), _) => tau,
            (None, Units::Real) => DEFAULT_TAU_FS,
            (None, Units::None) => {
                return Err(Error::input(
                    "sinr needs the thermostat time scale in a dimensionless scene: give --tau \
                     (thermostat masses Q = kT τ²)",
                ));
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
    pub fn setup(&mut self, dt: f64, system: &mut System) -> Result<()> {
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
            .map(|w| (self.lkt / w).sqrt())
            .collect();
        let v1_scale = (self.kt / self.q1).sqrt();
        let v2_scale = (self.kt / self.q2).sqrt();
        self.v1 = (0..n * l)
            .map(|_| v1_scale * self.gaussian.normal())
            .collect();
        self.v2 = (0..n * l)
            .map(|_| v2_scale * self.gaussian.normal())
            .collect();
        let p = &mut system.state.p;
        for (i, pi) in p.iter_mut().enumerate() {
            let thermo = &mut self.v1[i * l..(i + 1) * l];
            let bath: f64 = self.ratio * self.q1 * thermo.iter().map(|v| v * v).sum::<f64>();
            let scale = (self.lkt / (*pi * *pi * self.inverse_mass[i] + bath)).sqrt();
            *pi *= scale;
            thermo.iter_mut().for_each(|v| *v *= scale);
        }
        self.ou_decay = (-self.friction * dt).exp();
        self.ou_noise = (-self.kt * (-2.0 * self.friction * dt).exp_m1() / self.q2).sqrt();
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
        let sum: f64 = self.v1[i * l..(i + 1) * l].iter().map(|v| v * v).sum();
        self.ratio * self.q1 * sum / self.lkt
    }

    /// The isokinetic force operator `V(t)` with the force `−gradient` (bounded form, see
    /// the module doc). Coordinates with a collapsed thermostat are left as they are.
    pub fn isokinetic_kick(&mut self, p: &mut [f64], gradient: &[f64], t: f64) {
        let l = self.thermostats;
        for (i, (pi, gi)) in p.iter_mut().zip(gradient).enumerate() {
            let force = -gi;
            if force == 0.0 {
                continue;
            }
            let share = self.share(i);
            if collapsed(share) {
                self.collapsed.get_or_insert(i);
                continue;
            }
            let kappa = self.kappa[i];
            let sign = force.signum();
            let a = sign * *pi / kappa;
            let x = force.abs() * t / kappa;
            // e^{−x} − 1 exactly for small x; tanh x = (1 − e^{−2x})/(1 + e^{−2x}).
            let m = (-x).exp_m1();
            let e1 = 1.0 + m;
            let e2 = e1 * e1;
            let tanh = -m * (1.0 + e1) / (1.0 + e2);
            let sech = 2.0 * e1 / (1.0 + e2);
            let (numerator, denominator) = if a >= 0.0 {
                (tanh + a, 1.0 + a * tanh)
            } else {
                // 1 − |â| = share/(1 + |â|) (the constraint), 1 − tanh x = 2e^{−2x}/(1 + e^{−2x}).
                let gap = share / (1.0 - a);
                let one_minus_tanh = 2.0 * e2 / (1.0 + e2);
                (gap - one_minus_tanh, gap - a * one_minus_tanh)
            };
            *pi = sign * kappa * numerator / denominator;
            let factor = sech / denominator;
            self.v1[i * l..(i + 1) * l]
                .iter_mut()
                .for_each(|v| *v *= factor);
        }
    }

    /// The thermostat flow `N(δ)`: three Suzuki–Yoshida sub-steps per coordinate (the
    /// coordinates' thermostats are independent, so each runs its sub-steps in turn).
    pub fn thermostat_flow(&mut self, p: &mut [f64], delta: f64) {
        let l = self.thermostats;
        let (q1, q2, kt, ratio, lkt) = (self.q1, self.q2, self.kt, self.ratio, self.lkt);
        let mut decay = [0.0; MAX_THERMOSTATS];
        for (i, pi) in p.iter_mut().enumerate() {
            // A collapsed thermostat (v1 = 0) leaves m v² = L kT, so H = 1: no 0/0 here.
            let v1 = &mut self.v1[i * l..(i + 1) * l];
            let v2 = &mut self.v2[i * l..(i + 1) * l];
            for w in self.weights {
                let t = w * delta;
                let half = 0.5 * t;
                for (b, a) in v2.iter_mut().zip(v1.iter()) {
                    *b += half * (q1 * a * a - kt) / q2;
                }
                let mut kinetic = *pi * *pi * self.inverse_mass[i];
                for ((d, a), b) in decay.iter_mut().zip(v1.iter()).zip(v2.iter()) {
                    *d = (-t * b).exp();
                    kinetic += ratio * q1 * a * a * *d * *d;
                }
                let scale = (lkt / kinetic).sqrt();
                *pi *= scale;
                for (a, d) in v1.iter_mut().zip(&decay) {
                    *a *= scale * d;
                }
                for (b, a) in v2.iter_mut().zip(v1.iter()) {
                    *b += half * (q1 * a * a - kt) / q2;
                }
            }
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
            let kinetic = pi * pi * self.inverse_mass[i] / self.lkt;
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
            self.ratio, self.thermostats
        )
    }

    /// The run header's part.
    pub fn describe(&self) -> String {
        format!(
            ", kT = {}, L = {}, tau = {}, friction = {} (on v2), seed = {}",
            self.kt, self.thermostats, self.tau, self.friction, self.seed
        )
    }

    /// The summary's `sinr` object.
    pub fn report(&self) -> serde_json::Value {
        serde_json::json!({
            "kT": self.kt,
            "thermostats": self.thermostats,
            "tau": self.tau,
            "friction": self.friction,
            "seed": self.seed,
            "kinetic_temperature_factor": self.ratio,
            "kinetic_temperature_note": "SIN(R)'s kinetic temperature is L/(L+1) T by construction; judge it by configurational quantities",
            "constraint_max_violation": self.max_violation,
            "smallest_thermostat_share": self.min_share,
        })
    }
}
