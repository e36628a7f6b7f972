//! The plan of a step-size scan: what the user asked for, as data (the command line parses
//! it once, library code writes it), and its checks against the scene — the setup every
//! point shares, the outer steps, the criterion and, for a study file, each
//! configuration's own setup.

use std::path::{Path, PathBuf};

use super::criterion::drift::DEFAULT_DIMENSIONLESS_BOUND;
use super::criterion::sampling::{DEFAULT_BASIN_BOUND, SamplingCriterion};
use super::points::parse_steps;
use super::scan::{
    MAX_REPEATS, ScanConfig, ScanSetup, check_starts, check_starts_possible, check_until_decided,
    point_settings, thermostatted_by_drift,
};
use crate::analysis::dihedrals::{backbone_residues, scene_topology};
use crate::error::{Error, Result};
use crate::io::scene::{Scene, SceneFlags};
use crate::io::study_file::StudyConfig;
use crate::settings::{RunSpec, Value};
use crate::units::Units;

/// What judges a point of `scan steps`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Criterion {
    /// NVE energy drift (the default; NVE methods only).
    Drift,
    /// Potential energy per molecule, g(r) first-peak height and, for a peptide, the
    /// backbone basin populations against --reference.
    Sampling,
}

/// The default g(r) pair of the sampling criterion.
pub const DEFAULT_PAIR: &str = "O-O";
/// The default bound on |Δ mean potential energy per molecule| (scene energy unit).
pub const DEFAULT_POTENTIAL_BOUND: f64 = 0.1;
/// The default bound on |Δ g(r) first-peak height|.
pub const DEFAULT_PEAK_BOUND: f64 = 0.05;
/// The default number of blocks of the sampling criterion's error bars.
pub const DEFAULT_BLOCKS: usize = 10;
/// The default number of trajectory frames per run of the sampling criterion.
pub const DEFAULT_FRAMES: usize = 100;

/// The options of the sampling criterion, as given (`--reference`, `--pair`, …).
#[derive(Clone, Debug)]
pub struct SamplingPlan {
    /// The reference run directory (energy.csv and a trajectory).
    pub reference: Option<PathBuf>,
    /// The element pair whose g(r) first-peak height is compared, `A-B`.
    pub pair: String,
    pub potential_bound: f64,
    pub peak_bound: f64,
    pub basin_bound: f64,
    /// The temperature error `ΔT` of the configurational-temperature and per-term criteria.
    pub temperature_bound: f64,
    /// Start of each run left out (default: a fifth of the run length).
    pub discard: Option<Value>,
    pub blocks: usize,
    pub frames: usize,
}

impl Default for SamplingPlan {
    fn default() -> Self {
        SamplingPlan {
            reference: None,
            pair: DEFAULT_PAIR.into(),
            potential_bound: DEFAULT_POTENTIAL_BOUND,
            peak_bound: DEFAULT_PEAK_BOUND,
            basin_bound: DEFAULT_BASIN_BOUND,
            temperature_bound: super::criterion::reference::DEFAULT_TEMPERATURE_BOUND,
            discard: None,
            blocks: DEFAULT_BLOCKS,
            frames: DEFAULT_FRAMES,
        }
    }
}

/// A step-size scan as asked: the scene, the methods and outer steps (or a study file of
/// configurations), the settings every point shares, the criterion, and where the tables
/// go. Every field is as the user wrote it; [`super::scan_steps`] checks them against the
/// scene. `longstep scan steps` fills one from its flags (docs/studies.md).
#[derive(Clone, Debug)]
pub struct StepScanPlan {
    /// The scene file (TOML, or a topology).
    pub scene: PathBuf,
    /// Scene parameters set (`NAME=VALUE`, as `--set`).
    pub set: Vec<String>,
    /// A topology's coordinates, the electrostatics overrides, … (as `run`'s flags).
    pub flags: SceneFlags,
    /// Start every point from the positions of this structure file.
    pub start: Option<PathBuf>,
    /// `double` or `mixed` non-bonded arithmetic (`None`: double).
    pub precision: Option<String>,
    /// The methods to scan, in order (`--methods`; `run.method` adds its own).
    pub methods: Vec<String>,
    /// The settings every point shares, as `longstep run` takes them; `run.h` holds the
    /// outer steps (`LO:HI:STEP` or a list) and `run.t_end` each run's length.
    pub run: RunSpec,
    /// The drift criterion's bound (`None`: 0.05 kT/ns/dof in real units, else 1e-3).
    pub drift_bound: Option<f64>,
    /// Fit the drift from this time on.
    pub fit_from: Option<Value>,
    /// The fixed steps of the inner levels, outermost first (`--level-dt`).
    pub level_dt: Vec<Value>,
    /// What judges a point (`None`: drift, and refused for a thermostatted method).
    pub criterion: Option<Criterion>,
    pub sampling: SamplingPlan,
    /// Timed runs of each method at its largest safe step (0: no timings).
    pub repeats: usize,
    /// Record the energy every N steps.
    pub energy_every: usize,
    /// Run an undecided point again at twice its length, up to this factor.
    pub until_decided: Option<f64>,
    /// Independent starts per point of the drift criterion.
    pub starts: Option<usize>,
    /// A study file of configurations in place of `methods` and `run.h`.
    pub study: Option<PathBuf>,
    /// The output directory: scan.csv, timing.csv, runs/ of the sampling criterion.
    pub out: PathBuf,
    /// Run only the k-th of n slices of the points, `K/N`.
    pub shard: Option<String>,
    /// No notices or warnings (and no time spent on them).
    pub quiet: bool,
}

impl StepScanPlan {
    /// A plan for `scene` with the command line's defaults: no methods or steps yet, three
    /// timed repeats, the drift criterion, output to `out/scan-steps`.
    pub fn new(scene: impl Into<PathBuf>) -> Self {
        StepScanPlan {
            scene: scene.into(),
            set: Vec::new(),
            flags: SceneFlags::default(),
            start: None,
            precision: None,
            methods: Vec::new(),
            run: RunSpec::default(),
            drift_bound: None,
            fit_from: None,
            level_dt: Vec::new(),
            criterion: None,
            sampling: SamplingPlan::default(),
            repeats: 3,
            energy_every: 1,
            until_decided: None,
            starts: None,
            study: None,
            out: PathBuf::from("out/scan-steps"),
            shard: None,
            quiet: false,
        }
    }
}

/// The methods of a scan: `methods` and `run.method`, in order, at least one.
pub fn scan_methods(plan: &StepScanPlan) -> Result<Vec<String>> {
    let mut methods = plan.methods.clone();
    if let Some(method) = &plan.run.method {
        methods.extend(method.split(',').map(|m| m.trim().to_string()));
    }
    methods.retain(|m| !m.is_empty());
    if methods.is_empty() {
        return Err(Error::flag(
            "--methods",
            "scan steps needs the methods to scan: give --methods A,B (or --method A)",
        )
        .expected("--methods A,B or --method A"));
    }
    Ok(methods)
}

/// The scan's setup and its outer steps, from the plan and the scene.
pub fn scan_setup(plan: &StepScanPlan, scene: &Scene) -> Result<(ScanSetup, Vec<f64>)> {
    let h = plan.run.h.as_ref().ok_or_else(|| {
        Error::flag(
            "--h",
            "scan steps needs the outer steps to scan: give --h LO:HI:STEP or a list",
        )
        .expected("LO:HI:STEP or a list")
    })?;
    let steps = parse_steps(&h.to_string(), scene.units)?;
    Ok((base_setup(plan, scene)?, steps))
}

/// Each run's length, `t_end` (the plan's, else the scene's), checked positive.
fn run_length(plan: &StepScanPlan, scene: &Scene) -> Result<f64> {
    let t_end = plan
        .run
        .t_end
        .as_ref()
        .or(scene.run.t_end.as_ref())
        .ok_or_else(|| {
            Error::flag(
                "--t-end",
                "scan steps needs each run's length: give --t-end",
            )
            .expected("a run length")
        })?
        .evaluate_time(&scene.parameters, "--t-end", scene.units.time_units())?;
    if t_end <= 0.0 {
        return Err(Error::flag("--t-end", "--t-end must be positive"));
    }
    Ok(t_end)
}

/// The fixed inner-level steps (`--level-dt`) in the scene's time unit, checked.
fn level_dts(plan: &StepScanPlan, scene: &Scene) -> Result<Vec<f64>> {
    if !plan.level_dt.is_empty() && plan.run.level_steps.is_some() {
        return Err(Error::flag(
            "--level-dt",
            "give the inner levels either as --level-steps or as --level-dt, not both",
        )
        .expected("--level-steps or --level-dt, not both"));
    }
    if plan.level_dt.len() > 16 {
        return Err(Error::flag(
            "--level-dt",
            "--level-dt takes at most 16 steps",
        ));
    }
    plan.level_dt
        .iter()
        .map(|v| {
            let t = v.evaluate_time(&scene.parameters, "--level-dt", scene.units.time_units())?;
            if t > 0.0 {
                Ok(t)
            } else {
                Err(
                    Error::flag("--level-dt", "--level-dt steps must be positive")
                        .got(t.to_string()),
                )
            }
        })
        .collect()
}

/// The scan's setup from the plan and the scene: everything but the outer steps.
pub fn base_setup(plan: &StepScanPlan, scene: &Scene) -> Result<ScanSetup> {
    let units = scene.units;
    let t_end = run_length(plan, scene)?;
    if plan.energy_every == 0 {
        return Err(Error::flag(
            "--energy-every",
            "--energy-every must be at least 1",
        ));
    }
    let drift_bound = crate::run::drift::check_bound(plan.drift_bound)?.unwrap_or(match units {
        Units::Real => crate::run::drift::DEFAULT_REAL_BOUND,
        Units::None => DEFAULT_DIMENSIONLESS_BOUND,
    });
    let base = RunSpec {
        method: None,
        h: None,
        t_end: None,
        blowup: Some(plan.run.blowup.unwrap_or(10.0)),
        ..plan.run.clone()
    };
    let level_dts = level_dts(plan, scene)?;
    Ok(ScanSetup {
        scene: plan.scene.clone(),
        set: plan.set.clone(),
        base,
        t_end,
        drift_bound,
        energy_every: plan.energy_every,
        fit_from: crate::run::drift::fit_from(
            plan.fit_from.as_ref(),
            &scene.parameters,
            units,
            t_end,
        )?,
        level_dts,
        flags: plan.flags.clone(),
        start: plan.start.clone(),
        precision: plan.precision.clone(),
        until_decided: check_until_decided(plan.until_decided)?,
        kinetic_dof: None,
        starts: check_starts(plan.starts)?,
    })
}

/// The criterion: drift for NVE methods unless sampling is asked for; a thermostatted
/// method is never judged by drift, and sampling needs its reference.
pub fn choose_criterion(plan: &StepScanPlan, methods: &[String]) -> Result<Criterion> {
    let thermostatted = methods.iter().find(|m| crate::run::is_stochastic(m));
    match (plan.criterion, thermostatted) {
        (Some(Criterion::Drift) | None, Some(method)) => Err(thermostatted_by_drift(method)),
        (Some(Criterion::Sampling), _) if plan.sampling.reference.is_none() => Err(Error::flag(
            "--criterion",
            "--criterion sampling needs --reference DIR: a reference run (energy.csv and a \
                 trajectory; BAOAB at a small step, at the scan's temperature) to compare with",
        )),
        (Some(criterion), _) => Ok(criterion),
        (None, None) => Ok(Criterion::Drift),
    }
}

/// Several starts are the drift criterion's: the sampling criterion judges one run per
/// point against its reference. `config` names a study's configuration.
pub fn refuse_sampling_starts(
    criterion: Criterion,
    starts: usize,
    config: Option<&str>,
) -> Result<()> {
    if criterion != Criterion::Sampling || starts <= 1 {
        return Ok(());
    }
    let whose = config.map_or(String::new(), |c| format!("configuration \"{c}\": "));
    Err(Error::flag(
        "--starts",
        format!(
            "{whose}--starts {starts} applies to the drift criterion (the mean drift of several \
         starts); --criterion sampling judges one run per point against its reference: \
         leave out --starts (and a study's `starts`) for a sampling scan"
        ),
    )
    .expected("1 with --criterion sampling")
    .got_named(starts.to_string()))
}

/// The sampling criterion from the plan, checked.
pub fn sampling_criterion(
    plan: &StepScanPlan,
    scene: &Scene,
    t_end: f64,
) -> Result<SamplingCriterion> {
    let sampling = &plan.sampling;
    let reference = sampling
        .reference
        .clone()
        .ok_or_else(|| Error::flag("--criterion", "--criterion sampling needs --reference DIR"))?;
    let discard = match &sampling.discard {
        Some(value) => {
            value.evaluate_time(&scene.parameters, "--discard", scene.units.time_units())?
        }
        None => t_end / 5.0,
    };
    let criterion = SamplingCriterion {
        reference,
        pair: crate::analysis::run_analysis::parse_pair(&sampling.pair).map_err(|_| {
            Error::flag(
                "--pair",
                format!(
                    "--pair: \"{}\" is not an element pair like O-O",
                    sampling.pair
                ),
            )
        })?,
        potential_bound: sampling.potential_bound,
        peak_bound: sampling.peak_bound,
        basin_bound: sampling.basin_bound,
        temperature_bound: sampling.temperature_bound,
        // The scan's temperature, set where each point's settings are known.
        temperature: None,
        backbone: match scene_topology(&plan.scene)? {
            Some(topology) => backbone_residues(&topology),
            None => Vec::new(),
        },
        discard,
        blocks: sampling.blocks,
        frames: sampling.frames,
        runs: plan.out.join("runs"),
    };
    criterion.check(t_end)?;
    Ok(criterion)
}

/// `repeats` of the timings: at most [`MAX_REPEATS`] (0 takes none).
pub fn check_repeats(repeats: usize) -> Result<()> {
    if repeats > MAX_REPEATS {
        return Err(Error::flag(
            "--repeats",
            format!("--repeats must be at most {MAX_REPEATS}"),
        )
        .expected(format!("at most {MAX_REPEATS}"))
        .got(repeats.to_string()));
    }
    Ok(())
}

/// Build one point's settings, so a bad combination fails before any time is spent on
/// runs.
fn check_point(setup: &ScanSetup, method: &str, h: f64) -> Result<()> {
    check_starts_possible(setup, method, h)?;
    let settings = point_settings(setup, method, h)?;
    crate::run::prepare::check_settings(&settings)
        .map_err(|e| e.context(&format!("{method} at h = {h}")))
}

/// Build every point of a scan once.
pub fn check_points(setup: &ScanSetup, methods: &[String], steps: &[f64]) -> Result<()> {
    for method in methods {
        for &h in steps {
            check_point(setup, method, h)?;
        }
    }
    Ok(())
}

/// The error of a configuration: names the study file and the configuration's label.
pub fn in_config(study: &Path, label: &str, e: Error) -> Error {
    Error::Structure {
        path: study.to_path_buf(),
        message: format!("configuration \"{label}\": {e}"),
    }
}

/// The flags a study replaces: its configurations name their methods and steps.
pub fn refuse_single_flags(plan: &StepScanPlan) -> Result<()> {
    if !plan.methods.is_empty() || plan.run.method.is_some() || plan.run.h.is_some() {
        return Err(Error::flag(
            "--study",
            "--study names each configuration's method and outer steps: leave out --methods, \
             --method and --h",
        ));
    }
    Ok(())
}

/// A configuration's own run length and inner-level steps over the command line's.
fn config_times(
    plan: &StepScanPlan,
    scene: &Scene,
    setup: &mut ScanSetup,
    config: &StudyConfig,
) -> Result<()> {
    let units = scene.units;
    if let Some(t_end) = &config.run.t_end {
        setup.t_end = t_end.evaluate_time(&scene.parameters, "t_end", units.time_units())?;
        if setup.t_end <= 0.0 {
            return Err(Error::setting("t_end", "t_end must be positive")
                .expected("a positive time")
                .got(setup.t_end.to_string()));
        }
        setup.fit_from = crate::run::drift::fit_from(
            plan.fit_from.as_ref(),
            &scene.parameters,
            units,
            setup.t_end,
        )?;
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
    Ok(())
}

/// One configuration's setup: the command line's, overridden by the configuration's keys;
/// each of its points built once.
pub fn config_setup(
    plan: &StepScanPlan,
    scene: &Scene,
    base: &ScanSetup,
    config: &StudyConfig,
) -> Result<ScanConfig> {
    let mut setup = base.clone();
    let own = RunSpec {
        method: None,
        t_end: None,
        ..config.run.clone()
    };
    setup.base = base.base.overridden_by(&own);
    config_times(plan, scene, &mut setup, config)?;
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
    let steps = parse_steps(&config.steps, scene.units)?;
    for &h in &steps {
        check_point(&setup, &method, h)?;
    }
    Ok(ScanConfig {
        label: config.label.clone(),
        method,
        setup,
        steps,
    })
}
