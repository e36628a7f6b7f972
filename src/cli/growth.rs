//! `longstep scan growth`: long runs of several methods and outer steps, the envelope of
//! their energy error, its fitted exponential growth rate per step, and the rate predicted
//! by the spectral radius ρ of one outer step of the same integrator linearised about the
//! scene's equilibrium (2 ln ρ; GSS98 section 3, Figures 6–10).

use std::path::PathBuf;

use clap::Args;
use rayon::prelude::*;

use super::common::{MethodSteps, number, point_settings, progress_bar};
use crate::analysis::growth::{
    RateFit, default_fit_range, energy_errors, fit_range, fit_rate, window_maxima,
};
use crate::analysis::stability::integrator::{INTEGRATOR_TOLERANCE, IntegratorProbe, ProbeScene};
use crate::analysis::stability::{StabilityPoint, classify_matrix};
use crate::error::{Error, Result};
use crate::io::csv::write_table;
use crate::io::number::Num;
use crate::io::scene::{Scene, load_scene};
use crate::plot::{AxisSpec, LineChart, Series};
use crate::run::prepare::{self, RunRequest};
use crate::settings::{MethodSettings, Value};

// The shared method and step flags (common::MethodSteps); --t-end as this study uses it.
#[derive(Args, Debug)]
#[command(mut_arg("t_end", |a| a.help("Length of each run (whole outer steps up to it)")))]
pub struct ScanGrowthArgs {
    /// Scene file (TOML), for example systems/three-spring.toml, or a topology in its place
    /// (AMBER .prmtop/.parm7, GROMACS .top) with its coordinates (.inpcrd/.rst7, .gro)
    /// beside it, same name, or given by --coordinates.
    pub scene: PathBuf,
    #[command(flatten)]
    pub study: MethodSteps,
    /// Set a scene parameter (repeatable).
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
    /// Steps per envelope window (default: a thousandth of the run, at least 1).
    #[arg(long, value_name = "W")]
    pub window: Option<usize>,
    /// Fit the growth rate where the envelope |ΔE|/E0 lies in LO:HI (default: from ten times
    /// its level in the first 5 % of the run to a tenth of its largest, else after the first
    /// 5 %).
    #[arg(long, value_name = "LO:HI")]
    pub fit: Option<String>,
    /// Output directory: growth.csv (one row per run) and envelope.csv.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Picture of the envelopes against time (PNG).
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// The same picture as SVG.
    #[arg(long)]
    pub svg: Option<PathBuf>,
    /// No progress bar or notices on stderr.
    #[arg(long)]
    pub quiet: bool,
}

/// Most outer steps per run.
const MAX_STEPS: usize = 100_000_000;

/// One run's results.
struct GrowthRun {
    index: usize,
    method: String,
    h: f64,
    inner_steps: Option<usize>,
    linear: std::result::Result<StabilityPoint, String>,
    envelope: Vec<(usize, f64)>,
    fit: Option<RateFit>,
    steps: usize,
    max_error: f64,
    end: &'static str,
}

pub fn scan_growth_command(args: &ScanGrowthArgs) -> Result<()> {
    let (steps, t_end) = steps_and_end(args)?;
    if args.window == Some(0) {
        return Err(Error::flag("--window", "--window must be at least 1 step"));
    }
    let fit_bounds = fit_bounds(args)?;
    for path in [&args.png, &args.svg].into_iter().flatten() {
        crate::plot::Format::of(path)?;
    }
    // Check the scene and every (method, h) before any run.
    let scene = load_scene(&args.scene, &args.set)?;
    let points = growth_points(args, &scene, &steps, t_end)?;
    let probe_scene = ProbeScene::load(&args.scene)?;

    let bar = progress_bar(points.len() as u64, args.quiet, "scan growth");
    let runs = points
        .par_iter()
        .map(|(index, settings, n)| -> Result<GrowthRun> {
            let run = growth_run(args, &probe_scene, *index, settings, *n, fit_bounds);
            bar.inc(1);
            run
        })
        .collect::<Result<Vec<_>>>()?;
    bar.finish_and_clear();

    std::fs::create_dir_all(&args.out).map_err(|e| Error::io(&args.out, e))?;
    write_summary(&args.out.join("growth.csv"), &runs)?;
    write_envelopes(&args.out.join("envelope.csv"), &runs)?;
    print_growth_table(&runs);
    if !args.quiet {
        print_notices(args, &runs);
    }
    for path in [&args.png, &args.svg].into_iter().flatten() {
        chart(&scene.name, &runs).save(path)?;
    }
    Ok(())
}

/// The outer steps (--h) and the run length (--t-end), each checked positive.
fn steps_and_end(args: &ScanGrowthArgs) -> Result<(Vec<f64>, f64)> {
    let steps = args.study.steps()?;
    if let Some(&h) = steps.iter().find(|&&h| h <= 0.0) {
        return Err(Error::flag("--h", "--h must be positive").got(h.to_string()));
    }
    let t_end = args.study.t_end()?;
    if t_end <= 0.0 {
        return Err(Error::flag("--t-end", "--t-end must be positive").got(t_end.to_string()));
    }
    Ok((steps, t_end))
}

/// The --fit range LO:HI, if given.
fn fit_bounds(args: &ScanGrowthArgs) -> Result<Option<(f64, f64)>> {
    Ok(match &args.fit {
        Some(text) => {
            let parsed = text
                .split_once(':')
                .map(|(lo, hi)| Ok::<_, Error>((number(lo, "--fit")?, number(hi, "--fit")?)))
                .transpose()?;
            match parsed {
                Some((lo, hi)) if lo >= 0.0 && lo < hi => Some((lo, hi)),
                _ => {
                    return Err(Error::flag(
                        "--fit",
                        "--fit expects LO:HI with 0 ≤ LO < HI (relative energy errors)",
                    )
                    .got(format!("\"{text}\"")));
                }
            }
        }
        None => None,
    })
}

/// Every (index, settings, outer steps) of the scan, each method checked at each h.
fn growth_points(
    args: &ScanGrowthArgs,
    scene: &Scene,
    steps: &[f64],
    t_end: f64,
) -> Result<Vec<(usize, MethodSettings, usize)>> {
    let base = args.study.inner.spec();
    let mut points = Vec::new();
    for method in &args.study.methods {
        for &h in steps {
            // Whole steps up to t_end (the last may stop short of it).
            let n = (t_end / h * (1.0 + 1e-12)).floor() as usize;
            if n == 0 {
                return Err(Error::flag(
                    "--t-end",
                    format!("--t-end {t_end} is shorter than one outer step --h {h}"),
                ));
            }
            // Every step's error is kept (8 bytes each).
            if t_end / h > MAX_STEPS as f64 {
                return Err(Error::flag(
                    "--t-end",
                    format!(
                        "--t-end {t_end} / --h {h} is more than the {MAX_STEPS} steps a growth run \
                     records"
                    ),
                ));
            }
            let settings = point_settings(scene, &base, method, h)?;
            prepare::check_settings(&settings).map_err(|e| {
                Error::flag("--method", format!("--method {method} at h = {h}: {e}"))
            })?;
            points.push((points.len(), settings, n));
        }
    }
    Ok(points)
}

/// One line per run on stdout: the predicted and the measured growth rate.
fn print_growth_table(runs: &[GrowthRun]) {
    println!(
        "{:<15} {:>8} {:>6} {:>14} {:>6} {:>12} {:>12} {:>12}",
        "method", "h", "K", "rho", "type", "2 ln rho", "measured", "max |dE|/E0"
    );
    for run in runs {
        let (rho, kind, predicted) = match &run.linear {
            Ok(point) => (
                format!("{:.8}", point.spectral_radius),
                point.kind.code().to_string(),
                format!("{:.4e}", predicted_rate(point)),
            ),
            Err(_) => ("-".into(), "-".into(), "-".into()),
        };
        println!(
            "{:<15} {:>8} {:>6} {:>14} {:>6} {:>12} {:>12} {:>12.4e}{}",
            run.method,
            run.h,
            run.inner_steps.map_or("-".into(), |k| k.to_string()),
            rho,
            kind,
            predicted,
            run.fit.map_or("-".into(), |f| format!("{:.4e}", f.rate)),
            run.max_error,
            if run.end == "ok" {
                String::new()
            } else {
                format!("  ({} after {} steps)", run.end, run.steps)
            }
        );
    }
}

/// The runs without a linear prediction, and where the results are, on stderr.
fn print_notices(args: &ScanGrowthArgs, runs: &[GrowthRun]) {
    for run in runs {
        if let Err(reason) = &run.linear {
            eprintln!(
                "notice: {} at h = {}: no linear prediction ({reason})",
                run.method, run.h
            );
        }
    }
    eprintln!(
        "results in {} (growth.csv, envelope.csv)",
        args.out.display()
    );
}

/// 2 ln ρ: the growth rate per step of the energy error of an unstable linear step, zero
/// for a stable one.
fn predicted_rate(point: &StabilityPoint) -> f64 {
    if point.kind.is_stable() {
        0.0
    } else {
        2.0 * point.spectral_radius.ln()
    }
}

fn growth_run(
    args: &ScanGrowthArgs,
    probe_scene: &ProbeScene,
    index: usize,
    settings: &MethodSettings,
    n: usize,
    fit_bounds: Option<(f64, f64)>,
) -> Result<GrowthRun> {
    let mut spec = args.study.inner.spec();
    spec.method = Some(settings.method.clone());
    spec.h = Some(Value::Number(settings.h));
    let mut run = prepare::prepare(&RunRequest::new(&args.scene, &args.set, &spec))?;
    let (errors, end) = energy_errors(&mut run.scene.system, run.integrator.as_mut(), n)?;
    // The linearisation about the scene's equilibrium with the same method and steps; a
    // scene that does not start next to an equilibrium has none.
    let linear = IntegratorProbe::new(probe_scene.clone(), settings.clone())
        .and_then(|probe| probe.propagation_matrix(&args.set))
        .map(|matrix| classify_matrix(&matrix, INTEGRATOR_TOLERANCE))
        .map_err(|e| e.to_string());
    let window = args.window.unwrap_or((n / 1000).max(1));
    let envelope = window_maxima(&errors, window);
    let fitted = match fit_bounds {
        Some((lo, hi)) => fit_range(&envelope, lo, hi),
        None => default_fit_range(&envelope),
    };
    Ok(GrowthRun {
        index,
        method: settings.method.clone(),
        h: settings.h,
        inner_steps: settings.inner_steps,
        linear,
        fit: fit_rate(fitted),
        steps: errors.len() - 1,
        max_error: errors.iter().fold(0.0, |m: f64, &e| m.max(e)),
        envelope,
        end: end.name(),
    })
}

const SUMMARY_HEADER: [&str; 13] = [
    "index",
    "method",
    "h",
    "inner_steps",
    "spectral_radius",
    "type",
    "predicted_rate",
    "measured_rate",
    "fit_first_step",
    "fit_last_step",
    "max_relative_error",
    "steps",
    "status",
];

fn write_summary(path: &std::path::Path, runs: &[GrowthRun]) -> Result<()> {
    let first_line = format!("# longstep scan-growth, points = {}", runs.len());
    write_table(
        path,
        Some(&first_line),
        SUMMARY_HEADER,
        runs.iter().map(summary_fields),
    )
}

/// One run's row of growth.csv, numbers in `Num` form, empty where not known.
fn summary_fields(run: &GrowthRun) -> [String; 13] {
    let (rho, kind, predicted) = match &run.linear {
        Ok(point) => (
            Num(point.spectral_radius).to_string(),
            point.kind.code().to_string(),
            Num(predicted_rate(point)).to_string(),
        ),
        Err(_) => (String::new(), String::new(), String::new()),
    };
    let (rate, first, last) = match &run.fit {
        Some(fit) => (
            Num(fit.rate).to_string(),
            fit.first_step.to_string(),
            fit.last_step.to_string(),
        ),
        None => (String::new(), String::new(), String::new()),
    };
    [
        run.index.to_string(),
        run.method.clone(),
        Num(run.h).to_string(),
        run.inner_steps.map_or(String::new(), |k| k.to_string()),
        rho,
        kind,
        predicted,
        rate,
        first,
        last,
        Num(run.max_error).to_string(),
        run.steps.to_string(),
        run.end.to_string(),
    ]
}

fn write_envelopes(path: &std::path::Path, runs: &[GrowthRun]) -> Result<()> {
    let header = ["index", "method", "h", "step", "t", "max_relative_error"];
    let rows = runs.iter().flat_map(|run| {
        run.envelope.iter().map(|&(step, max)| {
            [
                run.index.to_string(),
                run.method.clone(),
                Num(run.h).to_string(),
                step.to_string(),
                Num(step as f64 * run.h).to_string(),
                Num(max).to_string(),
            ]
        })
    });
    write_table(path, None, header, rows)
}

fn chart(scene: &str, runs: &[GrowthRun]) -> LineChart {
    let mut chart = LineChart::new(
        &format!("Energy error envelope, {scene}"),
        AxisSpec::linear("t"),
        AxisSpec::log("max |E − E0| / E0 per window"),
    );
    for run in runs {
        let points: Vec<(f64, f64)> = run
            .envelope
            .iter()
            .filter(|&&(_, m)| m > 0.0)
            .map(|&(step, m)| (step as f64 * run.h, m))
            .collect();
        let name = match &run.linear {
            Ok(point) if !point.kind.is_stable() => {
                format!(
                    "{}, h = {} (ρ = {:.5})",
                    run.method, run.h, point.spectral_radius
                )
            }
            Ok(_) => format!("{}, h = {} (stable)", run.method, run.h),
            Err(_) => format!("{}, h = {}", run.method, run.h),
        };
        chart.series.push(Series::line(&name, points));
    }
    chart
}
