//! `longstep scan steps`: its flags parsed once into a [`StepScanPlan`], the scan run by
//! [`crate::studies::scan_steps`], and what it found printed (the safe-step table) and drawn
//! (`scan.png`, `ns-per-day.png`).

use std::path::PathBuf;
use std::sync::OnceLock;

use clap::Args;
use indicatif::ProgressBar;

use super::common::progress_bar;
use crate::error::Result;
use crate::settings::{RunSpec, Value};
use crate::studies::criterion::reference::DEFAULT_TEMPERATURE_BOUND;
use crate::studies::criterion::sampling::DEFAULT_BASIN_BOUND;
use crate::studies::plan::{
    DEFAULT_BLOCKS, DEFAULT_FRAMES, DEFAULT_PAIR, DEFAULT_PEAK_BOUND, DEFAULT_POTENTIAL_BOUND,
    SamplingPlan,
};
use crate::studies::{Criterion, StepScanPlan, Watch, scan_steps};

#[derive(Args, Debug)]
#[command(mut_arg("h", |a| a
    .help("Outer steps to scan, as LO:HI:STEP (inclusive) or a comma-separated list; in a \
           scene with real units they may carry time units (1fs:6fs:0.5fs)")
    .value_name("LO:HI:STEP")))]
#[command(mut_arg("method", |a| a.help("One method to scan (added to --methods)")))]
pub struct ScanStepsArgs {
    /// Scene file (TOML), or a topology in its place (AMBER .prmtop/.parm7, GROMACS .top)
    /// with its coordinates (.inpcrd/.rst7, .gro) beside it, same name, or given by
    /// --coordinates.
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
    #[arg(long, value_name = "DIR", default_value = "out/scan-steps")]
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
    #[arg(long, default_value = DEFAULT_PAIR, value_name = "A-B")]
    pub pair: String,
    /// Largest |Δ mean potential energy per molecule| that passes, in the scene's energy
    /// unit (kcal/mol in a real scene).
    #[arg(long, default_value_t = DEFAULT_POTENTIAL_BOUND, value_name = "BOUND")]
    pub potential_bound: f64,
    /// Largest |Δ g(r) first-peak height| that passes.
    #[arg(long, default_value_t = DEFAULT_PEAK_BOUND, value_name = "BOUND")]
    pub peak_bound: f64,
    /// Largest |Δ population| of a backbone (φ, ψ) basin (C7eq/β, αR, αL; pooled over the
    /// residues) that passes, when the scene's topology has a peptide backbone.
    #[arg(long, default_value_t = DEFAULT_BASIN_BOUND, value_name = "BOUND")]
    pub basin_bound: f64,
    /// The temperature error ΔT (kelvin in a real scene) the configurational temperature
    /// and each force-field term's mean energy are held to, as in `analyze --reference`.
    #[arg(long, default_value_t = DEFAULT_TEMPERATURE_BOUND, value_name = "DT")]
    pub temperature_bound: f64,
    /// Start of each run, and of the reference, left out as equilibration (default: a fifth
    /// of the run length --t-end).
    #[arg(long, value_name = "T")]
    pub discard: Option<Value>,
    /// Equal time blocks of the error bars.
    #[arg(long, default_value_t = DEFAULT_BLOCKS)]
    pub blocks: usize,
    /// Trajectory frames per run for g(r).
    #[arg(long, default_value_t = DEFAULT_FRAMES, value_name = "N")]
    pub frames: usize,
}

impl ScanStepsArgs {
    /// The plan these flags give: each flag as written, checked by the scan.
    pub fn plan(&self) -> Result<StepScanPlan> {
        let sampling = &self.sampling;
        Ok(StepScanPlan {
            scene: self.scene.clone(),
            set: self.set.clone(),
            flags: self.source.flags()?,
            start: self.start.clone(),
            precision: self.precision.clone(),
            methods: self.methods.clone(),
            run: self.run.clone(),
            drift_bound: self.drift.drift_bound,
            fit_from: self.drift.fit_from.clone(),
            level_dt: self.level_dt.clone(),
            criterion: self.criterion,
            sampling: SamplingPlan {
                reference: sampling.reference.clone(),
                pair: sampling.pair.clone(),
                potential_bound: sampling.potential_bound,
                peak_bound: sampling.peak_bound,
                basin_bound: sampling.basin_bound,
                temperature_bound: sampling.temperature_bound,
                discard: sampling.discard.clone(),
                blocks: sampling.blocks,
                frames: sampling.frames,
            },
            repeats: self.repeats,
            energy_every: self.energy_every,
            until_decided: self.until_decided,
            starts: self.starts,
            study: self.study.clone(),
            out: self.out.clone(),
            shard: self.shard.clone(),
            quiet: self.quiet,
        })
    }
}

/// The terminal's view of a scan: a progress bar over its points, its notices on stderr.
struct Terminal {
    quiet: bool,
    bar: OnceLock<ProgressBar>,
}

impl Watch for Terminal {
    fn start(&self, points: usize) {
        let _ = self
            .bar
            .set(progress_bar(points as u64, self.quiet, "scan steps"));
    }

    fn point_done(&self) {
        if let Some(bar) = self.bar.get() {
            bar.inc(1);
        }
    }

    fn finish(&self) {
        if let Some(bar) = self.bar.get() {
            bar.finish_and_clear();
        }
    }

    fn say(&self, line: &str) {
        eprintln!("{line}");
    }
}

pub fn scan_steps_command(args: &ScanStepsArgs) -> Result<()> {
    let plan = args.plan()?;
    let terminal = Terminal {
        quiet: plan.quiet,
        bar: OnceLock::new(),
    };
    let scan = scan_steps(&plan, &terminal)?;
    super::draw::draw_scan(&scan.table, &plan.out)?;
    if let Some(timing) = &scan.timing_table {
        super::draw::draw_ns_per_day(timing, &plan.out)?;
    }
    super::scan_report::print_scan_end(&scan);
    Ok(())
}
