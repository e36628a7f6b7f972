//! `scan steps` as a library call: [`scan_steps`] runs a [`StepScanPlan`] — its points
//! (methods × outer steps, or every configuration of a study file), the slice of a shard,
//! each point's starts and verdict, the safe steps and the timings — writes `scan.csv` and
//! `timing.csv` under the plan's `out`, and returns what it found ([`StepScan`]).

use std::path::{Path, PathBuf};

use super::criterion::sampling::SamplingCriterion;
use super::plan::{
    Criterion, StepScanPlan, base_setup, check_points, check_repeats, choose_criterion,
    config_setup, in_config, refuse_sampling_starts, refuse_single_flags, sampling_criterion,
    scan_methods, scan_setup,
};
use super::points::keep_shard;
use super::scan::{
    SafeStep, ScanConfig, ScanSetup, StepResult, Timing, config_points, constrained_dof,
    point_settings, run_config_points, run_point, run_points, run_sampling_point,
    run_sampling_points, safe_steps, scan_points, take_timings, undecided_notes, until_decided,
};
use super::table::{
    basins_notice, sampling_table, scan_meta, scan_table, study_meta, timing_table,
};
use crate::analysis::run_analysis::RunAnalysis;
use crate::error::{Error, Result};
use crate::io::scene::{Scene, load_scene_with};
use crate::io::study_csv::StudyTable;
use crate::io::study_file::{StudyFile, read_study};
use crate::units::Units;

/// The file name of a scan's table in its output directory.
pub const SCAN_STEPS: &str = "scan.csv";

/// Who watches a scan: told how many points it runs, each point's end, and the notices and
/// warnings of a scan that is not quiet (each a whole line, `notice: …`, `warning: …`).
/// Called from the threads that run the points.
pub trait Watch: Sync {
    fn start(&self, _points: usize) {}
    fn point_done(&self) {}
    fn finish(&self) {}
    fn say(&self, _line: &str) {}
}

/// A watcher that is told nothing.
pub struct Unwatched;

impl Watch for Unwatched {}

/// What a step-size scan found.
pub struct StepScan {
    pub criterion: Criterion,
    /// The scene's units (the steps and drifts are in them).
    pub units: Units,
    /// Every point run (of this shard), in index order.
    pub results: Vec<StepResult>,
    /// `scan.csv`: one row per point, its settings on the first line.
    pub table: StudyTable,
    /// Where the table was written.
    pub path: PathBuf,
    /// Each method's (each configuration's) largest safe step and its islands.
    pub safe: Vec<SafeStep>,
    /// The outer steps scanned, by configuration label (`None`: every method's).
    pub scanned: Vec<(Option<String>, Vec<f64>)>,
    /// The timings at the safe steps, and their table (`timing.csv`), when taken.
    pub timings: Vec<Timing>,
    pub timing_table: Option<StudyTable>,
    /// How many runs: `12 runs`, `12 runs of 3 configurations`.
    pub runs: String,
    /// The shard run, `K/N`.
    pub shard: Option<String>,
}

impl StepScan {
    /// The outer steps a safe step's method (configuration) was scanned at.
    pub fn steps_of(&self, safe: &SafeStep) -> Vec<f64> {
        self.scanned
            .iter()
            .find(|(label, _)| label.is_none() || *label == safe.config)
            .map_or_else(Vec::new, |(_, steps)| steps.clone())
    }
}

/// The sampling criterion and the reference's analysis, when a scan judges by sampling.
type Sampling = Option<(SamplingCriterion, RunAnalysis)>;

/// Run the scan `plan` describes (module documentation); `watch` is told its progress.
pub fn scan_steps(plan: &StepScanPlan, watch: &dyn Watch) -> Result<StepScan> {
    match &plan.study {
        Some(path) => scan_study(plan, path, watch),
        None => scan_methods_steps(plan, watch),
    }
}

/// The scene of a plan, with its `set` values and flags.
fn load(plan: &StepScanPlan) -> Result<Scene> {
    load_scene_with(&plan.scene, &plan.flags, &plan.set)
}

/// Every method at every outer step, method-major.
fn scan_methods_steps(plan: &StepScanPlan, watch: &dyn Watch) -> Result<StepScan> {
    let scene = load(plan)?;
    let methods = scan_methods(plan)?;
    let (mut setup, steps) = scan_setup(plan, &scene)?;
    let criterion = choose_criterion(plan, &methods)?;
    refuse_sampling_starts(criterion, setup.starts, None)?;
    check_repeats(plan.repeats)?;
    check_points(&setup, &methods, &steps)?;
    if !plan.quiet {
        async_band_warnings(&setup, &methods, &steps, watch)?;
    }
    let mut points = scan_points(&methods, &steps);
    let total = points.len();
    keep_shard(&mut points, plan.shard.as_deref())?;
    create_out(&plan.out)?;
    let sampling = match criterion {
        Criterion::Drift => None,
        Criterion::Sampling => {
            let mut c = sampling_criterion(plan, &scene, setup.t_end)?;
            setup.kinetic_dof = constrained_dof(&setup, &methods[0], steps[0])?;
            let temperature = point_settings(&setup, &methods[0], steps[0])?.temperature;
            c.temperature = temperature;
            let reference = reference_analysis(&scene, &c, temperature, setup.kinetic_dof)?;
            say_basins(plan, &c, &reference, watch);
            Some((c, reference))
        }
    };
    watch.start(points.len());
    let results = match &sampling {
        None => run_points(&setup, &points, &|| watch.point_done())?,
        Some((c, reference)) => {
            run_sampling_points(&setup, c, reference, &points, &|| watch.point_done())?
        }
    };
    watch.finish();
    let meta = scan_meta(plan, &setup, total, sampling.as_ref(), scene.units);
    let mut scan = finish_scan(plan, &scene, criterion, (meta, &sampling), results, watch)?;
    let repeats = timed_repeats(plan, "scan", watch);
    if repeats > 0 {
        scan.timings = take_timings(&setup, &scan.safe, repeats)?;
    }
    write_timings(plan, &mut scan)?;
    scan.scanned = vec![(None, steps)];
    scan.runs = format!("{} runs", scan.results.len());
    Ok(scan)
}

/// Every (configuration, h) point of a study file, configuration-major.
fn scan_study(plan: &StepScanPlan, path: &Path, watch: &dyn Watch) -> Result<StepScan> {
    refuse_single_flags(plan)?;
    check_repeats(plan.repeats)?;
    let study = read_study(path)?;
    // Before the configurations are built: their checks of the starts are the drift's.
    if plan.criterion == Some(Criterion::Sampling) {
        for c in &study.configs {
            let starts = c.starts.or(plan.starts).unwrap_or(1);
            refuse_sampling_starts(Criterion::Sampling, starts, Some(&c.label))?;
        }
    }
    let scene = load(plan)?;
    let (base, mut configs) = study_configs(plan, &scene, &study)?;
    let methods: Vec<String> = configs.iter().map(|c| c.method.clone()).collect();
    let criterion = choose_criterion(plan, &methods)?;
    if !plan.quiet {
        for c in &configs {
            async_band_warnings(&c.setup, std::slice::from_ref(&c.method), &c.steps, watch)?;
        }
    }
    let mut points = config_points(&configs);
    let total = points.len();
    keep_shard(&mut points, plan.shard.as_deref())?;
    create_out(&plan.out)?;
    let sampling = match criterion {
        Criterion::Drift => None,
        Criterion::Sampling => {
            let (c, reference) = study_reference(plan, &scene, &base, &mut configs, path)?;
            say_basins(plan, &c, &reference, watch);
            Some((c, reference))
        }
    };
    let results = run_study_points(&configs, &points, sampling.as_ref(), watch)?;
    let mut meta = scan_meta(plan, &base, total, sampling.as_ref(), scene.units);
    study_meta(&study, &mut meta);
    let mut scan = finish_scan(plan, &scene, criterion, (meta, &sampling), results, watch)?;
    scan.timings = study_timings(plan, &configs, &scan.safe, watch)?;
    write_timings(plan, &mut scan)?;
    scan.scanned = configs
        .iter()
        .map(|c| (Some(c.label.clone()), c.steps.clone()))
        .collect();
    scan.runs = format!(
        "{} runs of {} configurations",
        scan.results.len(),
        configs.len()
    );
    Ok(scan)
}

fn create_out(out: &Path) -> Result<()> {
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))
}

/// After the points: the notes on undecided points, the table written, the safe steps.
fn finish_scan(
    plan: &StepScanPlan,
    scene: &Scene,
    criterion: Criterion,
    (meta, sampling): (std::collections::BTreeMap<String, String>, &Sampling),
    results: Vec<StepResult>,
    watch: &dyn Watch,
) -> Result<StepScan> {
    if !plan.quiet {
        for note in undecided_notes(&results, scene.units) {
            watch.say(&format!("notice: {note}"));
        }
    }
    let table = match sampling {
        None => scan_table(meta, &results),
        Some((c, reference)) => sampling_table(meta, &results, (c, reference), scene.units),
    };
    let path = plan.out.join(SCAN_STEPS);
    table.write(&path)?;
    Ok(StepScan {
        criterion,
        units: scene.units,
        safe: safe_steps(&results),
        results,
        table,
        path,
        scanned: Vec::new(),
        timings: Vec::new(),
        timing_table: None,
        runs: String::new(),
        shard: plan.shard.clone(),
    })
}

/// The repeats of the timings: none with `repeats` 0 or in a shard (which says so).
fn timed_repeats(plan: &StepScanPlan, what: &str, watch: &dyn Watch) -> usize {
    if plan.repeats == 0 {
        return 0;
    }
    if plan.shard.is_some() {
        if !plan.quiet {
            watch.say(&format!(
                "notice: a shard takes no timings (the largest safe step needs every point); \
                 run the {what} whole for ns/day"
            ));
        }
        return 0;
    }
    plan.repeats
}

/// Write `timing.csv` when there are timings.
fn write_timings(plan: &StepScanPlan, scan: &mut StepScan) -> Result<()> {
    if scan.timings.is_empty() {
        return Ok(());
    }
    let timing = timing_table(scan.table.meta.clone(), &scan.timings, scan.units);
    timing.write(&plan.out.join("timing.csv"))?;
    scan.timing_table = Some(timing);
    Ok(())
}

/// Warn before an asynchronous run enters an instability band (small linear scenes).
fn async_band_warnings(
    setup: &ScanSetup,
    methods: &[String],
    steps: &[f64],
    watch: &dyn Watch,
) -> Result<()> {
    if !methods.iter().any(|m| m == "async-pseudo-energy") {
        return Ok(());
    }
    for &h in steps {
        let mut scene = setup.load_scene()?;
        let settings = point_settings(setup, "async-pseudo-energy", h)?;
        if let Some(warning) =
            crate::analysis::async_stability::band_warning(&mut scene.system, &settings)
        {
            watch.say(&format!("warning: {warning}"));
        }
    }
    Ok(())
}

fn say_basins(
    plan: &StepScanPlan,
    c: &SamplingCriterion,
    reference: &RunAnalysis,
    watch: &dyn Watch,
) {
    if !plan.quiet {
        watch.say(&format!(
            "notice: backbone basins: {}",
            basins_notice(c, reference)
        ));
    }
}

/// Analyse the reference run and check that it was made at the scan's temperature.
fn reference_analysis(
    scene: &Scene,
    criterion: &SamplingCriterion,
    temperature: Option<f64>,
    dof: Option<f64>,
) -> Result<RunAnalysis> {
    let temperature = temperature.ok_or_else(|| {
        Error::flag(
            "--criterion",
            "--criterion sampling compares at a temperature: give --temperature (or set \
             temperature in the scene's [run] table)",
        )
    })?;
    let trajectory = scene
        .output
        .trajectory
        .clone()
        .unwrap_or_else(|| "trajectory.xyz".into());
    let files = crate::analysis::run_dir::run_files(&criterion.reference, &trajectory)?;
    let analysis = criterion.analyzer(scene, dof)?.analyze(&files)?;
    let unit = match scene.units {
        Units::Real => " K",
        Units::None => " (k_B T)",
    };
    super::criterion::sampling::check_reference_temperature(
        &analysis,
        temperature,
        unit,
        &criterion.reference,
    )?;
    Ok(analysis)
}

/// Every configuration's setup, each point built once: a bad configuration fails here,
/// before any run.
fn study_configs(
    plan: &StepScanPlan,
    scene: &Scene,
    study: &StudyFile,
) -> Result<(ScanSetup, Vec<ScanConfig>)> {
    let base = base_setup(plan, scene)?;
    let configs = study
        .configs
        .iter()
        .map(|c| {
            config_setup(plan, scene, &base, c).map_err(|e| in_config(&study.path, &c.label, e))
        })
        .collect::<Result<Vec<_>>>()?;
    Ok((base, configs))
}

/// The sampling criterion's reference, analysed once: every configuration must run at its
/// temperature.
fn study_reference(
    plan: &StepScanPlan,
    scene: &Scene,
    base: &ScanSetup,
    configs: &mut [ScanConfig],
    study: &Path,
) -> Result<(SamplingCriterion, RunAnalysis)> {
    let mut c = sampling_criterion(plan, scene, base.t_end)?;
    let temperature_of = |config: &ScanConfig| -> Result<Option<f64>> {
        Ok(point_settings(&config.setup, &config.method, config.steps[0])?.temperature)
    };
    let dof_of =
        |config: &ScanConfig| constrained_dof(&config.setup, &config.method, config.steps[0]);
    let temperature = temperature_of(&configs[0])?;
    let dof = dof_of(&configs[0])?;
    for config in configs.iter_mut() {
        c.check(config.setup.t_end)
            .map_err(|e| in_config(study, &config.label, e))?;
        config.setup.kinetic_dof = dof_of(config)?;
        if config.setup.kinetic_dof != dof {
            return Err(in_config(
                study,
                &config.label,
                Error::input(
                    "its constraints differ from the first configuration's: the sampling \
                     criterion compares every configuration with one reference of one model \
                     (flexible and constrained configurations take two study files)",
                ),
            ));
        }
        if temperature_of(config)? != temperature {
            return Err(in_config(
                study,
                &config.label,
                Error::input(
                    "its temperature differs from the first configuration's: the sampling \
                     criterion compares every configuration with one reference",
                ),
            ));
        }
    }
    c.temperature = temperature;
    let reference = reference_analysis(scene, &c, temperature, dof)?;
    Ok((c, reference))
}

/// Run the study's points (of this shard), each by the scan's criterion.
fn run_study_points(
    configs: &[ScanConfig],
    points: &[(usize, usize, f64)],
    sampling: Option<&(SamplingCriterion, RunAnalysis)>,
    watch: &dyn Watch,
) -> Result<Vec<StepResult>> {
    watch.start(points.len());
    let results = match sampling {
        None => run_config_points(configs, points, &run_point, &|| watch.point_done())?,
        Some((c, reference)) => {
            let runner = |setup: &ScanSetup, index: usize, method: &str, h: f64| {
                until_decided(setup, &|setup: &ScanSetup| {
                    run_sampling_point(setup, c, reference, (index, method, h))
                })
            };
            run_config_points(configs, points, &runner, &|| watch.point_done())?
        }
    };
    watch.finish();
    Ok(results)
}

/// Time each configuration at its largest safe step (not in a shard, nor with `repeats`
/// 0).
fn study_timings(
    plan: &StepScanPlan,
    configs: &[ScanConfig],
    safe: &[SafeStep],
    watch: &dyn Watch,
) -> Result<Vec<Timing>> {
    let repeats = timed_repeats(plan, "study", watch);
    if repeats == 0 {
        return Ok(Vec::new());
    }
    let mut timings = Vec::new();
    for config in configs {
        let own: Vec<_> = safe
            .iter()
            .filter(|s| s.config.as_deref() == Some(config.label.as_str()))
            .cloned()
            .collect();
        for mut t in take_timings(&config.setup, &own, repeats)? {
            t.config = Some(config.label.clone());
            timings.push(t);
        }
    }
    Ok(timings)
}
