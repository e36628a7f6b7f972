//! `longstep scan steps SCENE --study FILE`: every configuration of a study file (each a
//! method with its own outer steps and run settings, [`crate::io::study_file`]) scanned in
//! one command, its points sharded as one list.

use std::collections::BTreeMap;
use std::path::Path;

use super::super::common::{SCAN_STEPS, keep_shard, parse_steps, progress_bar};
use super::{
    Criterion, ScanStepsArgs, async_band_warnings, base_setup, basins_notice, check_repeats,
    choose_criterion, print_scan_end, reference_analysis, refuse_sampling_starts,
    sampling_criterion, sampling_table, scan_meta, scan_table, timing_table,
};
use crate::analysis::sampling::{constrained_dof, run_sampling_point};
use crate::analysis::scan::{
    ScanConfig, ScanSetup, StepResult, Timing, config_points, point_settings, run_config_points,
    run_point, safe_steps, take_timings, until_decided,
};
use crate::error::{Error, Result};
use crate::io::scene::Scene;
use crate::io::study_file::{StudyConfig, StudyFile, read_study};
use crate::settings::RunSpec;

/// The error of a configuration: names the study file and the configuration's label.
fn in_config(study: &Path, label: &str, e: Error) -> Error {
    Error::Structure {
        path: study.to_path_buf(),
        message: format!("configuration \"{label}\": {e}"),
    }
}

/// The flags a study replaces: its configurations name their methods and steps.
fn refuse_single_flags(args: &ScanStepsArgs) -> Result<()> {
    if !args.methods.is_empty() || args.run.method.is_some() || args.run.h.is_some() {
        return Err(Error::flag(
            "--study",
            "--study names each configuration's method and outer steps: leave out --methods, \
             --method and --h",
        ));
    }
    Ok(())
}

/// One configuration's setup: the command line's, overridden by the configuration's keys.
fn config_setup(
    args: &ScanStepsArgs,
    scene: &Scene,
    base: &ScanSetup,
    config: &StudyConfig,
) -> Result<ScanConfig> {
    let units = scene.units;
    let mut setup = base.clone();
    let own = RunSpec {
        method: None,
        t_end: None,
        ..config.run.clone()
    };
    setup.base = base.base.overridden_by(&own);
    if let Some(t_end) = &config.run.t_end {
        setup.t_end = t_end.evaluate_time(&scene.parameters, "t_end", units.time_units())?;
        if setup.t_end <= 0.0 {
            return Err(Error::setting("t_end", "t_end must be positive")
                .expected("a positive time")
                .got(setup.t_end.to_string()));
        }
        setup.fit_from = args.drift.fit_from(&scene.parameters, units, setup.t_end)?;
    }
    if !config.level_dt.is_empty() {
        setup.level_dts = config
            .level_dt
            .iter()
            .map(|v| v.evaluate_time(&scene.parameters, "level_dt", units.time_units()))
            .collect::<Result<Vec<f64>>>()?;
        if setup.level_dts.iter().any(|&t| t <= 0.0) || setup.level_dts.len() > 16 {
            return Err(
                Error::setting("level_dt", "`level_dt` takes at most 16 positive steps")
                    .expected("at most 16 positive steps"),
            );
        }
    }
    if !setup.level_dts.is_empty() && setup.base.level_steps.is_some() {
        return Err(Error::setting(
            "level_dt",
            "give the inner levels either as `level_steps` or as `level_dt` (--level-dt), \
             not both",
        )
        .expected("level_steps or level_dt, not both"));
    }
    setup.set.extend(config.set.iter().cloned());
    if let Some(starts) = config.starts {
        setup.starts = starts;
    }
    let electrostatics = &mut setup.flags.electrostatics;
    electrostatics.pme_level = config.pme_level.or(electrostatics.pme_level);
    electrostatics.nonbonded_level = config.nonbonded_level.or(electrostatics.nonbonded_level);
    if config.split.is_some() {
        electrostatics.split = config.split.clone();
    }
    let method = config.run.method.clone().unwrap_or_default();
    let steps = parse_steps(&config.steps, units)?;
    for &h in &steps {
        crate::analysis::scan::check_starts_possible(&setup, &method, h)?;
        let settings = point_settings(&setup, &method, h)?;
        crate::run::prepare::check_settings(&settings)
            .map_err(|e| e.context(&format!("{method} at h = {h}")))?;
    }
    Ok(ScanConfig {
        label: config.label.clone(),
        method,
        setup,
        steps,
    })
}

/// Every configuration's setup, each point built once: a bad configuration fails here,
/// before any run.
fn study_configs(
    args: &ScanStepsArgs,
    scene: &Scene,
    study: &StudyFile,
) -> Result<(ScanSetup, Vec<ScanConfig>)> {
    let base = base_setup(args, scene)?;
    let configs = study
        .configs
        .iter()
        .map(|c| {
            config_setup(args, scene, &base, c).map_err(|e| in_config(&study.path, &c.label, e))
        })
        .collect::<Result<Vec<_>>>()?;
    Ok((base, configs))
}

/// The settings the study's table records beside the command line's: the study file, the
/// fingerprint of its text and its labels, so shards of different studies never merge.
fn study_meta(study: &StudyFile, meta: &mut BTreeMap<String, String>) {
    meta.insert("study".into(), study.path.display().to_string());
    meta.insert("study_fingerprint".into(), study.fingerprint.clone());
    let labels: Vec<&str> = study.configs.iter().map(|c| c.label.as_str()).collect();
    meta.insert("configs".into(), labels.join(";").replace(',', ";"));
}

/// The sampling criterion's reference, analysed once: every configuration must run at its
/// temperature.
fn study_reference(
    args: &ScanStepsArgs,
    scene: &Scene,
    base: &ScanSetup,
    configs: &mut [ScanConfig],
    study: &Path,
) -> Result<(
    crate::analysis::sampling::SamplingCriterion,
    crate::analysis::run_analysis::RunAnalysis,
)> {
    let c = sampling_criterion(args, scene, base.t_end)?;
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
    let reference = reference_analysis(scene, &c, temperature, dof)?;
    if !args.quiet {
        eprintln!("notice: backbone basins: {}", basins_notice(&c, &reference));
    }
    Ok((c, reference))
}

/// Run the study's points (of this shard), each by the scan's criterion.
fn run_study_points(
    args: &ScanStepsArgs,
    configs: &[ScanConfig],
    points: &[(usize, usize, f64)],
    sampling: Option<&(
        crate::analysis::sampling::SamplingCriterion,
        crate::analysis::run_analysis::RunAnalysis,
    )>,
) -> Result<Vec<StepResult>> {
    let bar = progress_bar(points.len() as u64, args.quiet, "scan steps");
    let results = match sampling {
        None => run_config_points(configs, points, &run_point, &|| bar.inc(1))?,
        Some((c, reference)) => {
            let runner = |setup: &ScanSetup, index: usize, method: &str, h: f64| {
                until_decided(setup, &|setup: &ScanSetup| {
                    run_sampling_point(setup, c, reference, (index, method, h))
                })
            };
            run_config_points(configs, points, &runner, &|| bar.inc(1))?
        }
    };
    bar.finish_and_clear();
    Ok(results)
}

/// Time each configuration at its largest safe step (not in a shard, nor with --repeats
/// 0) and write `timing.csv` and its chart.
fn study_timings(
    args: &ScanStepsArgs,
    configs: &[ScanConfig],
    safe: &[crate::analysis::scan::SafeStep],
    meta: BTreeMap<String, String>,
    units: crate::units::Units,
) -> Result<Vec<Timing>> {
    if args.repeats == 0 || args.shard.is_some() {
        if args.shard.is_some() && args.repeats > 0 && !args.quiet {
            eprintln!(
                "notice: a shard takes no timings (the largest safe step needs every point); \
                 run the study whole for ns/day"
            );
        }
        return Ok(Vec::new());
    }
    let mut timings = Vec::new();
    for config in configs {
        let own: Vec<_> = safe
            .iter()
            .filter(|s| s.config.as_deref() == Some(config.label.as_str()))
            .cloned()
            .collect();
        for mut t in take_timings(&config.setup, &own, args.repeats)? {
            t.config = Some(config.label.clone());
            timings.push(t);
        }
    }
    if !timings.is_empty() {
        let timing = timing_table(meta, &timings, units);
        timing.write(&args.out.join("timing.csv"))?;
        super::super::draw::draw_ns_per_day(&timing, &args.out)?;
    }
    Ok(timings)
}

/// `scan steps SCENE --study FILE`: every (configuration, h) point, configuration-major.
pub(super) fn scan_study_command(args: &ScanStepsArgs, path: &Path) -> Result<()> {
    refuse_single_flags(args)?;
    check_repeats(args.repeats)?;
    let study = read_study(path)?;
    // Before the configurations are built: their checks of the starts are the drift's.
    if args.criterion == Some(Criterion::Sampling) {
        for c in &study.configs {
            let starts = c.starts.or(args.starts).unwrap_or(1);
            refuse_sampling_starts(Criterion::Sampling, starts, Some(&c.label))?;
        }
    }
    let scene = args.source.load(&args.scene, &args.set)?;
    let (base, mut configs) = study_configs(args, &scene, &study)?;
    let methods: Vec<String> = configs.iter().map(|c| c.method.clone()).collect();
    let criterion = choose_criterion(args, &methods)?;
    if !args.quiet {
        for c in &configs {
            async_band_warnings(&c.setup, std::slice::from_ref(&c.method), &c.steps)?;
        }
    }
    let mut points = config_points(&configs);
    let total = points.len();
    keep_shard(&mut points, args.shard.as_deref())?;
    std::fs::create_dir_all(&args.out).map_err(|e| Error::io(&args.out, e))?;
    let sampling = match criterion {
        Criterion::Drift => None,
        Criterion::Sampling => Some(study_reference(args, &scene, &base, &mut configs, path)?),
    };
    let results = run_study_points(args, &configs, &points, sampling.as_ref())?;
    if !args.quiet {
        for note in crate::analysis::scan::undecided_notes(&results, scene.units) {
            eprintln!("notice: {note}");
        }
    }
    let mut meta = scan_meta(args, &base, total, sampling.as_ref(), scene.units);
    study_meta(&study, &mut meta);
    let table = match &sampling {
        None => scan_table(meta.clone(), &results),
        Some((c, _)) => sampling_table(meta.clone(), &results, !c.backbone.is_empty(), scene.units),
    };
    let out = args.out.join(SCAN_STEPS);
    table.write(&out)?;
    super::super::draw::draw_scan(&table, &args.out)?;
    let safe = safe_steps(&results);
    let timings = study_timings(args, &configs, &safe, meta, scene.units)?;
    let steps_of = |s: &crate::analysis::scan::SafeStep| {
        configs
            .iter()
            .find(|c| s.config.as_deref() == Some(c.label.as_str()))
            .map_or_else(Vec::new, |c| c.steps.clone())
    };
    let runs = format!("{} runs of {} configurations", results.len(), configs.len());
    print_scan_end(
        (&safe, &steps_of, &timings),
        scene.units,
        (criterion, args.shard.as_deref()),
        (&runs, &results, &out),
    );
    Ok(())
}
