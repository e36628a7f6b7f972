//! Step-size safety scans: run each method at each outer step and judge the run by a
//! criterion ([`super::criterion`]): unstable, or pass, fail or undecided by the drift of an
//! NVE run or by what a thermostatted run samples.
//!
//! With `until_decided` > 1 ([`ScanSetup::until_decided`]) an undecided point is run again
//! at twice the length, and again, up to that factor of its length.
//!
//! With `starts` = N > 1 ([`ScanSetup::starts`], `--starts`) each point runs N independent
//! starts, Maxwell–Boltzmann velocities at the run's temperature with seeds `s, s+1, …,
//! s+N−1` (`s` the point's seed, else the default one), judged together
//! ([`super::criterion::drift::combine_starts`]); `until_decided` extends every start. The
//! starts of every point run in parallel, and are combined in seed order: the same result
//! at any thread count. Cost: N runs a point.
//!
//! The timings behind ns/day ([`time_point`]) are medians of repeated runs at one thread
//! count, taken apart from the scan: the scan's own table holds only what is the same bit
//! for bit on every machine.

use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::Serialize;

use super::criterion::Verdict;
use super::criterion::drift::{ScanDrift, classify, combined_drift};
use super::criterion::sampling::{Comparison, SamplingCriterion, point_dir};
use crate::analysis::run_analysis::RunAnalysis;
use crate::error::{Error, Result};
use crate::io::manifest::RunManifest;
use crate::io::scene::{Scene, SceneFlags};
use crate::io::summary::{RunSummary, Status, format_time};
use crate::run::prepare::{RunRequest, prepare};
use crate::run::verdict;
use crate::run::{RunOptions, TrajectoryOptions, is_stochastic};
use crate::settings::{MethodSettings, RunSpec, Value, whole_ratio};
use crate::system::velocities::DEFAULT_SEED;
use crate::units::Units;

pub use crate::io::study_file::MAX_STARTS;

/// One (method, outer step) point of a scan and what its run gave.
#[derive(Clone, Debug, Serialize)]
pub struct StepResult {
    pub index: usize,
    /// The label of the point's configuration in a study (`scan steps --study`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub config: Option<String>,
    pub method: String,
    pub h: f64,
    pub verdict: Verdict,
    /// The judged energy's drift (0 when the run had too few rows to fit one).
    pub drift: f64,
    /// The true energy's drift, and the energy judged (`total` or the method's conserved
    /// energy); `None` for a point judged by sampling.
    pub drift_detail: Option<ScanDrift>,
    /// When an unstable run stopped.
    pub blowup_time: Option<f64>,
    /// The run length (scene time unit) that would decide an undecided point, when one
    /// would ([`crate::run::verdict`]).
    pub decide_at: Option<f64>,
    /// The run length of the point's verdict (longer than the scan's `t_end` when
    /// `until_decided` extended it).
    pub t_end: f64,
    pub max_relative_error: f64,
    pub steps: u64,
    pub slow_evaluations: u64,
    pub fast_evaluations: u64,
    pub hessian_vector: u64,
    /// The independent starts the point's verdict combines (1 without `--starts`); the
    /// counts and `steps` above are one start's, `max_relative_error` the largest of any.
    pub starts: usize,
    /// The sampling criterion's comparison, when a point is judged by it.
    pub sampling: Option<Comparison>,
    #[serde(skip)]
    pub wall_seconds: f64,
}

/// What a scan runs: the scene, its parameter overrides, the method settings shared by every
/// point (inner step, Jacobian, temperature, …), and the run length and criteria.
#[derive(Clone, Debug, Default)]
pub struct ScanSetup {
    pub scene: PathBuf,
    pub set: Vec<String>,
    pub base: RunSpec,
    pub t_end: f64,
    /// In the scan's drift unit (see the module documentation).
    pub drift_bound: f64,
    pub energy_every: usize,
    /// Fit the drift from this time on (skipping a re-equilibration window).
    pub fit_from: Option<f64>,
    /// The steps of the inner levels, outermost first, held fixed while `h` varies: each
    /// point's `level_steps` are `h/T1, T1/T2, …` (empty: the base's `level_steps`).
    pub level_dts: Vec<f64>,
    /// A topology's coordinates, `--coulomb`, the PME flags, … ([`SceneFlags`]).
    pub flags: SceneFlags,
    /// Start every point from the positions of this structure file (`--start`).
    pub start: Option<PathBuf>,
    /// `--precision` of the terms that have the choice (`None`: double).
    pub precision: Option<String>,
    /// Run an undecided point again at twice the length, and again, up to this factor of
    /// `t_end` (≤ 1: never; [`until_decided`]).
    pub until_decided: f64,
    /// The degrees of freedom of the sampling criterion's kinetic temperature when the
    /// model has constraints (`None`: `3N`; [`constrained_dof`]).
    pub kinetic_dof: Option<f64>,
    /// Independent starts per point of the drift criterion (module documentation; 0 and 1
    /// are one start; at most [`MAX_STARTS`], [`check_starts`]).
    pub starts: usize,
}

impl ScanSetup {
    /// The request of a point with `spec` as its command-line settings.
    pub fn request<'a>(&'a self, spec: &'a RunSpec) -> RunRequest<'a> {
        RunRequest {
            flags: self.flags.clone(),
            start: self.start.as_deref(),
            precision: self.precision.as_deref(),
            ..RunRequest::new(&self.scene, &self.set, spec)
        }
    }

    /// The scene with `--set` values, the electrostatics overrides and `--start`.
    pub fn load_scene(&self) -> Result<Scene> {
        crate::run::prepare::load(&self.request(&RunSpec::default()))
    }
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

/// What one run of a point writes: nothing (drift scans and timings), or `energy.csv` and a
/// trajectory frame every `frame_every` steps into `dir` (the sampling criterion).
#[derive(Clone, Debug, Default)]
pub struct PointOutputs<'a> {
    pub dir: Option<&'a Path>,
    pub frame_every: usize,
}

/// The settings of one point.
pub fn point_settings(setup: &ScanSetup, method: &str, h: f64) -> Result<MethodSettings> {
    let scene = setup.load_scene()?;
    scene
        .run
        .overridden_by(&point_spec(setup, method, h)?)
        .resolve_with_units(&scene.parameters, scene.units)
        .map_err(|e| e.context(&format!("{method} at h = {h}")))
}

/// The run settings of one point: the setup's, with its method, step, length and levels.
pub fn point_spec(setup: &ScanSetup, method: &str, h: f64) -> Result<RunSpec> {
    let mut spec = setup.base.clone();
    spec.method = Some(method.to_string());
    spec.h = Some(Value::Number(h));
    spec.t_end = Some(Value::Number(setup.t_end));
    if !setup.level_dts.is_empty() {
        spec.level_steps = Some(level_steps_of(h, &setup.level_dts)?);
    }
    Ok(spec)
}

/// `level_steps` for outer step `h` and fixed inner-level steps `dts` (outermost first):
/// `h/T1, T1/T2, …`, each a whole number.
pub fn level_steps_of(h: f64, dts: &[f64]) -> Result<Vec<usize>> {
    let mut outer = h;
    let mut steps = Vec::with_capacity(dts.len());
    for (k, &dt) in dts.iter().enumerate() {
        let name = format!("--level-dt step {}", k + 1);
        let above = if k == 0 {
            "outer step h".to_string()
        } else {
            format!("--level-dt step {k}")
        };
        steps.push(whole_ratio(outer, dt, &name, &above)?);
        outer = dt;
    }
    Ok(steps)
}

/// Run one point once (at the start velocities its settings give) and return the summary.
pub fn run_once(
    setup: &ScanSetup,
    method: &str,
    h: f64,
    outputs: &PointOutputs,
) -> Result<RunSummary> {
    let spec = point_spec(setup, method, h)?;
    let mut prepared = prepare(&setup.request(&spec))?;
    let trajectory = outputs.dir.map(|dir| TrajectoryOptions {
        path: dir.join("trajectory.xyz"),
        every: outputs.frame_every.max(1),
        names: prepared.scene.elements.clone(),
        velocities: false,
    });
    // A point's folder is rewritten whole (both files, every time), so nothing stale is
    // left; its manifest lets `analyze` check the pair.
    let mut manifest = None;
    if let Some(dir) = outputs.dir {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let files = ["energy.csv", "trajectory.xyz"].map(String::from);
        let record = RunManifest::start(std::env::args().collect(), &files);
        record.write(dir)?;
        manifest = Some((dir, record));
    }
    let options = RunOptions {
        t_end: setup.t_end,
        energy_every: setup.energy_every,
        blowup: prepared.settings.blowup,
        energy_csv: outputs.dir.map(|dir| dir.join("energy.csv")),
        trajectory,
        units: prepared.scene.units,
        temperature: prepared.degrees_of_freedom,
        fit_from: setup.fit_from,
        ..RunOptions::default()
    };
    let summary = prepared.run(&options)?;
    if let Some((dir, mut record)) = manifest {
        record.finish(dir)?;
    }
    Ok(summary)
}

/// Most extension factor of `until_decided` (a bound on a user-given size: the run of an
/// undecided point grows to this many times its length).
pub const MAX_UNTIL_DECIDED: f64 = 64.0;

/// The `--until-decided` factor: `None` (never extend) is 0; a factor must lie in
/// `[1, MAX_UNTIL_DECIDED]`.
pub fn check_until_decided(factor: Option<f64>) -> Result<f64> {
    match factor {
        None => Ok(0.0),
        Some(f) if (1.0..=MAX_UNTIL_DECIDED).contains(&f) => Ok(f),
        Some(f) => Err(Error::flag(
            "--until-decided",
            format!(
                "--until-decided must be a factor of the run length between 1 and \
             {MAX_UNTIL_DECIDED}"
            ),
        )
        .expected(format!("1 to {MAX_UNTIL_DECIDED}"))
        .got(f.to_string())),
    }
}

/// Run a point by `run_point` and, while it is undecided, run it again at twice the length,
/// up to `setup.until_decided` times `setup.t_end` (each run from the start: the same start
/// and seed, so a longer run begins with the shorter one's rows). The result says the length
/// it was judged at (`t_end`).
pub fn until_decided(
    setup: &ScanSetup,
    run_point: &dyn Fn(&ScanSetup) -> Result<StepResult>,
) -> Result<StepResult> {
    let limit = setup.t_end * setup.until_decided.min(MAX_UNTIL_DECIDED);
    let mut current = setup.clone();
    loop {
        let result = run_point(&current)?;
        let longer = 2.0 * current.t_end;
        // A run length within round-off of the limit still counts (4 = 2·2 exactly, but a
        // limit from a decimal factor need not be).
        if result.verdict != Verdict::Undecided || longer > limit * (1.0 + 1e-12) {
            return Ok(result);
        }
        current.t_end = longer;
    }
}

/// Run one point's starts and judge it by drift (extended while undecided,
/// [`until_decided`]; every start at once).
pub fn run_point(setup: &ScanSetup, index: usize, method: &str, h: f64) -> Result<StepResult> {
    until_decided(setup, &|setup: &ScanSetup| {
        let summaries = start_setups(setup, method, h)?
            .par_iter()
            .map(|start| {
                run_once(start, method, h, &PointOutputs::default())
                    .map_err(|e| e.context(&format!("{method} at h = {h}")))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(judge_starts(
            index,
            method,
            h,
            &summaries,
            setup.drift_bound,
        ))
    })
}

/// The `--starts` count: `None` is one start; a count must lie in `[1, MAX_STARTS]`.
pub fn check_starts(starts: Option<usize>) -> Result<usize> {
    match starts {
        None => Ok(1),
        Some(n) if (1..=MAX_STARTS).contains(&n) => Ok(n),
        Some(n) => Err(Error::flag(
            "--starts",
            format!("--starts must be between 1 and {MAX_STARTS}"),
        )
        .expected(format!("1 to {MAX_STARTS}"))
        .got(n.to_string())),
    }
}

/// Refuse several starts of a point that cannot make them different: without a temperature
/// its velocities are the scene's own (its momenta or velocity file), the same every time.
pub fn check_starts_possible(setup: &ScanSetup, method: &str, h: f64) -> Result<()> {
    if setup.starts <= 1 || point_settings(setup, method, h)?.temperature.is_some() {
        return Ok(());
    }
    Err(Error::flag(
        "--starts",
        format!(
            "--starts {} needs start velocities drawn at a temperature (seeds s, s+1, …): {method} \
         at h = {h} has no --temperature (nor a [run] temperature), so every start would take \
         the scene's own velocities and be the same run; give --temperature T or --starts 1",
            setup.starts
        ),
    )
    .expected("--temperature T or --starts 1")
    .got_named(setup.starts.to_string()))
}

/// The setups of a point's starts: one (the setup itself), or `starts` with the seeds
/// `s, s+1, …` (`s` the point's seed, else [`DEFAULT_SEED`]).
pub fn start_setups(setup: &ScanSetup, method: &str, h: f64) -> Result<Vec<ScanSetup>> {
    if setup.starts <= 1 {
        return Ok(vec![setup.clone()]);
    }
    let seed = point_settings(setup, method, h)?
        .seed
        .unwrap_or(DEFAULT_SEED);
    (0..setup.starts as u64)
        .map(|k| {
            let mut start = setup.clone();
            start.base.seed = Some(seed.checked_add(k).ok_or_else(|| {
                Error::flag(
                    "--seed",
                    format!("--seed {seed} leaves no room for {} starts", setup.starts),
                )
                .expected(format!(
                    "a seed that leaves room for {} starts",
                    setup.starts
                ))
                .got_named(seed.to_string())
            })?);
            Ok(start)
        })
        .collect()
}

/// The row of a point from its starts' summaries (in seed order): unstable when any start
/// is (the first such start's row), else the verdict on their combined drift (undecided
/// when one is too short to fit); the counts are the first start's.
pub fn judge_starts(
    index: usize,
    method: &str,
    h: f64,
    summaries: &[RunSummary],
    bound: f64,
) -> StepResult {
    let judged: Vec<(Verdict, Option<ScanDrift>)> =
        summaries.iter().map(|s| classify(s, bound)).collect();
    let unstable = judged.iter().position(|(v, _)| *v == Verdict::Unstable);
    let mut result = match unstable {
        Some(k) => step_result(
            index,
            method,
            h,
            Verdict::Unstable,
            judged[k].1.clone(),
            &summaries[k],
        ),
        None => {
            let drifts: Option<Vec<ScanDrift>> = judged.iter().map(|(_, d)| d.clone()).collect();
            let drift = drifts.and_then(|d| combined_drift(&d, bound));
            let verdict = drift
                .as_ref()
                .map_or(Verdict::Undecided, |d| Verdict::of(&d.verdict));
            step_result(index, method, h, verdict, drift, &summaries[0])
        }
    };
    result.starts = summaries.len();
    result.max_relative_error = summaries
        .iter()
        .map(|s| s.energy.max_relative_error)
        .fold(result.max_relative_error, f64::max);
    result.wall_seconds = summaries.iter().map(|s| s.wall_seconds).sum();
    result
}

/// One line per undecided point: `impulse at h = 2 fs: undecided: a run of ~40 ps would
/// decide` (the wording of [`crate::run::verdict::Verdict::text`]).
pub fn undecided_notes(results: &[StepResult], units: Units) -> Vec<String> {
    results
        .iter()
        .filter(|r| r.verdict == Verdict::Undecided)
        .map(|r| {
            let verdict = verdict::Verdict::Undecided {
                decide_at: r.decide_at,
            };
            format!(
                "{} at h = {} (a run of {}): {}",
                r.config
                    .as_ref()
                    .map_or(r.method.clone(), |c| format!("{c} ({})", r.method)),
                format_time(r.h, units),
                format_time(r.t_end, units),
                verdict.text(units)
            )
        })
        .collect()
}

/// The table row of a finished point.
pub fn step_result(
    index: usize,
    method: &str,
    h: f64,
    verdict: Verdict,
    drift: Option<ScanDrift>,
    summary: &RunSummary,
) -> StepResult {
    let counts = &summary.force_evaluations;
    let decide_at = match drift.as_ref().map(|d| d.verdict) {
        Some(verdict::Verdict::Undecided { decide_at }) => decide_at,
        _ => None,
    };
    StepResult {
        index,
        config: None,
        method: method.to_string(),
        h,
        verdict,
        drift: drift.as_ref().map_or(0.0, |d| d.value),
        drift_detail: drift,
        blowup_time: (verdict == Verdict::Unstable).then_some(summary.t_end),
        decide_at,
        t_end: summary.t_end,
        max_relative_error: summary.energy.max_relative_error,
        steps: summary.steps,
        slow_evaluations: counts.slow,
        fast_evaluations: counts.fast,
        hessian_vector: counts.hessian_vector,
        starts: 1,
        sampling: None,
        wall_seconds: summary.wall_seconds,
    }
}

/// Run the given points in parallel; `progress` is called once per finished point.
pub fn run_points(
    setup: &ScanSetup,
    points: &[(usize, String, f64)],
    progress: &(dyn Fn() + Sync),
) -> Result<Vec<StepResult>> {
    if let Some((_, method, _)) = points.iter().find(|(_, m, _)| is_stochastic(m)) {
        return Err(thermostatted_by_drift(method));
    }
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

/// The degrees of freedom a point's kinetic temperature is measured over when its model has
/// constraints: `dim·N − N_c` (every remaining degree of freedom thermalised, the centre of
/// mass included, as the analyzer's `3N`); `None` without constraints.
pub fn constrained_dof(setup: &ScanSetup, method: &str, h: f64) -> Result<Option<f64>> {
    let spec = point_spec(setup, method, h)?;
    let prepared = prepare(&setup.request(&spec))?;
    let system = &prepared.scene.system;
    let constraints = system.constraints.as_ref().map_or(0, |c| c.count());
    Ok((constraints > 0).then(|| system.n_dofs().saturating_sub(constraints) as f64))
}

/// Run one point with its outputs and judge it against the reference analysis.
pub fn run_sampling_point(
    setup: &ScanSetup,
    criterion: &SamplingCriterion,
    reference: &RunAnalysis,
    (index, method, h): (usize, &str, f64),
) -> Result<StepResult> {
    let dir = point_dir(criterion, index, method, h);
    let outputs = PointOutputs {
        dir: Some(&dir),
        frame_every: criterion.frame_every(setup.t_end, h),
    };
    let summary = run_once(setup, method, h, &outputs)
        .map_err(|e| e.context(&format!("{method} at h = {h}")))?;
    judge_sampling_point(setup, criterion, reference, (index, method, h), &summary)
}

/// Judge a finished point's run (in its directory) against the reference analysis.
fn judge_sampling_point(
    setup: &ScanSetup,
    criterion: &SamplingCriterion,
    reference: &RunAnalysis,
    (index, method, h): (usize, &str, f64),
    summary: &RunSummary,
) -> Result<StepResult> {
    let dir = point_dir(criterion, index, method, h);
    if summary.status != Status::Ok {
        return Ok(step_result(
            index,
            method,
            h,
            Verdict::Unstable,
            None,
            summary,
        ));
    }
    let scene = setup.load_scene()?;
    let comparison = criterion.judge_run(&scene, setup.kinetic_dof, reference, &dir)?;
    let mut result = step_result(
        index,
        method,
        h,
        Verdict::of(&comparison.verdict),
        None,
        summary,
    );
    if let verdict::Verdict::Undecided { decide_at } = comparison.verdict {
        result.decide_at = decide_at;
    }
    result.sampling = Some(comparison);
    Ok(result)
}

/// Run the given points in parallel and judge each by sampling; `progress` is called once
/// per finished point.
pub fn run_sampling_points(
    setup: &ScanSetup,
    criterion: &SamplingCriterion,
    reference: &RunAnalysis,
    points: &[(usize, String, f64)],
    progress: &(dyn Fn() + Sync),
) -> Result<Vec<StepResult>> {
    let mut results = points
        .par_iter()
        .map(|(index, method, h)| {
            let result = until_decided(setup, &|setup: &ScanSetup| {
                run_sampling_point(setup, criterion, reference, (*index, method, *h))
            });
            progress();
            result
        })
        .collect::<Result<Vec<_>>>()?;
    results.sort_by_key(|r| r.index);
    Ok(results)
}

/// One configuration of a study (`scan steps --study`): a method with its own settings
/// and outer steps.
#[derive(Clone, Debug)]
pub struct ScanConfig {
    pub label: String,
    pub method: String,
    pub setup: ScanSetup,
    pub steps: Vec<f64>,
}

/// A study's points, configuration-major: `(index, configuration, h)`, the index counting
/// through every configuration's steps in order.
pub fn config_points(configs: &[ScanConfig]) -> Vec<(usize, usize, f64)> {
    let mut points = Vec::new();
    for (c, config) in configs.iter().enumerate() {
        for &h in &config.steps {
            points.push((points.len(), c, h));
        }
    }
    points
}

/// How one point of a study is run and judged: its configuration's setup, index, method
/// and step.
pub type PointRunner<'a> = dyn Fn(&ScanSetup, usize, &str, f64) -> Result<StepResult> + Sync + 'a;

/// Run a study's points in parallel by `run`, each with its configuration's setup, and
/// label each result with its configuration; `progress` is called once per finished point.
pub fn run_config_points(
    configs: &[ScanConfig],
    points: &[(usize, usize, f64)],
    run: &PointRunner,
    progress: &(dyn Fn() + Sync),
) -> Result<Vec<StepResult>> {
    let mut results = points
        .par_iter()
        .map(|&(index, c, h)| {
            let config = &configs[c];
            let result = run(&config.setup, index, &config.method, h)
                .map_err(|e| e.context(&format!("configuration \"{}\"", config.label)))
                .map(|mut r| {
                    r.config = Some(config.label.clone());
                    r
                });
            progress();
            result
        })
        .collect::<Result<Vec<_>>>()?;
    results.sort_by_key(|r| r.index);
    Ok(results)
}

/// The refusal of a thermostatted method under the drift criterion.
pub fn thermostatted_by_drift(method: &str) -> Error {
    Error::flag(
        "--criterion",
        format!(
            "{method} is thermostatted: it exchanges energy with its heat bath by design, so an \
         NVE energy drift cannot judge it; scan it with --criterion sampling --reference DIR \
         (a reference run at the same temperature)"
        ),
    )
    .expected("--criterion sampling")
}

/// Most timed repetitions of one point (a bound on a user-given count).
pub const MAX_REPEATS: usize = 100;

/// The wall time of one point's integration (the run loop, as `run` reports it), as the
/// median of `repeats` runs in a pool of `threads` threads (`None`: all cores).
pub fn time_point(
    setup: &ScanSetup,
    method: &str,
    h: f64,
    threads: Option<usize>,
    repeats: usize,
) -> Result<f64> {
    if !(1..=MAX_REPEATS).contains(&repeats) {
        return Err(Error::flag(
            "--repeats",
            format!("--repeats must be between 1 and {MAX_REPEATS}"),
        )
        .expected(format!("1 to {MAX_REPEATS}"))
        .got(repeats.to_string()));
    }
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(threads) = threads {
        builder = builder.num_threads(threads);
    }
    let pool = builder
        .build()
        .map_err(|e| Error::input(format!("cannot start a thread pool: {e}")))?;
    let mut walls = pool.install(|| {
        (0..repeats)
            .map(|_| run_once(setup, method, h, &PointOutputs::default()).map(|s| s.wall_seconds))
            .collect::<Result<Vec<f64>>>()
    })?;
    Ok(median(&mut walls))
}

/// The timing of one method at its largest safe step at one thread count.
pub struct Timing {
    /// The configuration's label in a study.
    pub config: Option<String>,
    pub method: String,
    pub h: f64,
    pub threads: usize,
    pub repeats: usize,
    pub median_seconds: f64,
    pub t_end: f64,
}

/// Median wall times of every method that has a safe step, at 1 thread and at all threads.
pub fn take_timings(setup: &ScanSetup, safe: &[SafeStep], repeats: usize) -> Result<Vec<Timing>> {
    let all = rayon::current_num_threads();
    let mut counts = vec![1, all];
    counts.dedup();
    let mut timings = Vec::new();
    for s in safe {
        let Some(h) = s.safe_up_to else { continue };
        for &threads in &counts {
            let median_seconds = time_point(setup, &s.method, h, Some(threads), repeats)?;
            timings.push(Timing {
                config: s.config.clone(),
                method: s.method.clone(),
                h,
                threads,
                repeats,
                median_seconds,
                t_end: setup.t_end,
            });
        }
    }
    Ok(timings)
}

/// The median (the mean of the middle two for an even count); NaN for none.
pub fn median(values: &mut [f64]) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    }
}

/// For one method: the largest scanned step below which every scanned step is stable, and
/// the stable steps beyond the first failure (islands between resonances).
#[derive(Clone, Debug, Serialize)]
pub struct SafeStep {
    /// The configuration's label in a study.
    pub config: Option<String>,
    pub method: String,
    pub safe_up_to: Option<f64>,
    pub first_failure: Option<(f64, Verdict)>,
    pub stable_beyond: Vec<f64>,
}

/// One scanned point as the safe-step table needs it (a run's result, or a row of a merged
/// `scan.csv`).
#[derive(Clone, Debug)]
pub struct ScanPoint {
    pub config: Option<String>,
    pub method: String,
    pub h: f64,
    pub verdict: Verdict,
}

/// The safe steps of each method (each configuration of a study), in order of appearance.
pub fn safe_steps(results: &[StepResult]) -> Vec<SafeStep> {
    let points: Vec<ScanPoint> = results
        .iter()
        .map(|r| ScanPoint {
            config: r.config.clone(),
            method: r.method.clone(),
            h: r.h,
            verdict: r.verdict,
        })
        .collect();
    safe_steps_of(&points)
}

/// [`safe_steps`] of points however they were found.
pub fn safe_steps_of(results: &[ScanPoint]) -> Vec<SafeStep> {
    let key = |r: &ScanPoint| (r.config.clone(), r.method.clone());
    let mut groups: Vec<(Option<String>, String)> = Vec::new();
    for r in results {
        if !groups.contains(&key(r)) {
            groups.push(key(r));
        }
    }
    groups
        .into_iter()
        .map(|(config, method)| {
            let mut rows: Vec<&ScanPoint> = results
                .iter()
                .filter(|r| r.method == method && r.config == config)
                .collect();
            rows.sort_by(|a, b| a.h.total_cmp(&b.h));
            let failure = rows.iter().position(|r| !r.verdict.is_safe());
            let safe_up_to = match failure {
                Some(0) => None,
                Some(i) => Some(rows[i - 1].h),
                None => rows.last().map(|r| r.h),
            };
            SafeStep {
                config,
                method: method.to_string(),
                safe_up_to,
                first_failure: failure.map(|i| (rows[i].h, rows[i].verdict)),
                stable_beyond: failure
                    .map(|i| {
                        rows[i..]
                            .iter()
                            .filter(|r| r.verdict.is_safe())
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

    #[test]
    fn starts_are_between_one_and_the_most() {
        assert_eq!(check_starts(None).unwrap(), 1);
        assert!(check_starts(Some(0)).is_err() && check_starts(Some(65)).is_err());
    }

    fn result(method: &str, h: f64, verdict: Verdict) -> StepResult {
        StepResult {
            index: 0,
            config: None,
            method: method.into(),
            h,
            verdict,
            drift: 0.0,
            drift_detail: None,
            blowup_time: None,
            decide_at: None,
            t_end: 1.0,
            max_relative_error: 0.0,
            steps: 0,
            slow_evaluations: 0,
            fast_evaluations: 0,
            hessian_vector: 0,
            starts: 1,
            sampling: None,
            wall_seconds: 0.0,
        }
    }

    #[test]
    fn safe_step_stops_at_the_first_failure_and_lists_islands() {
        use Verdict::*;
        let results = vec![
            result("impulse", 3.0, Unstable),
            result("impulse", 1.0, Pass),
            result("impulse", 2.0, Undecided),
            result("impulse", 4.0, Pass),
            result("long-average", 1.0, Unstable),
            result("verlet", 1.0, Pass),
        ];
        let safe = safe_steps(&results);
        assert_eq!(safe[0].method, "impulse");
        assert_eq!(safe[0].safe_up_to, Some(1.0));
        assert_eq!(safe[0].first_failure, Some((2.0, Undecided)));
        assert_eq!(safe[0].stable_beyond, vec![4.0]);
        assert_eq!(safe[1].safe_up_to, None);
        assert_eq!(safe[2].safe_up_to, Some(1.0));
        assert!(safe[2].first_failure.is_none());
    }
}
