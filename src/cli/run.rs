//! `longstep run` and `longstep check`.

use std::collections::BTreeMap;
use std::path::PathBuf;

use clap::Args;

use super::common::EXIT_UNSTABLE;
use crate::error::{Error, Result};
use crate::io::checkpoint::CHECKPOINT_FILE;
use crate::io::energy_table::EnergyTable;
use crate::io::manifest::{RunManifest, clear_earlier_run};
use crate::io::scene::{Scene, load_scene};
use crate::io::summary::{RunSummary, Status, format_time};
use crate::run::drift::judge;
use crate::run::prepare::{OutputPlan, PreparedRun, RunRequest, check_scene, prepare};
use crate::run::spin::Spinners;
use crate::run::{CheckpointPlan, RunOptions, TrajectoryOptions, is_stochastic};
use crate::settings::{MethodSettings, RunSpec, Value};
use crate::split::ParticleClass;
use crate::system::exact::position_error;
use crate::units::Units;

#[derive(Args, Debug)]
pub struct RunArgs {
    /// Scene file (TOML), for example systems/three-spring.toml, or a topology in its place
    /// (AMBER .prmtop/.parm7, GROMACS .top) with its coordinates (.inpcrd/.rst7, .gro)
    /// beside it, same name, or given by --coordinates.
    pub scene: PathBuf,
    /// Method and step settings; each overrides the scene's [run] table.
    #[command(flatten)]
    pub run: RunSpec,
    /// Set a scene parameter, e.g. --set omega1=12.3 (repeatable; values may be expressions).
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
    /// Output directory for energy.csv (default: the scene's [output] dir, else out/<scene>-<method>).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Print the summary as one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
    /// Write a row of energy.csv every N steps.
    #[arg(long, value_name = "N")]
    pub energy_every: Option<usize>,
    /// Write a trajectory frame every N steps (file: the scene's [output] trajectory, default
    /// trajectory.xyz in the output directory; any chemfiles format by extension).
    #[arg(long, value_name = "N")]
    pub trajectory_every: Option<usize>,
    /// Write the velocities beside the positions in every trajectory frame (extended XYZ
    /// `velo:R:3` columns, full precision); `--start` reads such a frame back with them.
    #[arg(long)]
    pub trajectory_velocities: bool,
    /// Print no level table or notices on stderr.
    #[arg(long)]
    pub quiet: bool,
    /// Also draw the energies against time (energy.png, energy.svg) and the relative error
    /// of the total energy (energy-error.png, energy-error.svg) in the output directory.
    #[arg(long)]
    pub plot: bool,
    /// Start from the positions of this structure file (e.g. from `minimize --save`): same
    /// atoms in the same order; the scene's force field and box are kept, and its
    /// velocities unless the file carries its own (a frame written with
    /// --trajectory-velocities).
    #[arg(long, value_name = "FILE")]
    pub start: Option<PathBuf>,
    /// Write checkpoint.json in the output directory every T of simulated time (e.g. 2ps;
    /// every round(T/h) outer steps), atomically, for --restart. It holds the pair lists'
    /// state too, so writing it changes nothing: energy.csv is the same bits as without.
    #[arg(long, value_name = "T")]
    pub checkpoint_every: Option<Value>,
    /// Continue from a checkpoint written by --checkpoint-every: give the original command
    /// (same scene, flags and settings; --t-end is the end of the whole run) with its own
    /// --out. energy.csv then holds the rows from the checkpoint on, the same bits as the
    /// uninterrupted run's.
    #[arg(long, value_name = "FILE")]
    pub restart: Option<PathBuf>,
    /// Run even when the estimated work (over 1e10 innermost steps, or 1e12 innermost steps
    /// × particles) or output (over 100 MB) is larger than a run is usually meant to be.
    #[arg(long)]
    pub allow_large: bool,
    /// Reuse an output directory that holds an earlier run's outputs: remove exactly those
    /// files first (the ones its manifest.json lists and the names a run or `analyze`
    /// writes), naming them on stderr. Without it such a directory is refused.
    #[arg(long)]
    pub force: bool,
    /// How the energy drift is judged at the end of the run.
    #[command(flatten)]
    pub drift: DriftArgs,
    /// Arithmetic of the non-bonded forces: double (default) or mixed (f32 pair arithmetic
    /// and PME mesh, f64 accumulation and integration).
    #[arg(long, value_parser = ["double", "mixed"])]
    pub precision: Option<String>,
    #[command(flatten)]
    pub source: super::common::SceneArgs,
}

#[derive(Args, Debug)]
pub struct CheckArgs {
    /// Scene file (TOML), or a topology in its place (AMBER .prmtop/.parm7, GROMACS .top)
    /// with its coordinates (.inpcrd/.rst7, .gro) beside it, same name, or given by
    /// --coordinates.
    pub scene: PathBuf,
    /// Set a scene parameter (repeatable).
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
    #[command(flatten)]
    pub source: super::common::SceneArgs,
    /// Run settings checked as `run` would take them (and the constraints and hydrogen
    /// masses they ask for, applied and reported); each overrides the scene's [run] table.
    #[command(flatten)]
    pub run: RunSpec,
}

/// How a run's energy drift is judged: fitted at the end of the run over the recorded
/// rows (by the method's conserved energy when it reports one, else the true energy) and
/// compared with a bound; beyond it the summary warns.
#[derive(Args, Clone, Debug, Default)]
pub struct DriftArgs {
    /// Largest |energy drift| not warned about: in kT/ns/dof in a scene with real units
    /// (default 0.05); in kT per unit time per degree of freedom in a dimensionless scene
    /// (default 0.001), as `scan steps` judges it.
    #[arg(long, value_name = "BOUND", allow_negative_numbers = true)]
    pub drift_bound: Option<f64>,
    /// Fit the drift from this time on, skipping a re-equilibration window (e.g. 2ps).
    #[arg(long, value_name = "T", allow_negative_numbers = true)]
    pub fit_from: Option<Value>,
}

impl DriftArgs {
    /// The bound, checked positive.
    pub fn bound(&self) -> Result<Option<f64>> {
        crate::run::drift::check_bound(self.drift_bound)
    }

    /// The start of the fit in scene time units, checked to lie in [0, t_end).
    pub fn fit_from(
        &self,
        parameters: &BTreeMap<String, f64>,
        units: Units,
        t_end: f64,
    ) -> Result<Option<f64>> {
        crate::run::drift::fit_from(self.fit_from.as_ref(), parameters, units, t_end)
    }
}

/// Runs inside a rayon pool (threads from `RAYON_NUM_THREADS`, default all cores): parallel
/// force loops then split their work from a worker thread, with no allocation per call.
pub fn run_command(args: &RunArgs) -> Result<i32> {
    let pool = rayon::ThreadPoolBuilder::new()
        .build()
        .map_err(|e| Error::input(format!("cannot start the thread pool: {e}")))?;
    pool.install(|| run_in_pool(args))
}

fn run_in_pool(args: &RunArgs) -> Result<i32> {
    let seed_source = match args.run.seed {
        Some(_) => "--seed",
        None => "the scene's [run] seed",
    };
    let request = RunRequest {
        scene: &args.scene,
        set: &args.set,
        overrides: &args.run,
        seed_source,
        start: args.start.as_deref(),
        precision: args.precision.as_deref(),
        flags: args.source.flags()?,
        restart: args.restart.as_deref(),
    };
    let mut prepared = prepare(&request)?;
    let t_end = prepared.t_end()?;
    let checkpoint_every = checkpoint_interval(args, &prepared)?;
    check_restart_end(&prepared, t_end)?;
    let (energy_every, trajectory_every) = output_intervals(args, &prepared.scene)?;
    let drift_bound = args.drift.bound()?;
    let scene = &prepared.scene;
    let fit_from = args.drift.fit_from(&scene.parameters, scene.units, t_end)?;
    if let Some(warning) = async_band_warning(args, &prepared.settings)? {
        // Before the integrator's own notices, as the header has always listed them.
        let own = prepared.integrator.notices(&prepared.scene.system).len();
        let at = prepared.notices.len() - own;
        prepared.notices.insert(at, warning);
    }
    let plan = OutputPlan {
        energy_every,
        trajectory_every,
        allow_large: args.allow_large,
    };
    let steps = prepared.check_size(t_end, &plan)?;
    let out_dir = output_dir(args, &prepared.scene, &prepared.settings.method)?;
    let dof = prepared.degrees_of_freedom.map(|d| d.count);
    let mut manifest = start_manifest(args, &prepared.scene, &out_dir, trajectory_every, dof)?;
    let checkpoint = checkpoint_every.map(|every| CheckpointPlan {
        path: out_dir.join(CHECKPOINT_FILE),
        every,
        fingerprint: prepared.fingerprint.clone(),
    });
    if !args.quiet {
        prepared
            .header()
            .iter()
            .for_each(|line| eprintln!("{line}"));
    }
    let options = RunOptions {
        t_end,
        energy_every,
        blowup: prepared.settings.blowup,
        energy_csv: Some(out_dir.join("energy.csv")),
        trajectory: trajectory_every.map(|every| {
            trajectory_options(&prepared.scene, &out_dir, every, args.trajectory_velocities)
        }),
        units: prepared.scene.units,
        temperature: prepared.degrees_of_freedom,
        fit_from,
        progress: run_progress(steps, args.quiet),
        checkpoint,
        resume: prepared.restart.clone(),
    };
    // This run owns its pool: its other workers spin between the step's parallel loops.
    let ran = Spinners::around(|| prepared.run(&options));
    let mut summary = ran.inspect_err(|_| manifest.withdraw(&out_dir))?;
    complete_summary(args, &prepared.scene, &mut summary, drift_bound)?;
    if args.plot {
        plot_energies(&out_dir.join("energy.csv"), &summary, &out_dir)?;
    }
    manifest.pair_lists = summary.pair_lists.clone();
    manifest.finish(&out_dir)?;
    if let Some(t) = &options.trajectory
        && !args.quiet
    {
        eprintln!("trajectory {}", t.path.display());
    }
    report(args, &summary)
}

/// Outer steps between checkpoints: `--checkpoint-every T` as round(T/h), at least one;
/// on a restart without the flag the checkpoint's own interval. Another interval is
/// refused only for a checkpoint whose run rebuilt pair lists at it (a term that cannot
/// save them): then a continued run must rebuild where the original did.
fn checkpoint_interval(args: &RunArgs, prepared: &PreparedRun) -> Result<Option<u64>> {
    let scene = &prepared.scene;
    let every = match &args.checkpoint_every {
        Some(value) => {
            let t = value.evaluate_time(
                &scene.parameters,
                "--checkpoint-every",
                scene.units.time_units(),
            )?;
            let steps = (t / prepared.settings.h).round();
            if !(t.is_finite() && t > 0.0 && (1.0..1e18).contains(&steps)) {
                return Err(Error::flag(
                    "--checkpoint-every",
                    format!(
                        "--checkpoint-every must be at least one outer step (h = {}), got {}",
                        format_time(prepared.settings.h, scene.units),
                        format_time(t, scene.units)
                    ),
                ));
            }
            Some(steps as u64)
        }
        None => None,
    };
    let Some(restart) = &prepared.restart else {
        return Ok(every);
    };
    let saved = restart.checkpoint.every;
    match every {
        Some(every) if every != saved && restart.checkpoint.rebuilt_lists => {
            Err(Error::Checkpoint {
                path: restart.path.clone(),
                message: format!(
                    "written every {saved} outer steps, rebuilding pair lists at each, but \
                     --checkpoint-every asks for every {every}: give the original interval \
                     (or leave the flag out to keep it)"
                ),
            })
        }
        Some(every) => Ok(Some(every)),
        None => Ok(Some(saved)),
    }
}

/// A restart must have somewhere to go: `--t-end` (the whole run's end) past the
/// checkpoint's time.
fn check_restart_end(prepared: &PreparedRun, t_end: f64) -> Result<()> {
    let Some(restart) = &prepared.restart else {
        return Ok(());
    };
    let t = restart.checkpoint.t;
    if t_end <= t {
        let units = prepared.scene.units;
        return Err(Error::Checkpoint {
            path: restart.path.clone(),
            message: format!(
                "written at t = {}, but the run ends at t = {}: --t-end is the end of the whole \
                 run and must lie after the checkpoint",
                format_time(t, units),
                format_time(t_end, units)
            ),
        });
    }
    Ok(())
}

/// Steps between energy rows (default 1) and between trajectory frames (default none):
/// the flag, else the scene's `[output]` table; each at least 1.
fn output_intervals(args: &RunArgs, scene: &Scene) -> Result<(usize, Option<usize>)> {
    let energy_every = args.energy_every.or(scene.output.energy_every).unwrap_or(1);
    let trajectory_every = args.trajectory_every.or(scene.output.trajectory_every);
    if args.trajectory_velocities && trajectory_every.is_none() {
        return Err(Error::flag(
            "--trajectory-velocities",
            "--trajectory-velocities needs a trajectory: give --trajectory-every N",
        ));
    }
    for (flag, every) in [
        ("--energy-every", Some(energy_every)),
        ("--trajectory-every", trajectory_every),
    ] {
        if every == Some(0) {
            return Err(Error::flag(flag, format!("{flag} must be at least 1")));
        }
    }
    Ok((energy_every, trajectory_every))
}

/// The asynchronous pseudo-energy scheme's warning before it enters an instability band;
/// checked on a scratch copy of the scene, since the check steps it.
fn async_band_warning(args: &RunArgs, settings: &MethodSettings) -> Result<Option<String>> {
    if settings.method != "async-pseudo-energy" {
        return Ok(None);
    }
    let mut scratch = load_scene(&args.scene, &args.set)?;
    Ok(crate::analysis::async_stability::band_warning(
        &mut scratch.system,
        settings,
    ))
}

/// `--out`, else the scene's `[output] dir`, else `out/<scene>-<method>`; created here,
/// once every setting has been checked.
fn output_dir(args: &RunArgs, scene: &Scene, method: &str) -> Result<PathBuf> {
    let out_dir = args
        .out
        .clone()
        .or_else(|| scene.output.dir.as_ref().map(PathBuf::from))
        .unwrap_or_else(|| PathBuf::from("out").join(format!("{}-{method}", scene.name)));
    std::fs::create_dir_all(&out_dir).map_err(|e| Error::io(&out_dir, e))?;
    Ok(out_dir)
}

/// Clear `out_dir` of an earlier run's outputs (refused without `--force`), then write the
/// manifest of this run ([`RunManifest`]) with the files it plans to write and the degrees
/// of freedom its temperature column counts.
fn start_manifest(
    args: &RunArgs,
    scene: &Scene,
    out_dir: &std::path::Path,
    trajectory_every: Option<usize>,
    dof: Option<usize>,
) -> Result<RunManifest> {
    let mut planned = vec!["energy.csv".to_string()];
    if trajectory_every.is_some() {
        planned.push(trajectory_name(scene).to_string());
    }
    if args.checkpoint_every.is_some() || args.restart.is_some() {
        planned.push(CHECKPOINT_FILE.to_string());
    }
    if args.plot {
        planned.extend(
            [
                "energy.png",
                "energy.svg",
                "energy-error.png",
                "energy-error.svg",
            ]
            .map(String::from),
        );
    }
    let removed = clear_earlier_run(out_dir, &planned, args.force)?;
    if !removed.is_empty() {
        eprintln!(
            "--force: removed the earlier run's {} from {}",
            removed.join(", "),
            out_dir.display()
        );
    }
    let manifest =
        RunManifest::start(std::env::args().collect(), &planned).with_degrees_of_freedom(dof);
    manifest.write(out_dir)?;
    Ok(manifest)
}

/// The trajectory's file name in the output directory: the scene's `[output] trajectory`,
/// else `trajectory.xyz`.
fn trajectory_name(scene: &Scene) -> &str {
    scene
        .output
        .trajectory
        .as_deref()
        .unwrap_or("trajectory.xyz")
}

fn trajectory_options(
    scene: &Scene,
    out_dir: &std::path::Path,
    every: usize,
    velocities: bool,
) -> TrajectoryOptions {
    TrajectoryOptions {
        path: out_dir.join(trajectory_name(scene)),
        every,
        names: scene.elements.clone(),
        velocities,
    }
}

/// What the summary learns after the run: units, precision, the drift verdict, the error
/// against an exact solution.
fn complete_summary(
    args: &RunArgs,
    scene: &Scene,
    summary: &mut RunSummary,
    drift_bound: Option<f64>,
) -> Result<()> {
    summary.set_units(scene.units);
    if let Some(precision) = &args.precision {
        summary.extra.insert(
            "precision".into(),
            serde_json::Value::from(precision.as_str()),
        );
    }
    judge_drift(summary, drift_bound);
    if let Some(exact) = &scene.exact {
        let error = position_error(exact.as_ref(), &scene.system.state)?;
        let value = serde_json::to_value(&error)
            .map_err(|e| Error::input(format!("cannot write the exact error as JSON: {e}")))?;
        summary.extra.insert("exact_error".into(), value);
    }
    Ok(())
}

/// Print the summary (text or JSON); the exit code: 0, or 3 for a run that stopped early.
fn report(args: &RunArgs, summary: &RunSummary) -> Result<i32> {
    if args.json {
        let json = serde_json::to_string_pretty(summary)
            .map_err(|e| Error::input(format!("cannot write the summary as JSON: {e}")))?;
        println!("{json}");
    } else {
        println!("{}", summary.to_text());
    }
    if summary.status == Status::Ok {
        return Ok(0);
    }
    if args.json && !args.quiet {
        let what = match summary.status {
            Status::Unstable => "unstable",
            _ => "failed",
        };
        eprintln!(
            "{what} at t = {}: {}",
            summary.t_end,
            summary.message.as_deref().unwrap_or("")
        );
    }
    Ok(EXIT_UNSTABLE)
}

/// A progress bar with the time left on a terminal (cleared when the run ends; a short run
/// shows it for a moment only), hidden otherwise and under `--quiet`.
fn run_progress(steps: f64, quiet: bool) -> indicatif::ProgressBar {
    super::common::counted_bar(steps as u64, quiet, "run", "outer steps")
}

/// Judge a finished run's energy drift against its bound (pass, fail or undecided,
/// [`crate::run::verdict`]); a failing drift is a warning.
/// A thermostatted (stochastic) method exchanges energy with its bath by design, and a run
/// that stopped early has already said why: neither is judged.
fn judge_drift(summary: &mut RunSummary, bound: Option<f64>) {
    if summary.status != Status::Ok || is_stochastic(&summary.method) {
        return;
    }
    let Some(fit) = &summary.fit else {
        return;
    };
    let report = judge(fit, summary.scene_units, bound);
    summary.warnings.extend(report.warning());
    summary.drift = Some(report);
}

pub fn check_command(args: &CheckArgs) -> Result<()> {
    let request = RunRequest {
        flags: args.source.flags()?,
        ..RunRequest::new(&args.scene, &args.set, &args.run)
    };
    let (scene, notices) = check_scene(&request)?;
    for line in &scene.forcefield_report {
        println!("{line}");
    }
    for notice in &notices {
        println!("notice: {notice}");
    }
    let system = &scene.system;
    println!("scene      {} — {}", scene.name, scene.description);
    println!(
        "particles  {} in {} D{}",
        system.n_particles(),
        system.dim,
        match &system.periodic_box {
            Some(b) => format!(
                ", periodic box {}",
                box_text(&scene, &b.lengths[..system.dim])
            ),
            None => String::new(),
        }
    );
    if !scene.parameters.is_empty() {
        let parameters: Vec<String> = scene
            .parameters
            .iter()
            .map(|(name, value)| format!("{name} = {value}"))
            .collect();
        println!("parameters {}", parameters.join(", "));
    }
    println!("{}", system.forces.level_table());
    let classes = system.forces.classify_particles(system.n_particles());
    let count = |class| classes.iter().filter(|&&c| c == class).count();
    println!(
        "classes    {} fast, {} mixed, {} slow (MEMM18 section 4.1)",
        count(ParticleClass::Fast),
        count(ParticleClass::Mixed),
        count(ParticleClass::Slow)
    );
    let components = system.forces.fast_components(system.n_particles());
    let largest = components.iter().map(Vec::len).max().unwrap_or(0);
    println!(
        "fast graph {} connected components, the largest with {largest} particles",
        components.len()
    );
    if let Some(mass) = &system.mass_matrix {
        println!(
            "mass       non-diagonal, bandwidth {} (only pseudo-energy solves with it)",
            mass.bandwidth()
        );
    }
    if let Some(exact) = &scene.exact {
        println!("exact      {}", exact.describe());
    }
    println!("{}", energy_line(&scene));
    Ok(())
}

/// The energy pictures of a run from its energy.csv: `energy.*` in three panels, each on
/// its own scale (kinetic, potential, and total with the method's conserved energy when
/// it reports one), and `energy-error.*`, the relative change of the total and of the
/// conserved energy — the one the drift verdict judges.
fn plot_energies(
    csv: &std::path::Path,
    summary: &crate::io::summary::RunSummary,
    out: &std::path::Path,
) -> Result<()> {
    use crate::plot::{AxisSpec, LineChart, save_panels};
    let table = EnergyTable::read(csv, &["t", "kinetic", "potential", "total"])?;
    // The method's conserved energy, where its energy.csv has one.
    let conserved = crate::run::drift::CONSERVED_COLUMNS
        .iter()
        .find_map(|name| {
            EnergyTable::read(csv, &[name])
                .ok()
                .map(|t| (name.to_string(), t.column(0).to_vec()))
        });
    let judged = match (&summary.drift, &conserved) {
        (Some(report), _) => report.energy.clone(),
        (None, Some((name, _))) => name.clone(),
        (None, None) => "total".to_string(),
    };
    let (time_scale, time_label, energy_label) = energy_axes(summary);
    let time: Vec<f64> = table.column(0).iter().map(|t| t / time_scale).collect();
    let title = format!(
        "{}: {}, h = {}",
        summary.scene,
        summary.method,
        crate::io::summary::format_time(summary.h, summary.scene_units)
    );
    let panel = |title: &str, lines: Vec<(&str, &[f64])>| {
        let mut chart = LineChart::new(
            title,
            AxisSpec::linear(&time_label),
            AxisSpec::linear(&energy_label),
        );
        for (name, values) in lines {
            chart.series.push(along(&time, name, values));
        }
        chart
    };
    let mut totals: Vec<(&str, &[f64])> = vec![("total", table.column(3))];
    if let Some((name, values)) = &conserved {
        totals.push((name.as_str(), values));
    }
    let panels = [
        panel(&title, vec![("kinetic", table.column(1))]),
        panel("potential energy", vec![("potential", table.column(2))]),
        panel(
            "total energy and the energy the method conserves",
            totals.clone(),
        ),
    ];
    let initial = summary.energy.initial;
    let scale = if initial != 0.0 { initial.abs() } else { 1.0 };
    let mut error = LineChart::new(
        &format!("{title}: energy error"),
        AxisSpec::linear(&time_label),
        AxisSpec::linear("(E − E(0))/|E0|"),
    );
    for (name, values) in totals {
        let change: Vec<f64> = values.iter().map(|e| (e - values[0]) / scale).collect();
        let label = if judged == name {
            format!("{name} (judged by the drift verdict)")
        } else {
            name.to_string()
        };
        error.series.push(along(&time, &label, &change));
    }
    for extension in ["png", "svg"] {
        save_panels(
            &panels,
            &out.join(format!("energy.{extension}")),
            (900, 900),
        )?;
        error.save(&out.join(format!("energy-error.{extension}")))?;
    }
    Ok(())
}

/// A line of `values` against `time`.
fn along(time: &[f64], name: &str, values: &[f64]) -> crate::plot::Series {
    crate::plot::Series::line(
        name,
        time.iter().copied().zip(values.iter().copied()).collect(),
    )
}

/// The time scale (ps beyond 1 ps of run in a real scene) and the axis labels, with units.
fn energy_axes(summary: &crate::io::summary::RunSummary) -> (f64, String, String) {
    match summary.scene_units {
        Units::None => (1.0, "time t".to_string(), "energy".to_string()),
        units if summary.t_end > 1e3 => (
            1e3,
            "time t (ps)".to_string(),
            format!("energy ({})", units.energy_name()),
        ),
        units => (
            1.0,
            format!("time t ({})", units.time_name()),
            format!("energy ({})", units.energy_name()),
        ),
    }
}

/// `check`'s energy line: E0, kinetic and per-level potential energies to 10 significant
/// digits, in the scene's energy unit.
fn energy_line(scene: &Scene) -> String {
    use crate::io::summary::significant;
    let system = &scene.system;
    let unit = match scene.units {
        crate::units::Units::None => String::new(),
        units => format!(" {}", units.energy_name()),
    };
    let levels: Vec<String> = system
        .potential_energies()
        .iter()
        .map(|&e| significant(e, 10))
        .collect();
    format!(
        "energy     E0 = {}{unit} (kinetic {}, potential per level [{}])",
        significant(system.total_energy(), 10),
        significant(system.kinetic_energy(), 10),
        levels.join(", ")
    )
}

/// The periodic box as `a × b × c` to 10 significant digits, with the length unit.
fn box_text(scene: &Scene, lengths: &[f64]) -> String {
    let unit = match scene.units {
        crate::units::Units::None => String::new(),
        units => format!(" {}", units.length_name()),
    };
    let sides: Vec<String> = lengths
        .iter()
        .map(|&l| crate::io::summary::significant(l, 10))
        .collect();
    format!("{}{unit}", sides.join(" × "))
}
