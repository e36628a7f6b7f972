//! `longstep chart work-precision`: error against cost for methods and outer steps, as
//! tables and pictures (drawn by `super::draw`).

use std::collections::BTreeMap;
use std::path::PathBuf;

use clap::{Args, Subcommand};

use super::common::{
    InnerSteps, WALL_TIME, WORK_PRECISION, check_methods, meta_of, or_default, parse_shard,
    parse_steps, progress_bar,
};
use super::draw::draw_work_precision;
use crate::analysis::work_precision::{
    CostWeights, PrecisionResult, Samples, StudySetup, measure_cost_weights, reference, run_points,
    sample_times,
};
use crate::error::{Error, Result};
use crate::io::number::Num;
use crate::io::scene::SceneFlags;
use crate::io::study_csv::StudyTable;
use crate::run::prepare::{self, RunRequest};
use crate::settings::{RunSpec, Value, whole_ratio};

#[derive(Subcommand, Debug)]
pub enum ChartCommand {
    /// Error against cost for methods and outer steps: CSV, PNG and SVG.
    WorkPrecision(WorkPrecisionArgs),
}

// The shared inner-step flags (common::InnerSteps) in this chart's words; its --dt takes no
// value that starts with `-`.
#[derive(Args, Debug)]
#[command(mut_arg("inner_steps", |a| a
    .help("Inner steps K per outer step for the multiple-time-step methods")))]
#[command(mut_arg("dt", |a| a
    .help("A fixed inner step instead of --inner")
    .allow_negative_numbers(false)))]
pub struct WorkPrecisionArgs {
    /// Scene file (TOML), or a topology in its place (AMBER .prmtop/.parm7, GROMACS .top)
    /// with its coordinates (.inpcrd/.rst7, .gro) beside it, same name, or given by
    /// --coordinates.
    pub scene: PathBuf,
    /// Methods, comma-separated.
    #[arg(long, alias = "method", value_delimiter = ',', required = true)]
    pub methods: Vec<String>,
    /// Outer steps, comma-separated (or LO:HI:STEP).
    #[arg(long)]
    pub h_list: String,
    /// End time.
    #[arg(long)]
    pub t_end: Value,
    /// Sample interval of the position error (default: the largest h; every h must divide it).
    #[arg(long)]
    pub sample: Option<Value>,
    #[command(flatten)]
    pub inner: InnerSteps,
    /// Quadrature of the pseudo-energy methods.
    #[arg(long)]
    pub quadrature: Option<String>,
    /// Block size of the structural methods.
    #[arg(long)]
    pub block: Option<usize>,
    /// Method of the reference solution.
    #[arg(long, default_value = "verlet")]
    pub reference_method: String,
    /// Step of the reference solution (default: the smallest h / 64, fitted to the sample).
    #[arg(long)]
    pub reference_h: Option<Value>,
    /// Relative costs of a fast gradient, a slow gradient and a Hessian-vector product
    /// (F,S,H), instead of timing them. Give the same weights to every shard of a study.
    #[arg(long, value_delimiter = ',', value_name = "F,S,H")]
    pub weights: Option<Vec<f64>>,
    /// Blow-up factor: a run beyond it is drawn as unstable.
    #[arg(long, default_value_t = 10.0)]
    pub blowup: f64,
    /// Set a scene parameter (repeatable).
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
    /// Output directory.
    #[arg(long, value_name = "DIR", default_value = "out/work-precision")]
    pub out: PathBuf,
    /// Run only the k-th of n slices of the points.
    #[arg(long, value_name = "K/N")]
    pub shard: Option<String>,
    #[arg(long)]
    pub quiet: bool,
    /// Start every run, and the reference, from the positions of this structure file.
    #[arg(long, value_name = "FILE")]
    pub start: Option<PathBuf>,
    #[command(flatten)]
    pub source: super::common::SceneArgs,
}

pub fn work_precision_command(args: &WorkPrecisionArgs) -> Result<()> {
    let flags = args.source.flags()?;
    let mut scene = prepare::load(&RunRequest {
        flags: flags.clone(),
        start: args.start.as_deref(),
        ..RunRequest::new(&args.scene, &args.set, &RunSpec::default())
    })?;
    let times = study_times(args, scene.units)?;
    let setup = study_setup(args, &times, flags);
    check_methods(&scene, &setup.base, &args.methods, &times.steps)?;
    let weights = cost_weights(args, &mut scene.system)?;
    std::fs::create_dir_all(&args.out).map_err(|e| Error::io(&args.out, e))?;
    let reference = reference_samples(args, &setup, &times)?;
    let (points, total) = study_points(args, &times.steps)?;
    let bar = progress_bar(points.len() as u64, args.quiet, "work-precision");
    let results = run_points(&setup, &points, &reference, weights, &|| bar.inc(1))?;
    bar.finish_and_clear();

    let meta = work_precision_meta(args, &times, total, weights);
    let (table, wall) = work_precision_tables(meta, &results);
    let table = table.with_units(&[
        ("h", scene.units.time_name()),
        ("max_position_error", scene.units.length_name()),
    ]);
    table.write(&args.out.join(WORK_PRECISION))?;
    wall.write(&args.out.join(WALL_TIME))?;
    draw_work_precision(&table, Some(&wall), &args.out)?;
    if !args.quiet {
        eprintln!(
            "{} runs against {} (h = {}); tables and pictures in {}",
            results.len(),
            args.reference_method,
            times.reference_h,
            args.out.display()
        );
    }
    Ok(())
}

/// The outer steps and times of a work-precision study, checked against each other.
struct StudyTimes {
    steps: Vec<f64>,
    t_end: f64,
    sample: f64,
    reference_h: f64,
}

fn study_times(args: &WorkPrecisionArgs, scene_units: crate::units::Units) -> Result<StudyTimes> {
    let units = scene_units.time_units();
    let steps = parse_steps(&args.h_list, scene_units)?;
    let no_parameters = BTreeMap::new();
    let t_end = args.t_end.evaluate_time(&no_parameters, "--t-end", units)?;
    let largest = steps.iter().copied().fold(0.0, f64::max);
    let smallest = steps.iter().copied().fold(f64::INFINITY, f64::min);
    let sample = match &args.sample {
        Some(v) => v.evaluate_time(&no_parameters, "--sample", units)?,
        None => largest,
    };
    if !(t_end > 0.0 && sample > 0.0 && sample <= t_end) {
        return Err(Error::flag(
            "--t-end",
            format!(
                "--t-end ({t_end}) and --sample ({sample}) must be positive, the sample no longer than the run"
            ),
        ));
    }
    for &h in &steps {
        whole_ratio(sample, h, "outer step h", "sample interval")?;
    }
    let reference_h = match &args.reference_h {
        Some(v) => v.evaluate_time(&no_parameters, "--reference-h", units)?,
        None => sample / (64.0 * sample / smallest).ceil(),
    };
    whole_ratio(sample, reference_h, "reference step", "sample interval")?;
    Ok(StudyTimes {
        steps,
        t_end,
        sample,
        reference_h,
    })
}

fn study_setup(args: &WorkPrecisionArgs, times: &StudyTimes, flags: SceneFlags) -> StudySetup {
    StudySetup {
        scene: args.scene.clone(),
        set: args.set.clone(),
        flags,
        start: args.start.clone(),
        base: RunSpec {
            quadrature: args.quadrature.clone(),
            block: args.block,
            blowup: Some(args.blowup),
            ..args.inner.spec()
        },
        t_end: times.t_end,
        sample: times.sample,
        blowup: args.blowup,
    }
}

/// The --weights given, else the costs timed on the scene.
fn cost_weights(
    args: &WorkPrecisionArgs,
    system: &mut crate::system::System,
) -> Result<CostWeights> {
    Ok(match &args.weights {
        Some(w) => {
            if w.len() != 3 || w.iter().any(|x| !(x.is_finite() && *x >= 0.0)) {
                return Err(Error::flag(
                    "--weights",
                    "--weights expects three non-negative numbers F,S,H",
                ));
            }
            if w.iter().all(|&x| x == 0.0) {
                return Err(Error::flag(
                    "--weights",
                    "--weights 0,0,0 makes every run free: give at least one positive cost",
                ));
            }
            CostWeights {
                fast: w[0],
                slow: w[1],
                hessian_vector: w[2],
            }
        }
        None => measure_cost_weights(system),
    })
}

fn reference_samples(
    args: &WorkPrecisionArgs,
    setup: &StudySetup,
    times: &StudyTimes,
) -> Result<Samples> {
    // The reference takes only what its own method may need, never the studied methods'
    // inner steps.
    let reference_base = StudySetup {
        base: RunSpec {
            blowup: Some(1e6),
            block: args.block,
            quadrature: args.quadrature.clone(),
            ..Default::default()
        },
        ..setup.clone()
    };
    let reference = reference(
        &reference_base,
        &args.reference_method,
        times.reference_h,
        &args.out.join("reference.csv"),
    )?;
    if reference.times.len() != sample_times(times.sample, times.t_end).len() {
        return Err(Error::flag(
            "--t-end",
            "the reference run does not reach --t-end",
        ));
    }
    Ok(reference)
}

/// One run of a study: its index, method and outer step h.
type StudyPoint = (usize, String, f64);

/// Every (index, method, h) of the study, kept to this shard's slice, and how many in all.
fn study_points(args: &WorkPrecisionArgs, steps: &[f64]) -> Result<(Vec<StudyPoint>, usize)> {
    let mut points = Vec::new();
    for method in &args.methods {
        for &h in steps {
            points.push((points.len(), method.clone(), h));
        }
    }
    let total = points.len();
    let shard = args.shard.as_deref().map(parse_shard).transpose()?;
    if let Some((k, n)) = shard {
        points.retain(|(index, _, _)| index % n == k);
    }
    Ok((points, total))
}

fn work_precision_meta(
    args: &WorkPrecisionArgs,
    times: &StudyTimes,
    total: usize,
    weights: CostWeights,
) -> BTreeMap<String, String> {
    let mut meta = meta_of(&[
        ("points", total.to_string()),
        ("scene", args.scene.display().to_string()),
        ("set", args.set.join(" ")),
        ("t_end", times.t_end.to_string()),
        ("sample", times.sample.to_string()),
        (
            "reference",
            format!("{} h = {}", args.reference_method, times.reference_h),
        ),
        ("inner_steps", or_default(args.inner.inner_steps)),
        (
            "weights",
            format!(
                "fast {} slow {} hessian_vector {}",
                weights.fast, weights.slow, weights.hessian_vector
            ),
        ),
    ]);
    if let Some(shard) = &args.shard {
        meta.insert("shard".into(), shard.clone());
    }
    meta
}

/// The work-precision table and its wall-time companion.
fn work_precision_tables(
    meta: BTreeMap<String, String>,
    results: &[PrecisionResult],
) -> (StudyTable, StudyTable) {
    let mut table = StudyTable::new(
        "work-precision",
        meta.clone(),
        &[
            "index",
            "method",
            "h",
            "status",
            "max_position_error",
            "max_relative_energy_error",
            "slow_evaluations",
            "fast_evaluations",
            "hessian_vector",
            "weighted_evaluations",
        ],
    );
    let mut wall = StudyTable::new("work-precision-wall-time", meta, &["index", "wall_seconds"]);
    for r in results {
        table.rows.push(vec![
            r.index.to_string(),
            r.method.clone(),
            Num(r.h).to_string(),
            r.status.clone(),
            Num(r.max_position_error).to_string(),
            Num(r.max_relative_energy_error).to_string(),
            r.slow_evaluations.to_string(),
            r.fast_evaluations.to_string(),
            r.hessian_vector.to_string(),
            Num(r.weighted_evaluations).to_string(),
        ]);
        wall.rows
            .push(vec![r.index.to_string(), Num(r.wall_seconds).to_string()]);
    }
    (table, wall)
}
