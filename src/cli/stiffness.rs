//! `longstep scan stiffness`: the largest position error against a parameter of the scene
//! (GSS98 section 4, Figures 11–13), with a reference solution per value
//! ([`crate::analysis::stiffness`]).

use std::path::PathBuf;

use clap::Args;
use rayon::prelude::*;

use super::common::{MethodSteps, meta_of, number, or_default, parse_shard, progress_bar};
use crate::analysis::stiffness::{StiffnessPoint, StiffnessStudy, Unit, largest};
use crate::error::{Error, Result};
use crate::io::csv::CsvWriter;
use crate::io::number::Num;
use crate::io::study_csv::StudyTable;
use crate::plot::{AxisSpec, LineChart, MarkerSet, MarkerShape, PALETTE, Series};

// The shared method and step flags (common::MethodSteps), described as this study uses them.
#[derive(Args, Debug)]
#[command(mut_arg("methods", |a| a
    .help("Method(s), comma-separated: one curve per method and outer step")))]
#[command(mut_arg("inner_steps", |a| a
    .help("Inner steps K per outer step (default: max(100, ⌈h ω_max / 0.05⌉))")))]
#[command(mut_arg("dt", |a| a
    .help("A fixed inner step dt instead of --inner (every h must be a multiple of it)")))]
#[command(mut_arg("t_end", |a| a.help("Length of each run; a whole number of every outer step")))]
pub struct ScanStiffnessArgs {
    /// Scene file (TOML), for example systems/two-spring.toml (GSS98 section 4).
    pub scene: PathBuf,
    #[command(flatten)]
    pub study: MethodSteps,
    /// The scene parameter to scan, e.g. omega1.
    #[arg(long)]
    pub param: String,
    /// Range of the parameter as LO:HI (numbers or expressions, e.g. 0:10*pi).
    #[arg(long, value_name = "LO:HI")]
    pub range: String,
    /// Values of the parameter, evenly spaced from LO to HI inclusive.
    #[arg(long, default_value_t = 400)]
    pub n: usize,
    /// Reference Verlet steps per outer step (default as for --inner); the reference is
    /// Richardson-extrapolated from M, 2M and 4M steps.
    #[arg(long, value_name = "M")]
    pub reference_steps: Option<usize>,
    /// Set a scene parameter (repeatable).
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
    /// CSV output: index,method,h,<param>,max_error,error_time,reference_error,inner_steps,reference_steps,status.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Chart of the largest error against the parameter (PNG).
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// The same chart as SVG.
    #[arg(long)]
    pub svg: Option<PathBuf>,
    /// A logarithmic error axis.
    #[arg(long)]
    pub log_y: bool,
    /// Compute only the k-th of n interleaved slices of the (h, value) units (k from 1 to
    /// n), for job arrays; the CSV's index column orders the merged rows.
    #[arg(long, value_name = "K/N")]
    pub shard: Option<String>,
    /// No progress bar or summary on stderr.
    #[arg(long)]
    pub quiet: bool,
}

/// Most parameter values a study takes (each is a row of every curve, kept for the picture).
const MAX_VALUES: usize = 1_000_000;

/// `LO:HI` and a count → the evenly spaced values.
pub fn parse_values(range: &str, n: usize) -> Result<Vec<f64>> {
    let Some((lo, hi)) = range.split_once(':') else {
        return Err(Error::flag("--range", "--range expects LO:HI").got(format!("\"{range}\"")));
    };
    let (lo, hi) = (number(lo, "--range")?, number(hi, "--range")?);
    if lo >= hi {
        return Err(Error::flag(
            "--range",
            format!("--range: {lo} is not below {hi}"),
        ));
    }
    if n < 2 {
        return Err(
            Error::flag("--n", "--n must be at least 2 (the two ends of --range)")
                .got(n.to_string()),
        );
    }
    if n > MAX_VALUES {
        return Err(Error::flag(
            "--n",
            format!("--n {n} is more than the {MAX_VALUES} values a study holds"),
        ));
    }
    let step = (hi - lo) / (n - 1) as f64;
    Ok((0..n)
        .map(|i| if i + 1 == n { hi } else { lo + i as f64 * step })
        .collect())
}

pub fn scan_stiffness_command(args: &ScanStiffnessArgs) -> Result<()> {
    super::common::check_out_file(&args.out, "scan stiffness")?;
    let (study, units) = stiffness_study(args)?;
    if !args.quiet {
        print_setup(&study);
    }
    let mut out = stiffness_csv(args, &study)?;
    let bar = progress_bar(units.len() as u64, args.quiet, "scan stiffness");
    let mut all: Vec<StiffnessPoint> = Vec::with_capacity(units.len() * study.methods.len());
    // Blocks of a few units per thread keep the file current without idling the threads.
    let block = 4 * rayon::current_num_threads().max(1);
    for chunk in units.chunks(block) {
        let results = chunk
            .par_iter()
            .map(|&unit| {
                let points = study.evaluate(unit);
                bar.inc(1);
                points
            })
            .collect::<Result<Vec<_>>>()?;
        for point in results.into_iter().flatten() {
            out.record(csv_fields(&point))?;
            all.push(point);
        }
        out.flush()?;
    }
    bar.finish_and_clear();

    let curves = curves(&study, &all);
    if !args.quiet {
        print_summary(args, &study, &curves, &all);
    }
    for path in [&args.png, &args.svg].into_iter().flatten() {
        chart(&study, &curves, args.log_y).save(path)?;
    }
    Ok(())
}

/// The study the flags ask for, checked, and the (h, value) units of this shard.
fn stiffness_study(args: &ScanStiffnessArgs) -> Result<(StiffnessStudy, Vec<Unit>)> {
    let values = parse_values(&args.range, args.n)?;
    let steps = args.study.steps()?;
    let t_end = args.study.t_end()?;
    let shard = args.shard.as_deref().map(parse_shard).transpose()?;
    for path in [&args.png, &args.svg].into_iter().flatten() {
        crate::plot::Format::of(path)?;
    }
    let study = StiffnessStudy::new(
        &args.scene,
        args.set.clone(),
        &args.param,
        values,
        args.study.methods.clone(),
        steps,
        args.study.inner.spec(),
        t_end,
        args.reference_steps,
    )?;
    let mut units = study.units();
    if let Some((k, n)) = shard {
        units.retain(|u| u.unit % n == k);
    }
    Ok((study, units))
}

/// One line per outer step on stderr: each method's inner steps and the reference's.
fn print_setup(study: &StiffnessStudy) {
    for &h in &study.steps {
        let inner: Vec<String> = study
            .methods
            .iter()
            .map(|m| {
                study
                    .settings(m, h, study.values[0])
                    .map(|s| match s.inner_steps {
                        Some(k) => format!("{m} K = {k}"),
                        None => m.clone(),
                    })
                    .unwrap_or_else(|_| m.clone())
            })
            .collect();
        eprintln!(
            "h = {h}: {}; reference: Verlet with {}, {} and {} steps per h, \
             extrapolated (fastest fast mode over the scan: ω = {:.4})",
            inner.join(", "),
            study.reference_steps(h),
            2 * study.reference_steps(h),
            4 * study.reference_steps(h),
            study.omega_max
        );
    }
}

/// The study's CSV, created with its first lines. A comment line names the study, its size
/// and settings, so shards can be checked and merged; then rows are written and flushed
/// block by block as they finish.
fn stiffness_csv(args: &ScanStiffnessArgs, study: &StiffnessStudy) -> Result<CsvWriter> {
    let mut header = vec!["index", "method", "h"];
    header.push(&study.param);
    header.extend([
        "max_error",
        "error_time",
        "reference_error",
        "inner_steps",
        "reference_steps",
        "status",
    ]);
    let mut meta = meta_of(&[
        ("points", study.total_points().to_string()),
        ("scene", args.scene.display().to_string()),
        ("set", args.set.join(" ")),
        ("method", args.study.methods.join(" ")),
        ("param", args.param.clone()),
        ("range", args.range.clone()),
        ("n", args.n.to_string()),
        ("h", args.study.h.join(" ")),
        ("inner_steps", or_default(args.study.inner.inner_steps)),
        ("dt", or_default(args.study.inner.dt.as_ref())),
        ("jacobian", or_default(args.study.inner.jacobian.as_ref())),
        ("t_end", args.study.t_end.clone()),
        ("reference_steps", or_default(args.reference_steps)),
    ]);
    if let Some(shard) = &args.shard {
        meta.insert("shard".into(), shard.clone());
    }
    CsvWriter::create_after(
        &args.out,
        Some(&StudyTable::new("scan-stiffness", meta, &[]).first_line()),
        &header,
    )
}

/// The summary on stderr: the largest error of each curve and where, and whether the
/// reference is accurate enough beside the errors measured.
fn print_summary(
    args: &ScanStiffnessArgs,
    study: &StiffnessStudy,
    curves: &[(String, Vec<&StiffnessPoint>)],
    all: &[StiffnessPoint],
) {
    for (name, points) in curves {
        match largest(points) {
            Some((value, error)) => eprintln!(
                "{name}: largest error {error:.4e} at {} = {value:.6}",
                study.param
            ),
            None => eprintln!("{name}: no finite error"),
        }
    }
    let worst_reference = all.iter().map(|p| p.reference_error).fold(0.0, f64::max);
    let smallest_error = all
        .iter()
        .filter(|p| p.max_error.is_finite())
        .map(|p| p.max_error)
        .fold(f64::INFINITY, f64::min);
    if worst_reference > 0.01 * smallest_error {
        eprintln!(
            "notice: the reference's estimated error (up to {worst_reference:.2e}) is not \
             small beside the smallest measured error ({smallest_error:.2e}); raise \
             --reference-steps"
        );
    }
    eprintln!("{} rows in {}", all.len(), args.out.display());
}

/// The points of each (method, h) curve, in study order, named "method, h = …".
fn curves<'a>(
    study: &StiffnessStudy,
    points: &'a [StiffnessPoint],
) -> Vec<(String, Vec<&'a StiffnessPoint>)> {
    let mut curves = Vec::new();
    for method in &study.methods {
        for &h in &study.steps {
            let members: Vec<&StiffnessPoint> = points
                .iter()
                .filter(|p| &p.method == method && p.h == h)
                .collect();
            if !members.is_empty() {
                curves.push((format!("{method}, h = {h}"), members));
            }
        }
    }
    curves
}

fn chart(
    study: &StiffnessStudy,
    curves: &[(String, Vec<&StiffnessPoint>)],
    log_y: bool,
) -> LineChart {
    let y_label = "max position error ‖q − q_ref‖";
    let mut chart = LineChart::new(
        &format!(
            "Largest position error over t ≤ {} against {}",
            study.t_end, study.param
        ),
        AxisSpec::linear(&study.param),
        AxisSpec::log(y_label),
    );
    if !log_y {
        // A linear axis from 0 (the errors' natural floor) to just above the largest.
        let top = curves
            .iter()
            .flat_map(|(_, p)| p.iter())
            .map(|p| p.max_error)
            .filter(|e| e.is_finite())
            .fold(0.0, f64::max);
        chart.y = AxisSpec::linear(y_label);
        if top > 0.0 {
            chart.y = chart.y.with_range(0.0, 1.05 * top);
        }
    }
    // Unstable runs sit on the axis (their error is unbounded), as crosses in their
    // method's colour.
    let floor = curves
        .iter()
        .flat_map(|(_, p)| p.iter())
        .filter(|p| p.max_error.is_finite() && p.max_error > 0.0)
        .map(|p| p.max_error)
        .fold(f64::INFINITY, f64::min);
    let failed_y = if log_y && floor.is_finite() {
        floor
    } else {
        0.0
    };
    let mut maxima = Vec::new();
    for (k, (name, points)) in curves.iter().enumerate() {
        let colour = PALETTE[k % PALETTE.len()];
        let finite: Vec<(f64, f64)> = points
            .iter()
            .filter(|p| p.max_error.is_finite() && (!log_y || p.max_error > 0.0))
            .map(|p| (p.value, p.max_error))
            .collect();
        let failed: Vec<(f64, f64)> = points
            .iter()
            .filter(|p| !p.max_error.is_finite())
            .map(|p| (p.value, failed_y))
            .collect();
        if let Some(peak) = largest(points) {
            maxima.push(peak);
        }
        let mut series = Series::line(name, finite);
        series.colour = Some(colour);
        chart.series.push(series);
        if !failed.is_empty() {
            chart
                .markers
                .push(MarkerSet::unstable_of(name, colour, failed));
        }
    }
    if !maxima.is_empty() {
        chart.markers.push(MarkerSet::new(
            "largest",
            MarkerShape::Circle,
            plotters::style::RGBColor(0, 0, 0),
            maxima,
        ));
    }
    chart
}

/// One row of the study's CSV, numbers in `Num` form (exponent form for tiny and huge ones).
fn csv_fields(p: &StiffnessPoint) -> [String; 10] {
    [
        p.index.to_string(),
        p.method.clone(),
        Num(p.h).to_string(),
        Num(p.value).to_string(),
        Num(p.max_error).to_string(),
        Num(p.error_time).to_string(),
        Num(p.reference_error).to_string(),
        p.inner_steps.to_string(),
        p.reference_steps.to_string(),
        p.status.to_string(),
    ]
}
