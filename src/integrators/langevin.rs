//! The stochastic part of the thermostatted methods: seeded Gaussian numbers and the
//! Langevin O step of BAOAB (LM13).
//!
//! **O step** (LM13, the exact flow of `dp = −γ p dt + √(2γ kT M) dW` over `dt`):
//! `p ← a p + √((1 − a²) kT m) ξ` per coordinate, `a = exp(−γ dt)`, ξ standard normal
//! (in velocities, `v ← a v + √((1 − a²) kT/m) ξ`, as OpenMM's Langevin integrators write it).
//! `1 − a²` is computed as `−expm1(−2γ dt)`, exact also for `γ dt ≪ 1`.
//!
//! **Random numbers.** One stream per method, seeded from `--seed` (xoshiro256++, a fixed
//! algorithm, so a seed means the same numbers in every build), drawn sequentially over
//! the coordinates in index order: the numbers do not depend on how many threads compute
//! the forces, so the same seed gives the same bits at any `RAYON_NUM_THREADS`. Each
//! method salts the seed with its own constant, so the noise is not the stream that drew
//! the start velocities from the same `--seed`. The O step draws one normal per
//! coordinate and is `O(n)` next to a force evaluation: not worth parallelising.

use super::innermost::InnermostStep;
use super::integrator::{StepFailure, drift};
use crate::error::{Error, Result};
use crate::settings::MethodSettings;
use crate::system::System;
use crate::units::Units;
use rand::rngs::Xoshiro256PlusPlus;
use rand::{RngExt, SeedableRng};
use rand_distr::StandardNormal;

/// The seed used when `--seed` is not given (runs stay reproducible; say `--seed` to vary).
pub const DEFAULT_SEED: u64 = 2013;

/// A seeded stream of standard normal numbers. Its state is the generator's four words
/// (rand's serde form), which a checkpoint saves so a continued run draws the same numbers.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Gaussian {
    rng: Xoshiro256PlusPlus,
}

impl Gaussian {
    /// The stream for `seed`, salted by `salt` (one salt per use of the seed).
    pub fn new(seed: u64, salt: u64) -> Self {
        Gaussian {
            rng: Xoshiro256PlusPlus::seed_from_u64(seed ^ salt),
        }
    }

    /// Refuse a restored generator whose state is all zeros: Xoshiro256++ then returns
    /// zeros for ever (no seed gives that state, so only an edited file holds it).
    pub fn check(&self, method: &str) -> Result<()> {
        let zero = serde_json::to_value(&self.rng)
            .ok()
            .and_then(|v| v.get("s").cloned())
            .and_then(|s| serde_json::from_value::<[u64; 4]>(s).ok())
            .is_some_and(|s| s == [0; 4]);
        if zero {
            return Err(Error::input(format!(
                "the checkpoint's random-number generator of {method} is all zeros, which no \
                 seed gives"
            )));
        }
        Ok(())
    }

    /// The next standard normal number.
    #[inline]
    pub fn normal(&mut self) -> f64 {
        self.rng.sample(StandardNormal)
    }
}

/// The default friction of a real scene: 1/ps (OpenMM's usual choice, the setting).
pub const DEFAULT_FRICTION_PER_FS: f64 = 1e-3;

/// `k_B T` of a thermostatted method, or the error saying how to give the temperature.
pub fn required_kt(settings: &MethodSettings) -> Result<f64> {
    settings.kt().ok_or_else(|| {
        let how = match settings.units {
            Units::Real => "--temperature 300K",
            Units::None => {
                "--temperature KT (a number: k_B T with k_B = 1 in a dimensionless scene)"
            }
        };
        Error::setting(
            "temperature",
            format!(
                "{} is thermostatted and needs a temperature: give {how}",
                settings.method
            ),
        )
        .expected(how)
    })
}

/// "LANGEVIN" in ASCII: the salt of the O step's stream.
const SALT: u64 = 0x4c41_4e47_4556_494e;

/// The Langevin O step with friction γ at `kT`, for a fixed step `dt` set in
/// [`Langevin::setup`].
#[derive(Clone, Debug)]
pub struct Langevin {
    friction: f64,
    kt: f64,
    seed: u64,
    gaussian: Gaussian,
    decay: f64,
    /// `√((1 − a²) kT m)` per coordinate.
    noise: Vec<f64>,
}

impl Langevin {
    /// An O step with friction `friction` (inverse time) at `kt` (energy), noise from `seed`.
    pub fn new(kt: f64, friction: f64, seed: u64) -> Self {
        Langevin {
            friction,
            kt,
            seed,
            gaussian: Gaussian::new(seed, SALT),
            decay: 1.0,
            noise: Vec::new(),
        }
    }

    /// The O step a method's settings ask for: `--temperature` (required), `--friction`
    /// (default 1/ps in a real scene; required in a dimensionless one), `--seed`.
    pub fn from_settings(settings: &MethodSettings) -> Result<Self> {
        let kt = required_kt(settings)?;
        let friction = match (settings.friction, settings.units) {
            (Some(gamma), _) => gamma,
            (None, Units::Real) => DEFAULT_FRICTION_PER_FS,
            (None, Units::None) => {
                return Err(Error::setting("friction", format!("{} needs the friction γ in a dimensionless scene: give --friction (an inverse time)", settings.method)).expected("an inverse time"));
            }
        };
        Ok(Langevin::new(
            kt,
            friction,
            settings.seed.unwrap_or(DEFAULT_SEED),
        ))
    }

    /// The run header's part: `, kT = …, friction = …, seed = …`.
    pub fn describe(&self) -> String {
        format!(
            ", kT = {}, friction = {}, seed = {}",
            self.kt, self.friction, self.seed
        )
    }

    /// The summary's `langevin` object.
    pub fn report(&self) -> serde_json::Value {
        serde_json::json!({
            "kT": self.kt,
            "friction": self.friction,
            "seed": self.seed,
            "decay_per_inner_step": self.decay,
        })
    }

    pub fn friction(&self) -> f64 {
        self.friction
    }

    pub fn kt(&self) -> f64 {
        self.kt
    }

    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// Size the noise amplitudes for steps of `dt` and per-coordinate inverse masses, and
    /// restart the stream (so a run set up twice draws the same numbers).
    pub fn setup(&mut self, dt: f64, inverse_mass: &[f64]) {
        self.decay = (-self.friction * dt).exp();
        let variance = -(-2.0 * self.friction * dt).exp_m1();
        self.noise = inverse_mass
            .iter()
            .map(|w| (variance * self.kt / w).sqrt())
            .collect();
        self.gaussian = Gaussian::new(self.seed, SALT);
    }

    /// `a = exp(−γ dt)`.
    pub fn decay(&self) -> f64 {
        self.decay
    }

    /// The O step on the momenta: `p ← a p + √((1 − a²) kT m) ξ`.
    pub fn apply(&mut self, p: &mut [f64]) {
        let a = self.decay;
        for (pi, sigma) in p.iter_mut().zip(&self.noise) {
            *pi = a * *pi + sigma * self.gaussian.normal();
        }
    }
}

/// BAOAB (LM13) as the innermost step of r-RESPA (`langevin-respa`, OpenMM's
/// `MTSLangevinIntegrator`): kick `dt/2`, drift `dt/2`, the O step, drift `dt/2`, kick
/// `dt/2`. With one force level it is plain BAOAB.
pub struct Baoab(pub Langevin);

impl InnermostStep for Baoab {
    fn method_name(&self) -> Option<&'static str> {
        Some("langevin-respa")
    }

    fn describe(&self) -> String {
        self.0.describe()
    }

    fn setup(&mut self, dt: f64, system: &mut System) -> Result<()> {
        self.0.setup(dt, &system.inverse_mass);
        Ok(())
    }

    fn flight(&mut self, system: &mut System, dt: f64) -> Result<(), StepFailure> {
        let half = 0.5 * dt;
        let (state, w) = (&mut system.state, &system.inverse_mass);
        drift(&mut state.q, &state.p, w, half);
        self.0.apply(&mut state.p);
        drift(&mut state.q, &state.p, w, half);
        Ok(())
    }

    fn report(&self) -> Option<(&'static str, serde_json::Value)> {
        Some(("langevin", self.0.report()))
    }

    /// The generator: the only state of BAOAB's O step (the noise amplitudes follow from
    /// the masses).
    fn save_state(&self) -> Result<serde_json::Value> {
        self.0.save_state()
    }

    fn restore_state(&mut self, state: &serde_json::Value) -> Result<()> {
        self.0.restore_state(state)
    }
}

/// What a checkpoint holds of a Langevin O step.
#[derive(serde::Serialize, serde::Deserialize)]
struct LangevinState {
    gaussian: Gaussian,
}

impl Langevin {
    /// The generator's state for a checkpoint.
    pub fn save_state(&self) -> Result<serde_json::Value> {
        super::integrator::state_to_json(
            "langevin",
            &LangevinState {
                gaussian: self.gaussian.clone(),
            },
        )
    }

    /// Restore the generator saved by [`Langevin::save_state`].
    pub fn restore_state(&mut self, state: &serde_json::Value) -> Result<()> {
        let saved: LangevinState = super::integrator::state_from_json("langevin", state)?;
        saved.gaussian.check("langevin")?;
        self.gaussian = saved.gaussian;
        Ok(())
    }
}
