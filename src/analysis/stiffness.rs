//! Accuracy against stiffness (GSS98 section 4, Figures 11–13): the largest position error
//! of a method over a fixed time interval, for each value of a scene parameter (typically
//! the stiff spring's frequency Ω1), against a reference solution of the same scene.
//!
//! **The error.** The method runs `N = t_end / h` outer steps; after each, the Euclidean
//! norm of the difference of all position coordinates from the reference,
//! `‖q_n − q_ref(nh)‖₂`; the study reports the largest over n and when it occurred.
//!
//! **The reference.** Velocity Verlet on the same scene with every force at every step,
//! with the steps `τ = h/M`, `τ/2` and `τ/4`, combined by Richardson extrapolation. Verlet
//! is symmetric, so its global error expands in even powers of τ: `R(a, b) = (4 q_b − q_a)/3`
//! of two runs with steps in ratio 2 removes the τ² term. The reference is
//! `R(τ/2, τ/4)`, fourth-order, and `reference_error = max ‖R(τ, τ/2) − R(τ/2, τ/4)‖ / 15`
//! its estimated error (the τ⁴ terms of the two differ by a factor 16). The command warns
//! when it is not small beside the measured errors.
//!
//! **Default steps.** Unless given, `M` (reference steps per outer step) and the method's
//! inner step count `K` are both `max(100, ⌈h ω_max / 0.05⌉)`, ω_max the fastest normal mode
//! of the fast forces over all the scanned values (at the starting geometry): the inner
//! Verlet then resolves every fast oscillation with `dt·ω ≤ 0.05`. For GSS98's two-spring
//! scene with Ω1 ≤ 32 at h = 1/2 that is M = K = 320; the reference's estimated error is
//! then below 1e-7 everywhere (`tests/stiffness.rs`), against measured errors of 1e-3 and
//! more.

use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::analysis::modes::fast_modes;
use crate::error::{Error, Result};
use crate::integrators::METHODS;
use crate::io::scene::{SceneFile, build_parsed_scene, parse_scene};
use crate::run::prepare::{study_integrator, study_integrator_on};
use crate::settings::{MethodSettings, RunSpec, Value};
use crate::system::System;

/// The largest `dt · ω_max` the default inner and reference steps allow.
pub const DEFAULT_STEP_PHASE: f64 = 0.05;
/// The fewest default inner / reference steps per outer step.
pub const MIN_DEFAULT_SUBSTEPS: usize = 100;
/// The most default inner / reference steps per outer step.
pub const MAX_DEFAULT_SUBSTEPS: usize = 10_000_000;

/// What a stiffness study computes: every method at every outer step for every value.
pub struct StiffnessStudy {
    text: String,
    path: PathBuf,
    parsed: SceneFile,
    /// `--set` overrides applied before the scanned parameter.
    pub set: Vec<String>,
    /// The scanned scene parameter.
    pub param: String,
    pub values: Vec<f64>,
    pub methods: Vec<String>,
    /// Outer steps h.
    pub steps: Vec<f64>,
    /// Method settings shared by every point (inner step, Jacobian).
    pub base: RunSpec,
    pub t_end: f64,
    /// The fastest fast-mode frequency over the scanned values.
    pub omega_max: f64,
    reference_steps: Option<usize>,
}

/// One unit of work: one outer step and one parameter value, every method.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Unit {
    /// Position in the study: `step_index × values + value_index`.
    pub unit: usize,
    pub step_index: usize,
    pub value_index: usize,
}

/// The error of one method at one outer step and one parameter value.
#[derive(Clone, Debug, Serialize)]
pub struct StiffnessPoint {
    /// `unit × methods + method index`: the row order of the CSV.
    pub index: usize,
    pub method: String,
    pub h: f64,
    pub value: f64,
    /// `max_n ‖q_n − q_ref(nh)‖₂` (infinite when the run overflowed).
    pub max_error: f64,
    /// When the largest error occurred.
    pub error_time: f64,
    /// Estimated error of the reference (see the module documentation).
    pub reference_error: f64,
    /// The method's inner steps per outer step (0 for a single-step method).
    pub inner_steps: usize,
    /// Reference Verlet steps per outer step (M; the extrapolation also uses 2M and 4M).
    pub reference_steps: usize,
    /// `ok`, `unstable` (non-finite state) or `failed` (the method stopped).
    pub status: &'static str,
}

impl StiffnessStudy {
    /// Check everything that can be checked before any run: the scene, the parameter, the
    /// steps (t_end must be a whole number of every h), every method at every h.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        scene: &Path,
        set: Vec<String>,
        param: &str,
        values: Vec<f64>,
        methods: Vec<String>,
        steps: Vec<f64>,
        base: RunSpec,
        t_end: f64,
        reference_steps: Option<usize>,
    ) -> Result<Self> {
        let text = std::fs::read_to_string(scene).map_err(|e| Error::io(scene, e))?;
        let parsed = parse_scene(&text, scene)?;
        check_param(&parsed, param, scene)?;
        check_scan(&values, &methods, &steps, t_end, reference_steps)?;
        let mut study = StiffnessStudy {
            text,
            path: scene.to_path_buf(),
            parsed,
            set,
            param: param.to_string(),
            values,
            methods,
            steps,
            base,
            t_end,
            omega_max: 0.0,
            reference_steps,
        };
        study.omega_max = study.fastest_frequency()?;
        study.check_default_steps()?;
        study.check_methods()?;
        Ok(study)
    }

    /// Builds every value once: the scene must build, and the default steps need the
    /// fastest frequency over the scan.
    fn fastest_frequency(&self) -> Result<f64> {
        let mut omega_max = 0.0_f64;
        for &value in &self.values {
            let mut system = self.system(value)?;
            let fastest = fast_modes(&mut system)
                .iter()
                .map(|m| m.frequency)
                .fold(0.0, f64::max);
            omega_max = omega_max.max(fastest);
        }
        Ok(omega_max)
    }

    /// Refuses an outer step whose default inner or reference steps would be too many.
    fn check_default_steps(&self) -> Result<()> {
        for &h in &self.steps {
            let needed = h * self.omega_max / DEFAULT_STEP_PHASE;
            let defaulted = self.reference_steps.is_none()
                || (self.base.inner_steps.is_none() && self.base.dt.is_none());
            if defaulted && (needed > MAX_DEFAULT_SUBSTEPS as f64 || needed.is_nan()) {
                return Err(Error::flag(
                    "--h",
                    format!(
                        "--h {h}: the fastest fast mode over the scan (ω = {:e}) would need more \
                     than {MAX_DEFAULT_SUBSTEPS} default inner or reference steps per outer \
                     step; give --inner (or --dt) and --reference-steps",
                        self.omega_max
                    ),
                )
                .expected("--inner (or --dt) and --reference-steps")
                .got_named(h.to_string()));
            }
        }
        Ok(())
    }

    /// Every method must build at every outer step (at the first value).
    fn check_methods(&self) -> Result<()> {
        let first = self.values[0];
        for method in &self.methods {
            for &h in &self.steps {
                let settings = self.settings(method, h, first)?;
                study_integrator(&settings, &mut Vec::new())
                    .map_err(|e| e.context(&format!("--method {method} at h = {h}")))?;
            }
        }
        Ok(())
    }

    /// `parameter=value` after the `--set` overrides.
    fn overrides(&self, value: f64) -> Vec<String> {
        let mut overrides = self.set.clone();
        overrides.push(format!("{}={value:e}", self.param));
        overrides
    }

    fn system(&self, value: f64) -> Result<System> {
        Ok(
            build_parsed_scene(&self.parsed, &self.text, &self.path, &self.overrides(value))?
                .system,
        )
    }

    /// The default count of inner and reference steps per outer step h.
    pub fn default_substeps(&self, h: f64) -> usize {
        // At most MAX_DEFAULT_SUBSTEPS: `new` refuses a scan that would need more.
        let needed = (h * self.omega_max / DEFAULT_STEP_PHASE)
            .ceil()
            .min(MAX_DEFAULT_SUBSTEPS as f64);
        (needed as usize).max(MIN_DEFAULT_SUBSTEPS)
    }

    /// Reference Verlet steps per outer step h.
    pub fn reference_steps(&self, h: f64) -> usize {
        self.reference_steps
            .unwrap_or_else(|| self.default_substeps(h))
    }

    /// The method's settings at h: the scene's `[run]` table, the shared flags, and the
    /// default inner step when a method that needs one is given none.
    pub fn settings(&self, method: &str, h: f64, value: f64) -> Result<MethodSettings> {
        let scene =
            build_parsed_scene(&self.parsed, &self.text, &self.path, &self.overrides(value))?;
        let mut spec = self.base.clone();
        spec.method = Some(method.to_string());
        spec.h = Some(Value::Number(h));
        spec.t_end = Some(Value::Number(self.t_end));
        let mut settings = scene
            .run
            .overridden_by(&spec)
            .resolve_with_units(&scene.parameters, scene.units)?;
        let uses_inner = METHODS
            .iter()
            .any(|m| m.name == method && m.uses.contains(&"inner_steps"));
        if uses_inner && settings.inner_steps.is_none() && settings.level_steps.is_none() {
            settings.inner_steps = Some(self.default_substeps(h));
        }
        Ok(settings)
    }

    /// The work units (outer step × value), in order.
    pub fn units(&self) -> Vec<Unit> {
        let n = self.values.len();
        (0..self.steps.len() * n)
            .map(|unit| Unit {
                unit,
                step_index: unit / n,
                value_index: unit % n,
            })
            .collect()
    }

    /// Rows of the whole study (units × methods).
    pub fn total_points(&self) -> usize {
        self.steps.len() * self.values.len() * self.methods.len()
    }

    /// The reference positions at t = 0, h, …, N h for one value, and their estimated error.
    pub fn reference(&self, h: f64, value: f64) -> Result<(Vec<Vec<f64>>, f64)> {
        let n = outer_steps(self.t_end, h)?;
        let m = self.reference_steps(h);
        let runs = [
            self.verlet_samples(h, m, n, value)?,
            self.verlet_samples(h, 2 * m, n, value)?,
            self.verlet_samples(h, 4 * m, n, value)?,
        ];
        let mut error = 0.0_f64;
        let mut samples = Vec::with_capacity(n + 1);
        for ((coarse, middle), fine) in runs[0].iter().zip(&runs[1]).zip(&runs[2]) {
            let extrapolate = |c: &[f64], f: &[f64]| -> Vec<f64> {
                c.iter().zip(f).map(|(c, f)| (4.0 * f - c) / 3.0).collect()
            };
            let first = extrapolate(coarse, middle);
            let second = extrapolate(middle, fine);
            error = error.max(distance(&first, &second) / 15.0);
            samples.push(second);
        }
        Ok((samples, error))
    }

    /// Verlet with step h/substeps, positions after every `substeps` steps.
    fn verlet_samples(
        &self,
        h: f64,
        substeps: usize,
        n: usize,
        value: f64,
    ) -> Result<Vec<Vec<f64>>> {
        let mut system = self.system(value)?;
        let verlet_settings = MethodSettings::new("verlet", h / substeps as f64);
        let mut verlet = study_integrator_on(&verlet_settings, &mut system)?;
        let mut samples = Vec::with_capacity(n + 1);
        samples.push(system.state.q.clone());
        for _ in 0..n {
            for _ in 0..substeps {
                verlet
                    .step(&mut system)
                    .map_err(|f| Error::input(format!("reference Verlet failed: {}", f.0)))?;
            }
            samples.push(system.state.q.clone());
        }
        Ok(samples)
    }

    /// Every method at one unit, in method order.
    pub fn evaluate(&self, unit: Unit) -> Result<Vec<StiffnessPoint>> {
        let h = self.steps[unit.step_index];
        let value = self.values[unit.value_index];
        let (reference, reference_error) = self.reference(h, value)?;
        let mut points = Vec::with_capacity(self.methods.len());
        for (k, method) in self.methods.iter().enumerate() {
            let settings = self.settings(method, h, value)?;
            let mut system = self.system(value)?;
            let mut integrator = study_integrator_on(&settings, &mut system)?;
            let (mut max_error, mut error_time) = (0.0_f64, 0.0);
            let mut status = "ok";
            for (step, sample) in reference.iter().enumerate().skip(1) {
                if integrator.step(&mut system).is_err() {
                    status = "failed";
                    max_error = f64::INFINITY;
                    error_time = step as f64 * h;
                    break;
                }
                let error = distance(&system.state.q, sample);
                if !error.is_finite() {
                    status = "unstable";
                    max_error = f64::INFINITY;
                    error_time = step as f64 * h;
                    break;
                }
                if error > max_error {
                    max_error = error;
                    error_time = step as f64 * h;
                }
            }
            points.push(StiffnessPoint {
                index: unit.unit * self.methods.len() + k,
                method: method.clone(),
                h,
                value,
                max_error,
                error_time,
                reference_error,
                inner_steps: settings.inner_steps.unwrap_or(0),
                reference_steps: self.reference_steps(h),
                status,
            });
        }
        Ok(points)
    }
}

/// `t_end / h` when it is a whole number (to 1e-9 relative), else an error naming both.
pub fn outer_steps(t_end: f64, h: f64) -> Result<usize> {
    let ratio = t_end / h;
    let n = ratio.round();
    if n < 1.0 || (ratio - n).abs() > 1e-9 * ratio {
        return Err(Error::flag(
            "--t-end",
            format!("--t-end {t_end} is not a whole number of outer steps --h {h} (ratio {ratio})"),
        )
        .expected("a whole number of outer steps --h")
        .got_named(t_end.to_string()));
    }
    // The reference keeps the positions at every outer step.
    if n > MAX_OUTER_STEPS as f64 {
        return Err(Error::flag(
            "--t-end",
            format!(
                "--t-end {t_end} / --h {h} is {n} outer steps, more than the {MAX_OUTER_STEPS} a \
             stiffness study keeps"
            ),
        )
        .expected(format!("at most {MAX_OUTER_STEPS} outer steps"))
        .got_named(t_end.to_string()));
    }
    Ok(n as usize)
}

/// Most outer steps per run of a stiffness study.
pub const MAX_OUTER_STEPS: usize = 10_000_000;

/// Euclidean distance of two coordinate arrays.
fn distance(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt()
}

/// Index and value of the largest finite `max_error` among `points`.
pub fn largest(points: &[&StiffnessPoint]) -> Option<(f64, f64)> {
    points
        .iter()
        .filter(|p| p.max_error.is_finite())
        .max_by(|a, b| a.max_error.total_cmp(&b.max_error))
        .map(|p| (p.value, p.max_error))
}

/// The scanned parameter must be one of the scene's.
fn check_param(parsed: &SceneFile, param: &str, scene: &Path) -> Result<()> {
    if !parsed.parameters.contains_key(param) {
        let known: Vec<&str> = parsed.parameters.keys().map(String::as_str).collect();
        let known = if known.is_empty() {
            "none".to_string()
        } else {
            known.join(", ")
        };
        return Err(Error::flag(
            "--param",
            format!(
                "--param {param}: the scene {} has no parameter \"{param}\" (it has: {known})",
                scene.display()
            ),
        )
        .expected(format!("a parameter of the scene: {known}"))
        .got_named(param));
    }
    Ok(())
}

/// The scan's values, methods, outer steps (each a whole number of `t_end`) and
/// reference steps, checked in that order.
fn check_scan(
    values: &[f64],
    methods: &[String],
    steps: &[f64],
    t_end: f64,
    reference_steps: Option<usize>,
) -> Result<()> {
    if values.is_empty() || values.iter().any(|v| !v.is_finite()) {
        return Err(
            Error::flag("--range", "--range must give finite values").expected("finite values")
        );
    }
    if methods.is_empty() {
        return Err(
            Error::flag("--method", "--method: give at least one method")
                .expected("at least one method"),
        );
    }
    if !(t_end.is_finite() && t_end > 0.0) {
        return Err(Error::flag("--t-end", "--t-end must be positive")
            .expected("a positive time")
            .got(t_end.to_string()));
    }
    for &h in steps {
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::flag("--h", "--h must be positive")
                .expected("a positive step")
                .got(h.to_string()));
        }
        outer_steps(t_end, h)?;
    }
    if steps.is_empty() {
        return Err(Error::flag("--h", "--h: give at least one outer step")
            .expected("at least one outer step"));
    }
    if reference_steps == Some(0) {
        return Err(
            Error::flag("--reference-steps", "--reference-steps must be at least 1")
                .expected("at least 1")
                .got("0"),
        );
    }
    Ok(())
}
