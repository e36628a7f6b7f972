//! `longstep async-stability-map`: the spectral radius of the asynchronous pseudo-energy
//! scheme's one-coarse-step amplification matrix on a linear scene, over the coarse (or
//! fine) step and the ratio K, written as CSV ([`crate::analysis::async_stability`]).
//!
//! `longstep async-stability-map systems/wave-inhomogeneous.toml --set n=100 \
//!  --param h-slow --range 0.2*dx:1.2*dx --n 101 --ratio 10 --out map.csv`
//!
//! (To be folded under `stability-map --method async-pseudo-energy` at merge.)

use std::path::PathBuf;

use clap::Args;

use crate::analysis::async_stability::{
    MapParameter, MapSpec, RadiusOptions, async_stability_map, unstable_bands, write_map_csv,
};
use crate::error::{Error, Result};
use crate::integrators::quadrature::Quadrature;
use crate::io::scene::{Scene, load_scene};
use crate::settings::Value;

// The defaults, shared with `stability-map --method async-pseudo-energy`.
pub const DEFAULT_PARAM: &str = "h-slow";
pub const DEFAULT_N: usize = 101;
pub const DEFAULT_QUADRATURE: &str = "midpoint";
pub const DEFAULT_OUT: &str = "out/async-stability-map.csv";
pub const DEFAULT_TOLERANCE: f64 = 1e-8;
pub const DEFAULT_MAX_DENSE: usize = 1500;

#[derive(Args, Debug)]
pub struct AsyncMapArgs {
    /// Linear scene (TOML): springs of rest length 0, for example systems/wave-inhomogeneous.toml.
    pub scene: PathBuf,
    /// The step varied along the map: h-slow (h_fast = h_slow / K) or h-fast (h_slow = K h_fast).
    #[arg(long, default_value = DEFAULT_PARAM)]
    pub param: String,
    /// Range FROM:TO of the varied step; numbers or expressions in the scene's parameters (0.2*dx:1.2*dx).
    #[arg(long, value_name = "FROM:TO")]
    pub range: String,
    /// Number of points along the range (ends included).
    #[arg(long, default_value_t = DEFAULT_N)]
    pub n: usize,
    /// Ratio K = h_slow / h_fast, or a range of ratios A:B (every whole K in it).
    #[arg(long, value_name = "K|A:B")]
    pub ratio: String,
    /// Quadrature (midpoint is exact for linear forces).
    #[arg(long, default_value = DEFAULT_QUADRATURE)]
    pub quadrature: String,
    /// Output CSV.
    #[arg(long, value_name = "FILE", default_value = DEFAULT_OUT)]
    pub out: PathBuf,
    /// Spectral radius above 1 + TOL counts as unstable.
    #[arg(long, default_value_t = DEFAULT_TOLERANCE, value_name = "TOL")]
    pub tolerance: f64,
    /// Largest state size 3 n_dofs for the dense eigenvalue method; power iteration beyond.
    #[arg(long, default_value_t = DEFAULT_MAX_DENSE)]
    pub max_dense: usize,
    /// Set a scene parameter, e.g. --set n=100 (repeatable).
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
    /// No progress bar (there is one only on a terminal).
    #[arg(long)]
    pub quiet: bool,
}

/// The `--n` values of the mapped parameter over `--range FROM:TO` (expressions in the
/// scene's parameters), evenly spaced; each end positive.
fn map_values(args: &AsyncMapArgs, scene: &Scene) -> Result<Vec<f64>> {
    let Some((from, to)) = args.range.split_once(':') else {
        return Err(Error::flag(
            "--range",
            format!("--range expects FROM:TO, got \"{}\"", args.range),
        ));
    };
    let evaluate = |text: &str, what: &str| -> Result<f64> {
        let value: Value = text.parse().unwrap_or(Value::Number(f64::NAN));
        let x = value.evaluate(&scene.parameters, what)?;
        if x <= 0.0 {
            return Err(Error::flag(what, format!("{what} must be positive")).got(x.to_string()));
        }
        Ok(x)
    };
    let (from, to) = (
        evaluate(from, "--range start")?,
        evaluate(to, "--range end")?,
    );
    if args.n == 0 {
        return Err(Error::flag("--n", "--n must be at least 1"));
    }
    Ok((0..args.n)
        .map(|k| {
            if args.n == 1 {
                from
            } else {
                from + (to - from) * k as f64 / (args.n - 1) as f64
            }
        })
        .collect())
}

pub fn async_map_command(args: &AsyncMapArgs) -> Result<i32> {
    super::common::check_out_file(&args.out, "async-stability-map")?;
    let scene = load_scene(&args.scene, &args.set)?;
    let parameter = MapParameter::parse(&args.param)?;
    let values = map_values(args, &scene)?;
    let ratios = parse_ratios(&args.ratio)?;
    if !(args.tolerance.is_finite() && args.tolerance > 0.0) {
        return Err(Error::flag(
            "--tolerance",
            format!("--tolerance must be positive, got {}", args.tolerance),
        ));
    }
    let spec = MapSpec {
        parameter,
        values,
        ratios,
        quadrature: Quadrature::by_name(&args.quadrature)?,
        dx: scene.parameters.get("dx").copied(),
        tolerance: args.tolerance,
        options: RadiusOptions {
            max_dense: args.max_dense,
            ..RadiusOptions::default()
        },
    };
    let path = args.scene.clone();
    let set = args.set.clone();
    // One system per point: counting them is the map's progress (points started).
    let bar = super::common::progress_bar(
        (spec.values.len() * spec.ratios.len()) as u64,
        args.quiet,
        "async-stability-map",
    );
    let make_system = || {
        bar.inc(1);
        load_scene(&path, &set).map(|scene| scene.system)
    };
    let points = async_stability_map(&make_system, &spec);
    bar.finish_and_clear();
    let points = points?;
    if let Some(parent) = args.out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(|e| Error::io(parent, e))?;
    }
    write_map_csv(&args.out, &points, spec.dx)?;
    let bands = unstable_bands(&points, parameter);
    println!(
        "{} points, {} unstable (spectral radius > 1 + {}); map in {}",
        points.len(),
        points.iter().filter(|p| p.unstable).count(),
        args.tolerance,
        args.out.display()
    );
    for (k, first, last, worst) in bands {
        let scaled = |h: f64| match spec.dx {
            Some(dx) => format!("{h} ({:.4} dx)", h / dx),
            None => h.to_string(),
        };
        println!(
            "unstable band  K = {k}: {} from {} to {}, largest spectral radius {worst:.6}",
            args.param,
            scaled(first),
            scaled(last)
        );
    }
    Ok(0)
}

/// `K` or `A:B`.
fn parse_ratios(text: &str) -> Result<Vec<usize>> {
    let parse = |t: &str| -> Result<usize> {
        match t.trim().parse::<usize>() {
            Ok(k) if k >= 1 => Ok(k),
            _ => Err(
                Error::flag("--ratio", "--ratio expects whole numbers ≥ 1 (K or A:B)")
                    .got(format!("\"{text}\"")),
            ),
        }
    };
    match text.split_once(':') {
        Some((a, b)) => {
            let (a, b) = (parse(a)?, parse(b)?);
            if b < a {
                return Err(Error::flag(
                    "--ratio",
                    format!("--ratio range {a}:{b} is empty"),
                ));
            }
            Ok((a..=b).collect())
        }
        None => Ok(vec![parse(text)?]),
    }
}
