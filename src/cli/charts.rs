//! `longstep chart work-precision`, `longstep merge`, and the pictures of the studies.
//!
//! Every picture is drawn from its study table (`src/io/study_csv.rs`), so a merged set of
//! shards gives the same pictures as a single run.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use clap::{Args, Subcommand};

use super::common::{
    InnerSteps, check_methods, meta_of, or_default, parse_shard, parse_steps, progress_bar,
};
use crate::analysis::modes::{fast_modes, predicted_resonances};
use crate::analysis::stability::map::Shard;
use crate::analysis::work_precision::{
    CostWeights, PrecisionResult, Samples, StudySetup, measure_cost_weights, reference, run_points,
    sample_times,
};
use crate::error::{Error, Result};
use crate::io::csv::write_table;
use crate::io::scene::load_scene;
use crate::io::study_csv::{StudyTable, differing_setting, merge};
use crate::plot::{AxisSpec, Corner, Guide, LineChart, MarkerSet, PALETTE, Series, SeriesStyle};
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
    /// Scene file (TOML).
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
    #[arg(long, default_value = "out/work-precision")]
    pub out: PathBuf,
    /// Run only the k-th of n slices of the points.
    #[arg(long, value_name = "K/N")]
    pub shard: Option<String>,
    #[arg(long)]
    pub quiet: bool,
}

#[derive(Args, Debug)]
pub struct MergeArgs {
    /// Output directories (or CSV files) of the shards.
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// Where to write the merged tables and pictures.
    #[arg(long, default_value = "out/merged")]
    pub out: PathBuf,
}

const WORK_PRECISION: &str = "work-precision.csv";
const WALL_TIME: &str = "wall-time.csv";
const SCAN_STEPS: &str = "scan.csv";
const SCAN_STIFFNESS: &str = "scan-stiffness.csv";

pub fn work_precision_command(args: &WorkPrecisionArgs) -> Result<()> {
    let scene_units = load_scene(&args.scene, &args.set)?.units;
    let times = study_times(args, scene_units)?;
    let setup = study_setup(args, &times);
    let mut scene = check_methods(
        &setup.scene,
        &setup.set,
        &setup.base,
        &args.methods,
        &times.steps,
    )?;
    let weights = cost_weights(args, &mut scene.system)?;
    std::fs::create_dir_all(&args.out).map_err(|e| Error::io(&args.out, e))?;
    let reference = reference_samples(args, &setup, &times)?;
    let (points, total) = study_points(args, &times.steps)?;
    let bar = progress_bar(points.len() as u64, args.quiet, "work-precision");
    let results = run_points(&setup, &points, &reference, weights, &|| bar.inc(1))?;
    bar.finish_and_clear();

    let meta = work_precision_meta(args, &times, total, weights);
    let (table, wall) = work_precision_tables(meta, &results);
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
        return Err(Error::input(format!(
            "--t-end ({t_end}) and --sample ({sample}) must be positive, the sample no longer than the run"
        )));
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

fn study_setup(args: &WorkPrecisionArgs, times: &StudyTimes) -> StudySetup {
    StudySetup {
        scene: args.scene.clone(),
        set: args.set.clone(),
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
                return Err(Error::input(
                    "--weights expects three non-negative numbers F,S,H",
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
        return Err(Error::input("the reference run does not reach --t-end"));
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
            r.h.to_string(),
            r.status.clone(),
            r.max_position_error.to_string(),
            r.max_relative_energy_error.to_string(),
            r.slow_evaluations.to_string(),
            r.fast_evaluations.to_string(),
            r.hessian_vector.to_string(),
            r.weighted_evaluations.to_string(),
        ]);
        wall.rows
            .push(vec![r.index.to_string(), r.wall_seconds.to_string()]);
    }
    (table, wall)
}

/// The scene's file stem and its --set values, for titles.
fn scene_label(table: &StudyTable) -> String {
    let path = table
        .meta
        .get("scene")
        .map(String::as_str)
        .unwrap_or_default();
    let stem = Path::new(path)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let stem = if stem == "scene" {
        // systems/<name>/scene.toml: the folder names it.
        Path::new(path)
            .parent()
            .and_then(|p| p.file_name())
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or(stem)
    } else {
        stem
    };
    match table.meta.get("set").filter(|s| !s.is_empty()) {
        Some(set) => format!("{stem} ({set})"),
        None => stem,
    }
}

/// A method's (cost, error) points: finished runs, then unstable or failed ones.
/// One method's runs on an error-against-cost chart: stable runs as (cost, error) with
/// their outer step, unstable runs as (cost, error).
struct MethodPoints {
    method: String,
    stable: Vec<((f64, f64), String)>,
    failed: Vec<(f64, f64)>,
}

/// Points of each method, unstable runs separated.
fn method_points(
    table: &StudyTable,
    cost: &dyn Fn(&[String]) -> f64,
    error_column: usize,
) -> Result<Vec<MethodPoints>> {
    let method = table.column("method")?;
    let status = table.column("status")?;
    let h = table.column("h")?;
    let mut groups: Vec<MethodPoints> = Vec::new();
    for row in &table.rows {
        let name = &row[method];
        let k = match groups.iter().position(|g| &g.method == name) {
            Some(k) => k,
            None => {
                groups.push(MethodPoints {
                    method: name.clone(),
                    stable: Vec::new(),
                    failed: Vec::new(),
                });
                groups.len() - 1
            }
        };
        let point = (cost(row), table.number(row, error_column));
        if row[status] == "ok" {
            groups[k].stable.push((point, format!("h = {}", row[h])));
        } else {
            groups[k].failed.push(point);
        }
    }
    Ok(groups)
}

type CostFn<'a> = Box<dyn Fn(&[String]) -> f64 + 'a>;

/// One picture of the work-precision set: its file name, axis labels and what it plots.
struct WorkPrecisionChart<'a> {
    name: &'static str,
    x_label: &'static str,
    cost: CostFn<'a>,
    error_column: usize,
    y_label: &'static str,
}

/// Error-against-cost pictures; unstable runs are drawn as crosses at the top of the plot.
pub fn draw_work_precision(
    table: &StudyTable,
    wall: Option<&StudyTable>,
    out: &Path,
) -> Result<()> {
    let slow = table.column("slow_evaluations")?;
    let weighted = table.column("weighted_evaluations")?;
    let position = table.column("max_position_error")?;
    let energy = table.column("max_relative_energy_error")?;
    let wall_of: BTreeMap<String, f64> = wall
        .map(|w| {
            w.rows
                .iter()
                .map(|r| (r[0].clone(), w.number(r, 1)))
                .collect()
        })
        .unwrap_or_default();
    let weighted_label = "force evaluations, weighted by measured cost (slow-force units)";
    let mut charts = vec![
        WorkPrecisionChart {
            name: "error-vs-slow-evaluations",
            x_label: "slow-force evaluations",
            cost: Box::new(move |r: &[String]| table.number(r, slow)),
            error_column: position,
            y_label: "max position error",
        },
        WorkPrecisionChart {
            name: "error-vs-force-evaluations",
            x_label: weighted_label,
            cost: Box::new(move |r: &[String]| table.number(r, weighted)),
            error_column: position,
            y_label: "max position error",
        },
        WorkPrecisionChart {
            name: "energy-error-vs-force-evaluations",
            x_label: weighted_label,
            cost: Box::new(move |r: &[String]| table.number(r, weighted)),
            error_column: energy,
            y_label: "max relative energy error",
        },
    ];
    if wall.is_some() {
        charts.push(WorkPrecisionChart {
            name: "error-vs-wall-time",
            x_label: "wall time (s)",
            cost: Box::new(|r: &[String]| wall_of.get(&r[0]).copied().unwrap_or(f64::NAN)),
            error_column: position,
            y_label: "max position error",
        });
    }
    let scene = scene_label(table);
    for spec in charts {
        let groups = method_points(table, spec.cost.as_ref(), spec.error_column)?;
        let chart = work_precision_chart(&scene, &spec, &groups);
        if chart.series.is_empty() && chart.markers.is_empty() {
            continue;
        }
        for extension in ["png", "svg"] {
            chart.save(&out.join(format!("{}.{extension}", spec.name)))?;
        }
    }
    Ok(())
}

/// One error-against-cost chart: a line per method with each point labelled by its outer
/// step, and the method's unstable runs as crosses in its colour at the top.
fn work_precision_chart(
    scene: &str,
    spec: &WorkPrecisionChart,
    groups: &[MethodPoints],
) -> LineChart {
    let finite = |p: &(f64, f64)| p.0 > 0.0 && p.1 > 0.0 && p.0.is_finite() && p.1.is_finite();
    let top = groups
        .iter()
        .flat_map(|g| g.stable.iter().map(|s| s.0))
        .filter(finite)
        .map(|p| p.1)
        .fold(f64::NAN, f64::max);
    let mut chart = LineChart::new(
        &format!("Work–precision, {scene}"),
        AxisSpec::log(spec.x_label),
        AxisSpec::log(spec.y_label),
    );
    chart.legend = Corner::LowerLeft;
    for (k, group) in groups.iter().enumerate() {
        let colour = PALETTE[k % PALETTE.len()];
        let (points, labels): (Vec<(f64, f64)>, Vec<String>) = group
            .stable
            .iter()
            .filter(|s| finite(&s.0))
            .cloned()
            .unzip();
        if !points.is_empty() {
            let mut series = Series::line(&group.method, points);
            series.style = SeriesStyle::LineAndPoints;
            series.colour = Some(colour);
            series.point_labels = labels;
            chart.series.push(series);
        }
        // An unstable run has no meaningful error: it is drawn at the top of the plot.
        let ceiling = if top.is_finite() { 2.0 * top } else { 1.0 };
        let unstable: Vec<(f64, f64)> = group
            .failed
            .iter()
            .filter(|p| p.0 > 0.0 && p.0.is_finite())
            .map(|p| (p.0, ceiling))
            .collect();
        if !unstable.is_empty() {
            chart
                .markers
                .push(MarkerSet::unstable_of(&group.method, colour, unstable));
        }
    }
    chart
}

/// The pictures of a scan's table: by its criterion.
pub fn draw_scan(table: &StudyTable, out: &Path) -> Result<()> {
    if table.meta.get("criterion").map(String::as_str) == Some("sampling") {
        draw_scan_sampling(table, out)
    } else {
        draw_scan_steps(table, out)
    }
}

/// The sampling criterion's differences to the reference against outer step, one chart per
/// compared quantity (`scan-potential`, `scan-peak`), unstable runs as crosses.
fn draw_scan_sampling(table: &StudyTable, out: &Path) -> Result<()> {
    let (method, h, status) = (
        table.column("method")?,
        table.column("h")?,
        table.column("status")?,
    );
    let scene = scene_label(table);
    let quantities = [
        (
            "potential_difference",
            "Δ potential energy per molecule",
            "scan-potential",
        ),
        ("peak_difference", "Δ g(r) first-peak height", "scan-peak"),
    ];
    for (column, label, name) in quantities {
        let value = table.column(column)?;
        let mut chart = LineChart::new(
            &format!("Sampling against the reference, {scene}"),
            AxisSpec::linear("outer step h"),
            AxisSpec::linear(&format!("{label} (run − reference)")),
        );
        chart.legend = Corner::UpperLeft;
        let mut methods: Vec<&str> = Vec::new();
        for row in &table.rows {
            if !methods.contains(&row[method].as_str()) {
                methods.push(&row[method]);
            }
        }
        for (k, m) in methods.iter().enumerate() {
            let colour = PALETTE[k % PALETTE.len()];
            let (mut points, mut unstable) = (Vec::new(), Vec::new());
            for row in table.rows.iter().filter(|r| r[method] == *m) {
                let (x, y) = (table.number(row, h), table.number(row, value));
                if row[status] == "unstable" {
                    unstable.push((x, 0.0));
                } else if y.is_finite() {
                    points.push((x, y));
                }
            }
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            if !points.is_empty() {
                let mut series = Series::line(m, points);
                series.style = SeriesStyle::LineAndPoints;
                series.colour = Some(colour);
                chart.series.push(series);
            }
            if !unstable.is_empty() {
                chart
                    .markers
                    .push(MarkerSet::unstable_of(m, colour, unstable));
            }
        }
        if chart.series.is_empty() && chart.markers.is_empty() {
            continue;
        }
        for extension in ["png", "svg"] {
            chart.save(&out.join(format!("{name}.{extension}")))?;
        }
    }
    Ok(())
}

/// Simulated time per day at each method's largest safe step against the thread count,
/// from the timing table.
pub fn draw_ns_per_day(timing: &StudyTable, out: &Path) -> Result<()> {
    let (method, h, threads) = (
        timing.column("method")?,
        timing.column("h")?,
        timing.column("threads")?,
    );
    let (per_day, unit) = match timing.column("ns_per_day") {
        Ok(c) => (c, "ns/day"),
        Err(_) => (timing.column("time_per_day")?, "time units/day"),
    };
    let mut chart = LineChart::new(
        &format!("Speed at the largest safe step, {}", scene_label(timing)),
        AxisSpec::linear("threads"),
        AxisSpec::log(&format!("simulated time per day ({unit})")),
    );
    chart.legend = Corner::UpperLeft;
    let mut methods: Vec<(&str, &str)> = Vec::new();
    for row in &timing.rows {
        if !methods.contains(&(row[method].as_str(), row[h].as_str())) {
            methods.push((&row[method], &row[h]));
        }
    }
    for (m, step) in methods {
        let points: Vec<(f64, f64)> = timing
            .rows
            .iter()
            .filter(|r| r[method] == m)
            .map(|r| (timing.number(r, threads), timing.number(r, per_day)))
            .filter(|p| p.1.is_finite() && p.1 > 0.0)
            .collect();
        if !points.is_empty() {
            let mut series = Series::line(&format!("{m}, h = {step}"), points);
            series.style = SeriesStyle::LineAndPoints;
            chart.series.push(series);
        }
    }
    if chart.series.is_empty() {
        return Ok(());
    }
    for extension in ["png", "svg"] {
        chart.save(&out.join(format!("ns-per-day.{extension}")))?;
    }
    Ok(())
}

/// Drift against outer step for each method, unstable runs as crosses, and the resonances
/// predicted from the fast normal modes as guide lines.
fn draw_scan_steps(table: &StudyTable, out: &Path) -> Result<()> {
    let method = table.column("method")?;
    let h = table.column("h")?;
    let status = table.column("status")?;
    let drift = table.column("drift")?;
    let scene = scene_label(table);
    let mut chart = LineChart::new(
        &format!("Step-size safety scan, {scene}"),
        AxisSpec::linear("outer step h"),
        AxisSpec::log(&format!(
            "|energy drift| ({})",
            table
                .meta
                .get("drift_unit")
                .map_or("kT per unit time per dof", String::as_str)
        )),
    );
    chart.legend = Corner::UpperLeft;
    let floor = 1e-16;
    let mut methods: Vec<&str> = Vec::new();
    for row in &table.rows {
        if !methods.contains(&row[method].as_str()) {
            methods.push(&row[method]);
        }
    }
    let top = table
        .rows
        .iter()
        .map(|r| table.number(r, drift).abs())
        .filter(|d| d.is_finite())
        .fold(floor, f64::max);
    for (k, name) in methods.iter().enumerate() {
        let colour = PALETTE[k % PALETTE.len()];
        let (mut points, mut unstable) = (Vec::new(), Vec::new());
        for row in table.rows.iter().filter(|r| r[method] == *name) {
            let x = table.number(row, h);
            if row[status] == "unstable" {
                unstable.push((x, 10.0 * top));
            } else {
                points.push((x, table.number(row, drift).abs().max(floor)));
            }
        }
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        if !points.is_empty() {
            let mut series = Series::line(name, points);
            series.style = SeriesStyle::LineAndPoints;
            series.colour = Some(colour);
            chart.series.push(series);
        }
        if !unstable.is_empty() {
            chart
                .markers
                .push(MarkerSet::unstable_of(name, colour, unstable));
        }
    }
    chart.guides.extend(resonance_guides(table, h));
    if chart.series.is_empty() && chart.markers.is_empty() {
        return Ok(());
    }
    for extension in ["png", "svg"] {
        chart.save(&out.join(format!("scan.{extension}")))?;
    }
    Ok(())
}

/// Guide lines at the resonances predicted from the scene's fast modes, within the scanned
/// range of a scan table's `h` column.
fn resonance_guides(table: &StudyTable, h: usize) -> Vec<Guide> {
    let mut guides = Vec::new();
    let hs: Vec<f64> = table.rows.iter().map(|r| table.number(r, h)).collect();
    let (lo, hi) = (
        hs.iter().copied().fold(f64::INFINITY, f64::min),
        hs.iter().copied().fold(0.0, f64::max),
    );
    if let Some(path) = table.meta.get("scene") {
        let set: Vec<String> = table
            .meta
            .get("set")
            .map(|s| {
                s.split(' ')
                    .filter(|x| !x.is_empty())
                    .map(str::to_string)
                    .collect()
            })
            .unwrap_or_default();
        if let Ok(mut scene) = load_scene(Path::new(path), &set) {
            let modes = fast_modes(&mut scene.system);
            for r in predicted_resonances(&modes, lo, hi, 3) {
                guides.push(Guide {
                    x: r.h,
                    label: format!("{:?} k={}", r.kind, r.k).to_lowercase(),
                });
            }
        }
    }
    guides
}

const MAP_HEADER: &str = "gamma1,gamma2,spectral_radius,type";

/// Stability-map shards are contiguous slices of the grid, which runs Γ1-major: the whole
/// map's rows are the shards' rows in shard order. Each shard's first line names its map's
/// settings and its `k/n`: the shards must agree on every setting and hold every slice
/// 1..n once, each with the rows its slice has.
fn merge_maps(maps: &[(PathBuf, StudyTable)], out: &Path) -> Result<()> {
    let (first_path, first) = &maps[0];
    let points = first.points()?;
    let mut slices: Vec<Option<&(PathBuf, StudyTable)>> = Vec::new();
    for entry in maps {
        let (path, table) = entry;
        if let Some((key, theirs, ours)) = differing_setting(&table.meta, &first.meta) {
            return Err(Error::input(format!(
                "the map shards differ in {key}: {theirs} in {}, {ours} in {}",
                path.display(),
                first_path.display()
            )));
        }
        let shard = table
            .meta
            .get("shard")
            .map(|s| Shard::parse(s))
            .transpose()?
            .ok_or_else(|| Error::Structure {
                path: path.clone(),
                message: "a stability-map table without its `shard`".into(),
            })?;
        if slices.is_empty() {
            slices = vec![None; shard.count];
        }
        if shard.count != slices.len() {
            return Err(Error::input(format!(
                "{} is shard {}/{} but {} is one of {}: give the shards of one --shard split",
                path.display(),
                shard.index,
                shard.count,
                first_path.display(),
                slices.len()
            )));
        }
        if let Some((other, _)) = slices[shard.index - 1] {
            return Err(Error::input(format!(
                "shard {}/{} appears twice: {} and {}",
                shard.index,
                shard.count,
                other.display(),
                path.display()
            )));
        }
        let expected = shard.range(points).len();
        if table.rows.len() != expected {
            return Err(Error::Structure {
                path: path.clone(),
                message: format!(
                    "shard {}/{} of {points} points holds {} rows, not its {expected}",
                    shard.index,
                    shard.count,
                    table.rows.len()
                ),
            });
        }
        slices[shard.index - 1] = Some(entry);
    }
    if let Some(k) = slices.iter().position(Option::is_none) {
        return Err(Error::input(format!(
            "the map shards do not cover its {points} points: shard {}/{} is missing",
            k + 1,
            slices.len()
        )));
    }
    let path = out.join("stability-map.csv");
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let rows = slices.iter().flatten().flat_map(|(_, table)| &table.rows);
    write_table(&path, None, &first.header, rows)?;
    eprintln!(
        "merged {} map shards ({points} points) into {}",
        maps.len(),
        path.display()
    );
    Ok(())
}

/// `longstep merge DIR…`: combine shard outputs into what a single run writes.
pub fn merge_command(args: &MergeArgs) -> Result<()> {
    // Tables are grouped by the study they name, so shard files may be called anything.
    let mut by_study: BTreeMap<String, Vec<(String, StudyTable)>> = BTreeMap::new();
    let mut maps: Vec<(PathBuf, StudyTable)> = Vec::new();
    for input in &args.inputs {
        let files: Vec<PathBuf> = if input.is_dir() {
            [WORK_PRECISION, WALL_TIME, SCAN_STEPS, SCAN_STIFFNESS]
                .iter()
                .map(|f| input.join(f))
                .filter(|p| p.exists())
                .collect()
        } else {
            vec![input.clone()]
        };
        if files.is_empty() {
            return Err(Error::input(format!(
                "{}: no study table ({WORK_PRECISION}, {SCAN_STEPS}, {SCAN_STIFFNESS}) in it",
                input.display()
            )));
        }
        for file in files {
            let text = std::fs::read_to_string(&file).map_err(|e| Error::io(&file, e))?;
            if text.starts_with(MAP_HEADER) {
                return Err(Error::Structure {
                    path: file.clone(),
                    message: "a whole stability map (written without --shard): merge takes \
                              the shards of one map"
                        .into(),
                });
            }
            let table = StudyTable::read(&file)?;
            if table.study == "stability-map" {
                maps.push((file.clone(), table));
                continue;
            }
            let name = file.display().to_string();
            by_study
                .entry(table.study.clone())
                .or_default()
                .push((name, table));
        }
    }
    if !maps.is_empty() {
        merge_maps(&maps, &args.out)?;
    }
    std::fs::create_dir_all(&args.out).map_err(|e| Error::io(&args.out, e))?;
    let mut merged_tables = BTreeMap::new();
    for (study, tables) in by_study {
        let count = tables.len();
        let merged = merge(tables)?;
        let name = match study.as_str() {
            "work-precision" => WORK_PRECISION,
            "work-precision-wall-time" => WALL_TIME,
            "scan-steps" => SCAN_STEPS,
            "scan-stiffness" => SCAN_STIFFNESS,
            _ => "merged.csv",
        };
        merged.write(&args.out.join(name))?;
        eprintln!(
            "merged {count} shards of {study} into {}",
            args.out.join(name).display()
        );
        merged_tables.insert(study, merged);
    }
    if let Some(table) = merged_tables.get("work-precision") {
        draw_work_precision(
            table,
            merged_tables.get("work-precision-wall-time"),
            &args.out,
        )?;
    }
    if let Some(table) = merged_tables.get("scan-steps") {
        draw_scan(table, &args.out)?;
    }
    if merged_tables.contains_key("scan-stiffness") {
        eprintln!(
            "notice: a merged stiffness scan is a table only; its picture is drawn by \
             `longstep scan stiffness` itself"
        );
    }
    Ok(())
}
