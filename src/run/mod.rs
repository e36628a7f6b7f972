//! The run loop: step an integrator to the end time, record energies, stop on a blow-up.

pub mod drift;
pub mod monitor;
pub mod prepare;
pub mod spin;
pub mod verdict;

pub use prepare::{
    PreparedRun, RunRequest, StartReport, check_seed_used, is_stochastic, prepare, start_velocities,
};

use std::path::PathBuf;
use std::time::Instant;

use crate::error::{Error, Result};
use crate::integrators::Integrator;
use crate::io::checkpoint::{Checkpoint, Fingerprint, Restart};
use crate::io::csv::CsvWriter;
use crate::io::summary::{
    Continuation, EnergySummary, ForceEvaluations, RunSummary, Status, TemperatureSummary,
};
use crate::io::trajectory::{Momenta, TrajectoryWriter};
use crate::run::drift::{CONSERVED_COLUMNS, DriftFit};
use crate::run::monitor::EnergyMonitor;
use crate::system::System;
use crate::system::velocities::DegreesOfFreedom;
use crate::units::Units;

#[derive(Clone, Debug)]
pub struct RunOptions {
    pub t_end: f64,
    /// Record energies every this many steps (and at the last step).
    pub energy_every: usize,
    /// Blow-up factor of [`EnergyMonitor`].
    pub blowup: f64,
    /// Where to write `energy.csv`; `None` writes nothing.
    pub energy_csv: Option<PathBuf>,
    /// Trajectory frames (the first, then every `every` steps and the last).
    pub trajectory: Option<TrajectoryOptions>,
    /// The scene's units: the units of `energy.csv`'s columns ([`column_header`]).
    pub units: Units,
    /// Record the kinetic temperature over these degrees of freedom (a `temperature`
    /// column and its mean in the summary).
    pub temperature: Option<DegreesOfFreedom>,
    /// Fit the energy drift over the rows from this time on (default: every row).
    pub fit_from: Option<f64>,
    /// Advanced by one per outer step (a terminal's progress bar; hidden by default).
    pub progress: indicatif::ProgressBar,
    /// Write a checkpoint every so many outer steps (`run --checkpoint-every`).
    pub checkpoint: Option<CheckpointPlan>,
    /// Continue from this checkpoint (`run --restart`): its state is already in the
    /// system ([`prepare`](crate::run::prepare)); the run restores the integrator's hidden
    /// state and counts steps and time from the checkpoint's.
    pub resume: Option<Restart>,
}

/// Where and how often a run writes its checkpoint.
#[derive(Clone, Debug)]
pub struct CheckpointPlan {
    pub path: PathBuf,
    /// Outer steps between checkpoints (counted from the start of the whole run).
    pub every: u64,
    pub fingerprint: Fingerprint,
}

/// A trajectory file: positions through chemfiles, format by extension.
#[derive(Clone, Debug)]
pub struct TrajectoryOptions {
    pub path: PathBuf,
    pub every: usize,
    /// Atom names (element symbols) for the file.
    pub names: Vec<String>,
    /// Velocities beside the positions (extended XYZ only; not with a mass matrix).
    pub velocities: bool,
}

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            t_end: 1.0,
            energy_every: 1,
            blowup: 10.0,
            energy_csv: None,
            trajectory: None,
            units: Units::None,
            temperature: None,
            fit_from: None,
            progress: indicatif::ProgressBar::hidden(),
            checkpoint: None,
            resume: None,
        }
    }
}

/// Integrate `system` with `integrator` to `options.t_end`. An unstable or failed run is
/// not an error: it returns a summary whose status says when and why it stopped, with
/// everything recorded up to then already written.
pub fn run(
    scene: &str,
    system: &mut System,
    integrator: &mut dyn Integrator,
    options: &RunOptions,
) -> Result<RunSummary> {
    check_applicable(scene, system, integrator)?;
    system.forces.reset_counts();
    integrator.setup(system)?;
    resume_state(system, integrator, options)?;
    let first_step = options.resume.as_ref().map_or(0, |r| r.checkpoint.step);
    // The trajectory first: a format chemfiles cannot write fails before energy.csv exists.
    let mut trajectory = open_trajectory(system, options, first_step)?;
    let mut recorder = Recorder::new(system, integrator, options)?;
    if first_step.is_multiple_of(options.energy_every as u64) {
        recorder.record(system, integrator)?;
    }
    if let Some(t) = &mut trajectory {
        t.writer
            .write_state(&system.state.q, momenta(system), first_step, system.state.t)?;
    }
    let t_start = options
        .resume
        .as_ref()
        .map_or(system.state.t, |r| r.checkpoint.t0);
    let mut stepping = Stepping {
        h: integrator.outer_step(),
        t_start,
        steps: first_step,
        status: Status::Ok,
        message: None,
    };
    let started = Instant::now();
    step_loop(
        system,
        integrator,
        options,
        &mut recorder,
        &mut trajectory,
        &mut stepping,
    )?;
    let wall_seconds = started.elapsed().as_secs_f64();
    options.progress.finish_and_clear();
    // A run that stopped early keeps the state it stopped in, for the user to look at.
    if let Some(t) = &mut trajectory
        && t.written != stepping.steps
    {
        let (q, t_now) = (&system.state.q, system.state.t);
        t.writer
            .write_state(q, momenta(system), stepping.steps, t_now)?;
    }
    if let Some(csv) = &mut recorder.csv {
        csv.flush()?;
    }
    let outcome = Outcome {
        h: stepping.h,
        steps: stepping.steps - first_step,
        status: stepping.status,
        message: stepping.message,
        wall_seconds,
    };
    let mut summary = summarise(scene, system, integrator, &recorder, outcome);
    summary.requested_t_end = Some(options.t_end);
    summary.continued_from = options.resume.as_ref().map(|resume| Continuation {
        checkpoint: resume.path.display().to_string(),
        step: resume.checkpoint.step,
        t: resume.checkpoint.t,
        t0: resume.checkpoint.t0,
    });
    Ok(summary)
}

/// Where the stepping loop stands: the outer step, the time the step count counts from,
/// the steps taken (a restart's included) and how the run ends.
struct Stepping {
    h: f64,
    t_start: f64,
    steps: u64,
    status: Status,
    message: Option<String>,
}

/// The trajectory being written: its writer, every how many steps a frame, and the step of
/// the last frame written.
struct OpenTrajectory {
    writer: TrajectoryWriter,
    every: u64,
    written: u64,
}

/// A restart's saved method state into `integrator`, its positions and momenta once more
/// (`setup` may change them), and the pair lists once more as the
/// checkpoint saved them: [`prepare`](crate::run::prepare) restored them before `setup`,
/// so that the cached forces are computed over the writing run's lists, and `setup`'s
/// evaluations may have pruned or rebuilt them since; the writing run's next step starts
/// from the saved lists, so the continued run's does too. With checkpoints asked for, a
/// method whose state cannot be saved says so before the run, not at its first checkpoint.
fn resume_state(
    system: &mut System,
    integrator: &mut dyn Integrator,
    options: &RunOptions,
) -> Result<()> {
    if let Some(resume) = &options.resume {
        check_resume_time(resume, integrator)?;
        let in_checkpoint = |e: Error| Error::Checkpoint {
            path: resume.path.clone(),
            message: e.to_string(),
        };
        integrator
            .restore_state(&resume.checkpoint.integrator)
            .map_err(in_checkpoint)?;
        // `setup` may have moved the state (SIN(R) scales the momenta onto its constraint
        // with fresh thermostat variables): the writing run went on from the saved one.
        system.state.q.copy_from_slice(&resume.checkpoint.q);
        system.state.p.copy_from_slice(&resume.checkpoint.p);
        system
            .forces
            .restore_lists(&resume.checkpoint.lists)
            .map_err(in_checkpoint)?;
    }
    if options.checkpoint.is_some() {
        integrator.save_state()?;
    }
    Ok(())
}

/// The trajectory writer of `options`, if any, its first frame due at `first_step`.
fn open_trajectory(
    system: &System,
    options: &RunOptions,
    first_step: u64,
) -> Result<Option<OpenTrajectory>> {
    let Some(t) = &options.trajectory else {
        return Ok(None);
    };
    let mut writer = TrajectoryWriter::create(&t.path, &t.names, system.dim, system.periodic_box)?;
    if t.velocities {
        if system.mass_matrix.is_some() {
            return Err(Error::flag(
                "--trajectory-velocities",
                "--trajectory-velocities: the velocities of a non-diagonal mass matrix \
                 are not written; leave the flag out",
            )
            .expected("a scene with a diagonal mass matrix"));
        }
        writer = writer.with_velocities()?;
    }
    Ok(Some(OpenTrajectory {
        writer,
        every: t.every.max(1) as u64,
        written: first_step,
    }))
}

/// Step to `options.t_end`: checkpoints, trajectory frames and energy rows as due; a
/// failed step or a blow-up ends the loop with its status.
fn step_loop(
    system: &mut System,
    integrator: &mut dyn Integrator,
    options: &RunOptions,
    recorder: &mut Recorder,
    trajectory: &mut Option<OpenTrajectory>,
    stepping: &mut Stepping,
) -> Result<()> {
    let end_tolerance = 1e-9 * stepping.h;
    while system.state.t < options.t_end - end_tolerance {
        if let Err(failure) = integrator.step(system) {
            stepping.status = Status::Failed;
            stepping.message = Some(failure.0);
            break;
        }
        stepping.steps += 1;
        let steps = stepping.steps;
        if integrator.fixed_step() {
            system.state.t = stepping.t_start + steps as f64 * stepping.h;
        }
        let last = system.state.t >= options.t_end - end_tolerance;
        // The kinetic energy is cheap: check it every step so a blow-up is caught when
        // it happens, not at the next recorded row.
        let kinetic_finite = system.kinetic_energy().is_finite();
        options.progress.inc(1);
        if let Some(plan) = &options.checkpoint
            && kinetic_finite
            && steps.is_multiple_of(plan.every)
        {
            // Every row and frame before the checkpoint on disk first: a run killed after
            // it and continued from it leaves no gap in its outputs.
            if let Some(csv) = &mut recorder.csv {
                csv.sync()?;
            }
            if let Some(t) = trajectory {
                t.writer.sync()?;
            }
            let at = CheckpointAt {
                step: steps,
                t0: stepping.t_start,
                monitor: &recorder.monitor,
            };
            write_checkpoint(plan, system, integrator, at)?;
        }
        if let Some(t) = trajectory
            && (last || !kinetic_finite || steps.is_multiple_of(t.every))
        {
            t.writer
                .write_state(&system.state.q, momenta(system), steps, system.state.t)?;
            t.written = steps;
        }
        if last || !kinetic_finite || steps.is_multiple_of(options.energy_every as u64) {
            let total = recorder.record(system, integrator)?;
            if let Err(reason) = recorder.monitor.record(total) {
                stepping.status = Status::Unstable;
                stepping.message = Some(reason);
                break;
            }
        }
    }
    Ok(())
}

/// The momenta and inverse masses a trajectory frame's velocities come from.
fn momenta(system: &System) -> Option<Momenta<'_>> {
    Some(Momenta {
        p: &system.state.p,
        inverse_mass: &system.inverse_mass,
    })
}

/// A fixed-step method's time is `t0 + step h` exactly (the run loop sets it so): a
/// checkpoint whose three disagree was edited or damaged, and would run for ever or from
/// the wrong time.
fn check_resume_time(resume: &Restart, integrator: &dyn Integrator) -> Result<()> {
    let c = &resume.checkpoint;
    let h = integrator.outer_step();
    if integrator.fixed_step() && c.t0 + c.step as f64 * h != c.t {
        return Err(Error::Checkpoint {
            path: resume.path.clone(),
            message: format!(
                "its time t = {} is not t0 + step h = {} + {} × {h}: the file was changed",
                c.t, c.t0, c.step
            ),
        });
    }
    Ok(())
}

/// Where in the whole run a checkpoint is taken.
struct CheckpointAt<'a> {
    step: u64,
    t0: f64,
    monitor: &'a EnergyMonitor,
}

/// Write the checkpoint: the state, the integrator's hidden state and every term's
/// pair-list state, which a continued run restores ([`crate::run::prepare`]) before
/// recomputing its cached forces at the same positions over the same lists: the same
/// bits, so the writing run goes on untouched (a run with checkpoints is the run without).
/// The fallback for a term that keeps lists but cannot save them: its lists are rebuilt
/// here, as the continued run builds them afresh, and the integrator's cached forces
/// recomputed (`setup`, then its saved state, positions, momenta and the other terms'
/// lists back), as the continued run does. Allocates (the saved states, the JSON), once
/// per checkpoint.
fn write_checkpoint(
    plan: &CheckpointPlan,
    system: &mut System,
    integrator: &mut dyn Integrator,
    at: CheckpointAt,
) -> Result<()> {
    let state = integrator.save_state()?;
    let lists = system.forces.list_states();
    let rebuilt = system.forces.rebuild_lists_without_state(&lists);
    let mut checkpoint = Checkpoint::new(&plan.fingerprint, &system.state.q, &system.state.p);
    checkpoint.every = plan.every;
    checkpoint.step = at.step;
    checkpoint.t0 = at.t0;
    checkpoint.t = system.state.t;
    checkpoint.initial_kinetic = at.monitor.initial_kinetic;
    checkpoint.initial_potentials = at.monitor.initial_potentials.clone();
    checkpoint.integrator = state;
    checkpoint.lists = lists;
    checkpoint.rebuilt_lists = rebuilt;
    checkpoint.write(&plan.path)?;
    if !rebuilt {
        return Ok(());
    }
    let (state, lists) = (checkpoint.integrator, checkpoint.lists);
    let (q, p) = (system.state.q.clone(), system.state.p.clone());
    integrator.setup(system)?;
    integrator.restore_state(&state)?;
    // As the continued run does after its setup (`resume_state`).
    system.state.q.copy_from_slice(&q);
    system.state.p.copy_from_slice(&p);
    system.forces.restore_lists(&lists)
}

/// How a run ended, for its summary.
struct Outcome {
    h: f64,
    steps: u64,
    status: Status,
    message: Option<String>,
    wall_seconds: f64,
}

/// The summary of a finished or stopped run: counts, energies, the drift fit and what the
/// integrator reports.
fn summarise(
    scene: &str,
    system: &System,
    integrator: &dyn Integrator,
    recorder: &Recorder,
    outcome: Outcome,
) -> RunSummary {
    let Outcome {
        h,
        steps,
        status,
        message,
        wall_seconds,
    } = outcome;
    let stopped_early = status != Status::Ok;
    let monitor = &recorder.monitor;
    RunSummary {
        scene: scene.to_string(),
        method: integrator.name().to_string(),
        parameters: integrator.describe(),
        h,
        steps,
        t_end: system.state.t,
        force_evaluations: ForceEvaluations::from(system.forces.counts()),
        energy: EnergySummary {
            initial: monitor.initial,
            last: monitor.last,
            max_abs_error: monitor.max_abs_error,
            max_relative_error: monitor.max_relative_error(),
        },
        wall_seconds,
        status,
        unstable_at: stopped_early.then_some(system.state.t),
        message: message.map(|m| format!("{} stopped: {m}", integrator.name())),
        energy_csv: recorder
            .csv
            .as_ref()
            .map(|c| c.path().display().to_string()),
        fit: recorder
            .fit
            .result(recorder.conserved.map(|(name, _)| name), system.state.t)
            .map(|mut drift| {
                // The kinetic temperature of the fitted rows, where the run records one.
                drift.temperature = recorder.temperature.as_ref().map(|r| {
                    r.degrees_of_freedom
                        .temperature(drift.mean_kinetic, r.boltzmann)
                });
                drift
            }),
        energy_reference: monitor.reference,
        temperature: recorder.temperature.as_ref().map(|t| t.summary()),
        extra: integrator
            .report()
            .map(|(key, value)| (key.to_string(), value))
            .into_iter()
            .collect(),
        ..RunSummary::default()
    }
}

/// Refuse a system the method cannot integrate (magnetic terms, a mass matrix).
fn check_applicable(scene: &str, system: &System, integrator: &dyn Integrator) -> Result<()> {
    if !integrator.handles_magnetic()
        && let Some(term) = system
            .forces
            .terms()
            .iter()
            .find(|t| t.term.magnetic().is_some())
    {
        return Err(Error::setting(
            "method",
            format!(
                "{} \"{}\" is a velocity-dependent (magnetic) term, which {} cannot integrate; \
             use structural-zd or structural-zds",
                term.term.kind(),
                term.name,
                integrator.name()
            ),
        )
        .expected("structural-zd or structural-zds")
        .got_named(integrator.name()));
    }
    if system.mass_matrix.is_some() && !integrator.supports_mass_matrix() {
        return Err(Error::setting(
            "method",
            format!(
                "{scene} has a non-diagonal mass matrix, which {} cannot use; run it with \
             --method pseudo-energy, or set lump = true in the scene's [mass_matrix]",
                integrator.name()
            ),
        )
        .expected("pseudo-energy")
        .got_named(integrator.name()));
    }
    Ok(())
}

/// The unit of an `energy.csv` column by its name: energies (`kinetic*`, `potential*`,
/// `total`, a method's `*_energy` or `*_total`), times (`t`, `h`, `dt`) and the kinetic
/// temperature; counts and anything else have none.
fn column_unit(name: &str, units: Units) -> Option<&'static str> {
    if units == Units::None {
        return None;
    }
    let energy = name.starts_with("kinetic")
        || name.starts_with("potential")
        || name.ends_with("energy")
        || name.ends_with("total");
    match name {
        "t" | "h" | "dt" => Some(units.time_name()),
        "temperature" => Some(units.temperature_name()),
        _ if energy => Some(units.energy_name()),
        _ => None,
    }
}

/// An `energy.csv` header field: the name, with its unit in square brackets in a scene with
/// real units (`t[fs]`, `kinetic[kcal/mol]`, `temperature[K]`); readers take the name
/// before `[` ([`column_matches`](crate::io::energy_table::column_matches)).
pub fn column_header(name: &str, units: Units) -> String {
    match column_unit(name, units) {
        Some(unit) => format!("{name}[{unit}]"),
        None => name.to_string(),
    }
}

/// Running statistics of the kinetic temperature.
struct TemperatureRecord {
    degrees_of_freedom: DegreesOfFreedom,
    boltzmann: f64,
    rows: usize,
    initial: f64,
    last: f64,
    mean: f64,
}

impl TemperatureRecord {
    fn add(&mut self, kinetic: f64) -> f64 {
        let t = self.degrees_of_freedom.temperature(kinetic, self.boltzmann);
        if self.rows == 0 {
            self.initial = t;
        }
        self.rows += 1;
        self.mean += (t - self.mean) / self.rows as f64;
        self.last = t;
        t
    }

    fn summary(&self) -> TemperatureSummary {
        TemperatureSummary {
            mean: self.mean,
            initial: self.initial,
            last: self.last,
            rows: self.rows,
            degrees_of_freedom: self.degrees_of_freedom.count,
        }
    }
}

/// What every recorded row goes through: `energy.csv`, the blow-up monitor, the drift fit
/// and the temperature statistics. Its buffers are sized once.
struct Recorder {
    csv: Option<CsvWriter>,
    row: Vec<f64>,
    potentials: Vec<f64>,
    extras: Vec<f64>,
    monitor: EnergyMonitor,
    fit: DriftFit,
    fit_from: f64,
    /// The conserved energy's column and its index among the method's extra columns.
    conserved: Option<(&'static str, usize)>,
    temperature: Option<TemperatureRecord>,
}

impl Recorder {
    fn new(system: &System, integrator: &dyn Integrator, options: &RunOptions) -> Result<Self> {
        let n_levels = system.forces.n_levels();
        let mut names: Vec<String> = ["t", "kinetic", "potential", "total"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        names.extend((0..n_levels).map(|level| {
            format!(
                "potential_{}",
                system.forces.level_name(level).replace(' ', "_")
            )
        }));
        let extra_columns = integrator.extra_columns();
        names.extend(extra_columns.iter().map(|s| s.to_string()));
        if options.temperature.is_some() {
            names.push("temperature".into());
        }
        let header: Vec<String> = names
            .iter()
            .map(|n| column_header(n, options.units))
            .collect();
        let header: Vec<&str> = header.iter().map(String::as_str).collect();
        let csv = match &options.energy_csv {
            Some(path) => Some(CsvWriter::create(path, &header)?),
            None => None,
        };
        let conserved = extra_columns
            .iter()
            .enumerate()
            .find(|(_, c)| CONSERVED_COLUMNS.contains(c))
            .map(|(i, c)| (*c, i));
        Ok(Recorder {
            csv,
            row: Vec::with_capacity(header.len()),
            potentials: vec![0.0; n_levels],
            extras: Vec::with_capacity(extra_columns.len()),
            monitor: match &options.resume {
                Some(resume) => EnergyMonitor::new(
                    resume.checkpoint.initial_kinetic,
                    &resume.checkpoint.initial_potentials,
                    options.blowup,
                ),
                None => EnergyMonitor::new(
                    system.kinetic_energy(),
                    &system.potential_energies(),
                    options.blowup,
                ),
            },
            fit: DriftFit::default(),
            fit_from: options.fit_from.unwrap_or(f64::NEG_INFINITY),
            conserved,
            temperature: options.temperature.map(|dofs| TemperatureRecord {
                degrees_of_freedom: dofs,
                boltzmann: options.units.boltzmann(),
                rows: 0,
                initial: 0.0,
                last: 0.0,
                mean: 0.0,
            }),
        })
    }

    /// Record the current state; returns the total energy.
    fn record(&mut self, system: &System, integrator: &dyn Integrator) -> Result<f64> {
        let kinetic = system.kinetic_energy();
        system.potential_energies_into(&mut self.potentials);
        let potential: f64 = self.potentials.iter().sum();
        let total = kinetic + potential;
        self.extras.clear();
        if self.csv.is_some() || self.conserved.is_some() {
            integrator.extra_values(system, &mut self.extras);
        }
        let t = system.state.t;
        if t >= self.fit_from - 1e-9 * t.abs().max(1.0) {
            let conserved = self
                .conserved
                .and_then(|(_, i)| self.extras.get(i).copied());
            self.fit.add(t, kinetic, total, conserved);
        }
        let temperature = self.temperature.as_mut().map(|r| r.add(kinetic));
        if let Some(csv) = &mut self.csv {
            self.row.clear();
            self.row.extend([t, kinetic, potential, total]);
            self.row.extend(&self.potentials);
            self.row.extend(&self.extras);
            self.row.extend(temperature);
            csv.row(&self.row)?;
        }
        Ok(total)
    }
}
