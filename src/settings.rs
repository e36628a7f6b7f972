//! Run and method settings: one definition for the scene's `[run]` table and the
//! command-line flags of `longstep run`, so a key and its flag can never drift apart
//! (`inner_steps` ↔ `--inner`, `t_end` ↔ `--t-end`, `h_slow` ↔ `--h-slow`, …).
//!
//! Steps are named as everywhere in longstep: `h` is the outer step (the slowest
//! forces are sampled once per `h`), `inner_steps` the number of inner steps per outer
//! step and `dt = h / inner_steps` the inner step.

use std::collections::BTreeMap;

use clap::Args;
use serde::Deserialize;

use crate::error::{Error, Result};
use crate::expr;

/// The highest temperature a real scene takes (K).
pub const MAX_TEMPERATURE_K: f64 = 1e5;

/// A number, or an expression in the scene's parameters (`"omega1^2"`, `"2*pi/omega1"`).
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    Number(f64),
    Expression(String),
}

/// By hand rather than `untagged`, so a wrong type reads "expected a number or an
/// expression" instead of serde's "did not match any variant of untagged enum Value".
impl<'de> Deserialize<'de> for Value {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl serde::de::Visitor<'_> for Visitor {
            type Value = Value;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a number or an expression in quotes (such as \"2*pi/omega1\")")
            }
            fn visit_f64<E>(self, x: f64) -> Result<Value, E> {
                Ok(Value::Number(x))
            }
            fn visit_i64<E>(self, x: i64) -> Result<Value, E> {
                Ok(Value::Number(x as f64))
            }
            fn visit_u64<E>(self, x: u64) -> Result<Value, E> {
                Ok(Value::Number(x as f64))
            }
            fn visit_str<E>(self, text: &str) -> Result<Value, E> {
                Ok(Value::Expression(text.to_string()))
            }
        }
        deserializer.deserialize_any(Visitor)
    }
}

impl std::str::FromStr for Value {
    type Err = std::convert::Infallible;

    fn from_str(text: &str) -> std::result::Result<Self, Self::Err> {
        Ok(match text.trim().parse::<f64>() {
            Ok(number) => Value::Number(number),
            Err(_) => Value::Expression(text.trim().to_string()),
        })
    }
}

/// As the user wrote it: `0.5`, `2*pi/omega1`, `4fs`.
impl std::fmt::Display for Value {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Value::Number(x) => write!(f, "{x}"),
            Value::Expression(text) => f.write_str(text),
        }
    }
}

impl Value {
    /// The value with the given parameters; `what` names it in the error.
    pub fn evaluate(&self, parameters: &BTreeMap<String, f64>, what: &str) -> Result<f64> {
        let value = match self {
            Value::Number(x) => *x,
            Value::Expression(text) => expr::evaluate(text, parameters).map_err(|e| {
                Error::setting(what, format!("{what}: {e}"))
                    .expected("a number or an expression of the parameters")
            })?,
        };
        if !value.is_finite() {
            return Err(
                Error::setting(what, format!("{what} is not finite ({value})"))
                    .expected("a finite number"),
            );
        }
        Ok(value)
    }

    /// A time value, which may carry a unit suffix from `time_units` (`4fs`, `10ps`).
    pub fn evaluate_time(
        &self,
        parameters: &BTreeMap<String, f64>,
        what: &str,
        time_units: &[(&str, f64)],
    ) -> Result<f64> {
        let value = match self {
            Value::Number(x) => *x,
            Value::Expression(text) => expr::evaluate_with_units(text, parameters, time_units)
                .map_err(|e| {
                    Error::setting(what, format!("{what}: {e}"))
                        .expected("a number or an expression of the parameters")
                })?,
        };
        if !value.is_finite() {
            return Err(
                Error::setting(what, format!("{what} is not finite ({value})"))
                    .expected("a finite number"),
            );
        }
        Ok(value)
    }
}

/// Which bonds are constrained (`--constraints`, scene key `constraints`): as OpenMM's
/// `constraints=None|HBonds|AllBonds`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ConstraintSet {
    #[default]
    None,
    /// Every bond with a hydrogen at one end.
    HBonds,
    AllBonds,
}

impl ConstraintSet {
    /// The names of the command line and scenes.
    pub const NAMES: [&'static str; 3] = ["none", "h-bonds", "all-bonds"];

    pub fn parse(text: &str) -> Result<Self, String> {
        match text {
            "none" => Ok(ConstraintSet::None),
            "h-bonds" => Ok(ConstraintSet::HBonds),
            "all-bonds" => Ok(ConstraintSet::AllBonds),
            other => Err(format!(
                "constraints must be one of none, h-bonds, all-bonds; got \"{other}\""
            )),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            ConstraintSet::None => "none",
            ConstraintSet::HBonds => "h-bonds",
            ConstraintSet::AllBonds => "all-bonds",
        }
    }
}

/// The method parameters: the settings a method may use, and that a method which does not
/// use them ignores with a notice. Each is written here once, as `field: kind`: the field
/// has that name in [`RunSpec`] (its flag and `[run]` key) and in [`MethodSettings`] (its
/// resolved value, set in [`RunSpec::resolve_with_units`]), and `kind` is the
/// [`Parameter`] its value is recorded as. What lists the parameters derives from this
/// table: [`MethodSettings::given`] (the notices of `integrators::build`), a checkpoint's
/// settings (`io::checkpoint`), a scene's settings for another method (`run::prepare`),
/// [`RunSpec::given_parameters`] (a study's record) and [`RunSpec::overridden_by`].
/// `$then!(ARGS; field: kind, …)` is called with the table.
macro_rules! method_parameters {
    ($then:ident $(, $arg:tt)*) => {
        $then!($($arg)*;
            inner_steps: Count,
            level_steps: Steps,
            jacobian: Text,
            quadrature: Text,
            h_slow: Time,
            h_fast: Time,
            ratio: Count,
            adaptive: Number,
            control: Text,
            h_min: Time,
            h_max: Time,
            block: Count,
            tol: Number,
            max_iter: Count,
            friction: PerTime,
            thermostats: Count,
            tau: Time,
            mollifier: Text,
            molly_constraints: Text,
            molly_jacobian: Text,
        )
    };
}
pub(crate) use method_parameters;

/// A method parameter's resolved value and what it is, for records: a count, the steps of
/// each level, a name, a plain number, a time, an inverse time (in the scene's units).
#[derive(Clone, Debug, PartialEq)]
pub enum Parameter {
    Count(Option<usize>),
    Steps(Option<Vec<usize>>),
    Text(Option<String>),
    Number(Option<f64>),
    Time(Option<f64>),
    PerTime(Option<f64>),
}

/// A `[run]` value as the user wrote it (`4fs`, `2,4`), for records.
trait Written {
    fn written(&self) -> String;
}

impl Written for Value {
    fn written(&self) -> String {
        self.to_string()
    }
}

impl Written for String {
    fn written(&self) -> String {
        self.clone()
    }
}

impl Written for usize {
    fn written(&self) -> String {
        self.to_string()
    }
}

impl Written for Vec<usize> {
    fn written(&self) -> String {
        let steps: Vec<String> = self.iter().map(usize::to_string).collect();
        steps.join(",")
    }
}

/// The `[run]` table of a scene, and the same settings as `longstep run` flags.
/// Everything is optional: the command line overrides the scene, field by field.
#[derive(Args, Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunSpec {
    /// Integration method (see `longstep methods`); default verlet.
    #[arg(long)]
    pub method: Option<String>,
    /// Outer step h: the step at which the slowest forces are sampled (number or expression).
    #[arg(long, allow_negative_numbers = true)]
    pub h: Option<Value>,
    /// Inner steps K per outer step (inner step dt = h / K), for multiple-time-step methods.
    #[arg(long = "inner", value_name = "K")]
    pub inner_steps: Option<usize>,
    /// Inner step dt instead of --inner; h / dt must be a whole number.
    #[arg(long, allow_negative_numbers = true)]
    pub dt: Option<Value>,
    /// End time of the run.
    #[arg(long, allow_negative_numbers = true)]
    pub t_end: Option<Value>,
    /// Stop as unstable when |E - E0| exceeds this many times the initial energy scale (default 10).
    #[arg(long, value_name = "FACTOR", allow_negative_numbers = true)]
    pub blowup: Option<f64>,
    /// Recursive r-RESPA with more than two levels: steps of each level per step of the
    /// level above, outermost first (e.g. 2,4); default: --inner between every pair of levels.
    #[arg(long, value_delimiter = ',', value_name = "N,N,…")]
    pub level_steps: Option<Vec<usize>>,
    /// Jacobian of the mollified methods' averaging: forward, adjoint or auto (by component size).
    #[arg(long)]
    pub jacobian: Option<String>,
    /// Quadrature of the pseudo-energy schemes: midpoint, gl3, gl5 (Gauss–Lobatto), gauss3, gauss5 (Gauss–Legendre).
    #[arg(long)]
    pub quadrature: Option<String>,
    /// Coarse (slow-particle) step of the asynchronous pseudo-energy scheme.
    #[arg(long, allow_negative_numbers = true)]
    pub h_slow: Option<Value>,
    /// Fine (fast-particle) step of the asynchronous pseudo-energy scheme.
    #[arg(long, allow_negative_numbers = true)]
    pub h_fast: Option<Value>,
    /// Ratio K = h_slow / h_fast of the asynchronous pseudo-energy scheme.
    #[arg(long)]
    pub ratio: Option<usize>,
    /// Adaptive step halving of the pseudo-energy scheme with tolerance EPS (MEMM18 Remark 8).
    #[arg(long, value_name = "EPS", allow_negative_numbers = true)]
    pub adaptive: Option<Value>,
    /// Step control of adaptive Verlet: arclength or min-distance.
    #[arg(long)]
    pub control: Option<String>,
    /// Smallest physical step an adaptive method may take.
    #[arg(long, allow_negative_numbers = true)]
    pub h_min: Option<Value>,
    /// Largest physical step an adaptive method may take.
    #[arg(long, allow_negative_numbers = true)]
    pub h_max: Option<Value>,
    /// Block size R of the structural schemes.
    #[arg(long, value_name = "R")]
    pub block: Option<usize>,
    /// Tolerance of an implicit solver (structural schemes' fixed point).
    #[arg(long, allow_negative_numbers = true)]
    pub tol: Option<Value>,
    /// Iteration cap of an implicit solver.
    #[arg(long)]
    pub max_iter: Option<usize>,
    /// Temperature: Maxwell–Boltzmann start velocities and the target of thermostatted
    /// methods (`300K` in a real scene; in a dimensionless one the number k_B T).
    #[arg(long, allow_hyphen_values = true)]
    pub temperature: Option<Value>,
    /// Seed of the random numbers (start velocities, stochastic methods).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Friction γ of a stochastic method, an inverse time (`1/ps` in a real scene).
    #[arg(long, allow_hyphen_values = true)]
    pub friction: Option<Value>,
    /// Thermostat pairs L per degree of freedom (SIN(R)).
    #[arg(long, value_name = "L")]
    pub thermostats: Option<usize>,
    /// Thermostat time scale τ (SIN(R): thermostat masses Q = k_B T τ²).
    #[arg(long, allow_negative_numbers = true)]
    pub tau: Option<Value>,
    /// Mollified slow force of the thermostatted r-RESPA methods (langevin-respa, sinr):
    /// short-average, long-average or linear-average (GSS98), or equilibrium-molly (IRS99,
    /// with --molly-constraints, --molly-jacobian).
    #[arg(long)]
    pub mollifier: Option<String>,
    /// What the equilibrium mollifier holds at rest: bonds, or bonds-angles.
    #[arg(long)]
    pub molly_constraints: Option<String>,
    /// Jacobian of the equilibrium mollifier: exact (conserves K + W(q) + U(A(q))) or
    /// projection (the older literature's; does not conserve).
    #[arg(long)]
    pub molly_jacobian: Option<String>,
    /// Constrained bonds: none, h-bonds (bonds to hydrogen) or all-bonds, held at their
    /// force-field rest lengths by SHAKE/RATTLE (verlet, impulse, the mollified methods,
    /// langevin-respa).
    #[arg(long)]
    pub constraints: Option<String>,
    /// Rigid three-site water (SETTLE), whatever --constraints says; `--rigid-water` alone
    /// means true.
    #[arg(long, num_args = 0..=1, default_missing_value = "true", value_name = "BOOL")]
    pub rigid_water: Option<bool>,
    /// Relative tolerance of the SHAKE/RATTLE iterations (default 1e-8).
    #[arg(long, allow_negative_numbers = true)]
    pub constraint_tolerance: Option<Value>,
    /// Hydrogen mass repartitioning: every hydrogen bonded to a heavy atom (water aside)
    /// gets this mass (`3amu`), taken from its heavy atom.
    #[arg(long, allow_negative_numbers = true)]
    pub hydrogen_mass: Option<Value>,
}

/// `RunSpec { field: over.field.or(base.field), … }` for the run-wide fields `[…]` and the
/// method parameters (called by `method_parameters!`).
macro_rules! override_fields {
    ($base:ident $over:ident [$($run:ident),*]; $($field:ident: $kind:ident),* $(,)?) => {
        RunSpec {
            $($run: $over.$run.or($base.$run),)*
            $($field: $over.$field.or($base.$field)),*
        }
    };
}

impl RunSpec {
    /// These settings with every field `other` gives replacing ours. An inner step given
    /// in either form (`inner_steps` or `dt`) replaces both forms of ours.
    pub fn overridden_by(&self, other: &RunSpec) -> RunSpec {
        let base = self.clone();
        let over = other.clone();
        let mut merged = method_parameters!(
            override_fields,
            base,
            over,
            [
                method,
                h,
                dt,
                t_end,
                blowup,
                temperature,
                seed,
                constraints,
                rigid_water,
                constraint_tolerance,
                hydrogen_mass
            ]
        );
        if other.inner_steps.is_some() || other.dt.is_some() {
            merged.inner_steps = other.inner_steps;
            merged.dt = other.dt.clone();
        }
        merged
    }

    /// The method parameters given, by name, each as written (`4fs`, `2,4`).
    pub fn given_parameters(&self) -> Vec<(&'static str, String)> {
        macro_rules! written {
            ($s:tt; $($field:ident: $kind:ident),* $(,)?) => {
                [$((stringify!($field), $s.$field.as_ref().map(Written::written))),*]
            };
        }
        let values = method_parameters!(written, self);
        values
            .into_iter()
            .filter_map(|(name, value)| value.map(|v| (name, v)))
            .collect()
    }

    /// Evaluate into the numbers a method is built from (a dimensionless scene).
    pub fn resolve(&self, parameters: &BTreeMap<String, f64>) -> Result<MethodSettings> {
        self.resolve_with_units(parameters, crate::units::Units::None)
    }

    /// Evaluate into the numbers a method is built from; the time values (`h`, `dt`,
    /// `t_end`, `h_slow`, `h_fast`, `h_min`, `h_max`) may carry the time units of `units`.
    pub fn resolve_with_units(
        &self,
        parameters: &BTreeMap<String, f64>,
        units: crate::units::Units,
    ) -> Result<MethodSettings> {
        let values = Values { parameters, units };
        let h = values
            .positive_time(&self.h, ("h", "outer step h"))?
            .ok_or_else(|| {
                Error::setting(
                    "h",
                    "no outer step h: give --h or set h in the scene's [run] table",
                )
            })?;
        let dt = values.positive_time(&self.dt, ("dt", "inner step dt"))?;
        let inner_steps = self.inner_steps_of(h, dt)?;
        self.check_counts()?;
        let temperature = self.temperature_of(parameters, units)?;
        // An inverse time: `1/ps` is 1/1000 per fs, the unit standing alone being its factor.
        let friction = match values.time(&self.friction, ("friction", "friction"))? {
            Some(g) if g <= 0.0 => {
                return Err(Error::setting(
                    "friction",
                    "friction must be positive (an inverse time, e.g. 1/ps)",
                )
                .expected("a positive inverse time")
                .got(g.to_string()));
            }
            other => other,
        };
        Ok(MethodSettings {
            method: self.method.clone().unwrap_or_else(|| "verlet".into()),
            h,
            inner_steps,
            t_end: values.positive_time(&self.t_end, ("t_end", "end time t_end"))?,
            blowup: self.blowup.unwrap_or(10.0),
            level_steps: self.level_steps.clone(),
            jacobian: self.jacobian.clone(),
            quadrature: self.quadrature.clone(),
            h_slow: values.positive_time(&self.h_slow, ("h_slow", "h_slow"))?,
            h_fast: values.positive_time(&self.h_fast, ("h_fast", "h_fast"))?,
            ratio: self.ratio,
            adaptive: values.positive(&self.adaptive, ("adaptive", "adaptive tolerance"))?,
            control: self.control.clone(),
            h_min: values.positive_time(&self.h_min, ("h_min", "h_min"))?,
            h_max: values.positive_time(&self.h_max, ("h_max", "h_max"))?,
            block: self.block,
            tol: values.positive(&self.tol, ("tol", "tol"))?,
            max_iter: self.max_iter,
            temperature,
            seed: self.seed,
            friction,
            thermostats: self.thermostats,
            tau: values.positive_time(&self.tau, ("tau", "thermostat time scale tau"))?,
            mollifier: self.mollifier.clone(),
            molly_constraints: self.molly_constraints.clone(),
            molly_jacobian: self.molly_jacobian.clone(),
            constraints: match &self.constraints {
                Some(text) => ConstraintSet::parse(text).map_err(|e| {
                    Error::setting("constraints", e).expected(ConstraintSet::NAMES.join(", "))
                })?,
                None => ConstraintSet::None,
            },
            rigid_water: self.rigid_water.unwrap_or(false),
            constraint_tolerance: self.constraint_tolerance_of(parameters)?,
            hydrogen_mass: self.hydrogen_mass_of(parameters, units)?,
            units,
        })
    }

    /// The relative constraint tolerance, in (0, 1).
    fn constraint_tolerance_of(&self, parameters: &BTreeMap<String, f64>) -> Result<Option<f64>> {
        let Some(value) = &self.constraint_tolerance else {
            return Ok(None);
        };
        let key = "constraint_tolerance";
        let tolerance = value.evaluate(parameters, key).map_err(|e| e.key(key))?;
        if !(tolerance > 0.0 && tolerance < 1.0) {
            return Err(Error::setting(
                key,
                "constraint_tolerance must lie between 0 and 1 (a relative error, e.g. 1e-8)",
            )
            .expected("a number in (0, 1)")
            .got(tolerance.to_string()));
        }
        Ok(Some(tolerance))
    }

    /// The hydrogen mass in the scene's mass unit (`3amu` or `3` in a real scene), positive.
    fn hydrogen_mass_of(
        &self,
        parameters: &BTreeMap<String, f64>,
        units: crate::units::Units,
    ) -> Result<Option<f64>> {
        let Some(value) = &self.hydrogen_mass else {
            return Ok(None);
        };
        let mass_units: &[(&str, f64)] = match units {
            crate::units::Units::Real => &[("amu", 1.0), ("Da", 1.0)],
            crate::units::Units::None => &[],
        };
        let key = "hydrogen_mass";
        let mass = value
            .evaluate_time(parameters, key, mass_units)
            .map_err(|e| e.key(key))?;
        if mass <= 0.0 {
            return Err(Error::setting(key, "hydrogen_mass must be positive")
                .expected("a positive mass")
                .got(mass.to_string()));
        }
        Ok(Some(mass))
    }

    /// The inner steps per outer step, from `inner_steps` or `dt` (not both).
    fn inner_steps_of(&self, h: f64, dt: Option<f64>) -> Result<Option<usize>> {
        Ok(match (self.inner_steps, dt) {
            (Some(_), Some(_)) => {
                return Err(Error::setting(
                    "inner_steps",
                    "give the inner step either as inner steps (--inner) or as dt (--dt), not both",
                ));
            }
            (Some(0), None) => {
                return Err(
                    Error::setting("inner_steps", "inner steps must be at least 1").expected("≥ 1"),
                );
            }
            (Some(k), None) => Some(k),
            (None, Some(dt)) => {
                Some(whole_ratio(h, dt, "inner step dt", "outer step h").map_err(|e| e.key("dt"))?)
            }
            (None, None) => None,
        })
    }

    /// The counts and factors that must be at least 1 (or positive).
    fn check_counts(&self) -> Result<()> {
        if let Some(blowup) = self.blowup
            && !(blowup.is_finite() && blowup > 0.0)
        {
            return Err(Error::setting("blowup", "blow-up factor must be positive")
                .expected("a positive number")
                .got(blowup.to_string()));
        }
        if let Some(steps) = &self.level_steps
            && steps.contains(&0)
        {
            return Err(Error::setting(
                "level_steps",
                "level_steps must all be at least 1",
            ));
        }
        if self.ratio == Some(0) {
            return Err(Error::setting("ratio", "ratio must be at least 1"));
        }
        if self.block == Some(0) {
            return Err(Error::setting("block", "block size R must be at least 1"));
        }
        if self.max_iter == Some(0) {
            return Err(Error::setting("max_iter", "max_iter must be at least 1"));
        }
        if self.thermostats == Some(0) {
            return Err(Error::setting(
                "thermostats",
                "thermostats (L, thermostat pairs per degree of freedom) must be at least 1",
            ));
        }
        Ok(())
    }

    /// The temperature in the scene's units (kelvin in real units), positive.
    fn temperature_of(
        &self,
        parameters: &BTreeMap<String, f64>,
        units: crate::units::Units,
    ) -> Result<Option<f64>> {
        Ok(match &self.temperature {
            Some(v) => {
                let kelvin = units.temperature_units();
                let key = "temperature";
                let t = v
                    .evaluate_time(parameters, key, kelvin)
                    .map_err(|e| e.key(key))?;
                let real = units == crate::units::Units::Real;
                let unit = if real { " K" } else { "" };
                if t <= 0.0 {
                    return Err(Error::setting(key, "temperature must be positive")
                        .expected("a positive temperature")
                        .got(format!("{t}{unit}")));
                }
                // A molecular force field holds to a few thousand kelvin; far above, start
                // velocities and the thermostat's noise tear the system apart at once.
                if real && (t.is_nan() || t > MAX_TEMPERATURE_K) {
                    return Err(Error::setting(
                        key,
                        format!(
                            "temperature beyond {MAX_TEMPERATURE_K} K: no molecular force \
                             field holds there"
                        ),
                    )
                    .expected(format!("a temperature up to {MAX_TEMPERATURE_K} K"))
                    .got(format!("{t:e}{unit}")));
                }
                Some(t)
            }
            None => None,
        })
    }
}

/// `numerator / denominator` as a whole number, or an error saying it is not one.
pub fn whole_ratio(numerator: f64, denominator: f64, small: &str, large: &str) -> Result<usize> {
    let ratio = numerator / denominator;
    let k = ratio.round();
    if k < 1.0 || (ratio - k).abs() > 1e-9 * ratio {
        return Err(Error::input(format!(
            "{small} = {denominator} does not divide the {large} = {numerator} (ratio \
             {ratio}); choose {small} = {large}/k for a whole number k"
        ))
        .expected(format!("{large}/k for a whole number k")));
    }
    Ok(k as usize)
}

/// Settings after evaluation: what a method is built from.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MethodSettings {
    pub method: String,
    /// Outer step.
    pub h: f64,
    /// Inner steps per outer step (from `inner_steps`, or `h / dt`).
    pub inner_steps: Option<usize>,
    pub t_end: Option<f64>,
    pub blowup: f64,
    pub level_steps: Option<Vec<usize>>,
    pub jacobian: Option<String>,
    pub quadrature: Option<String>,
    pub h_slow: Option<f64>,
    pub h_fast: Option<f64>,
    pub ratio: Option<usize>,
    pub adaptive: Option<f64>,
    pub control: Option<String>,
    pub h_min: Option<f64>,
    pub h_max: Option<f64>,
    pub block: Option<usize>,
    pub tol: Option<f64>,
    pub max_iter: Option<usize>,
    /// In the scene's temperature unit (K in a real scene; k_B T in a dimensionless one).
    pub temperature: Option<f64>,
    pub seed: Option<u64>,
    /// In inverse scene time units (1/fs in a real scene).
    pub friction: Option<f64>,
    pub thermostats: Option<usize>,
    pub tau: Option<f64>,
    /// Mollified slow force of a thermostatted r-RESPA method (an average's name).
    pub mollifier: Option<String>,
    pub molly_constraints: Option<String>,
    pub molly_jacobian: Option<String>,
    /// Constrained bonds.
    pub constraints: ConstraintSet,
    /// Rigid three-site water (SETTLE).
    pub rigid_water: bool,
    /// Relative SHAKE/RATTLE tolerance (`None`: the default, 1e-8).
    pub constraint_tolerance: Option<f64>,
    /// Hydrogen mass repartitioning, in the scene's mass unit (amu in a real scene).
    pub hydrogen_mass: Option<f64>,
    /// The scene's units, for `k_B` and for reports.
    pub units: crate::units::Units,
}

impl MethodSettings {
    /// `k_B T` in the scene's energy unit, when a temperature is given.
    pub fn kt(&self) -> Option<f64> {
        self.temperature.map(|t| t * self.units.boltzmann())
    }

    /// A bare setting for tests and studies: `method` with outer step `h`.
    pub fn new(method: &str, h: f64) -> Self {
        MethodSettings {
            method: method.to_string(),
            h,
            blowup: 10.0,
            ..Default::default()
        }
    }

    /// Whether the run holds constraints (bonds or rigid water).
    pub fn constrained(&self) -> bool {
        self.constraints != ConstraintSet::None || self.rigid_water
    }

    pub fn with_inner_steps(mut self, inner_steps: usize) -> Self {
        self.inner_steps = Some(inner_steps);
        self
    }

    /// The names of the method parameters that are given (`method_parameters!`'s order),
    /// for methods that report what they do not use. Temperature and seed are the run's
    /// (start velocities) as well as a method's, so they are never "ignored" by a method.
    pub fn given(&self) -> Vec<&'static str> {
        macro_rules! given {
            ($s:tt; $($field:ident: $kind:ident),* $(,)?) => {
                [$((stringify!($field), $s.$field.is_some())),*]
            };
        }
        let flags = method_parameters!(given, self);
        flags
            .into_iter()
            .filter_map(|(name, is_given)| is_given.then_some(name))
            .collect()
    }
}

/// The `[run]` values of one scene, each evaluated in its parameters (times in its units)
/// and checked; an error names the setting by its `[run]` key, a message by its name.
struct Values<'a> {
    parameters: &'a BTreeMap<String, f64>,
    units: crate::units::Units,
}

impl Values<'_> {
    fn number(&self, v: &Option<Value>, (key, what): (&str, &str)) -> Result<Option<f64>> {
        v.as_ref()
            .map(|v| v.evaluate(self.parameters, what).map_err(|e| e.key(key)))
            .transpose()
    }

    fn time(&self, v: &Option<Value>, (key, what): (&str, &str)) -> Result<Option<f64>> {
        v.as_ref()
            .map(|v| {
                v.evaluate_time(self.parameters, what, self.units.time_units())
                    .map_err(|e| e.key(key))
            })
            .transpose()
    }

    fn positive_time(&self, v: &Option<Value>, setting: (&str, &str)) -> Result<Option<f64>> {
        match self.time(v, setting)? {
            Some(x) if x <= 0.0 => Err(must_be_positive(x, setting)),
            other => Ok(other),
        }
    }

    fn positive(&self, v: &Option<Value>, setting: (&str, &str)) -> Result<Option<f64>> {
        match self.number(v, setting)? {
            Some(x) if x <= 0.0 => Err(must_be_positive(x, setting)),
            other => Ok(other),
        }
    }
}

fn must_be_positive(x: f64, (key, what): (&str, &str)) -> Error {
    Error::setting(key, format!("{what} must be positive and finite"))
        .expected("a positive number")
        .got(x.to_string())
}
