//! Work–precision: error against cost for methods and outer steps on one scene.
//!
//! *Error* is the largest position error at the sample times `Δ, 2Δ, … ≤ t_end` against a
//! reference solution (the same scene integrated by a much finer run of a chosen method,
//! computed once and cached on disk), and the largest relative energy error.
//! A method whose steps do not land on the sample times (adaptive methods) is evaluated by
//! cubic Hermite interpolation of its own trajectory (positions and velocities `M⁻¹p`),
//! whose error O(Δt⁴) is far below the method's own.
//!
//! *Cost* is counted three ways: slow-force evaluations (what MTS methods save), all force
//! evaluations weighted by their measured relative cost (fast, slow, Hessian-vector
//! products; the weights are timed once per scene), and wall time.

use std::path::Path;
use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;

use crate::error::{Error, Result};
use crate::integrators::Integrator;
use crate::io::csv::CsvWriter;
use crate::io::scene::{Scene, SceneFlags};
use crate::run::monitor::EnergyMonitor;
use crate::run::prepare::{RunRequest, prepare};
use crate::settings::{RunSpec, Value};
use crate::system::System;

/// What a work–precision study runs.
#[derive(Clone, Debug)]
pub struct StudySetup {
    pub scene: std::path::PathBuf,
    pub set: Vec<String>,
    /// A topology's coordinates, `--coulomb`, the PME flags, … ([`SceneFlags`]).
    pub flags: SceneFlags,
    /// Start every run from the positions of this structure file (`--start`).
    pub start: Option<std::path::PathBuf>,
    /// Settings shared by every run (inner steps, Jacobian, …).
    pub base: RunSpec,
    pub t_end: f64,
    /// Sample interval Δ of the position error.
    pub sample: f64,
    pub blowup: f64,
}

/// Positions at the sample times.
#[derive(Clone, Debug, PartialEq)]
pub struct Samples {
    pub times: Vec<f64>,
    pub positions: Vec<Vec<f64>>,
}

/// One run's outcome.
#[derive(Clone, Debug, Serialize)]
pub struct PrecisionResult {
    pub index: usize,
    pub method: String,
    pub h: f64,
    /// `ok`, `unstable` or `failed`.
    pub status: String,
    pub max_position_error: f64,
    pub max_relative_energy_error: f64,
    pub slow_evaluations: u64,
    pub fast_evaluations: u64,
    pub hessian_vector: u64,
    /// `fast·w_fast + slow·w_slow + hv·w_hv` in units of one slow evaluation.
    pub weighted_evaluations: f64,
    #[serde(skip)]
    pub wall_seconds: f64,
}

/// Relative cost of one fast gradient, one slow gradient and one fast Hessian-vector product,
/// in units of one slow gradient (median of repeated timings on the scene's start).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct CostWeights {
    pub fast: f64,
    pub slow: f64,
    pub hessian_vector: f64,
}

pub fn measure_cost_weights(system: &mut System) -> CostWeights {
    let q = system.state.q.clone();
    let n = q.len();
    let v: Vec<f64> = (0..n).map(|k| ((k * 37) % 11) as f64 - 5.0).collect();
    let mut out = vec![0.0; n];
    let top = system.forces.n_levels() - 1;
    let mut time = |f: &mut dyn FnMut(&mut System, &mut [f64])| -> f64 {
        let mut samples: Vec<f64> = (0..15)
            .map(|_| {
                let start = Instant::now();
                for _ in 0..20 {
                    f(system, &mut out);
                }
                start.elapsed().as_secs_f64() / 20.0
            })
            .collect();
        samples.sort_by(f64::total_cmp);
        samples[samples.len() / 2]
    };
    let fast = time(&mut |s, o| s.forces.gradient(0, &q, o));
    let slow = time(&mut |s, o| s.forces.gradient(top, &q, o));
    let hessian_vector = time(&mut |s, o| s.forces.hessian_vector(0, &q, &v, o));
    system.forces.reset_counts();
    let unit = if slow > 0.0 {
        slow
    } else {
        fast.max(f64::MIN_POSITIVE)
    };
    CostWeights {
        fast: fast / unit,
        slow: slow / unit,
        hessian_vector: hessian_vector / unit,
    }
}

/// Sample times `Δ, 2Δ, …` up to `t_end` (within round-off).
pub fn sample_times(sample: f64, t_end: f64) -> Vec<f64> {
    let count = (t_end / sample + 1e-9).floor() as usize;
    (1..=count).map(|i| i as f64 * sample).collect()
}

/// Integrate `method` with outer step `h` and collect positions at the sample times.
/// Returns the samples (as far as the run got), the run's status, its max relative energy
/// error, counts and wall time.
fn integrate_sampled(
    setup: &StudySetup,
    method: &str,
    h: f64,
) -> Result<(Samples, String, f64, [u64; 3], f64)> {
    let (mut scene, mut integrator) = scene_and_integrator(setup, method, h)?;
    let system = &mut scene.system;
    system.forces.reset_counts();
    integrator.setup(system)?;
    let times = sample_times(setup.sample, setup.t_end);
    let mut samples = Samples {
        times: Vec::with_capacity(times.len()),
        positions: Vec::with_capacity(times.len()),
    };
    let mut monitor = EnergyMonitor::new(
        system.kinetic_energy(),
        &system.potential_energies(),
        setup.blowup,
    );
    // The last two step points (t, q, M⁻¹p), reused every step.
    let n = system.n_dofs();
    let mut previous = (0.0, vec![0.0; n], vec![0.0; n]);
    let mut current = previous.clone();
    point(system, &mut previous);
    let mut next = 0;
    let mut status = "ok".to_string();
    let started = Instant::now();
    let end = setup.t_end - 1e-9 * h;
    while next < times.len() && system.state.t < end + 1e-9 * h {
        if let Err(failure) = integrator.step(system) {
            status = format!("failed: {}", failure.0);
            break;
        }
        if integrator.fixed_step() {
            // Rounding of t += h must not move a sample to the next step.
            let n = ((system.state.t - previous.0) / h).round();
            system.state.t = previous.0 + n * h;
        }
        if let Err(reason) = monitor.record(system.total_energy()) {
            status = format!("unstable: {reason}");
            break;
        }
        point(system, &mut current);
        while next < times.len() && times[next] <= current.0 + 1e-9 * h {
            samples.times.push(times[next]);
            samples
                .positions
                .push(hermite(&previous, &current, times[next]));
            next += 1;
        }
        std::mem::swap(&mut previous, &mut current);
    }
    let wall = started.elapsed().as_secs_f64();
    Ok((
        samples,
        status,
        monitor.max_relative_error(),
        evaluation_counts(system),
        wall,
    ))
}

/// The scene of the study and `method` at outer step `h` on it (the study's run settings
/// overridden), prepared as `longstep run` prepares a run.
fn scene_and_integrator(
    setup: &StudySetup,
    method: &str,
    h: f64,
) -> Result<(Scene, Box<dyn Integrator>)> {
    let mut spec = setup.base.clone();
    spec.method = Some(method.to_string());
    spec.h = Some(Value::Number(h));
    let prepared = prepare(&RunRequest {
        flags: setup.flags.clone(),
        start: setup.start.as_deref(),
        ..RunRequest::new(&setup.scene, &setup.set, &spec)
    })?;
    Ok((prepared.scene, prepared.integrator))
}

/// The step point `(t, q, M⁻¹p)` of `s` into `into` (no allocation).
fn point(s: &System, into: &mut (f64, Vec<f64>, Vec<f64>)) {
    into.0 = s.state.t;
    into.1.copy_from_slice(&s.state.q);
    for ((v, p), w) in into.2.iter_mut().zip(&s.state.p).zip(&s.inverse_mass) {
        *v = p * w;
    }
}

/// Gradient evaluations of the first and the last level, and Hessian-vector products.
fn evaluation_counts(system: &System) -> [u64; 3] {
    let counts = system.forces.counts();
    let hv: u64 = counts.hessian_vector_total();
    [
        counts.gradient.first().copied().unwrap_or(0),
        counts.gradient.last().copied().unwrap_or(0),
        hv,
    ]
}

/// Cubic Hermite interpolation between `(t0, q0, v0)` and `(t1, q1, v1)` at `t`.
fn hermite(a: &(f64, Vec<f64>, Vec<f64>), b: &(f64, Vec<f64>, Vec<f64>), t: f64) -> Vec<f64> {
    let span = b.0 - a.0;
    if span <= 0.0 || (t - b.0).abs() <= 1e-12 * span.max(1.0) {
        return b.1.clone();
    }
    let s = (t - a.0) / span;
    let (h00, h10, h01, h11) = (
        2.0 * s * s * s - 3.0 * s * s + 1.0,
        s * s * s - 2.0 * s * s + s,
        -2.0 * s * s * s + 3.0 * s * s,
        s * s * s - s * s,
    );
    (0..a.1.len())
        .map(|k| h00 * a.1[k] + h10 * span * a.2[k] + h01 * b.1[k] + h11 * span * b.2[k])
        .collect()
}

/// The samples cached in `cache` if its first line is `key`: rows of the time and the
/// positions; a row that does not read as numbers is left out (the caller then finds too
/// few samples and runs the reference again).
fn read_cached(cache: &Path, key: &str) -> Option<Samples> {
    let text = std::fs::read_to_string(cache).ok()?;
    let (first, rows) = text.split_once('\n')?;
    if first != key {
        return None;
    }
    let mut samples = Samples {
        times: Vec::new(),
        positions: Vec::new(),
    };
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .from_reader(rows.as_bytes());
    for record in reader.records().flatten() {
        let values: std::result::Result<Vec<f64>, _> =
            record.iter().map(str::parse::<f64>).collect();
        if let Ok(values) = values
            && values.len() > 1
        {
            samples.times.push(values[0]);
            samples.positions.push(values[1..].to_vec());
        }
    }
    Some(samples)
}

/// The reference solution: `method` at step `h`, cached in `cache` (a CSV of the sample
/// times and positions, whose first line records what produced it).
pub fn reference(setup: &StudySetup, method: &str, h: f64, cache: &Path) -> Result<Samples> {
    let key = format!(
        "# reference scene={} set={:?} method={method} h={h} t_end={} sample={} base={:?}",
        setup.scene.display(),
        setup.set,
        setup.t_end,
        setup.sample,
        setup.base
    );
    if let Some(samples) = read_cached(cache, &key)
        && samples.times.len() == sample_times(setup.sample, setup.t_end).len()
    {
        return Ok(samples);
    }
    let (samples, status, ..) = integrate_sampled(setup, method, h)?;
    if status != "ok" {
        return Err(Error::input(format!(
            "the reference run ({method}, h = {h}) did not finish: {status}"
        )));
    }
    let mut out = CsvWriter::headerless(cache, Some(&key))?;
    for (t, q) in samples.times.iter().zip(&samples.positions) {
        out.record(std::iter::once(t).chain(q).map(f64::to_string))?;
    }
    out.flush()?;
    Ok(samples)
}

/// Run the given (index, method, h) points against `reference`.
pub fn run_points(
    setup: &StudySetup,
    points: &[(usize, String, f64)],
    reference: &Samples,
    weights: CostWeights,
    progress: &(dyn Fn() + Sync),
) -> Result<Vec<PrecisionResult>> {
    let mut results = points
        .par_iter()
        .map(|(index, method, h)| {
            let (samples, status, energy_error, counts, wall) =
                integrate_sampled(setup, method, *h)?;
            progress();
            let mut error: f64 = 0.0;
            for (q, q_ref) in samples.positions.iter().zip(&reference.positions) {
                for (a, b) in q.iter().zip(q_ref) {
                    error = error.max((a - b).abs());
                }
            }
            let status = status.split(':').next().unwrap_or("failed").to_string();
            if status != "ok" {
                // The error is that of the part that ran; the status marks the point.
                error = if error.is_finite() {
                    error
                } else {
                    f64::INFINITY
                };
            }
            Ok(PrecisionResult {
                index: *index,
                method: method.clone(),
                h: *h,
                status,
                max_position_error: error,
                max_relative_energy_error: energy_error,
                slow_evaluations: counts[1],
                fast_evaluations: counts[0],
                hessian_vector: counts[2],
                weighted_evaluations: counts[0] as f64 * weights.fast
                    + counts[1] as f64 * weights.slow
                    + counts[2] as f64 * weights.hessian_vector,
                wall_seconds: wall,
            })
        })
        .collect::<Result<Vec<_>>>()?;
    results.sort_by_key(|r| r.index);
    Ok(results)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hermite_is_exact_for_cubics() {
        let f = |t: f64| 1.0 + 2.0 * t - t * t + 0.5 * t * t * t;
        let df = |t: f64| 2.0 - 2.0 * t + 1.5 * t * t;
        let a = (0.3, vec![f(0.3)], vec![df(0.3)]);
        let b = (1.1, vec![f(1.1)], vec![df(1.1)]);
        for t in [0.3, 0.5, 0.77, 1.1] {
            assert!((hermite(&a, &b, t)[0] - f(t)).abs() < 1e-14);
        }
    }

    #[test]
    fn sample_times_reach_the_end_despite_round_off() {
        assert_eq!(sample_times(0.1, 0.3).len(), 3);
        assert_eq!(sample_times(0.5, 8.0).len(), 16);
    }
}
