//! The studies: `longstep modes`, `longstep scan steps`, `longstep minimize`.

use std::path::{Path, PathBuf};

use clap::{Args, Subcommand};

mod study;

use super::common::{SCAN_STEPS, keep_shard, or_default, parse_steps, progress_bar};
use crate::analysis::dihedrals::{backbone_residues, scene_topology};
use crate::analysis::minimize::{MinimizeOptions, minimize};
use crate::analysis::modes::{Mode, Resonance, fast_modes, predicted_resonances};
use crate::analysis::run_analysis::RunAnalysis;
use crate::analysis::sampling::{
    SamplingCriterion, check_reference_temperature, run_sampling_points,
};
use crate::analysis::scan::{
    MAX_REPEATS, SafeStep, ScanSetup, StepResult, Timing, point_settings, run_points, safe_steps,
    scan_points, take_timings,
};
use crate::error::{Error, Result};
use crate::io::number::Num;
use std::collections::BTreeMap;

use crate::io::study_csv::StudyTable;
use crate::io::summary::{REAL_DRIFT_UNIT, format_time};
use crate::run::prepare::{self, RunRequest};
use crate::settings::{RunSpec, Value};
use crate::units::Units;

#[derive(Args, Debug)]
pub struct ModesArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Set a scene parameter (repeatable).
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
    /// Minimise the energy (FIRE) before computing the modes.
    #[arg(long)]
    pub minimize: bool,
    /// Range of outer steps in which to predict resonances, as LO:HI.
    #[arg(long, value_name = "LO:HI")]
    pub h_range: Option<String>,
    /// How many of the fastest distinct frequencies enter the predictions.
    #[arg(long, default_value_t = 4)]
    pub top: usize,
    /// Print the result as JSON.
    #[arg(long)]
    pub json: bool,
    /// Draw the spectrum (periods as sticks) with the predicted resonant outer steps
    /// marked, as PNG.
    #[arg(long, value_name = "FILE")]
    pub png: Option<PathBuf>,
    /// The same picture as SVG.
    #[arg(long, value_name = "FILE")]
    pub svg: Option<PathBuf>,
    /// Start from the positions of this structure file (e.g. from `minimize --save`): same
    /// atoms in the same order; the scene's force field, velocities and box are kept.
    #[arg(long, value_name = "FILE")]
    pub start: Option<PathBuf>,
    #[command(flatten)]
    pub source: super::common::SceneArgs,
    #[command(flatten)]
    pub iterative: super::modes_lanczos::LanczosArgs,
}

#[derive(Subcommand, Debug)]
pub enum ScanCommand {
    /// Run each method at each outer step and classify it: stable, drifting or unstable.
    Steps(Box<ScanStepsArgs>),
    /// The largest position error against a scene parameter such as a stiff spring's
    /// frequency (GSS98 Figures 11–13), against an extrapolated Verlet reference.
    Stiffness(Box<super::stiffness::ScanStiffnessArgs>),
    /// Long runs: the energy error's envelope, its fitted growth rate per step, and 2 ln ρ
    /// from the linearised step of the same method (GSS98 Figures 6–10).
    Growth(Box<super::growth::ScanGrowthArgs>),
}

/// What judges a point of `scan steps`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Criterion {
    /// NVE energy drift (the default; NVE methods only).
    Drift,
    /// Potential energy per molecule, g(r) first-peak height and, for a peptide, the
    /// backbone basin populations against --reference.
    Sampling,
}

#[derive(Args, Debug)]
#[command(mut_arg("h", |a| a
    .help("Outer steps to scan, as LO:HI:STEP (inclusive) or a comma-separated list; in a \
           scene with real units they may carry time units (1fs:6fs:0.5fs)")
    .value_name("LO:HI:STEP")))]
#[command(mut_arg("method", |a| a.help("One method to scan (added to --methods)")))]
pub struct ScanStepsArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Methods to scan, comma-separated (--method names one).
    #[arg(long, value_delimiter = ',')]
    pub methods: Vec<String>,
    /// The method settings every point shares, as `longstep run` takes them (--h is the
    /// list of outer steps; --t-end each run's length).
    #[command(flatten)]
    pub run: RunSpec,
    /// How the drift criterion judges: in kT/ns/dof in a scene with real units (default
    /// 0.05, as `run`); in kT per unit time per degree of freedom in a dimensionless one
    /// (default 1e-3).
    #[command(flatten)]
    pub drift: super::run::DriftArgs,
    /// The steps of the inner levels, outermost first, held fixed while --h varies (e.g.
    /// 2fs,0.5fs for a three-level split): each point's --level-steps are h/T1, T1/T2, ….
    #[arg(long, value_delimiter = ',', value_name = "T1,T2,…")]
    pub level_dt: Vec<Value>,
    /// What judges a point: drift (NVE methods; the default) or sampling (against
    /// --reference; the only criterion for thermostatted methods).
    #[arg(long, value_enum)]
    pub criterion: Option<Criterion>,
    #[command(flatten)]
    pub sampling: SamplingArgs,
    /// Timed runs of each method at its largest safe step, at 1 thread and at all threads:
    /// their medians give ns/day (timing.csv). 0 takes no timings.
    #[arg(long, default_value_t = 3, value_name = "N")]
    pub repeats: usize,
    /// Record the energy every N steps for the drift fit.
    #[arg(long, default_value_t = 1)]
    pub energy_every: usize,
    /// Run an undecided point again at twice its length, and again, up to FACTOR times
    /// --t-end (e.g. 4; at most 64; default: never).
    #[arg(long, value_name = "FACTOR")]
    pub until_decided: Option<f64>,
    /// Independent starts per point for the drift criterion (at most 64; default 1):
    /// Maxwell–Boltzmann velocities at --temperature with seeds s, s+1, …, s+N−1 (s: --seed
    /// or the default). A point's drift is their mean, its error the larger of their fits'
    /// √(Σσᵢ²)/N and their spread over √N; any start unstable makes the point unstable.
    #[arg(long, value_name = "N")]
    pub starts: Option<usize>,
    /// Set a scene parameter (repeatable).
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
    /// A study file (TOML) of configurations, each a method with its own outer steps and
    /// run settings, in place of --methods and --h (docs/studies.md); the command line's
    /// run flags are the settings every configuration starts from.
    #[arg(long, value_name = "FILE")]
    pub study: Option<PathBuf>,
    /// Output directory (scan.csv, timing.csv, charts; runs/ under --criterion sampling).
    #[arg(long, default_value = "out/scan-steps")]
    pub out: PathBuf,
    /// Run only the k-th of n deterministic slices of the points (1-based), for job arrays.
    #[arg(long, value_name = "K/N")]
    pub shard: Option<String>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// Start from the positions of this structure file (e.g. from `minimize --save`): same
    /// atoms in the same order; the scene's force field, velocities and box are kept.
    #[arg(long, value_name = "FILE")]
    pub start: Option<PathBuf>,
    #[command(flatten)]
    pub source: super::common::SceneArgs,
    /// Arithmetic of the non-bonded forces in every point's run: double (default) or mixed
    /// (f32 pair arithmetic and PME mesh, f64 accumulation and integration), as
    /// `run --precision`.
    #[arg(long, value_parser = ["double", "mixed"])]
    pub precision: Option<String>,
}

/// The options of `--criterion sampling`.
#[derive(Args, Debug)]
pub struct SamplingArgs {
    /// Reference run directory (energy.csv and a trajectory) for --criterion sampling: a
    /// BAOAB run at a small step at the scan's temperature, e.g. `longstep run SCENE
    /// --method langevin-respa --inner 1 --h 0.5fs --friction 1/ps --temperature 300K
    /// --trajectory-every 100`.
    #[arg(long, value_name = "DIR")]
    pub reference: Option<PathBuf>,
    /// The element pair whose g(r) first-peak height is compared.
    #[arg(long, default_value = "O-O", value_name = "A-B")]
    pub pair: String,
    /// Largest |Δ mean potential energy per molecule| that passes, in the scene's energy
    /// unit (kcal/mol in a real scene).
    #[arg(long, default_value_t = 0.1, value_name = "BOUND")]
    pub potential_bound: f64,
    /// Largest |Δ g(r) first-peak height| that passes.
    #[arg(long, default_value_t = 0.05, value_name = "BOUND")]
    pub peak_bound: f64,
    /// Largest |Δ population| of a backbone (φ, ψ) basin (C7eq/β, αR, αL; pooled over the
    /// residues) that passes, when the scene's topology has a peptide backbone.
    #[arg(long, default_value_t = crate::analysis::sampling::DEFAULT_BASIN_BOUND, value_name = "BOUND")]
    pub basin_bound: f64,
    /// Start of each run, and of the reference, left out as equilibration (default: a fifth
    /// of the run length --t-end).
    #[arg(long, value_name = "T")]
    pub discard: Option<Value>,
    /// Equal time blocks of the error bars.
    #[arg(long, default_value_t = 10)]
    pub blocks: usize,
    /// Trajectory frames per run for g(r).
    #[arg(long, default_value_t = 100, value_name = "N")]
    pub frames: usize,
}

#[derive(Args, Debug)]
pub struct MinimizeArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Set a scene parameter (repeatable).
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
    /// Stop when the largest force component is below this.
    #[arg(long, default_value_t = 1e-6)]
    pub tolerance: f64,
    /// Most FIRE iterations.
    #[arg(long, default_value_t = 100_000)]
    pub max_iterations: usize,
    /// Save the minimised positions to this structure file (format by extension, e.g.
    /// min.xyz); `longstep run SCENE --start min.xyz` starts a run from it.
    #[arg(long, value_name = "FILE")]
    pub save: Option<PathBuf>,
    #[command(flatten)]
    pub source: super::common::SceneArgs,
}

/// `LO:HI` → (lo, hi), in the scene's time units when it has them.
fn parse_range(text: &str, what: &str, units: Units) -> Result<(f64, f64)> {
    let parts: Vec<&str> = text.split(':').collect();
    let [lo, hi] = parts.as_slice() else {
        return Err(Error::flag(what, format!("{what} expects LO:HI")).got(format!("\"{text}\"")));
    };
    let value = |s: &str| -> Result<f64> {
        s.parse::<Value>()
            .map_err(|_| {
                Error::flag(what, format!("bad number in {what}"))
                    .expected("a number LO:HI")
                    .got(format!("\"{s}\""))
            })?
            .evaluate_time(&Default::default(), what, units.time_units())
    };
    let (lo, hi) = (value(lo)?, value(hi)?);
    if lo >= hi {
        return Err(Error::flag(what, format!("{what}: {lo} is not below {hi}")));
    }
    Ok((lo, hi))
}

/// Build every point of a scan once, so a bad combination fails before any time is spent
/// on runs.
fn check_points(setup: &ScanSetup, methods: &[String], steps: &[f64]) -> Result<()> {
    for method in methods {
        for &h in steps {
            crate::analysis::scan::check_starts_possible(setup, method, h)?;
            let settings = point_settings(setup, method, h)?;
            crate::run::prepare::check_settings(&settings)
                .map_err(|e| e.context(&format!("{method} at h = {h}")))?;
        }
    }
    Ok(())
}

pub fn modes_command(args: &ModesArgs) -> Result<()> {
    if args.iterative.wanted() {
        return modes_iterative(args);
    }
    let mut scene = prepare::load(&RunRequest {
        flags: args.source.flags()?,
        start: args.start.as_deref(),
        ..RunRequest::new(&args.scene, &args.set, &RunSpec::default())
    })?;
    let minimized = if args.minimize {
        Some(minimize(&mut scene.system, &MinimizeOptions::default()))
    } else {
        None
    };
    let modes = fast_modes(&mut scene.system);
    let fastest = modes.iter().map(|m| m.frequency).fold(0.0, f64::max);
    let (lo, hi) = match &args.h_range {
        Some(range) => parse_range(range, "--h-range", scene.units)?,
        None if fastest > 0.0 => (0.0, 4.0 * std::f64::consts::TAU / fastest),
        None => (0.0, 0.0),
    };
    let resonances = predicted_resonances(&modes, lo, hi, args.top);
    for path in [&args.png, &args.svg].into_iter().flatten() {
        super::draw::draw_modes(path, &scene.name, &modes, &resonances, hi, scene.units)?;
        if !args.json {
            println!("picture    {}", path.display());
        }
    }
    if args.json {
        let json = serde_json::json!({
            "scene": scene.name,
            "minimization": minimized,
            "modes": modes,
            "h_range": [lo, hi],
            "resonances": resonances,
        });
        println!(
            "{}",
            serde_json::to_string_pretty(&json).map_err(|e| Error::input(e.to_string()))?
        );
        return Ok(());
    }
    if let Some(report) = &minimized {
        println!("minimised  {}", report.text(scene.units));
    }
    print_curvature_warning(&modes, minimized.is_some());
    print_modes(&modes, scene.units);
    print_resonances(&resonances, lo, hi, scene.units);
    Ok(())
}

/// `modes` with --lanczos, constraints or HMR: the iterative path (`cli/modes_lanczos.rs`).
fn modes_iterative(args: &ModesArgs) -> Result<()> {
    let request = super::modes_lanczos::LanczosRequest {
        scene: &args.scene,
        set: &args.set,
        start: args.start.as_deref(),
        flags: args.source.flags()?,
        args: &args.iterative,
        h_range: args.h_range.as_deref(),
        top: args.top,
        json: args.json,
        pictures: [&args.png, &args.svg]
            .into_iter()
            .flatten()
            .cloned()
            .collect(),
    };
    if args.minimize {
        return Err(Error::flag(
            "--minimize",
            "the iterative modes (--lanczos, constraints, HMR) are those of the structure as \
             it runs; minimise first with `longstep minimize --save` and give it as --start",
        ));
    }
    super::modes_lanczos::lanczos_modes(&request, &|range, units| {
        parse_range(range, "--h-range", units)
    })
}

/// Modes of negative curvature predict no resonance; the warning says why they are there.
fn print_curvature_warning(modes: &[Mode], minimized: bool) {
    let unstable = modes.iter().filter(|m| m.unstable).count();
    if unstable > 0 && minimized {
        // The minimiser minimises all forces; the modes are those of the fast ones alone.
        println!(
            "warning    {unstable} modes have negative curvature: the minimum of all forces \
             is not a minimum of the fast forces alone (the slow forces hold it there); \
             these modes do not oscillate and predict no resonance"
        );
    } else if unstable > 0 {
        println!(
            "warning    {unstable} modes have negative curvature: the geometry is not at a \
             minimum of the fast forces (try --minimize)"
        );
    }
}

/// Speed of light in cm/fs, for wavenumbers ω / (2π c).
const LIGHT_CM_PER_FS: f64 = 2.997_924_58e-5;

/// The table of the twelve fastest oscillating modes; in a real scene ω in rad/fs, the
/// period in fs and the wavenumber in cm⁻¹.
fn print_modes(modes: &[Mode], units: Units) {
    let real = units == Units::Real;
    println!("fastest modes of the fast subsystem (level 0):");
    let (omega, period) = if real {
        ("omega (rad/fs)", "period (fs)")
    } else {
        ("omega", "period")
    };
    let wavenumber = if real { "      cm^-1" } else { "" };
    println!(
        "  {:>4}  {omega:>14}  {period:>14}{wavenumber}  {:>9}",
        "#", "component"
    );
    for (i, mode) in modes
        .iter()
        .filter(|m| m.frequency > 0.0)
        .take(12)
        .enumerate()
    {
        let cm = if real {
            let wavenumber = mode.frequency / (std::f64::consts::TAU * LIGHT_CM_PER_FS);
            format!("  {wavenumber:>9.1}")
        } else {
            String::new()
        };
        println!(
            "  {:>4}  {:>14.6}  {:>14.6}{cm}  {:>9}{}",
            i + 1,
            mode.frequency,
            mode.period,
            mode.component,
            if mode.unstable {
                "  (negative curvature)"
            } else {
                ""
            }
        );
    }
}

/// The predicted resonant outer steps in `[lo, hi]` (in fs in a real scene), each with the
/// methods it affects.
fn print_resonances(resonances: &[Resonance], lo: f64, hi: f64, units: Units) {
    let unit = match units {
        Units::Real => " fs",
        Units::None => "",
    };
    println!("predicted resonant outer steps in [{lo}, {hi}]{unit}:");
    for r in resonances {
        let methods: Vec<&str> = ["impulse", "short-average", "linear-average", "long-average"]
            .into_iter()
            .filter(|m| r.kind.affects(m))
            .collect();
        let h = format!("{:.6}{unit}", r.h);
        println!(
            "  h = {h:<14} {:?} k = {}  frequencies {:?}  ({})",
            r.kind,
            r.k,
            r.frequencies,
            methods.join(", ")
        );
    }
}

/// The methods of a scan: `--methods` and `--method`, in order, at least one.
fn scan_methods(args: &ScanStepsArgs) -> Result<Vec<String>> {
    let mut methods = args.methods.clone();
    if let Some(method) = &args.run.method {
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

/// The scan's setup and its outer steps, from the arguments and the scene.
fn scan_setup(
    args: &ScanStepsArgs,
    scene: &crate::io::scene::Scene,
) -> Result<(ScanSetup, Vec<f64>)> {
    let units = scene.units;
    let h = args.run.h.as_ref().ok_or_else(|| {
        Error::flag(
            "--h",
            "scan steps needs the outer steps to scan: give --h LO:HI:STEP or a list",
        )
        .expected("LO:HI:STEP or a list")
    })?;
    let steps = parse_steps(&h.to_string(), units)?;
    Ok((base_setup(args, scene)?, steps))
}

/// The scan's setup from the arguments and the scene: everything but the outer steps.
fn base_setup(args: &ScanStepsArgs, scene: &crate::io::scene::Scene) -> Result<ScanSetup> {
    let units = scene.units;
    let t_end = args
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
        .evaluate_time(&scene.parameters, "--t-end", units.time_units())?;
    if t_end <= 0.0 {
        return Err(Error::flag("--t-end", "--t-end must be positive"));
    }
    if args.energy_every == 0 {
        return Err(Error::flag(
            "--energy-every",
            "--energy-every must be at least 1",
        ));
    }
    let drift_bound = args.drift.bound()?.unwrap_or(match units {
        Units::Real => crate::run::drift::DEFAULT_REAL_BOUND,
        Units::None => crate::analysis::scan::DEFAULT_DIMENSIONLESS_BOUND,
    });
    let base = RunSpec {
        method: None,
        h: None,
        t_end: None,
        blowup: Some(args.run.blowup.unwrap_or(10.0)),
        ..args.run.clone()
    };
    if !args.level_dt.is_empty() && args.run.level_steps.is_some() {
        return Err(Error::flag(
            "--level-dt",
            "give the inner levels either as --level-steps or as --level-dt, not both",
        )
        .expected("--level-steps or --level-dt, not both"));
    }
    if args.level_dt.len() > 16 {
        return Err(Error::flag(
            "--level-dt",
            "--level-dt takes at most 16 steps",
        ));
    }
    let level_dts = args
        .level_dt
        .iter()
        .map(|v| {
            let t = v.evaluate_time(&scene.parameters, "--level-dt", units.time_units())?;
            if t > 0.0 {
                Ok(t)
            } else {
                Err(
                    Error::flag("--level-dt", "--level-dt steps must be positive")
                        .got(t.to_string()),
                )
            }
        })
        .collect::<Result<Vec<f64>>>()?;
    let setup = ScanSetup {
        scene: args.scene.clone(),
        set: args.set.clone(),
        base,
        t_end,
        drift_bound,
        energy_every: args.energy_every,
        fit_from: args.drift.fit_from(&scene.parameters, units, t_end)?,
        level_dts,
        flags: args.source.flags()?,
        start: args.start.clone(),
        precision: args.precision.clone(),
        until_decided: crate::analysis::scan::check_until_decided(args.until_decided)?,
        kinetic_dof: None,
        starts: crate::analysis::scan::check_starts(args.starts)?,
    };
    Ok(setup)
}

/// The criterion: drift for NVE methods unless sampling is asked for; a thermostatted
/// method is never judged by drift, and sampling needs its reference.
fn choose_criterion(args: &ScanStepsArgs, methods: &[String]) -> Result<Criterion> {
    let thermostatted = methods.iter().find(|m| crate::run::is_stochastic(m));
    match (args.criterion, thermostatted) {
        (Some(Criterion::Drift) | None, Some(method)) => {
            Err(crate::analysis::scan::thermostatted_by_drift(method))
        }
        (Some(Criterion::Sampling), _) if args.sampling.reference.is_none() => Err(Error::flag(
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
fn refuse_sampling_starts(criterion: Criterion, starts: usize, config: Option<&str>) -> Result<()> {
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

/// The reference's basin populations with their errors and the residues pooled, or that
/// there is no peptide backbone.
fn basins_notice(c: &SamplingCriterion, reference: &RunAnalysis) -> String {
    let note = c.basins_note();
    match crate::analysis::dihedrals::pooled_populations(&reference.basins) {
        Some(p) => {
            let cells: Vec<String> = crate::analysis::dihedrals::BASINS
                .iter()
                .zip(p)
                .map(|(name, e)| format!("{name} {:.3} ± {:.3}", e.mean, e.error))
                .collect();
            format!("{note}: reference {}", cells.join(", "))
        }
        None => note,
    }
}

/// The sampling criterion from the arguments, checked.
fn sampling_criterion(
    args: &ScanStepsArgs,
    scene: &crate::io::scene::Scene,
    t_end: f64,
) -> Result<SamplingCriterion> {
    let reference =
        args.sampling.reference.clone().ok_or_else(|| {
            Error::flag("--criterion", "--criterion sampling needs --reference DIR")
        })?;
    let discard = match &args.sampling.discard {
        Some(value) => {
            value.evaluate_time(&scene.parameters, "--discard", scene.units.time_units())?
        }
        None => t_end / 5.0,
    };
    let criterion = SamplingCriterion {
        reference,
        pair: crate::analysis::run_analysis::parse_pair(&args.sampling.pair).map_err(|_| {
            Error::flag(
                "--pair",
                format!(
                    "--pair: \"{}\" is not an element pair like O-O",
                    args.sampling.pair
                ),
            )
        })?,
        potential_bound: args.sampling.potential_bound,
        peak_bound: args.sampling.peak_bound,
        basin_bound: args.sampling.basin_bound,
        backbone: match scene_topology(&args.scene)? {
            Some(topology) => backbone_residues(&topology),
            None => Vec::new(),
        },
        discard,
        blocks: args.sampling.blocks,
        frames: args.sampling.frames,
        runs: args.out.join("runs"),
    };
    criterion.check(t_end)?;
    Ok(criterion)
}

/// Analyse the reference run and check that it was made at the scan's temperature.
fn reference_analysis(
    scene: &crate::io::scene::Scene,
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
    let files = super::analyze::run_files(&criterion.reference, &trajectory)?;
    let analysis = criterion.analyzer(scene, dof)?.analyze(&files)?;
    let unit = match scene.units {
        Units::Real => " K",
        Units::None => " (k_B T)",
    };
    check_reference_temperature(&analysis, temperature, unit, &criterion.reference)?;
    Ok(analysis)
}

pub fn scan_steps_command(args: &ScanStepsArgs) -> Result<()> {
    if let Some(path) = &args.study {
        return study::scan_study_command(args, path);
    }
    let scene = args.source.load(&args.scene, &args.set)?;
    let methods = scan_methods(args)?;
    let (mut setup, steps) = scan_setup(args, &scene)?;
    let criterion = choose_criterion(args, &methods)?;
    refuse_sampling_starts(criterion, setup.starts, None)?;
    check_repeats(args.repeats)?;
    check_points(&setup, &methods, &steps)?;
    if !args.quiet {
        async_band_warnings(&setup, &methods, &steps)?;
    }
    let mut points = scan_points(&methods, &steps);
    let total = points.len();
    keep_shard(&mut points, args.shard.as_deref())?;
    std::fs::create_dir_all(&args.out).map_err(|e| Error::io(&args.out, e))?;
    let sampling = match criterion {
        Criterion::Drift => None,
        Criterion::Sampling => {
            let c = sampling_criterion(args, &scene, setup.t_end)?;
            setup.kinetic_dof =
                crate::analysis::sampling::constrained_dof(&setup, &methods[0], steps[0])?;
            let temperature = point_settings(&setup, &methods[0], steps[0])?.temperature;
            let reference = reference_analysis(&scene, &c, temperature, setup.kinetic_dof)?;
            if !args.quiet {
                eprintln!("notice: backbone basins: {}", basins_notice(&c, &reference));
            }
            Some((c, reference))
        }
    };
    let bar = progress_bar(points.len() as u64, args.quiet, "scan steps");
    let results = match &sampling {
        None => run_points(&setup, &points, &|| bar.inc(1))?,
        Some((c, reference)) => run_sampling_points(&setup, c, reference, &points, &|| bar.inc(1))?,
    };
    bar.finish_and_clear();
    if !args.quiet {
        for note in crate::analysis::scan::undecided_notes(&results, scene.units) {
            eprintln!("notice: {note}");
        }
    }

    let path = args.out.join(SCAN_STEPS);
    let meta = scan_meta(args, &setup, total, sampling.as_ref(), scene.units);
    let table = match &sampling {
        None => scan_table(meta.clone(), &results),
        Some((c, _)) => sampling_table(meta.clone(), &results, !c.backbone.is_empty(), scene.units),
    };
    table.write(&path)?;
    super::draw::draw_scan(&table, &args.out)?;
    let safe = safe_steps(&results);
    let timings = write_timings(args, &setup, &safe, meta, scene.units)?;
    let runs = format!("{} runs", results.len());
    print_scan_end(
        (&safe, &|_| steps.clone(), &timings),
        scene.units,
        (criterion, args.shard.as_deref()),
        (&runs, &results, &path),
    );
    Ok(())
}

/// `--repeats` of the timings: at most [`MAX_REPEATS`] (0 takes none).
pub(super) fn check_repeats(repeats: usize) -> Result<()> {
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

/// A scan's safe steps, the outer steps each was chosen from, and the timings.
pub(super) type SafeTable<'a> = (
    &'a [SafeStep],
    &'a dyn Fn(&SafeStep) -> Vec<f64>,
    &'a [Timing],
);

/// The end of a scan: its safe-step table, then how many runs (`runs`: "12 runs") took
/// how long, and where the results are.
pub(super) fn print_scan_end(
    (safe, steps, timings): SafeTable,
    units: Units,
    (criterion, shard): (Criterion, Option<&str>),
    (runs, results, out): (&str, &[StepResult], &Path),
) {
    print_safe_steps(safe, steps, timings, units, (criterion, shard));
    let wall: f64 = results.iter().map(|r| r.wall_seconds).sum();
    eprintln!(
        "{runs}, {wall:.1} s of run time; results in {}",
        out.display()
    );
}

/// Warn before an asynchronous run enters an instability band (small linear scenes).
fn async_band_warnings(setup: &ScanSetup, methods: &[String], steps: &[f64]) -> Result<()> {
    if !methods.iter().any(|m| m == "async-pseudo-energy") {
        return Ok(());
    }
    for &h in steps {
        let mut scene = setup.load_scene()?;
        let settings = point_settings(setup, "async-pseudo-energy", h)?;
        if let Some(warning) =
            crate::analysis::async_stability::band_warning(&mut scene.system, &settings)
        {
            eprintln!("warning: {warning}");
        }
    }
    Ok(())
}

/// Time every method at its largest safe step (not in a shard, nor with `--repeats 0`) and
/// write `timing.csv` and its chart.
fn write_timings(
    args: &ScanStepsArgs,
    setup: &ScanSetup,
    safe: &[SafeStep],
    meta: BTreeMap<String, String>,
    units: Units,
) -> Result<Vec<Timing>> {
    if args.repeats == 0 {
        return Ok(Vec::new());
    }
    if args.shard.is_some() {
        if !args.quiet {
            eprintln!(
                "notice: a shard takes no timings (the largest safe step needs every point); \
                 run the scan whole for ns/day"
            );
        }
        return Ok(Vec::new());
    }
    let timings = take_timings(setup, safe, args.repeats)?;
    if !timings.is_empty() {
        let timing = timing_table(meta, &timings, units);
        timing.write(&args.out.join("timing.csv"))?;
        super::draw::draw_ns_per_day(&timing, &args.out)?;
    }
    Ok(timings)
}

/// Simulated time per day of wall time: ns/day in a scene with real units, scene time
/// units per day otherwise.
fn per_day(t_end: f64, seconds: f64, units: Units) -> f64 {
    crate::io::summary::ns_per_day(t_end, seconds, units)
        .unwrap_or_else(|| t_end / (seconds / 86_400.0))
}

/// The unit of a scan's drift column.
fn drift_unit(units: Units) -> &'static str {
    match units {
        Units::Real => crate::io::summary::REAL_DRIFT_UNIT,
        Units::None => "kT per unit time per dof",
    }
}

fn per_day_unit(units: Units) -> &'static str {
    match units {
        Units::Real => "ns/day",
        Units::None => "time units/day",
    }
}

/// The timing file: wall-clock medians, which no two machines share, apart from the
/// deterministic scan table.
fn timing_table(meta: BTreeMap<String, String>, timings: &[Timing], units: Units) -> StudyTable {
    let per_day_column = match units {
        Units::Real => "ns_per_day",
        Units::None => "time_per_day",
    };
    let mut table = StudyTable::new(
        "scan-steps-timing",
        meta,
        &[
            "method",
            "h",
            "threads",
            "repeats",
            "median_wall_seconds",
            per_day_column,
        ],
    );
    table = table.with_units(&[("h", units.time_name())]);
    for t in timings {
        table.rows.push(vec![
            t.method.clone(),
            Num(t.h).to_string(),
            t.threads.to_string(),
            t.repeats.to_string(),
            Num(t.median_seconds).to_string(),
            Num(per_day(t.t_end, t.median_seconds, units)).to_string(),
        ]);
    }
    with_config_column(table, timings.iter().map(|t| t.config.as_deref()))
}

/// The summary table: one line per method (per configuration of a study), with the
/// scanned steps of each (`steps`) for its islands.
pub(super) fn print_safe_steps(
    safe: &[SafeStep],
    steps: &dyn Fn(&SafeStep) -> Vec<f64>,
    timings: &[Timing],
    units: Units,
    (criterion, shard): (Criterion, Option<&str>),
) {
    // A shard's slice is not the answer: the largest safe step needs every point.
    if let Some(shard) = shard {
        println!(
            "shard {shard}: its points are in scan.csv; `longstep merge` the shards' outputs \
             for the safe-step table"
        );
        return;
    }
    let mut threads: Vec<usize> = timings.iter().map(|t| t.threads).collect();
    threads.sort_unstable();
    threads.dedup();
    let unit = per_day_unit(units);
    let heads: Vec<String> = threads
        .iter()
        .map(|n| format!("{unit} ({n} thr)"))
        .collect();
    let again = match criterion {
        Criterion::Drift => "stable again at",
        Criterion::Sampling => "passes again at",
    };
    let safe_head = match criterion {
        Criterion::Drift => "safe up to",
        Criterion::Sampling => "passes up to",
    };
    let label = |s: &SafeStep| s.config.clone().unwrap_or_else(|| s.method.clone());
    let width = safe
        .iter()
        .map(|s| label(s).chars().count())
        .fold(18, usize::max);
    let first = match safe.iter().any(|s| s.config.is_some()) {
        true => "configuration",
        false => "method",
    };
    let mut head = format!("{first:<width$} {:>12}  {:<24}", safe_head, "first failure");
    for h in &heads {
        head += &format!(" {h:>20}");
    }
    println!("{head}  {again}");
    for s in safe {
        let mut line = format!(
            "{:<width$} {:>12}  {:<24}",
            label(s),
            s.safe_up_to
                .map_or("none".to_string(), |h| format_time(h, units)),
            s.first_failure.map_or("-".to_string(), |(h, v)| format!(
                "{} at {}",
                v.name(),
                format_time(h, units)
            )),
        );
        for &n in &threads {
            let cell = timings
                .iter()
                .find(|t| t.method == s.method && t.config == s.config && t.threads == n)
                .map_or("-".to_string(), |t| {
                    crate::io::summary::significant(per_day(t.t_end, t.median_seconds, units), 4)
                });
            line += &format!(" {cell:>20}");
        }
        println!("{line}  {}", islands(&s.stable_beyond, &steps(s), units));
    }
}

/// The settings a scan's table records on its first line, so shards of different scans
/// never merge: the run length and criteria, and every method setting given.
fn scan_meta(
    args: &ScanStepsArgs,
    setup: &ScanSetup,
    total: usize,
    sampling: Option<&(SamplingCriterion, RunAnalysis)>,
    units: Units,
) -> BTreeMap<String, String> {
    let run = &args.run;
    let mut pairs: Vec<(&str, String)> = vec![
        ("points", total.to_string()),
        ("scene", args.scene.display().to_string()),
        ("set", args.set.join(" ")),
        (
            "t_end",
            run.t_end
                .as_ref()
                .map_or(setup.t_end.to_string(), |t| t.to_string()),
        ),
        ("inner_steps", or_default(run.inner_steps)),
        ("dt", or_default(run.dt.as_ref())),
        ("blowup", setup.base.blowup.unwrap_or(10.0).to_string()),
        (
            "precision",
            args.precision.clone().unwrap_or_else(|| "double".into()),
        ),
    ];
    let given = given_settings(run);
    pairs.extend(given.iter().map(|(k, v)| (*k, v.clone())));
    if !args.level_dt.is_empty() {
        let dts: Vec<String> = args.level_dt.iter().map(|v| v.to_string()).collect();
        pairs.push(("level_dt", dts.join(";")));
    }
    match sampling {
        None => {
            pairs.push(("drift_bound", setup.drift_bound.to_string()));
            pairs.push(("drift_unit", drift_unit(units).to_string()));
            pairs.push(("starts", setup.starts.max(1).to_string()));
            if let Some(t) = setup.fit_from {
                pairs.push(("fit_from", t.to_string()));
            }
        }
        Some((c, reference)) => {
            pairs.extend(sampling_meta(c, reference));
        }
    }
    let mut meta: BTreeMap<String, String> = pairs
        .into_iter()
        .map(|(k, v)| (k.to_string(), v.replace(',', ";")))
        .collect();
    if let Some(shard) = &args.shard {
        meta.insert("shard".into(), shard.clone());
    }
    meta
}

fn sampling_meta(c: &SamplingCriterion, reference: &RunAnalysis) -> Vec<(&'static str, String)> {
    let peak = crate::analysis::sampling::peak_height(reference);
    vec![
        ("criterion", "sampling".into()),
        ("reference", c.reference.display().to_string()),
        ("pair", format!("{}-{}", c.pair.0, c.pair.1)),
        ("potential_bound", c.potential_bound.to_string()),
        ("peak_bound", c.peak_bound.to_string()),
        ("basin_bound", c.basin_bound.to_string()),
        ("basins", basins_notice(c, reference)),
        ("discard", c.discard.to_string()),
        ("blocks", c.blocks.to_string()),
        ("frames", c.frames.to_string()),
        (
            "reference_potential",
            format!(
                "{} ± {}",
                reference.potential_per_molecule.mean, reference.potential_per_molecule.error
            ),
        ),
        (
            "reference_peak",
            peak.map_or("none".into(), |p| format!("{} ± {}", p.mean, p.error)),
        ),
    ]
}

/// The method settings given on the command line, in the user's terms.
fn given_settings(run: &RunSpec) -> Vec<(&'static str, String)> {
    let text = |v: &Option<Value>| v.as_ref().map(|v| v.to_string());
    let string = |v: &Option<String>| v.clone();
    let number = |v: Option<usize>| v.map(|v| v.to_string());
    let candidates: [(&'static str, Option<String>); 20] = [
        (
            "level_steps",
            run.level_steps.as_ref().map(|l| {
                l.iter()
                    .map(|x| x.to_string())
                    .collect::<Vec<_>>()
                    .join(";")
            }),
        ),
        ("jacobian", string(&run.jacobian)),
        ("quadrature", string(&run.quadrature)),
        ("h_slow", text(&run.h_slow)),
        ("h_fast", text(&run.h_fast)),
        ("ratio", number(run.ratio)),
        ("adaptive", text(&run.adaptive)),
        ("control", string(&run.control)),
        ("h_min", text(&run.h_min)),
        ("h_max", text(&run.h_max)),
        ("block", number(run.block)),
        ("tol", text(&run.tol)),
        ("max_iter", number(run.max_iter)),
        ("temperature", text(&run.temperature)),
        ("seed", run.seed.map(|s| s.to_string())),
        ("friction", text(&run.friction)),
        ("thermostats", number(run.thermostats)),
        ("tau", text(&run.tau)),
        ("mollifier", string(&run.mollifier)),
        (
            "molly",
            string(&run.molly_constraints).map(|c| {
                format!(
                    "{c} {}",
                    run.molly_jacobian
                        .clone()
                        .unwrap_or_else(|| "default".into())
                )
            }),
        ),
    ];
    candidates
        .into_iter()
        .filter_map(|(k, v)| v.map(|v| (k, v)))
        .collect()
}

/// The scan's study table by the drift criterion (see `src/io/study_csv.rs`): one row per
/// point in index order.
pub fn scan_table(meta: BTreeMap<String, String>, results: &[StepResult]) -> StudyTable {
    let mut table = StudyTable::new(
        "scan-steps",
        meta.clone(),
        &[
            "index",
            "method",
            "h",
            "status",
            "drift",
            "true_drift",
            "judged_energy",
            "blowup_time",
            "max_relative_error",
            "steps",
            "slow_evaluations",
            "fast_evaluations",
            "hessian_vector",
            "drift_error",
            "decide_at",
            "starts",
        ],
    );
    let drift = match meta.get("drift_unit").map(String::as_str) {
        Some(REAL_DRIFT_UNIT) => (REAL_DRIFT_UNIT, Units::Real.time_name()),
        _ => ("", ""),
    };
    table = table.with_units(&[
        ("h", drift.1),
        ("drift", drift.0),
        ("true_drift", drift.0),
        ("blowup_time", drift.1),
        ("drift_error", drift.0),
        ("decide_at", drift.1),
    ]);
    for r in results {
        let detail = r.drift_detail.as_ref();
        table.rows.push(vec![
            r.index.to_string(),
            r.method.clone(),
            Num(r.h).to_string(),
            r.verdict.name().to_string(),
            Num(r.drift).to_string(),
            detail.map_or(String::new(), |d| Num(d.true_energy).to_string()),
            detail.map_or(String::new(), |d| d.energy.clone()),
            r.blowup_time.map_or(String::new(), |t| Num(t).to_string()),
            Num(r.max_relative_error).to_string(),
            r.steps.to_string(),
            r.slow_evaluations.to_string(),
            r.fast_evaluations.to_string(),
            r.hessian_vector.to_string(),
            detail.map_or(String::new(), |d| Num(d.error).to_string()),
            r.decide_at.map_or(String::new(), |t| Num(t).to_string()),
            r.starts.to_string(),
        ]);
    }
    with_config_column(table, results.iter().map(|r| r.config.as_deref()))
}

/// A study's table gains a `config` column after `index`, the label of each row's
/// configuration; a single scan's table is left as it was.
fn with_config_column<'a>(
    mut table: StudyTable,
    labels: impl Iterator<Item = Option<&'a str>>,
) -> StudyTable {
    let labels: Vec<Option<&str>> = labels.collect();
    if labels.iter().all(Option::is_none) {
        return table;
    }
    table.header.insert(1, "config".into());
    for (row, label) in table.rows.iter_mut().zip(labels) {
        row.insert(1, label.unwrap_or_default().to_string());
    }
    table
}

/// The scan's study table by the sampling criterion: each point's differences to the
/// reference and their combined errors; with a peptide `backbone`, each basin's Δp, its
/// combined error and the run's population. In a scene with real units the headers carry
/// them (`h[fs]`, `potential_difference[kcal/mol]`, `kinetic_temperature[K]`).
pub fn sampling_table(
    meta: BTreeMap<String, String>,
    results: &[StepResult],
    backbone: bool,
    units: Units,
) -> StudyTable {
    let mut table = StudyTable::new(
        "scan-steps",
        meta,
        &[
            "index",
            "method",
            "h",
            "status",
            "potential_difference",
            "potential_combined_error",
            "peak_difference",
            "peak_combined_error",
            "potential_per_molecule",
            "potential_error",
            "peak_height",
            "peak_error",
            "kinetic_temperature",
            "kinetic_temperature_error",
            "blowup_time",
            "steps",
            "slow_evaluations",
            "fast_evaluations",
            "decide_at",
        ],
    )
    .with_units(&sampling_units(units));
    for r in results {
        let mut row = vec![
            r.index.to_string(),
            r.method.clone(),
            Num(r.h).to_string(),
            r.verdict.name().to_string(),
        ];
        match &r.sampling {
            Some(c) => row.extend(
                [
                    c.potential_difference,
                    c.potential_combined_error,
                    c.peak_difference,
                    c.peak_combined_error,
                    c.potential,
                    c.potential_error,
                    c.peak,
                    c.peak_error,
                    c.kinetic_temperature,
                    c.kinetic_temperature_error,
                ]
                .map(|x| Num(x).to_string()),
            ),
            None => row.extend(std::iter::repeat_n(String::new(), 10)),
        }
        row.extend([
            r.blowup_time.map_or(String::new(), |t| Num(t).to_string()),
            r.steps.to_string(),
            r.slow_evaluations.to_string(),
            r.fast_evaluations.to_string(),
            r.decide_at.map_or(String::new(), |t| Num(t).to_string()),
        ]);
        table.rows.push(row);
    }
    if backbone {
        add_basin_columns(&mut table, results);
    }
    with_config_column(table, results.iter().map(|r| r.config.as_deref()))
}

/// The units of the sampling table's columns (empty in a dimensionless scene; the g(r) peak
/// heights and the basin populations have none).
fn sampling_units(units: Units) -> [(&'static str, &'static str); 9] {
    let (time, energy, temperature) = (
        units.time_name(),
        units.energy_name(),
        units.temperature_name(),
    );
    [
        ("h", time),
        ("potential_difference", energy),
        ("potential_combined_error", energy),
        ("potential_per_molecule", energy),
        ("potential_error", energy),
        ("kinetic_temperature", temperature),
        ("kinetic_temperature_error", temperature),
        ("blowup_time", time),
        ("decide_at", time),
    ]
}

/// The basin columns of the sampling table: `{basin}_difference`, `{basin}_combined_error`
/// and `{basin}_population` for each basin (`/` written `_`); empty for a point without a
/// comparison (unstable).
fn add_basin_columns(table: &mut StudyTable, results: &[StepResult]) {
    for name in crate::analysis::dihedrals::BASINS {
        let key = name.replace('/', "_");
        for part in ["difference", "combined_error", "population"] {
            table.header.push(format!("{key}_{part}"));
        }
    }
    for (row, r) in table.rows.iter_mut().zip(results) {
        let basins = r.sampling.as_ref().map_or(&[][..], |c| &c.basins[..]);
        for name in crate::analysis::dihedrals::BASINS {
            match basins.iter().find(|b| b.basin == name) {
                Some(b) => row.extend(
                    [b.difference, b.combined_error, b.population].map(|x| Num(x).to_string()),
                ),
                None => row.extend(std::iter::repeat_n(String::new(), 3)),
            }
        }
    }
}

/// Stable steps beyond the first failure as intervals of consecutive scanned steps,
/// e.g. "0.23–0.255, 0.27–0.305" (`7 fs, 9 fs–10 fs` in a real scene).
fn islands(stable: &[f64], scanned: &[f64], units: Units) -> String {
    let mut sorted: Vec<f64> = scanned.to_vec();
    sorted.sort_by(f64::total_cmp);
    let mut runs: Vec<(f64, f64)> = Vec::new();
    let mut previous: Option<usize> = None;
    for &h in stable {
        let position = sorted.iter().position(|&x| x == h);
        match (position, previous, runs.last_mut()) {
            (Some(i), Some(j), Some(run)) if i == j + 1 => run.1 = h,
            _ => runs.push((h, h)),
        }
        previous = position;
    }
    if runs.is_empty() {
        return "-".into();
    }
    runs.iter()
        .map(|(a, b)| {
            if a == b {
                format_time(*a, units)
            } else {
                format!("{}–{}", format_time(*a, units), format_time(*b, units))
            }
        })
        .collect::<Vec<_>>()
        .join(", ")
}

pub fn minimize_command(args: &MinimizeArgs) -> Result<()> {
    let mut scene = prepare::load(&RunRequest {
        flags: args.source.flags()?,
        ..RunRequest::new(&args.scene, &args.set, &RunSpec::default())
    })?;
    let report = minimize(
        &mut scene.system,
        &MinimizeOptions {
            force_tolerance: args.tolerance,
            max_iterations: args.max_iterations,
        },
    );
    println!("{}", report.text(scene.units));
    if let Some(path) = &args.save {
        let system = &scene.system;
        let mut writer = crate::io::trajectory::TrajectoryWriter::create(
            path,
            &scene.elements,
            system.dim,
            system.periodic_box,
        )?;
        writer.write(&system.state.q, 0, system.state.t)?;
        println!(
            "saved      {} (start a run from it: longstep run {} --start {})",
            path.display(),
            args.scene.display(),
            path.display()
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn islands_carry_the_time_unit_in_a_real_scene() {
        let scanned = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
        assert_eq!(
            islands(&[3.0, 4.0, 6.0], &scanned, Units::Real),
            "3 fs–4 fs, 6 fs"
        );
        assert_eq!(islands(&[3.0, 4.0, 6.0], &scanned, Units::None), "3–4, 6");
        assert_eq!(islands(&[], &scanned, Units::Real), "-");
    }
}
