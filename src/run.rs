//! The run loop: step an integrator to the end time, record energies, stop on a blow-up.

pub mod monitor;

use std::path::PathBuf;
use std::time::Instant;

use crate::error::{Error, Result};
use crate::integrators::Integrator;
use crate::io::csv::CsvWriter;
use crate::io::summary::{EnergySummary, ForceEvaluations, RunSummary, Status};
use crate::io::trajectory::TrajectoryWriter;
use crate::run::monitor::EnergyMonitor;
use crate::system::System;

#[derive(Clone, Debug)]
pub struct RunOptions {
    pub t_end: f64,
    /// Record energies every this many steps (and at the last step).
    pub energy_every: usize,
    /// Blow-up factor of [`EnergyMonitor`].
    pub blowup: f64,
    /// Where to write `energy.csv`; `None` writes nothing.
    pub energy_csv: Option<PathBuf>,
    /// Keep `(t, kinetic, total)` of every recorded row in the summary (for drift fits).
    pub keep_series: bool,
    /// Trajectory frames (the first, then every `every` steps and the last).
    pub trajectory: Option<TrajectoryOptions>,
}

/// A trajectory file: positions through chemfiles, format by extension.
#[derive(Clone, Debug)]
pub struct TrajectoryOptions {
    pub path: PathBuf,
    pub every: usize,
    /// Atom names (element symbols) for the file.
    pub names: Vec<String>,
}

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            t_end: 1.0,
            energy_every: 1,
            blowup: 10.0,
            energy_csv: None,
            keep_series: false,
            trajectory: None,
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
    if !integrator.handles_magnetic()
        && let Some(term) = system
            .forces
            .terms()
            .iter()
            .find(|t| t.term.magnetic().is_some())
    {
        return Err(Error::input(format!(
            "{} \"{}\" is a velocity-dependent (magnetic) term, which {} cannot integrate; \
             use structural-zd or structural-zds",
            term.term.kind(),
            term.name,
            integrator.name()
        )));
    }
    if system.mass_matrix.is_some() && !integrator.supports_mass_matrix() {
        return Err(Error::input(format!(
            "{scene} has a non-diagonal mass matrix, which {} cannot use; run it with \
             --method pseudo-energy, or set lump = true in the scene's [mass_matrix]",
            integrator.name()
        )));
    }
    system.forces.reset_counts();
    integrator.setup(system)?;
    let h = integrator.outer_step();

    let n_levels = system.forces.n_levels();
    let level_columns: Vec<String> = (0..n_levels)
        .map(|level| {
            format!(
                "potential_{}",
                system.forces.level_name(level).replace(' ', "_")
            )
        })
        .collect();
    let mut header = vec!["t", "kinetic", "potential", "total"];
    header.extend(level_columns.iter().map(String::as_str));
    let extra_columns = integrator.extra_columns();
    header.extend(extra_columns.iter().copied());
    let mut csv = match &options.energy_csv {
        Some(path) => Some(CsvWriter::create(path, &header)?),
        None => None,
    };

    let mut row = Vec::with_capacity(header.len());
    let mut potentials = vec![0.0; n_levels];
    let mut series = Vec::new();
    let mut record = |system: &System,
                      integrator: &dyn Integrator,
                      csv: &mut Option<CsvWriter>|
     -> Result<f64> {
        let kinetic = system.kinetic_energy();
        system.potential_energies_into(&mut potentials);
        let potential: f64 = potentials.iter().sum();
        let total = kinetic + potential;
        if options.keep_series {
            series.push([system.state.t, kinetic, total]);
        }
        if let Some(csv) = csv {
            row.clear();
            row.extend([system.state.t, kinetic, potential, total]);
            row.extend(&potentials);
            integrator.extra_values(system, &mut row);
            csv.row(&row)?;
        }
        Ok(total)
    };

    let mut monitor = EnergyMonitor::new(
        system.kinetic_energy(),
        &system.potential_energies(),
        options.blowup,
    );
    record(system, integrator, &mut csv)?;
    let mut trajectory = match &options.trajectory {
        Some(t) => {
            let mut writer =
                TrajectoryWriter::create(&t.path, &t.names, system.dim, system.periodic_box)?;
            writer.write(&system.state.q, 0, system.state.t)?;
            Some((writer, t.every.max(1) as u64))
        }
        None => None,
    };

    let t_start = system.state.t;
    let started = Instant::now();
    let end_tolerance = 1e-9 * h;
    let mut steps: u64 = 0;
    let mut status = Status::Ok;
    let mut message = None;
    while system.state.t < options.t_end - end_tolerance {
        if let Err(failure) = integrator.step(system) {
            status = Status::Failed;
            message = Some(failure.0);
            break;
        }
        steps += 1;
        if integrator.fixed_step() {
            system.state.t = t_start + steps as f64 * h;
        }
        let last = system.state.t >= options.t_end - end_tolerance;
        // The kinetic energy is cheap: check it every step so a blow-up is caught when
        // it happens, not at the next recorded row.
        let kinetic_finite = system.kinetic_energy().is_finite();
        if let Some((writer, every)) = &mut trajectory
            && (last || !kinetic_finite || steps.is_multiple_of(*every))
        {
            writer.write(&system.state.q, steps, system.state.t)?;
        }
        if last || !kinetic_finite || steps.is_multiple_of(options.energy_every as u64) {
            let total = record(system, integrator, &mut csv)?;
            if let Err(reason) = monitor.record(total) {
                status = Status::Unstable;
                message = Some(reason);
                break;
            }
        }
    }
    let wall_seconds = started.elapsed().as_secs_f64();
    if let Some(csv) = &mut csv {
        csv.flush()?;
    }

    let stopped_early = status != Status::Ok;
    Ok(RunSummary {
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
        energy_csv: csv.as_ref().map(|c| c.path().display().to_string()),
        series,
        extra: integrator
            .report()
            .map(|(key, value)| (key.to_string(), value))
            .into_iter()
            .collect(),
    })
}
