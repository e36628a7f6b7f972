//! `longstep run` and `longstep check`.

use std::collections::BTreeMap;
use std::path::PathBuf;

use clap::Args;

use super::common::EXIT_UNSTABLE;
use crate::error::{Error, Result};
use crate::forces::Precision;
use crate::integrators;
use crate::io::energy_table::EnergyTable;
use crate::io::number::Num;
use crate::io::scene::{Scene, load_scene};
use crate::io::summary::{RunSummary, Status};
use crate::run::drift::judge;
use crate::run::{
    RunOptions, StartReport, TrajectoryOptions, check_seed_used, is_stochastic, run,
    start_velocities,
};
use crate::settings::{MethodSettings, RunSpec, Value};
use crate::split::ParticleClass;
use crate::system::exact::position_error;
use crate::system::velocities::DegreesOfFreedom;
use crate::units::Units;

#[derive(Args, Debug)]
pub struct RunArgs {
    /// Scene file (TOML), for example systems/three-spring.toml.
    pub scene: PathBuf,
    /// Method and step settings; each overrides the scene's [run] table.
    #[command(flatten)]
    pub run: RunSpec,
    /// Set a scene parameter, e.g. --set omega1=12.3 (repeatable; values may be expressions).
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
    /// Output directory for energy.csv (default: the scene's [output] dir, else out/<scene>-<method>).
    #[arg(long)]
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
    /// Print no level table or notices on stderr.
    #[arg(long)]
    pub quiet: bool,
    /// Also draw the energies against time (energy.png and energy.svg in the output directory).
    #[arg(long)]
    pub plot: bool,
    /// Start from the positions of this structure file (e.g. from `minimize --save`): same
    /// atoms in the same order; the scene's force field, velocities and box are kept.
    #[arg(long, value_name = "FILE")]
    pub start: Option<PathBuf>,
    /// Run even when the estimated step count (over 1e10) or output (over 2 GB) is huge.
    #[arg(long)]
    pub allow_large: bool,
    /// How the energy drift is judged at the end of the run.
    #[command(flatten)]
    pub drift: DriftArgs,
    /// Arithmetic of the non-bonded pair forces: double (default) or mixed (f32 pair
    /// arithmetic, f64 accumulation and integration).
    #[arg(long, value_parser = ["double", "mixed"])]
    pub precision: Option<String>,
}

#[derive(Args, Debug)]
pub struct CheckArgs {
    /// Scene file (TOML), or a topology (.prmtop) with its coordinates.
    pub scene: PathBuf,
    /// The coordinates of a topology (.inpcrd, .rst7); default: beside it, same name.
    #[arg(long, value_name = "FILE")]
    pub coordinates: Option<PathBuf>,
    /// Set a scene parameter (repeatable).
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
}

/// How a run's energy drift is judged: fitted at the end of the run over the recorded
/// rows (by the method's conserved energy when it reports one, else the true energy) and
/// compared with a bound; beyond it the summary warns.
#[derive(Args, Clone, Debug, Default)]
pub struct DriftArgs {
    /// Largest |energy drift| not warned about: in kT/ns/dof in a scene with real units
    /// (default 0.05); in a dimensionless scene the fitted change of the energy over the
    /// fitted span relative to |E0| (default 0.01).
    #[arg(long, value_name = "BOUND", allow_negative_numbers = true)]
    pub drift_bound: Option<f64>,
    /// Fit the drift from this time on, skipping a re-equilibration window (e.g. 2ps).
    #[arg(long, value_name = "T", allow_negative_numbers = true)]
    pub fit_from: Option<Value>,
}

impl DriftArgs {
    /// The bound, checked positive.
    pub fn bound(&self) -> Result<Option<f64>> {
        match self.drift_bound {
            Some(b) if !(b.is_finite() && b > 0.0) => Err(Error::input(format!(
                "--drift-bound must be positive and finite, got {b}"
            ))),
            other => Ok(other),
        }
    }

    /// The start of the fit in scene time units, checked to lie in [0, t_end).
    pub fn fit_from(
        &self,
        parameters: &BTreeMap<String, f64>,
        units: Units,
        t_end: f64,
    ) -> Result<Option<f64>> {
        let Some(value) = &self.fit_from else {
            return Ok(None);
        };
        let t = value.evaluate_time(parameters, "--fit-from", units.time_units())?;
        if !(0.0..t_end).contains(&t) {
            return Err(Error::input(format!(
                "--fit-from {t} is outside the run [0, {t_end}): the fit needs rows after it"
            )));
        }
        Ok(Some(t))
    }
}

/// `--precision`: every term that has the choice computes in it; a notice when none has.
fn set_precision(
    scene: &crate::io::scene::Scene,
    name: Option<&str>,
    notices: &mut Vec<String>,
) -> Result<()> {
    let Some(name) = name else {
        return Ok(());
    };
    let precision = Precision::parse(name).ok_or_else(|| {
        Error::input(format!(
            "--precision must be double or mixed, got \"{name}\""
        ))
    })?;
    if scene.system.forces.set_precision(precision) == 0 && precision != Precision::Double {
        notices.push(format!(
            "--precision {name}: no term of this scene has a {name}-precision form; all run in double"
        ));
    }
    Ok(())
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
    let mut scene = load_scene(&args.scene, &args.set)?;
    if let Some(path) = &args.start {
        start_positions(&mut scene, path)?;
    }
    let settings = scene
        .run
        .overridden_by(&args.run)
        .resolve_with_units(&scene.parameters, scene.units)
        .map_err(|e| blame_run_table(&scene, e))?;
    let t_end = settings.t_end.ok_or_else(|| {
        Error::input("no end time: give --t-end or set t_end in the scene's [run] table")
    })?;
    let (energy_every, trajectory_every) = output_intervals(args, &scene)?;
    let seed_source = match args.run.seed {
        Some(_) => "--seed",
        None => "the scene's [run] seed",
    };
    check_seed_used(&settings, seed_source)?;
    let drift_bound = args.drift.bound()?;
    let fit_from = args.drift.fit_from(&scene.parameters, scene.units, t_end)?;

    let mut notices = Vec::new();
    set_precision(&scene, args.precision.as_deref(), &mut notices)?;
    let mut integrator =
        integrators::build(&settings, &mut notices).map_err(|e| blame_run_table(&scene, e))?;
    let start = start_velocities(&mut scene, &settings, &mut notices)?;
    let degrees_of_freedom = temperature_degrees_of_freedom(&scene, start.as_ref());
    notices.extend(async_band_warning(args, &settings)?);
    notices.extend(integrator.notices(&scene.system));

    let steps = check_size(args, &scene, &settings, t_end, energy_every)?;
    let out_dir = output_dir(args, &scene, &settings.method)?;
    if !args.quiet {
        let start_lines = start.iter().flat_map(|s| &s.lines);
        print_header(&scene, start_lines, &notices);
    }
    let options = RunOptions {
        t_end,
        energy_every,
        blowup: settings.blowup,
        energy_csv: Some(out_dir.join("energy.csv")),
        trajectory: trajectory_every.map(|every| trajectory_options(&scene, &out_dir, every)),
        units: scene.units,
        temperature: degrees_of_freedom,
        fit_from,
        progress: run_progress(steps, args.quiet),
    };
    let mut summary = run(
        &scene.name,
        &mut scene.system,
        integrator.as_mut(),
        &options,
    )?;
    complete_summary(args, &scene, &mut summary, drift_bound)?;
    if args.plot {
        plot_energies(&out_dir.join("energy.csv"), &summary, &out_dir)?;
    }
    if let Some(t) = &options.trajectory
        && !args.quiet
    {
        eprintln!("trajectory {}", t.path.display());
    }
    report(args, &summary)
}

/// Steps between energy rows (default 1) and between trajectory frames (default none):
/// the flag, else the scene's `[output]` table; each at least 1.
fn output_intervals(args: &RunArgs, scene: &Scene) -> Result<(usize, Option<usize>)> {
    let energy_every = args.energy_every.or(scene.output.energy_every).unwrap_or(1);
    let trajectory_every = args.trajectory_every.or(scene.output.trajectory_every);
    for (flag, every) in [
        ("--energy-every", Some(energy_every)),
        ("--trajectory-every", trajectory_every),
    ] {
        if every == Some(0) {
            return Err(Error::input(format!("{flag} must be at least 1")));
        }
    }
    Ok((energy_every, trajectory_every))
}

/// The degrees of freedom the kinetic temperature is recorded over: in a real scene, and
/// wherever a temperature is given; a dimensionless scene without one keeps its outputs.
fn temperature_degrees_of_freedom(
    scene: &Scene,
    start: Option<&StartReport>,
) -> Option<DegreesOfFreedom> {
    match start {
        Some(start) => Some(start.degrees_of_freedom),
        None if scene.units == Units::Real => Some(DegreesOfFreedom::of(&scene.system)),
        None => None,
    }
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

/// The lines before a run: force-field report, level table, start velocities, notices.
fn print_header<'a>(
    scene: &Scene,
    start_lines: impl Iterator<Item = &'a String>,
    notices: &[String],
) {
    for line in &scene.forcefield_report {
        eprintln!("{line}");
    }
    eprintln!("{}", scene.system.forces.level_table());
    for line in start_lines {
        eprintln!("{line}");
    }
    for notice in notices {
        eprintln!("notice: {notice}");
    }
}

fn trajectory_options(scene: &Scene, out_dir: &std::path::Path, every: usize) -> TrajectoryOptions {
    let name = scene
        .output
        .trajectory
        .as_deref()
        .unwrap_or("trajectory.xyz");
    TrajectoryOptions {
        path: out_dir.join(name),
        every,
        names: scene.elements.clone(),
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

/// Most outer steps a run is allowed, and most bytes of output it writes, without
/// `--allow-large`: beyond them a mistyped `--t-end 1e300` or `--h 1e-300` would run for
/// ever or fill the disk.
const MAX_STEPS: f64 = 1e10;
const MAX_OUTPUT_BYTES: f64 = 2e9;

/// The run's outer step count, estimated before anything is written, and the refusal of a
/// run too long or too large to be meant (unless `--allow-large`).
fn check_size(
    args: &RunArgs,
    scene: &Scene,
    settings: &MethodSettings,
    t_end: f64,
    energy_every: usize,
) -> Result<f64> {
    let steps = ((t_end - scene.system.state.t) / settings.h)
        .max(0.0)
        .ceil();
    // About 20 bytes a number: energy.csv's ~8 columns, a trajectory's 3 per particle.
    let energy_bytes = steps / energy_every as f64 * 8.0 * 20.0;
    let every = args.trajectory_every.or(scene.output.trajectory_every);
    let frame_bytes = (scene.system.n_particles() * 3 * 20) as f64;
    let trajectory_bytes = every.map_or(0.0, |e| steps / e as f64 * frame_bytes);
    let bytes = energy_bytes + trajectory_bytes;
    if args.allow_large || (steps <= MAX_STEPS && bytes <= MAX_OUTPUT_BYTES) {
        return Ok(steps);
    }
    Err(Error::input(format!(
        "this run would take {steps:.3e} outer steps (h = {}, t_end = {}) and write about {:.2e} bytes \
         (limits {MAX_STEPS:.0e} steps, {MAX_OUTPUT_BYTES:.0e} bytes): check --h and --t-end, record less often \
         (--energy-every, --trajectory-every), or give --allow-large",
        Num(settings.h),
        Num(t_end),
        bytes,
    )))
}

/// A progress bar on a terminal for runs long enough to wait for; hidden otherwise.
fn run_progress(steps: f64, quiet: bool) -> indicatif::ProgressBar {
    if steps < 1e5 {
        return indicatif::ProgressBar::hidden();
    }
    let bar = super::common::terminal_bar(
        steps as u64,
        quiet,
        "{msg} [{bar:40}] {pos}/{len} outer steps, {elapsed} elapsed, ~{eta} left",
        Some("=> "),
    );
    bar.set_message("run");
    bar
}

/// Judge a finished run's energy drift against its bound; a drift beyond it is a warning.
/// A thermostatted (stochastic) method exchanges energy with its bath by design, and a run
/// that stopped early has already said why: neither is judged.
fn judge_drift(summary: &mut RunSummary, bound: Option<f64>) {
    if summary.status != Status::Ok || is_stochastic(&summary.method) {
        return;
    }
    let Some(fit) = &summary.fit else {
        return;
    };
    let report = judge(fit, summary.scene_units, summary.energy_reference, bound);
    summary.warnings.extend(report.warning());
    summary.drift = Some(report);
}

/// Replace the scene's positions by those of a structure file with the same atoms in the
/// same order (the force field, built from the scene's own structure, is kept).
fn start_positions(scene: &mut Scene, path: &std::path::Path) -> Result<()> {
    let structure = crate::io::structure::read_structure_with(path, false)?;
    let system = &mut scene.system;
    let n = system.n_particles();
    let mismatch = |message: String| Error::Structure {
        path: path.to_path_buf(),
        message,
    };
    if structure.atoms.len() != n {
        return Err(mismatch(format!(
            "--start: has {} atoms, the scene {n}",
            structure.atoms.len()
        )));
    }
    for (i, atom) in structure.atoms.iter().enumerate() {
        if let Some(name) = scene.elements.get(i)
            && !name.eq_ignore_ascii_case(&atom.name)
        {
            return Err(mismatch(format!(
                "--start: atom {i} is {}, the scene's is {name}: the atoms must be the \
                 scene's, in its order",
                atom.name
            )));
        }
        let dim = system.dim;
        system.state.q[i * dim..(i + 1) * dim].copy_from_slice(&atom.position[..dim]);
    }
    Ok(())
}

/// Check the scene's own `[run]` table as a run would use it; a missing `h` (it may come
/// from the command line) is stood in for by the inner step or 1.
fn check_run_table(scene: &Scene) -> Result<()> {
    let mut spec = scene.run.clone();
    if spec.h.is_none() {
        spec.h = Some(spec.dt.clone().unwrap_or(Value::Number(1.0)));
    }
    let settings = spec
        .resolve_with_units(&scene.parameters, scene.units)
        .map_err(|e| run_table_error(scene, e))?;
    integrators::build(&settings, &mut Vec::new()).map_err(|e| run_table_error(scene, e))?;
    Ok(())
}

/// An error of the merged run settings, located at the scene's `[run]` table when the table
/// alone gives it (when the command line is not to blame).
fn blame_run_table(scene: &Scene, error: Error) -> Error {
    match check_run_table(scene) {
        Err(located) if located.to_string().ends_with(&error.to_string()) => located,
        _ => error,
    }
}

/// `path:line: in [run]: message`, the line of the table's header.
fn run_table_error(scene: &Scene, error: Error) -> Error {
    let line = std::fs::read_to_string(&scene.path).ok().and_then(|text| {
        text.lines()
            .position(|l| l.trim_start().starts_with("[run]"))
            .map(|i| i + 1)
    });
    let location = match line {
        Some(line) => format!("{}:{line}", scene.path.display()),
        None => scene.path.display().to_string(),
    };
    Error::Scene {
        location,
        message: format!("in [run]: {error}"),
    }
}

pub fn check_command(args: &CheckArgs) -> Result<()> {
    let scene = crate::io::scene::load_scene_with_coordinates(
        &args.scene,
        args.coordinates.as_deref(),
        &args.set,
    )?;
    check_run_table(&scene)?;
    for line in &scene.forcefield_report {
        println!("{line}");
    }
    let system = &scene.system;
    println!("scene      {} — {}", scene.name, scene.description);
    println!(
        "particles  {} in {} D{}",
        system.n_particles(),
        system.dim,
        match &system.periodic_box {
            Some(b) => format!(", periodic box {:?}", &b.lengths[..system.dim]),
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
    println!(
        "energy     E0 = {} (kinetic {}, potential per level {:?})",
        system.total_energy(),
        system.kinetic_energy(),
        system.potential_energies()
    );
    Ok(())
}

/// Kinetic, potential and total energy against time from energy.csv, and the relative
/// error of the total on a second chart.
fn plot_energies(
    csv: &std::path::Path,
    summary: &crate::io::summary::RunSummary,
    out: &std::path::Path,
) -> Result<()> {
    use crate::plot::{AxisSpec, Corner, LineChart, Series};
    let table = EnergyTable::read(csv, &["t", "kinetic", "potential", "total"])?;
    let time = table.column(0);
    // In a real scene the axes carry units, time in ps beyond 1 ps of run.
    let units = summary.scene_units;
    let (time_scale, time_label, energy_label) = match units {
        Units::None => (1.0, "time t".to_string(), "energy".to_string()),
        _ if summary.t_end > 1e3 => (
            1e3,
            "time t (ps)".to_string(),
            format!("energy ({})", units.energy_name()),
        ),
        _ => (
            1.0,
            format!("time t ({})", units.time_name()),
            format!("energy ({})", units.energy_name()),
        ),
    };
    let series = |name: &str, c: usize| {
        Series::line(
            name,
            time.iter()
                .zip(table.column(c))
                .map(|(t, x)| (t / time_scale, *x))
                .collect(),
        )
    };
    let title = format!(
        "{}: {}, h = {}",
        summary.scene,
        summary.method,
        crate::io::summary::format_time(summary.h, units)
    );
    let mut chart = LineChart::new(
        &title,
        AxisSpec::linear(&time_label),
        AxisSpec::linear(&energy_label),
    );
    chart.series = vec![
        series("kinetic", 1),
        series("potential", 2),
        series("total", 3),
    ];
    chart.legend = Corner::UpperRight;
    let initial = summary.energy.initial;
    let scale = if initial != 0.0 { initial.abs() } else { 1.0 };
    let mut error = LineChart::new(
        &format!("{title}: energy error"),
        AxisSpec::linear(&time_label),
        AxisSpec::linear("(E − E0)/|E0|"),
    );
    error.series = vec![Series::line(
        "total",
        time.iter()
            .zip(table.column(3))
            .map(|(t, e)| (t / time_scale, (e - initial) / scale))
            .collect(),
    )];
    for extension in ["png", "svg"] {
        chart.save(&out.join(format!("energy.{extension}")))?;
        error.save(&out.join(format!("energy-error.{extension}")))?;
    }
    Ok(())
}
