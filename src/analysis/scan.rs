//! Step-size safety scans: run each method at each outer step and classify the run.
//!
//! * **unstable** — the run blew up (non-finite energy, or |E − E₀| beyond the blow-up
//!   factor); the time is reported;
//! * **drifting** — it finished, but the energy drifts: the slope of a least-squares line
//!   through E(t), in units of kT per unit time per degree of freedom, exceeds the bound;
//! * **stable** — otherwise.
//!
//! kT is estimated from the mean kinetic energy by equipartition, `kT = 2⟨K⟩/n_dof`, so the
//! drift rate is `slope / (2⟨K⟩)` and needs no thermostat or temperature in the scene. For a
//! scene in femtoseconds, 0.05 kT/ns/dof (the criterion of the water-box comparisons) is
//! 5e-8 per fs.

use std::path::PathBuf;

use rayon::prelude::*;
use serde::Serialize;

use crate::error::{Error, Result};
use crate::integrators;
use crate::io::scene::load_scene;
use crate::io::summary::{RunSummary, Status};
use crate::run::{RunOptions, run};
use crate::settings::{RunSpec, Value};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Verdict {
    Stable,
    Drifting,
    Unstable,
}

impl Verdict {
    pub fn name(self) -> &'static str {
        match self {
            Verdict::Stable => "stable",
            Verdict::Drifting => "drifting",
            Verdict::Unstable => "unstable",
        }
    }

    pub fn parse(text: &str) -> Option<Self> {
        match text {
            "stable" => Some(Verdict::Stable),
            "drifting" => Some(Verdict::Drifting),
            "unstable" => Some(Verdict::Unstable),
            _ => None,
        }
    }
}

/// Energy drift in kT per unit time per degree of freedom, from `(t, kinetic, total)`
/// samples: the least-squares slope of E(t) divided by `2⟨K⟩`.
pub fn drift_rate(series: &[[f64; 3]]) -> f64 {
    let n = series.len() as f64;
    if series.len() < 2 {
        return 0.0;
    }
    let mean_t = series.iter().map(|s| s[0]).sum::<f64>() / n;
    let mean_e = series.iter().map(|s| s[2]).sum::<f64>() / n;
    let mean_k = series.iter().map(|s| s[1]).sum::<f64>() / n;
    let (mut covariance, mut variance) = (0.0, 0.0);
    for s in series {
        covariance += (s[0] - mean_t) * (s[2] - mean_e);
        variance += (s[0] - mean_t) * (s[0] - mean_t);
    }
    if variance == 0.0 || mean_k <= 0.0 {
        return 0.0;
    }
    (covariance / variance) / (2.0 * mean_k)
}

/// The verdict on a finished run and its drift rate.
pub fn classify(summary: &RunSummary, drift_bound: f64) -> (Verdict, f64) {
    let drift = summary.fit.as_ref().map_or(0.0, |d| d.true_rate());
    let verdict = match summary.status {
        Status::Unstable | Status::Failed => Verdict::Unstable,
        Status::Ok if drift.abs() > drift_bound => Verdict::Drifting,
        Status::Ok => Verdict::Stable,
    };
    (verdict, drift)
}

/// One (method, outer step) point of a scan and what its run gave.
#[derive(Clone, Debug, Serialize)]
pub struct StepResult {
    pub index: usize,
    pub method: String,
    pub h: f64,
    pub verdict: Verdict,
    pub drift: f64,
    /// When an unstable run stopped.
    pub blowup_time: Option<f64>,
    pub max_relative_error: f64,
    pub steps: u64,
    pub slow_evaluations: u64,
    pub fast_evaluations: u64,
    pub hessian_vector: u64,
    #[serde(skip)]
    pub wall_seconds: f64,
}

/// What a scan runs: the scene, its parameter overrides, the method settings shared by every
/// point (inner step, Jacobian, …), and the run length and criteria.
#[derive(Clone, Debug)]
pub struct ScanSetup {
    pub scene: PathBuf,
    pub set: Vec<String>,
    pub base: RunSpec,
    pub t_end: f64,
    pub drift_bound: f64,
    pub energy_every: usize,
}

/// A scan's points, method-major: index = method × (number of steps) + step index.
pub fn scan_points(methods: &[String], steps: &[f64]) -> Vec<(usize, String, f64)> {
    let mut points = Vec::new();
    for method in methods {
        for &h in steps {
            points.push((points.len(), method.clone(), h));
        }
    }
    points
}

/// Run one point.
pub fn run_point(setup: &ScanSetup, index: usize, method: &str, h: f64) -> Result<StepResult> {
    let mut scene = load_scene(&setup.scene, &setup.set)?;
    let mut spec = setup.base.clone();
    spec.method = Some(method.to_string());
    spec.h = Some(Value::Number(h));
    spec.t_end = Some(Value::Number(setup.t_end));
    let settings = scene
        .run
        .overridden_by(&spec)
        .resolve_with_units(&scene.parameters, scene.units)?;
    let mut integrator = integrators::build(&settings, &mut Vec::new())?;
    let options = RunOptions {
        t_end: setup.t_end,
        energy_every: setup.energy_every,
        blowup: settings.blowup,
        energy_csv: None,
        trajectory: None,
        ..Default::default()
    };
    let summary = run(
        &scene.name,
        &mut scene.system,
        integrator.as_mut(),
        &options,
    )
    .map_err(|e| Error::input(format!("{method} at h = {h}: {e}")))?;
    let (verdict, drift) = classify(&summary, setup.drift_bound);
    let counts = &summary.force_evaluations;
    Ok(StepResult {
        index,
        method: method.to_string(),
        h,
        verdict,
        drift,
        blowup_time: (verdict == Verdict::Unstable).then_some(summary.t_end),
        max_relative_error: summary.energy.max_relative_error,
        steps: summary.steps,
        slow_evaluations: counts.slow,
        fast_evaluations: counts.fast,
        hessian_vector: counts.hessian_vector,
        wall_seconds: summary.wall_seconds,
    })
}

/// Run the given points in parallel; `progress` is called once per finished point.
pub fn run_points(
    setup: &ScanSetup,
    points: &[(usize, String, f64)],
    progress: &(dyn Fn() + Sync),
) -> Result<Vec<StepResult>> {
    let mut results = points
        .par_iter()
        .map(|(index, method, h)| {
            let result = run_point(setup, *index, method, *h);
            progress();
            result
        })
        .collect::<Result<Vec<_>>>()?;
    results.sort_by_key(|r| r.index);
    Ok(results)
}

/// For one method: the largest scanned step below which every scanned step is stable, and
/// the stable steps beyond the first failure (islands between resonances).
#[derive(Clone, Debug, Serialize)]
pub struct SafeStep {
    pub method: String,
    pub safe_up_to: Option<f64>,
    pub first_failure: Option<(f64, Verdict)>,
    pub stable_beyond: Vec<f64>,
}

pub fn safe_steps(results: &[StepResult]) -> Vec<SafeStep> {
    let mut methods: Vec<&str> = Vec::new();
    for r in results {
        if !methods.contains(&r.method.as_str()) {
            methods.push(&r.method);
        }
    }
    methods
        .into_iter()
        .map(|method| {
            let mut rows: Vec<&StepResult> =
                results.iter().filter(|r| r.method == method).collect();
            rows.sort_by(|a, b| a.h.total_cmp(&b.h));
            let failure = rows.iter().position(|r| r.verdict != Verdict::Stable);
            let safe_up_to = match failure {
                Some(0) => None,
                Some(i) => Some(rows[i - 1].h),
                None => rows.last().map(|r| r.h),
            };
            SafeStep {
                method: method.to_string(),
                safe_up_to,
                first_failure: failure.map(|i| (rows[i].h, rows[i].verdict)),
                stable_beyond: failure
                    .map(|i| {
                        rows[i..]
                            .iter()
                            .filter(|r| r.verdict == Verdict::Stable)
                            .map(|r| r.h)
                            .collect()
                    })
                    .unwrap_or_default(),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn series(slope: f64, kinetic: f64) -> Vec<[f64; 3]> {
        (0..100)
            .map(|i| {
                let t = i as f64 * 0.1;
                // An oscillation on top of the drift: it must not bias the slope.
                [t, kinetic, 3.0 + slope * t + 0.01 * (7.0 * t).sin()]
            })
            .collect()
    }

    #[test]
    fn drift_is_the_fitted_slope_over_twice_the_kinetic_energy() {
        let rate = drift_rate(&series(0.2, 0.5));
        assert!((rate - 0.2).abs() < 5e-3, "{rate}");
        assert!(drift_rate(&series(0.0, 0.5)).abs() < 5e-3);
        assert_eq!(drift_rate(&series(0.2, 0.0)), 0.0);
    }

    fn result(method: &str, h: f64, verdict: Verdict) -> StepResult {
        StepResult {
            index: 0,
            method: method.into(),
            h,
            verdict,
            drift: 0.0,
            blowup_time: None,
            max_relative_error: 0.0,
            steps: 0,
            slow_evaluations: 0,
            fast_evaluations: 0,
            hessian_vector: 0,
            wall_seconds: 0.0,
        }
    }

    #[test]
    fn safe_step_stops_at_the_first_failure_and_lists_islands() {
        use Verdict::*;
        let results = vec![
            result("impulse", 3.0, Unstable),
            result("impulse", 1.0, Stable),
            result("impulse", 2.0, Drifting),
            result("impulse", 4.0, Stable),
            result("long-average", 1.0, Unstable),
            result("verlet", 1.0, Stable),
        ];
        let safe = safe_steps(&results);
        assert_eq!(safe[0].method, "impulse");
        assert_eq!(safe[0].safe_up_to, Some(1.0));
        assert_eq!(safe[0].first_failure, Some((2.0, Drifting)));
        assert_eq!(safe[0].stable_beyond, vec![4.0]);
        assert_eq!(safe[1].safe_up_to, None);
        assert_eq!(safe[2].safe_up_to, Some(1.0));
        assert!(safe[2].first_failure.is_none());
    }
}
