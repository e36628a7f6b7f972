//! The studies: `longstep modes`, `longstep scan steps`, `longstep minimize`.

use std::io::IsTerminal;
use std::path::PathBuf;

use clap::{Args, Subcommand};

use crate::analysis::minimize::{MinimizeOptions, minimize};
use crate::analysis::modes::{fast_modes, predicted_resonances};
use crate::analysis::scan::{ScanSetup, StepResult, run_points, safe_steps, scan_points};
use crate::error::{Error, Result};
use std::collections::BTreeMap;

use crate::io::scene::load_scene;
use crate::io::study_csv::StudyTable;
use crate::settings::{RunSpec, Value};
use crate::units::Units;

#[derive(Args, Debug)]
pub struct ModesArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Set a scene parameter (repeatable).
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
    /// Minimise the energy (FIRE) before computing the modes.
    #[arg(long)]
    pub minimize: bool,
    /// Range of outer steps in which to predict resonances, as LO:HI.
    #[arg(long, value_name = "LO:HI")]
    pub h_range: Option<String>,
    /// How many of the fastest distinct frequencies enter the predictions.
    #[arg(long, default_value_t = 4)]
    pub top: usize,
    /// Print the result as JSON.
    #[arg(long)]
    pub json: bool,
}

#[derive(Subcommand, Debug)]
pub enum ScanCommand {
    /// Run each method at each outer step and classify it: stable, drifting or unstable.
    Steps(Box<ScanStepsArgs>),
    /// The largest position error against a scene parameter such as a stiff spring's
    /// frequency (GSS98 Figures 11–13), against an extrapolated Verlet reference.
    Stiffness(Box<super::stiffness::ScanStiffnessArgs>),
    /// Long runs: the energy error's envelope, its fitted growth rate per step, and 2 ln ρ
    /// from the linearised step of the same method (GSS98 Figures 6–10).
    Growth(Box<super::growth::ScanGrowthArgs>),
}

#[derive(Args, Debug)]
pub struct ScanStepsArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Methods to scan, comma-separated.
    #[arg(long, value_delimiter = ',', required = true)]
    pub methods: Vec<String>,
    /// Outer steps, as LO:HI:STEP (inclusive) or a comma-separated list.
    #[arg(long = "h", value_name = "LO:HI:STEP")]
    pub h: String,
    /// Inner steps K per outer step (dt = h/K varies with h).
    #[arg(long = "inner", value_name = "K")]
    pub inner_steps: Option<usize>,
    /// A fixed inner step dt (every h must be a multiple of it).
    #[arg(long)]
    pub dt: Option<Value>,
    /// Jacobian mode of the mollified methods.
    #[arg(long)]
    pub jacobian: Option<String>,
    /// Ratio K = h_slow / h_fast of the asynchronous pseudo-energy scheme (h is h_slow).
    #[arg(long)]
    pub ratio: Option<usize>,
    /// Quadrature of the pseudo-energy schemes.
    #[arg(long)]
    pub quadrature: Option<String>,
    /// Length of each run.
    #[arg(long)]
    pub t_end: Value,
    /// Largest |drift| counted as stable, in kT per unit time per degree of freedom
    /// (kT = 2⟨K⟩/n_dof). 5e-8 is 0.05 kT/ns/dof for a scene in femtoseconds.
    #[arg(long, default_value_t = 1e-3)]
    pub drift_bound: f64,
    /// Stop a run as unstable when |E − E0| exceeds this many times the initial energy scale.
    #[arg(long, default_value_t = 10.0)]
    pub blowup: f64,
    /// Record the energy every N steps for the drift fit.
    #[arg(long, default_value_t = 1)]
    pub energy_every: usize,
    /// Set a scene parameter (repeatable).
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
    /// Output directory (scan.csv, safe-steps.csv).
    #[arg(long, default_value = "out/scan-steps")]
    pub out: PathBuf,
    /// Run only the k-th of n deterministic slices of the points (1-based), for job arrays.
    #[arg(long, value_name = "K/N")]
    pub shard: Option<String>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

#[derive(Args, Debug)]
pub struct MinimizeArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
    /// Stop when the largest force component is below this.
    #[arg(long, default_value_t = 1e-6)]
    pub tolerance: f64,
    #[arg(long, default_value_t = 100_000)]
    pub max_iterations: usize,
}

/// `LO:HI` → (lo, hi), in the scene's time units when it has them.
fn parse_range(text: &str, what: &str, units: Units) -> Result<(f64, f64)> {
    let parts: Vec<&str> = text.split(':').collect();
    let [lo, hi] = parts.as_slice() else {
        return Err(Error::input(format!(
            "{what} expects LO:HI, got \"{text}\""
        )));
    };
    let value = |s: &str| -> Result<f64> {
        s.parse::<Value>()
            .map_err(|_| Error::input(format!("bad number in {what}")))?
            .evaluate_time(&Default::default(), what, units.time_units())
    };
    let (lo, hi) = (value(lo)?, value(hi)?);
    if lo >= hi {
        return Err(Error::input(format!("{what}: {lo} is not below {hi}")));
    }
    Ok((lo, hi))
}

/// `LO:HI:STEP` (inclusive, with a tolerance for the last point) or `A,B,C`; in a scene with
/// real units the values may carry time units (`1fs:10fs:0.25fs`).
pub fn parse_steps(text: &str, units: Units) -> Result<Vec<f64>> {
    let value = |s: &str| -> Result<f64> {
        let v: Value = s.parse().map_err(|_| Error::input("bad number"))?;
        let x = v.evaluate_time(&Default::default(), "--h", units.time_units())?;
        if x <= 0.0 {
            return Err(Error::input(format!(
                "--h: steps must be positive, got {x}"
            )));
        }
        Ok(x)
    };
    if text.contains(':') {
        let parts: Vec<&str> = text.split(':').collect();
        let [lo, hi, step] = parts.as_slice() else {
            return Err(Error::input(format!(
                "--h expects LO:HI:STEP, got \"{text}\""
            )));
        };
        let (lo, hi, step) = (value(lo)?, value(hi)?, value(step)?);
        if hi < lo {
            return Err(Error::input(format!("--h: {hi} is below {lo}")));
        }
        let count = ((hi - lo) / step + 1e-9).floor() as usize + 1;
        if count > 100_000 {
            return Err(Error::input(format!(
                "--h gives {count} steps; that is too many"
            )));
        }
        // Round to 12 significant digits so 0.2 + 0.1·9 reads 1.1, not 1.1000000000000001.
        let round = |x: f64| format!("{x:.11e}").parse::<f64>().unwrap_or(x);
        Ok((0..count).map(|i| round(lo + i as f64 * step)).collect())
    } else {
        text.split(',').map(value).collect()
    }
}

/// `k/n` → (k − 1, n), checked.
pub fn parse_shard(text: &str) -> Result<(usize, usize)> {
    let bad = || {
        Error::input(format!(
            "--shard expects K/N with 1 ≤ K ≤ N, got \"{text}\""
        ))
    };
    let (k, n) = text.split_once('/').ok_or_else(bad)?;
    let (k, n): (usize, usize) = (
        k.trim().parse().map_err(|_| bad())?,
        n.trim().parse().map_err(|_| bad())?,
    );
    if k == 0 || n == 0 || k > n {
        return Err(bad());
    }
    Ok((k - 1, n))
}

/// Load the scene and build every (method, h) once, so a bad combination fails before any
/// time is spent on runs.
pub fn check_methods(
    scene: &std::path::Path,
    set: &[String],
    base: &RunSpec,
    methods: &[String],
    steps: &[f64],
) -> Result<crate::io::scene::Scene> {
    let scene = load_scene(scene, set)?;
    for method in methods {
        for &h in steps {
            let mut spec = base.clone();
            spec.method = Some(method.clone());
            spec.h = Some(Value::Number(h));
            let settings = scene
                .run
                .overridden_by(&spec)
                .resolve_with_units(&scene.parameters, scene.units)?;
            crate::integrators::build(&settings, &mut Vec::new())
                .map_err(|e| Error::input(format!("{method} at h = {h}: {e}")))?;
        }
    }
    Ok(scene)
}

/// A progress bar on a terminal, nothing otherwise.
pub fn progress_bar(total: u64, quiet: bool, label: &str) -> indicatif::ProgressBar {
    if quiet || !std::io::stderr().is_terminal() {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(total);
    if let Ok(style) = indicatif::ProgressStyle::with_template(
        "{msg} [{bar:40}] {pos}/{len} runs, {elapsed} elapsed, ~{eta} left",
    ) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_message(label.to_string());
    bar
}

pub fn modes_command(args: &ModesArgs) -> Result<()> {
    let mut scene = load_scene(&args.scene, &args.set)?;
    let minimized = if args.minimize {
        Some(minimize(&mut scene.system, &MinimizeOptions::default()))
    } else {
        None
    };
    let modes = fast_modes(&mut scene.system);
    let fastest = modes.iter().map(|m| m.frequency).fold(0.0, f64::max);
    let (lo, hi) = match &args.h_range {
        Some(range) => parse_range(range, "--h-range", scene.units)?,
        None if fastest > 0.0 => (0.0, 4.0 * std::f64::consts::TAU / fastest),
        None => (0.0, 0.0),
    };
    let resonances = predicted_resonances(&modes, lo, hi, args.top);
    if args.json {
        let json = serde_json::json!({
            "scene": scene.name,
            "minimization": minimized,
            "modes": modes,
            "h_range": [lo, hi],
            "resonances": resonances,
        });
        println!(
            "{}",
            serde_json::to_string_pretty(&json).map_err(|e| Error::input(e.to_string()))?
        );
        return Ok(());
    }
    if let Some(report) = minimized {
        println!("minimised  {report}");
    }
    let unstable = modes.iter().filter(|m| m.unstable).count();
    if unstable > 0 {
        println!(
            "warning    {unstable} modes have negative curvature: the geometry is not at a \
             minimum of the fast forces (try --minimize)"
        );
    }
    println!("fastest modes of the fast subsystem (level 0):");
    println!(
        "  {:>4}  {:>14}  {:>14}  {:>9}",
        "#", "omega", "period", "component"
    );
    for (i, mode) in modes
        .iter()
        .filter(|m| m.frequency > 0.0)
        .take(12)
        .enumerate()
    {
        println!(
            "  {:>4}  {:>14.6}  {:>14.6}  {:>9}{}",
            i + 1,
            mode.frequency,
            mode.period,
            mode.component,
            if mode.unstable {
                "  (negative curvature)"
            } else {
                ""
            }
        );
    }
    println!("predicted resonant outer steps in [{lo}, {hi}]:");
    for r in &resonances {
        let methods: Vec<&str> = ["impulse", "short-average", "linear-average", "long-average"]
            .into_iter()
            .filter(|m| r.kind.affects(m))
            .collect();
        println!(
            "  h = {:<14.6} {:?} k = {}  frequencies {:?}  ({})",
            r.h,
            r.kind,
            r.k,
            r.frequencies,
            methods.join(", ")
        );
    }
    Ok(())
}

pub fn scan_steps_command(args: &ScanStepsArgs) -> Result<()> {
    let units = load_scene(&args.scene, &args.set)?.units;
    let steps = parse_steps(&args.h, units)?;
    let t_end = args
        .t_end
        .evaluate_time(&Default::default(), "--t-end", units.time_units())?;
    if t_end <= 0.0 {
        return Err(Error::input("--t-end must be positive"));
    }
    if args.energy_every == 0 {
        return Err(Error::input("--energy-every must be at least 1"));
    }
    let setup = ScanSetup {
        scene: args.scene.clone(),
        set: args.set.clone(),
        base: RunSpec {
            inner_steps: args.inner_steps,
            dt: args.dt.clone(),
            jacobian: args.jacobian.clone(),
            ratio: args.ratio,
            quadrature: args.quadrature.clone(),
            blowup: Some(args.blowup),
            ..Default::default()
        },
        t_end,
        drift_bound: args.drift_bound,
        energy_every: args.energy_every,
    };
    check_methods(&setup.scene, &setup.set, &setup.base, &args.methods, &steps)?;
    // Warn before an asynchronous run enters an instability band (small linear scenes).
    if args.methods.iter().any(|m| m == "async-pseudo-energy") && !args.quiet {
        for &h in &steps {
            let mut scene = load_scene(&setup.scene, &setup.set)?;
            let mut spec = setup.base.clone();
            spec.method = Some("async-pseudo-energy".into());
            spec.h = Some(Value::Number(h));
            let settings = scene
                .run
                .overridden_by(&spec)
                .resolve_with_units(&scene.parameters, scene.units)?;
            if let Some(warning) =
                crate::analysis::async_stability::band_warning(&mut scene.system, &settings)
            {
                eprintln!("warning: {warning}");
            }
        }
    }
    let mut points = scan_points(&args.methods, &steps);
    let total = points.len();
    if let Some(shard) = &args.shard {
        let (k, n) = parse_shard(shard)?;
        points.retain(|(index, _, _)| index % n == k);
    }
    let bar = progress_bar(points.len() as u64, args.quiet, "scan steps");
    let results = run_points(&setup, &points, &|| bar.inc(1))?;
    bar.finish_and_clear();

    std::fs::create_dir_all(&args.out).map_err(|e| Error::io(&args.out, e))?;
    let path = args.out.join("scan.csv");
    let table = scan_table(args, total, &results);
    table.write(&path)?;
    super::charts::draw_scan_steps(&table, &args.out)?;
    let safe = safe_steps(&results);
    println!(
        "{:<18} {:>12}  {:<24} stable again at",
        "method", "safe up to", "first failure"
    );
    for s in &safe {
        println!(
            "{:<18} {:>12}  {:<24} {}",
            s.method,
            s.safe_up_to.map_or("none".to_string(), |h| format!("{h}")),
            s.first_failure
                .map_or("-".to_string(), |(h, v)| format!("{} at {h}", v.name())),
            islands(&s.stable_beyond, &steps)
        );
    }
    let wall: f64 = results.iter().map(|r| r.wall_seconds).sum();
    eprintln!(
        "{} runs, {:.1} s of run time; results in {}",
        results.len(),
        wall,
        path.display()
    );
    Ok(())
}

/// The scan's study table (see `src/io/study_csv.rs`): one row per point in index order.
pub fn scan_table(args: &ScanStepsArgs, total: usize, results: &[StepResult]) -> StudyTable {
    let mut meta: BTreeMap<String, String> = [
        ("points", total.to_string()),
        ("scene", args.scene.display().to_string()),
        ("set", args.set.join(" ")),
        ("t_end", args.t_end.to_string()),
        ("inner_steps", super::charts::or_default(args.inner_steps)),
        ("dt", super::charts::or_default(args.dt.as_ref())),
        ("drift_bound", args.drift_bound.to_string()),
        ("blowup", args.blowup.to_string()),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v.replace(',', ";")))
    .collect();
    if let Some(shard) = &args.shard {
        meta.insert("shard".into(), shard.clone());
    }
    let mut table = StudyTable::new(
        "scan-steps",
        meta,
        &[
            "index",
            "method",
            "h",
            "status",
            "drift",
            "blowup_time",
            "max_relative_error",
            "steps",
            "slow_evaluations",
            "fast_evaluations",
            "hessian_vector",
        ],
    );
    for r in results {
        table.rows.push(vec![
            r.index.to_string(),
            r.method.clone(),
            r.h.to_string(),
            r.verdict.name().to_string(),
            r.drift.to_string(),
            r.blowup_time.map_or(String::new(), |t| t.to_string()),
            r.max_relative_error.to_string(),
            r.steps.to_string(),
            r.slow_evaluations.to_string(),
            r.fast_evaluations.to_string(),
            r.hessian_vector.to_string(),
        ]);
    }
    table
}

/// Stable steps beyond the first failure as intervals of consecutive scanned steps,
/// e.g. "0.23–0.255, 0.27–0.305".
fn islands(stable: &[f64], scanned: &[f64]) -> String {
    let mut sorted: Vec<f64> = scanned.to_vec();
    sorted.sort_by(f64::total_cmp);
    let mut runs: Vec<(f64, f64)> = Vec::new();
    let mut previous: Option<usize> = None;
    for &h in stable {
        let position = sorted.iter().position(|&x| x == h);
        match (position, previous, runs.last_mut()) {
            (Some(i), Some(j), Some(run)) if i == j + 1 => run.1 = h,
            _ => runs.push((h, h)),
        }
        previous = position;
    }
    if runs.is_empty() {
        return "-".into();
    }
    runs.iter()
        .map(|(a, b)| {
            if a == b {
                format!("{a}")
            } else {
                format!("{a}–{b}")
            }
        })
        .collect::<Vec<_>>()
        .join(", ")
}

pub fn minimize_command(args: &MinimizeArgs) -> Result<()> {
    let mut scene = load_scene(&args.scene, &args.set)?;
    let report = minimize(
        &mut scene.system,
        &MinimizeOptions {
            force_tolerance: args.tolerance,
            max_iterations: args.max_iterations,
        },
    );
    println!("{report}");
    Ok(())
}
