//! `longstep stability-map` and `longstep spectral-radius`: GSS98 sections 3 and 7.

use std::path::{Path, PathBuf};

use clap::{Args, ValueEnum};

use super::common::{meta_of, number, terminal_bar};
use crate::analysis::stability::analytic::LinearProblem;
use crate::analysis::stability::integrator::{IntegratorProbe, ProbeScene};
use crate::analysis::stability::map::{Axis, Evaluator, Grid, Shard, census, evaluate};
use crate::analysis::stability::{AnalyticMethod, Coupling, InstabilityType};
use crate::error::{Error, Result};
use crate::io::csv::CsvWriter;
use crate::io::study_csv::StudyTable;
use crate::plot::{AxisSpec, Category, Colouring, HeatMap};
use crate::settings::MethodSettings;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Mode {
    /// GSS98 Lemma 4: exact reduced flow and averages (impulse, short-average,
    /// long-average, linear-average).
    Analytic,
    /// One outer step of the real integrator on the horizontal three-spring scene.
    Integrator,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ColourBy {
    /// ρ − 1 on a logarithmic colour bar; stable points white.
    Radius,
    /// The instability type (1, 2, 3) as categories.
    Type,
}

/// The method, step and coupling shared by both commands.
#[derive(Args, Debug)]
pub struct ModelArgs {
    /// Method: impulse, short-average, long-average, linear-average (analytic mode), or any
    /// method of `longstep methods` (integrator mode).
    #[arg(long)]
    pub method: String,
    /// Outer step h (number or expression); not with async-pseudo-energy, whose map
    /// varies the step over --range.
    #[arg(long, allow_negative_numbers = true)]
    pub h: Option<String>,
    /// Slow coupling U = [[alpha1, beta], [beta, alpha2]] of GSS98 eq. (27) (analytic mode;
    /// default 1/2, the three-spring system).
    #[arg(long, allow_negative_numbers = true)]
    pub alpha1: Option<String>,
    /// See --alpha1 (default 1/2).
    #[arg(long, allow_negative_numbers = true)]
    pub alpha2: Option<String>,
    /// See --alpha1 (default -1/2).
    #[arg(long, allow_negative_numbers = true)]
    pub beta: Option<String>,
    /// analytic: Lemma 4's formula; integrator: one outer step of the real integrator.
    #[arg(long, value_enum, default_value_t = Mode::Analytic)]
    pub mode: Mode,
    /// Inner steps K per outer step (integrator mode).
    #[arg(long = "inner", value_name = "K")]
    pub inner_steps: Option<usize>,
    /// Scene to linearise in integrator mode (default: the built-in three-spring scene);
    /// it must have parameters omega1 and omega2 and start at rest at an equilibrium.
    #[arg(long)]
    pub scene: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub struct StabilityMapArgs {
    #[command(flatten)]
    pub model: ModelArgs,
    /// Range of Γ1 = hΩ1 as START:END (numbers or expressions, e.g. 0:4*pi).
    #[arg(long, default_value = "0:6.5")]
    pub gamma1: String,
    /// Range of Γ2 = hΩ2 as START:END.
    #[arg(long, default_value = "0:6.5")]
    pub gamma2: String,
    /// Points along each axis (default 400; along the range, 101, with async-pseudo-energy).
    #[arg(long)]
    pub n: Option<usize>,
    /// CSV output: gamma1,gamma2,spectral_radius,type (type 0 = stable, -1 = overflow);
    /// required but with async-pseudo-energy (default out/async-stability-map.csv).
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Heat-map picture (PNG).
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Heat-map picture (SVG).
    #[arg(long)]
    pub svg: Option<PathBuf>,
    /// What the picture's colours show.
    #[arg(long = "colour", alias = "color", value_enum, default_value_t = ColourBy::Radius)]
    pub colour: ColourBy,
    /// Compute only the k-th of n contiguous slices of the grid points (k from 1 to n);
    /// the CSV then holds only those rows, in grid order.
    #[arg(long, value_name = "k/n")]
    pub shard: Option<String>,
    /// No progress bar, notices or summary on stderr.
    #[arg(long)]
    pub quiet: bool,
    /// Write the map even when its CSV would be larger than 100 MB.
    #[arg(long)]
    pub allow_large: bool,
    /// The asynchronous map's own arguments (with --method async-pseudo-energy).
    #[command(flatten)]
    pub asynchronous: AsyncArgs,
}

/// `stability-map --method async-pseudo-energy SCENE …`: MEMM18's asynchronous scheme over
/// h_slow and K, with the arguments of `async-stability-map`.
#[derive(Args, Debug, Default)]
pub struct AsyncArgs {
    /// Linear scene of the asynchronous map (async-pseudo-energy only).
    #[arg(value_name = "SCENE")]
    pub linear_scene: Option<PathBuf>,
    /// The step varied: h-slow or h-fast (async-pseudo-energy only; default h-slow).
    #[arg(long)]
    pub param: Option<String>,
    /// Range FROM:TO of the varied step (async-pseudo-energy only).
    #[arg(long, value_name = "FROM:TO")]
    pub range: Option<String>,
    /// Ratio K = h_slow / h_fast, or A:B (async-pseudo-energy only).
    #[arg(long, value_name = "K|A:B")]
    pub ratio: Option<String>,
    /// Quadrature (async-pseudo-energy only; default midpoint).
    #[arg(long)]
    pub quadrature: Option<String>,
    /// Spectral radius above 1 + TOL counts as unstable (async-pseudo-energy only).
    #[arg(long, value_name = "TOL")]
    pub tolerance: Option<f64>,
    /// Largest state for the dense eigenvalue method (async-pseudo-energy only).
    #[arg(long)]
    pub max_dense: Option<usize>,
    /// Set a scene parameter (async-pseudo-energy only; repeatable).
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
}

impl AsyncArgs {
    fn given(&self) -> Option<&'static str> {
        [
            (self.linear_scene.is_some(), "SCENE"),
            (self.param.is_some(), "--param"),
            (self.range.is_some(), "--range"),
            (self.ratio.is_some(), "--ratio"),
            (self.quadrature.is_some(), "--quadrature"),
            (self.tolerance.is_some(), "--tolerance"),
            (self.max_dense.is_some(), "--max-dense"),
            (!self.set.is_empty(), "--set"),
        ]
        .into_iter()
        .find_map(|(given, name)| given.then_some(name))
    }
}

/// The outer step of the map's model, which every method but the asynchronous one needs.
fn step(model: &ModelArgs) -> Result<f64> {
    match &model.h {
        Some(text) => number(text, "--h"),
        None => Err(Error::flag(
            "--h",
            format!("--h is required with --method {}", model.method),
        )),
    }
}

/// The `async-stability-map` arguments of `stability-map --method async-pseudo-energy`.
fn asynchronous_map(args: &StabilityMapArgs) -> Result<super::async_map::AsyncMapArgs> {
    let a = &args.asynchronous;
    let model = &args.model;
    let stray = [
        (model.h.is_some(), "--h"),
        (args.png.is_some() || args.svg.is_some(), "--png/--svg"),
        (args.shard.is_some(), "--shard"),
        (model.scene.is_some(), "--scene (give the scene as SCENE)"),
    ];
    if let Some((_, name)) = stray.iter().find(|(given, _)| *given) {
        return Err(Error::flag(
            *name,
            format!(
                "{name} does not apply to --method async-pseudo-energy, whose map varies the step \
             over --range (see longstep async-stability-map --help)"
            ),
        )
        .expected("flags of async-pseudo-energy's map"));
    }
    let missing = |name: &str| {
        Error::flag(
            "--method",
            format!("--method async-pseudo-energy needs {name}"),
        )
    };
    use super::async_map as defaults;
    Ok(super::async_map::AsyncMapArgs {
        scene: a.linear_scene.clone().ok_or_else(|| missing("a SCENE"))?,
        param: a.param.clone().unwrap_or(defaults::DEFAULT_PARAM.into()),
        range: a.range.clone().ok_or_else(|| missing("--range"))?,
        n: args.n.unwrap_or(defaults::DEFAULT_N),
        ratio: a.ratio.clone().ok_or_else(|| missing("--ratio"))?,
        quadrature: a
            .quadrature
            .clone()
            .unwrap_or(defaults::DEFAULT_QUADRATURE.into()),
        out: args.out.clone().unwrap_or(defaults::DEFAULT_OUT.into()),
        tolerance: a.tolerance.unwrap_or(defaults::DEFAULT_TOLERANCE),
        max_dense: a.max_dense.unwrap_or(defaults::DEFAULT_MAX_DENSE),
        set: a.set.clone(),
        quiet: args.quiet,
    })
}

#[derive(Args, Debug)]
pub struct SpectralRadiusArgs {
    #[command(flatten)]
    pub model: ModelArgs,
    /// Γ1 = hΩ1 (number or expression, e.g. 3*pi/4).
    #[arg(long, allow_negative_numbers = true)]
    pub gamma1: String,
    /// Γ2 = hΩ2.
    #[arg(long, allow_negative_numbers = true)]
    pub gamma2: String,
    /// Print {"spectral_radius": …, "type": …} (type 0 = stable, 1–3 GSS98's types).
    #[arg(long)]
    pub json: bool,
}

/// The evaluator the flags ask for, its notices, and a description for titles.
fn evaluator(model: &ModelArgs) -> Result<(Evaluator, Vec<String>, String)> {
    let h = step(model)?;
    if h <= 0.0 {
        return Err(Error::flag("--h", "--h must be positive").got(h.to_string()));
    }
    match model.mode {
        Mode::Analytic => analytic_evaluator(model, h),
        Mode::Integrator => integrator_evaluator(model, h),
    }
}

/// `--mode analytic`: the reduced linear problem (GSS98 eq. (27)) at `h`.
fn analytic_evaluator(model: &ModelArgs, h: f64) -> Result<(Evaluator, Vec<String>, String)> {
    if model.inner_steps.is_some() {
        return Err(Error::flag(
            "--inner",
            "--inner applies to --mode integrator; analytic mode integrates the \
             reduced problem exactly",
        ));
    }
    if model.scene.is_some() {
        return Err(Error::flag(
            "--scene",
            "--scene applies to --mode integrator",
        ));
    }
    let method = AnalyticMethod::from_name(&model.method)?;
    let defaults = Coupling::default();
    let coupling = Coupling {
        alpha1: match &model.alpha1 {
            Some(text) => number(text, "--alpha1")?,
            None => defaults.alpha1,
        },
        alpha2: match &model.alpha2 {
            Some(text) => number(text, "--alpha2")?,
            None => defaults.alpha2,
        },
        beta: match &model.beta {
            Some(text) => number(text, "--beta")?,
            None => defaults.beta,
        },
    };
    let problem = LinearProblem::new(method, h, coupling)?;
    let description = format!(
        "{} (analytic), h = {}, α = ({}, {}), β = {}",
        method.paper_name(),
        h,
        coupling.alpha1,
        coupling.alpha2,
        coupling.beta
    );
    Ok((Evaluator::Analytic(problem), Vec::new(), description))
}

/// `--mode integrator`: the method's own step on a scene (default: the three springs).
fn integrator_evaluator(model: &ModelArgs, h: f64) -> Result<(Evaluator, Vec<String>, String)> {
    if model.alpha1.is_some() || model.alpha2.is_some() || model.beta.is_some() {
        return Err(Error::flag(
            "--alpha1",
            "--alpha1/--alpha2/--beta apply to --mode analytic; in integrator mode \
             the scene's slow spring sets the coupling",
        ));
    }
    let scene = match &model.scene {
        Some(path) => ProbeScene::load(path)?,
        None => ProbeScene::three_spring(),
    };
    let mut settings = MethodSettings::new(&model.method, h);
    if let Some(k) = model.inner_steps {
        if k == 0 {
            return Err(Error::flag("--inner", "--inner must be at least 1"));
        }
        settings = settings.with_inner_steps(k);
    }
    let probe = IntegratorProbe::new(scene, settings)?;
    let notices = probe.notices().to_vec();
    let description = format!(
        "{} (integrator{}), h = {}",
        model.method,
        model
            .inner_steps
            .map(|k| format!(", K = {k}"))
            .unwrap_or_default(),
        h
    );
    Ok((Evaluator::Integrator(Box::new(probe)), notices, description))
}

fn type_meaning(kind: InstabilityType) -> &'static str {
    match kind {
        InstabilityType::Stable => "stable",
        InstabilityType::Type1 => "type 1: non-real eigenvalues off the unit circle (D < 0)",
        InstabilityType::Type2 => "type 2: a real negative eigenvalue, coalesced at -1",
        InstabilityType::Type3 => "type 3: a real positive eigenvalue, coalesced at +1",
        InstabilityType::Overflow => "the step overflowed",
    }
}

pub fn spectral_radius_command(args: &SpectralRadiusArgs) -> Result<()> {
    let (evaluator, notices, _) = evaluator(&args.model)?;
    for notice in &notices {
        eprintln!("notice: {notice}");
    }
    let gamma1 = number(&args.gamma1, "--gamma1")?;
    let gamma2 = number(&args.gamma2, "--gamma2")?;
    if gamma1 < 0.0 || gamma2 < 0.0 {
        return Err(Error::flag(
            "--gamma1",
            format!("--gamma1 and --gamma2 must be non-negative, got {gamma1} and {gamma2}"),
        ));
    }
    let point = evaluator.point(gamma1, gamma2)?;
    if args.json {
        let json = serde_json::json!({
            "spectral_radius": point.spectral_radius,
            "type": point.kind.code(),
        });
        println!("{json}");
    } else {
        println!(
            "spectral radius {} ({})",
            point.spectral_radius,
            type_meaning(point.kind)
        );
    }
    Ok(())
}

/// Largest grid a picture is drawn for (25 million points, about 225 MB of picture data).
const MAX_PICTURE_POINTS: usize = 25_000_000;

/// Most points per axis: a 100 000² map is 1e10 points, days of work and ~400 GB of CSV
/// even when sharded.
const MAX_POINTS_PER_AXIS: usize = 100_000;

/// `--n` names itself when it is wrong, before the axes are parsed.
fn check_points(args: &StabilityMapArgs) -> Result<usize> {
    let n = args.n.unwrap_or(DEFAULT_POINTS);
    if n == 0 {
        return Err(Error::flag(
            "--n",
            "--n: a map needs at least one point per axis",
        ));
    }
    if n > MAX_POINTS_PER_AXIS {
        return Err(Error::flag(
            "--n",
            format!(
                "--n {n}: more than {MAX_POINTS_PER_AXIS} points per axis ({:.1e} points) is more \
             than a map can compute or store",
                (n as f64).powi(2)
            ),
        ));
    }
    Ok(n)
}

/// Bytes of one CSV row of a map, about (four numbers in their shortest round-trip form:
/// 340 MB for the first 8.5 million rows of a 20 000² map), and the most a map writes
/// without `--allow-large`.
const ROW_BYTES: f64 = 40.0;
const MAX_MAP_BYTES: f64 = 1e8;

/// Refuse a map whose CSV of `rows` rows would be larger than [`MAX_MAP_BYTES`], before
/// anything is written.
fn check_output_size(rows: usize, allow_large: bool) -> Result<()> {
    let bytes = rows as f64 * ROW_BYTES;
    if allow_large || bytes <= MAX_MAP_BYTES {
        return Ok(());
    }
    Err(Error::flag(
        "--n",
        format!(
            "the map's CSV would hold {rows} rows, about {:.0} MB (~{ROW_BYTES} bytes a row), more \
         than {:.0} MB: give a coarser --n, compute it in slices (--shard k/n), or --allow-large",
            bytes / 1e6,
            MAX_MAP_BYTES / 1e6
        ),
    )
    .expected(format!("a map of at most {:.0} MB", MAX_MAP_BYTES / 1e6))
    .got_named(rows.to_string()))
}

/// Points along each axis of a map without --n.
const DEFAULT_POINTS: usize = 400;

/// The CSV a map writes (required but with the asynchronous method).
fn map_csv(args: &StabilityMapArgs) -> Result<&std::path::Path> {
    let path = args
        .out
        .as_deref()
        .ok_or_else(|| Error::flag("--out", "--out FILE.csv is required: the map's CSV"))?;
    super::common::check_out_file(path, "stability-map")?;
    Ok(path)
}

pub fn stability_map_command(args: &StabilityMapArgs) -> Result<i32> {
    if args.model.method == "async-pseudo-energy" {
        return super::async_map::async_map_command(&asynchronous_map(args)?);
    }
    if let Some(name) = args.asynchronous.given() {
        return Err(Error::flag(
            name,
            format!("{name} applies to --method async-pseudo-energy only"),
        )
        .expected("--method async-pseudo-energy"));
    }
    map_csv(args)?;
    let (evaluator, notices, description) = evaluator(&args.model)?;
    let (grid, shard) = map_grid(args)?;
    if !args.quiet {
        for notice in &notices {
            eprintln!("notice: {notice}");
        }
    }
    let range = shard.range(grid.len());
    // The picture needs every value; the CSV streams. Keep the picture's arrays within a
    // few hundred megabytes (≈ 9 bytes per point).
    let drawing = args.png.is_some() || args.svg.is_some();
    if drawing && grid.len() > MAX_PICTURE_POINTS {
        return Err(Error::flag(
            "--n",
            format!(
                "a picture of {} points is more than the {MAX_PICTURE_POINTS} a picture can hold; \
             draw a coarser map (--n) or write only the CSV",
                grid.len()
            ),
        )
        .expected(format!("at most {MAX_PICTURE_POINTS} points"))
        .got_named(grid.len().to_string()));
    }
    check_output_size(range.len(), args.allow_large)?;
    let tally = compute_map(args, &evaluator, &grid, shard, range.clone(), drawing)?;

    let shard_note = if shard.count > 1 {
        format!(" (shard {}/{})", shard.index, shard.count)
    } else {
        String::new()
    };
    let what = match args.colour {
        ColourBy::Radius => "Spectral radius",
        ColourBy::Type => "Instability type",
    };
    let title = format!("{what}: {description}{shard_note}");
    for path in [&args.png, &args.svg].into_iter().flatten() {
        draw_map(
            path,
            &grid,
            &tally.values,
            &tally.kinds,
            args.colour,
            &title,
        )?;
    }
    if !args.quiet {
        report_map(args, range.len(), &shard_note, &tally);
    }
    Ok(0)
}

/// The grid and shard the flags ask for, checked, and the picture formats checked.
fn map_grid(args: &StabilityMapArgs) -> Result<(Grid, Shard)> {
    let n = check_points(args)?;
    let grid = Grid {
        gamma1: Axis::parse(&args.gamma1, n, "--gamma1")?,
        gamma2: Axis::parse(&args.gamma2, n, "--gamma2")?,
    };
    if grid.gamma1.start < 0.0 || grid.gamma2.start < 0.0 {
        return Err(Error::flag(
            if grid.gamma1.start < 0.0 {
                "--gamma1"
            } else {
                "--gamma2"
            },
            "Γ ranges must start at 0 or above",
        )
        .expected("a range starting at 0 or above"));
    }
    let shard = match &args.shard {
        Some(text) => Shard::parse(text)?,
        None => Shard::whole(),
    };
    for path in [&args.png, &args.svg].into_iter().flatten() {
        crate::plot::Format::of(path)?;
    }
    Ok((grid, shard))
}

/// What a map's points add up to: the picture's values and types (empty when nothing is
/// drawn), the count of each type and the largest spectral radius.
struct MapTally {
    values: Vec<f64>,
    kinds: Vec<Option<InstabilityType>>,
    counts: [usize; 5],
    largest: f64,
}

/// Evaluate the shard's points, streaming them to the CSV, and tally them.
fn compute_map(
    args: &StabilityMapArgs,
    evaluator: &Evaluator,
    grid: &Grid,
    shard: Shard,
    range: std::ops::Range<usize>,
    drawing: bool,
) -> Result<MapTally> {
    // A shard names its map's settings, so `longstep merge` can check that shards belong
    // together and cover the map exactly once.
    let first_line = match &args.shard {
        Some(_) => Some(shard_line(args, grid, shard)?),
        None => None,
    };
    let mut csv = CsvWriter::create_after(
        map_csv(args)?,
        first_line.as_deref(),
        &["gamma1", "gamma2", "spectral_radius", "type"],
    )?;
    let progress = terminal_bar(
        range.len() as u64,
        args.quiet,
        "{bar:40} {pos}/{len} points, {elapsed} elapsed, ~{eta} left",
        None,
    );
    let picture_len = if drawing { grid.len() } else { 0 };
    let mut tally = MapTally {
        values: vec![f64::NAN; picture_len],
        kinds: vec![None; picture_len],
        counts: [0usize; 5],
        largest: f64::NAN,
    };
    evaluate(evaluator, grid, range, |first, block| {
        for (offset, point) in block.iter().enumerate() {
            let k = first + offset;
            let (gamma1, gamma2) = grid.point(k);
            csv.row(&[
                gamma1,
                gamma2,
                point.spectral_radius,
                point.kind.code() as f64,
            ])?;
            if drawing {
                tally.values[k] = point.excess;
                tally.kinds[k] = Some(point.kind);
            }
            tally.largest = tally.largest.max(point.spectral_radius);
        }
        let block_counts = census(block);
        for (total, count) in tally.counts.iter_mut().zip(block_counts) {
            *total += count;
        }
        progress.inc(block.len() as u64);
        Ok(())
    })?;
    csv.flush()?;
    progress.finish_and_clear();
    Ok(tally)
}

/// The summary on stderr: the count of each type, the largest spectral radius and the
/// files written.
fn report_map(args: &StabilityMapArgs, points: usize, shard_note: &str, tally: &MapTally) {
    let counts = &tally.counts;
    eprintln!(
        "{} points{shard_note}: {} stable, {} type 1, {} type 2, {} type 3{}; largest \
         spectral radius {}",
        points,
        counts[0],
        counts[1],
        counts[2],
        counts[3],
        if counts[4] > 0 {
            format!(", {} overflowed", counts[4])
        } else {
            String::new()
        },
        tally.largest
    );
    let mut written = vec![
        args.out
            .as_deref()
            .map_or(String::new(), |p| p.display().to_string()),
    ];
    written.extend(
        [&args.png, &args.svg]
            .into_iter()
            .flatten()
            .map(|p| p.display().to_string()),
    );
    eprintln!("wrote {}", written.join(", "));
}

/// The first line of a shard's CSV: `# longstep stability-map, gamma1 = 0:6.5, h = 0.5, …,
/// points = N, shard = k/n` (the study-table form of `src/io/study_csv.rs`): every setting
/// that changes the map's values, numbers evaluated.
fn shard_line(args: &StabilityMapArgs, grid: &Grid, shard: Shard) -> Result<String> {
    let model = &args.model;
    let optional = |text: &Option<String>, what: &str| -> Result<String> {
        Ok(match text {
            Some(t) => number(t, what)?.to_string(),
            None => "default".into(),
        })
    };
    let axis = |a: &Axis| format!("{}:{}", a.start, a.end);
    let settings = vec![
        ("method", model.method.clone()),
        ("mode", format!("{:?}", model.mode).to_lowercase()),
        ("h", step(model)?.to_string()),
        ("gamma1", axis(&grid.gamma1)),
        ("gamma2", axis(&grid.gamma2)),
        ("n", args.n.unwrap_or(DEFAULT_POINTS).to_string()),
        ("alpha1", optional(&model.alpha1, "--alpha1")?),
        ("alpha2", optional(&model.alpha2, "--alpha2")?),
        ("beta", optional(&model.beta, "--beta")?),
        (
            "inner",
            model
                .inner_steps
                .map_or("default".into(), |k| k.to_string()),
        ),
        (
            "scene",
            model
                .scene
                .as_ref()
                .map_or("three-spring".into(), |p| p.display().to_string()),
        ),
        ("points", grid.len().to_string()),
        ("shard", format!("{}/{}", shard.index, shard.count)),
    ];
    Ok(StudyTable::new("stability-map", meta_of(&settings), &[]).first_line())
}

/// An axis of a map picture: in units of π for ranges of a radian or more, plain below,
/// and as an offset from the start for close-ups narrower than 1e-3 of their position.
fn map_axis(axis: &Axis, name: &str, meaning: &str) -> (AxisSpec, (f64, f64, usize)) {
    let span = axis.end - axis.start;
    if span >= 1.0 {
        (
            AxisSpec::pi(&format!("{name} = {meaning}")),
            (axis.start, axis.end, axis.count),
        )
    } else if span < 1e-3 * axis.start.abs().max(1.0) {
        (
            AxisSpec::linear(&format!("{name} − {} ({name} = {meaning})", axis.start)),
            (0.0, span, axis.count),
        )
    } else {
        (
            AxisSpec::linear(&format!("{name} = {meaning}")),
            (axis.start, axis.end, axis.count),
        )
    }
}

/// The colour of stable points in either colouring.
const STABLE_COLOUR: plotters::style::RGBColor = plotters::style::RGBColor(255, 255, 255);

/// The heat map of a stability map; points not computed (another shard's) show as no data.
pub fn draw_map(
    path: &Path,
    grid: &Grid,
    excesses: &[f64],
    kinds: &[Option<InstabilityType>],
    colour: ColourBy,
    title: &str,
) -> Result<()> {
    let (values, colouring) = match colour {
        ColourBy::Radius => radius_colouring(excesses, kinds),
        ColourBy::Type => type_colouring(kinds),
    };
    let (x, x_cells) = map_axis(&grid.gamma1, "Γ1", "hΩ1");
    let (y, y_cells) = map_axis(&grid.gamma2, "Γ2", "hΩ2");
    HeatMap {
        title: title.into(),
        x,
        y,
        x_cells,
        y_cells,
        values,
        colouring,
        size: (1000, 800),
        note: map_note(title),
    }
    .save(path)
}

/// What the map's symbols mean: Γ on the axes, and α, β where the title gives them.
fn map_note(title: &str) -> String {
    let gamma = "Γ1 = hΩ1, Γ2 = hΩ2: the outer step h times the fast frequencies Ω1, Ω2";
    if title.contains("α = (") {
        format!(
            "{gamma}; α = (α1, α2), β: the slow coupling U = [[α1, β], [β, α2]] (GSS98 eq. (27))"
        )
    } else {
        gamma.to_string()
    }
}

/// Colour by ρ − 1 on a log scale; stable points (ρ = 1) as their own category.
fn radius_colouring(excesses: &[f64], kinds: &[Option<InstabilityType>]) -> (Vec<f64>, Colouring) {
    // ρ − 1 for unstable points, 0 (drawn as "stable") for stable ones.
    let values: Vec<f64> = excesses
        .iter()
        .zip(kinds)
        .map(|(excess, kind)| match kind {
            None => f64::NAN,
            Some(InstabilityType::Stable) => 0.0,
            Some(_) => *excess,
        })
        .collect();
    let positive = values.iter().copied().filter(|v| v.is_finite() && *v > 0.0);
    let max = positive.clone().fold(f64::NAN, f64::max);
    let min = positive.fold(f64::NAN, f64::min);
    let (min, max) = if max.is_finite() {
        // At most twelve decades: weaker instabilities share the lowest colour.
        let min = min.max(max * 1e-12);
        if max > min {
            (min, max)
        } else {
            (max / 10.0, max)
        }
    } else {
        (1e-6, 1e-3)
    };
    (
        values,
        Colouring::Continuous {
            label: "spectral radius ρ − 1".into(),
            min,
            max,
            log: true,
            below: Some(Category {
                value: 0.0,
                name: "stable (ρ = 1)".into(),
                colour: STABLE_COLOUR,
            }),
        },
    )
}

/// Colour by the type of instability.
fn type_colouring(kinds: &[Option<InstabilityType>]) -> (Vec<f64>, Colouring) {
    let values = kinds
        .iter()
        .map(|kind| kind.map_or(f64::NAN, |k| k.code() as f64))
        .collect();
    let category = |kind: InstabilityType, name: &str, colour| Category {
        value: kind.code() as f64,
        name: name.into(),
        colour,
    };
    use plotters::style::RGBColor;
    // Stable always, the other categories only where they occur.
    let present = |kind: InstabilityType| kind.is_stable() || kinds.contains(&Some(kind));
    let categories = [
        category(InstabilityType::Stable, "stable", STABLE_COLOUR),
        category(InstabilityType::Type1, "type 1", RGBColor(214, 39, 40)),
        category(InstabilityType::Type2, "type 2", RGBColor(31, 119, 180)),
        category(InstabilityType::Type3, "type 3", RGBColor(44, 160, 44)),
        category(InstabilityType::Overflow, "overflow", RGBColor(0, 0, 0)),
    ]
    .into_iter()
    .filter(|c| InstabilityType::from_code(c.value as i32).is_some_and(present))
    .collect();
    (values, Colouring::Categorical(categories))
}
