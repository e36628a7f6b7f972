//! The one place a run is prepared: a scene and the command line's settings become a
//! ready run — the scene loaded (with `--start` positions), the settings merged over its
//! `[run]` table and resolved, the force precision set, the integrator built, the start
//! velocities drawn, the degrees of freedom counted, the size checked, and the header a
//! run prints. `longstep run`, `scan steps` and the studies all start here; the command
//! line only parses flags and prints.

use std::path::Path;

use crate::error::{Error, Result};
use crate::forces::Precision;
use crate::forces::nonbonded::Nonbonded;
use crate::integrators::{self, Integrator};

use crate::io::checkpoint::{Fingerprint, RequestParts, Restart};
use crate::io::number::Num;
use crate::io::scene::{Scene, SceneFlags, load_scene_with};
use crate::io::summary::{PairListSummary, RunSummary};
use crate::run::{RunOptions, run};
use crate::settings::{MethodSettings, RunSpec, Value};
use crate::system::System;
use crate::system::velocities::{DEFAULT_SEED, DegreesOfFreedom, maxwell_boltzmann};
use crate::units::Units;

/// What a run is asked for: the scene, its parameter overrides, the settings given on the
/// command line, and the start.
#[derive(Clone, Debug)]
pub struct RunRequest<'a> {
    pub scene: &'a Path,
    /// `name=value` settings of the scene's parameters (`--set`).
    pub set: &'a [String],
    /// Settings given on the command line; each overrides the scene's `[run]` table.
    pub overrides: &'a RunSpec,
    /// Where a seed came from, for the message when nothing uses it.
    pub seed_source: &'a str,
    /// Start from the positions of this structure file (`--start`).
    pub start: Option<&'a Path>,
    /// `--precision` of the terms that have the choice.
    pub precision: Option<&'a str>,
    /// A topology's coordinates, `--coulomb`, the PME flags, … ([`SceneFlags`]).
    pub flags: SceneFlags,
    /// Continue from this checkpoint (`run --restart`).
    pub restart: Option<&'a Path>,
}

impl<'a> RunRequest<'a> {
    /// A request for `scene` with `overrides` and nothing else.
    pub fn new(scene: &'a Path, set: &'a [String], overrides: &'a RunSpec) -> Self {
        RunRequest {
            scene,
            set,
            overrides,
            seed_source: "--seed",
            start: None,
            precision: None,
            flags: SceneFlags::default(),
            restart: None,
        }
    }
}

/// A run ready to start.
pub struct PreparedRun {
    pub scene: Scene,
    pub settings: MethodSettings,
    pub integrator: Box<dyn Integrator>,
    /// What the start at a temperature did (`None` without a temperature).
    pub start: Option<StartReport>,
    /// The degrees of freedom the kinetic temperature is recorded over: in a real scene,
    /// and wherever a temperature is given.
    pub degrees_of_freedom: Option<DegreesOfFreedom>,
    /// What the user should know before the run.
    pub notices: Vec<String>,
    /// What a checkpoint of this run must match to be continued from.
    pub fingerprint: Fingerprint,
    /// The checkpoint this run continues from (`run --restart`), its positions, momenta
    /// and time already in the system.
    pub restart: Option<Restart>,
}

/// The scene `request` names, with its flags and `--set` values, at the `--start`
/// positions when given: what `minimize`, `modes`, `analyze` and the studies work on.
pub fn load(request: &RunRequest) -> Result<Scene> {
    let mut scene = load_scene_with(request.scene, &request.flags, request.set)?;
    if let Some(path) = request.start {
        start_positions(&mut scene, path, "--start")?;
    }
    Ok(scene)
}

/// Prepare the run `request` asks for.
pub fn prepare(request: &RunRequest) -> Result<PreparedRun> {
    let mut scene = load(request)?;
    let settings = scene_run_for(&scene.run, request.overrides)
        .overridden_by(request.overrides)
        .resolve_with_units(&scene.parameters, scene.units)
        .map_err(|e| blame_run_table(&scene, e))?;
    check_seed_used(&settings, request.seed_source)?;
    let mut notices = Vec::new();
    set_precision(&scene, request.precision, &mut notices)?;
    scene.apply_molecular_settings(&settings, &mut notices)?;
    let integrator =
        integrators::build(&settings, &mut notices).map_err(|e| blame_run_table(&scene, e))?;
    let mut start = start_velocities(&mut scene, &settings, &mut notices)?;
    let degrees_of_freedom = match &start {
        Some(start) => Some(start.degrees_of_freedom),
        None if scene.units == Units::Real => Some(DegreesOfFreedom::of(&scene.system)),
        None => None,
    };
    notices.extend(integrator.notices(&scene.system));
    let parts = RequestParts {
        set: request.set,
        flags: request.flags.describe(),
        precision: request.precision,
    };
    let fingerprint = Fingerprint::of(&scene, &settings, parts)?;
    let restart = match request.restart {
        Some(path) => Some(restart_from(&mut scene, path, &fingerprint, &mut start)?),
        None => None,
    };
    Ok(PreparedRun {
        scene,
        settings,
        integrator,
        start,
        degrees_of_freedom,
        notices,
        fingerprint,
        restart,
    })
}

/// Read the checkpoint at `path`, check that it belongs to this run, and put its time,
/// positions and momenta into the scene's system; the start report says where the run
/// starts from instead of how velocities were drawn.
fn restart_from(
    scene: &mut Scene,
    path: &Path,
    fingerprint: &Fingerprint,
    start: &mut Option<StartReport>,
) -> Result<Restart> {
    let restart = Restart::read(path)?;
    restart.check_matches(fingerprint)?;
    let checkpoint = &restart.checkpoint;
    let state = &mut scene.system.state;
    state.q.copy_from_slice(&checkpoint.q);
    state.p.copy_from_slice(&checkpoint.p);
    state.t = checkpoint.t;
    scene
        .system
        .forces
        .restore_lists(&checkpoint.lists)
        .map_err(|e| Error::Checkpoint {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
    let line = format!(
        "start      checkpoint {}: step {}, t = {} (the run began at t0 = {}); its positions, \
         momenta and the method's state",
        path.display(),
        checkpoint.step,
        crate::io::summary::format_time(checkpoint.t, scene.units),
        crate::io::summary::format_time(checkpoint.t0, scene.units),
    );
    match start {
        Some(report) => report.lines = vec![line],
        None => {
            *start = Some(StartReport {
                degrees_of_freedom: DegreesOfFreedom::of(&scene.system),
                lines: vec![line],
            })
        }
    }
    Ok(restart)
}

/// Check that `settings` make a run before any time is spent on runs: the integrator
/// builds and a given seed is used (every point of a scan or study).
pub fn check_settings(settings: &MethodSettings) -> Result<()> {
    integrators::build(settings, &mut Vec::new())?;
    check_seed_used(settings, "--seed")
}

/// The integrator `settings` name, from the registry, its notices added to `notices`: the
/// door of the studies that step systems of their own rather than a prepared run (`scan
/// stiffness`, `stability-map --mode integrator`, `scan growth`).
pub fn study_integrator(
    settings: &MethodSettings,
    notices: &mut Vec<String>,
) -> Result<Box<dyn Integrator>> {
    integrators::build(settings, notices)
}

/// [`study_integrator`] set up on `system`, ready to step (its notices dropped).
pub fn study_integrator_on(
    settings: &MethodSettings,
    system: &mut System,
) -> Result<Box<dyn Integrator>> {
    let mut integrator = study_integrator(settings, &mut Vec::new())?;
    integrator.setup(system)?;
    Ok(integrator)
}

impl PreparedRun {
    /// The end time: `--t-end` or the scene's `[run] t_end`.
    pub fn t_end(&self) -> Result<f64> {
        self.settings.t_end.ok_or_else(|| {
            Error::setting(
                "t_end",
                "no end time: give --t-end or set t_end in the scene's [run] table",
            )
            .expected("an end time")
        })
    }

    /// The lines before a run: force-field report, level table, start velocities, notices.
    pub fn header(&self) -> Vec<String> {
        let mut lines = self.scene.forcefield_report.clone();
        lines.push(self.scene.system.forces.level_table());
        lines.extend(self.start.iter().flat_map(|s| s.lines.iter().cloned()));
        lines.extend(self.notices.iter().map(|n| format!("notice: {n}")));
        lines
    }

    /// The outer steps from the scene's start time to `t_end`.
    pub fn outer_steps(&self, t_end: f64) -> f64 {
        ((t_end - self.scene.system.state.t) / self.settings.h)
            .max(0.0)
            .ceil()
    }

    /// The run's outer step count, and the refusal of a run too long or too large to be
    /// meant (unless `plan.allow_large`).
    pub fn check_size(&self, t_end: f64, plan: &OutputPlan) -> Result<f64> {
        let steps = self.outer_steps(t_end);
        // About 20 bytes a number: energy.csv's ~8 columns, a trajectory's 3 per particle.
        let energy_bytes = steps / plan.energy_every as f64 * 8.0 * 20.0;
        let frame_bytes = (self.scene.system.n_particles() * 3 * 20) as f64;
        let trajectory_bytes = plan
            .trajectory_every
            .map_or(0.0, |e| steps / e as f64 * frame_bytes);
        let bytes = energy_bytes + trajectory_bytes;
        let innermost = steps * self.innermost_per_outer();
        let work = innermost * self.scene.system.n_particles() as f64;
        if plan.allow_large
            || (innermost <= MAX_STEPS && work <= MAX_PARTICLE_STEPS && bytes <= MAX_OUTPUT_BYTES)
        {
            return Ok(steps);
        }
        Err(Error::input(format!(
            "this run would take {steps:.3e} outer steps ({innermost:.3e} innermost steps of {} \
             particles; h = {}, t_end = {}) and write about {} MB (limits {MAX_STEPS:.0e} \
             innermost steps, {MAX_PARTICLE_STEPS:.0e} innermost steps × particles, {:.0} MB): \
             check --h, --inner/--dt/--level-steps and --t-end, record less often \
             (--energy-every, --trajectory-every), or give --allow-large",
            self.scene.system.n_particles(),
            Num(self.settings.h),
            Num(t_end),
            Num((bytes / 1e6).ceil()),
            MAX_OUTPUT_BYTES / 1e6,
        )))
    }

    /// Innermost steps per outer step: the product of `--level-steps`, else `--inner K`
    /// between every pair of levels, else one.
    fn innermost_per_outer(&self) -> f64 {
        let levels = self.scene.system.forces.n_levels().max(1);
        match (&self.settings.level_steps, self.settings.inner_steps) {
            (Some(steps), _) => steps.iter().map(|&k| k as f64).product(),
            (None, Some(k)) => (k as f64).powi(levels as i32 - 1),
            (None, None) => 1.0,
        }
    }

    /// Run to `options.t_end`; the summary carries the scene's units and the pair lists'
    /// builds and prunes during the run.
    pub fn run(&mut self, options: &RunOptions) -> Result<RunSummary> {
        let before = pair_lists(&self.scene.system);
        let mut summary = run(
            &self.scene.name,
            &mut self.scene.system,
            self.integrator.as_mut(),
            options,
        )?;
        summary.pair_lists = pair_lists(&self.scene.system);
        for (list, earlier) in summary.pair_lists.iter_mut().zip(&before) {
            list.builds -= earlier.builds;
            list.prunes -= earlier.prunes;
        }
        summary.set_units(self.scene.units);
        Ok(summary)
    }
}

/// The list counts so far and the buffers of every non-bonded term of `system`.
fn pair_lists(system: &System) -> Vec<PairListSummary> {
    let terms = system.forces.terms().iter();
    let nonbonded = terms.filter_map(|t| {
        let term = t.term.as_any()?.downcast_ref::<Nonbonded>()?;
        Some((t.name.clone(), term))
    });
    nonbonded
        .map(|(name, term)| {
            let counts = term.list_counts();
            let (outer_buffer, inner_buffer) = term.list_buffers();
            PairListSummary {
                term: name,
                builds: counts.builds,
                prunes: counts.prunes,
                cutoff: Some(term.list_statistics().0).filter(|c| c.is_finite()),
                outer_buffer,
                inner_buffer,
                outer_pairs: counts.outer_pairs,
                inner_pairs: counts.inner_pairs,
            }
        })
        .collect()
}

/// How often a run records, for its size check.
#[derive(Clone, Copy, Debug)]
pub struct OutputPlan {
    pub energy_every: usize,
    pub trajectory_every: Option<usize>,
    /// Run even when the run is huge (`--allow-large`).
    pub allow_large: bool,
}

/// The scene's `[run]` table as the base of a run whose command line may name another
/// method: the table's settings of its own method that the method named does not use are
/// dropped (issue 43 item 15: `--method verlet` on a topology scene whose `[run]` gives
/// impulse its `inner_steps` is no reason for a notice that verlet ignores them). A
/// setting the command line gives stays, and is noticed when ignored.
fn scene_run_for(scene_run: &RunSpec, overrides: &RunSpec) -> RunSpec {
    let mut base = scene_run.clone();
    let Some(method) = overrides.method.as_deref() else {
        return base;
    };
    if base.method.as_deref() == Some(method) {
        return base;
    }
    let Some(info) = integrators::METHODS.iter().find(|m| m.name == method) else {
        return base;
    };
    if !info.uses.contains(&"inner_steps") {
        base.dt = None;
    }
    macro_rules! drop_unused {
        ($base:ident; $($field:ident: $kind:ident),* $(,)?) => {
            $(if !info.uses.contains(&stringify!($field)) {
                $base.$field = None;
            })*
        };
    }
    crate::settings::method_parameters!(drop_unused, base);
    base
}

/// Most innermost steps a run is allowed, and most bytes of output it writes (100 MB),
/// without `--allow-large`: beyond them a mistyped `--t-end 1e300` or `--h 1e-300` would
/// run for ever or fill the disk.
const MAX_STEPS: f64 = 1e10;
const MAX_OUTPUT_BYTES: f64 = 1e8;

/// Most innermost steps × particles (the work of the innermost forces) a run is allowed
/// without `--allow-large`: 1e12 is beyond a 50 ns run of an 8 867-atom protein at h = 2 fs
/// with 4 inner steps (8.9e11), and far beyond `--inner 1000000000` mistyped on the
/// 648-atom water box for 10 fs (3.2e12).
const MAX_PARTICLE_STEPS: f64 = 1e12;

/// `--precision`: every term that has the choice computes in it; a notice when none has.
fn set_precision(scene: &Scene, name: Option<&str>, notices: &mut Vec<String>) -> Result<()> {
    let Some(name) = name else {
        return Ok(());
    };
    let precision = Precision::parse(name).ok_or_else(|| {
        Error::flag("--precision", "--precision must be double or mixed")
            .expected("double or mixed")
            .got(format!("\"{}\"", name))
    })?;
    if scene.system.forces.set_precision(precision) == 0 && precision != Precision::Double {
        notices.push(format!(
            "--precision {name}: no term of this scene has a {name}-precision form; all run in double"
        ));
    }
    Ok(())
}

/// Replace the scene's positions by those of a structure file with the same atoms in the
/// same order (the force field, built from the scene's own structure, is kept); `flag`
/// names the option the file came from in a message.
pub fn start_positions(scene: &mut Scene, path: &Path, flag: &str) -> Result<()> {
    let structure = crate::io::structure::read_structure_with(path, false)?;
    let system = &mut scene.system;
    let n = system.n_particles();
    let mismatch = |message: String| Error::Structure {
        path: path.to_path_buf(),
        message,
    };
    if structure.atoms.len() != n {
        return Err(mismatch(format!(
            "{flag}: has {} atoms, the scene {n}",
            structure.atoms.len()
        )));
    }
    for (i, atom) in structure.atoms.iter().enumerate() {
        if let Some(name) = scene.elements.get(i)
            && !name.eq_ignore_ascii_case(&atom.name)
        {
            return Err(mismatch(format!(
                "{flag}: atom {i} is {}, the scene's is {name}: the atoms must be the \
                 scene's, in its order",
                atom.name
            )));
        }
        let dim = system.dim;
        system.state.q[i * dim..(i + 1) * dim].copy_from_slice(&atom.position[..dim]);
    }
    if let Some(velocities) = &structure.velocities {
        // p = M v: the file's velocities (a trajectory written with
        // --trajectory-velocities) replace the scene's momenta.
        let dim = system.dim;
        for (i, v) in velocities.iter().enumerate() {
            for (a, va) in v.iter().take(dim).enumerate() {
                let k = i * dim + a;
                let w = system.inverse_mass[k];
                system.state.p[k] = if w > 0.0 { va / w } else { 0.0 };
            }
        }
        scene.velocities_file = Some(path.to_path_buf());
    }
    Ok(())
}

/// The scene `longstep check` shows: loaded with the command line's flags, its `[run]`
/// table checked, and what `overrides` (with the table) ask of the molecule before a run —
/// hydrogen masses, constraints — applied, as a run would; the notices that gives. A
/// missing `h` is stood in for as in [`check_run_table`].
pub fn check_scene(request: &RunRequest) -> Result<(Scene, Vec<String>)> {
    let mut scene = load_scene_with(request.scene, &request.flags, request.set)?;
    check_run_table(&scene)?;
    let mut spec = scene.run.overridden_by(request.overrides);
    if spec.h.is_none() {
        spec.h = Some(spec.dt.clone().unwrap_or(Value::Number(1.0)));
    }
    let settings = spec
        .resolve_with_units(&scene.parameters, scene.units)
        .map_err(|e| blame_run_table(&scene, e))?;
    let mut notices = Vec::new();
    scene.apply_molecular_settings(&settings, &mut notices)?;
    Ok((scene, notices))
}

/// Check the scene's own `[run]` table as a run would use it; a missing `h` (it may come
/// from the command line) is stood in for by the inner step or 1.
pub fn check_run_table(scene: &Scene) -> Result<()> {
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
    error.in_scene(&scene.path, line, "in [run]")
}

/// Whether `method` is stochastic: its registry entry uses a seed
/// ([`MethodInfo::uses`](crate::integrators::MethodInfo)).
pub fn is_stochastic(method: &str) -> bool {
    crate::integrators::METHODS
        .iter()
        .find(|m| m.name == method)
        .is_some_and(|m| m.uses.contains(&"seed"))
}

/// A seed where nothing uses it (no temperature to draw start velocities at, and a method
/// that is not stochastic) is a mistake worth stopping for: the user expects randomness
/// that is not there. `source` names where the seed came from.
pub fn check_seed_used(settings: &MethodSettings, source: &str) -> Result<()> {
    match settings.seed {
        Some(seed) if settings.temperature.is_none() && !is_stochastic(&settings.method) => {
            Err(Error::setting(
                if source == "--seed" { "--seed" } else { "seed" },
                format!(
                    "{source} {seed} is given, but nothing uses it: there is no temperature \
                 (--temperature or the scene's [run] temperature) to draw start velocities \
                 at, and {} is not a stochastic method; drop the seed or give a temperature",
                    settings.method
                ),
            )
            .expected("a temperature or a stochastic method with it")
            .got_named(seed.to_string()))
        }
        _ => Ok(()),
    }
}

/// What a start at a temperature did, for the run header.
pub struct StartReport {
    /// The degrees of freedom the temperature is counted over.
    pub degrees_of_freedom: DegreesOfFreedom,
    /// Lines for the run header.
    pub lines: Vec<String>,
}

/// Start velocities: with a temperature, a Maxwell–Boltzmann draw
/// ([`maxwell_boltzmann`]) replacing the scene's momenta (and its velocity file), seeded
/// by the settings' seed or [`DEFAULT_SEED`]; without one, the scene's momenta, with a
/// notice when every particle starts at rest. Returns `None` without a temperature.
pub fn start_velocities(
    scene: &mut Scene,
    settings: &MethodSettings,
    notices: &mut Vec<String>,
) -> Result<Option<StartReport>> {
    let Some(kt) = settings.kt() else {
        if scene.system.state.p.iter().all(|&p| p == 0.0) {
            notices.push(
                "every particle starts at rest and no temperature is given: the motion comes \
                 from the potential alone (--temperature T draws Maxwell–Boltzmann velocities)"
                    .into(),
            );
        }
        return Ok(None);
    };
    let had_momenta = scene.system.state.p.iter().any(|&p| p != 0.0);
    let seed = settings.seed.unwrap_or(DEFAULT_SEED);
    let start = maxwell_boltzmann(&mut scene.system, kt, seed)?;
    let units = scene.units;
    let temperature = match units {
        Units::None => format!("k_B T = {}", kt),
        _ => format!(
            "{} {}",
            crate::io::summary::significant(kt / units.boltzmann(), 6),
            units.temperature_name()
        ),
    };
    let seed_text = match settings.seed {
        Some(seed) => format!("seed {seed}"),
        None => format!("seed {DEFAULT_SEED}, the default: give --seed N for another draw"),
    };
    let replaced = match &scene.velocities_file {
        Some(path) => format!(", replacing the velocities of {}", path.display()),
        None if had_momenta => ", replacing the scene's momenta".to_string(),
        None => String::new(),
    };
    let dofs = start.degrees_of_freedom;
    let lines = vec![format!(
        "start      Maxwell–Boltzmann velocities at {temperature} ({seed_text}){replaced}; \
         rescaled to exactly that over {}",
        dofs.describe(scene.system.dim, scene.system.n_particles())
    )];
    Ok(Some(StartReport {
        degrees_of_freedom: dofs,
        lines,
    }))
}
