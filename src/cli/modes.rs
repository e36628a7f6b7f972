//! `longstep modes`: the normal modes of the fast forces and the outer steps where the
//! multiple-time-step methods resonate.

use std::path::PathBuf;

use clap::Args;

use crate::analysis::minimize::{MinimizeOptions, minimize};
use crate::analysis::modes::{Mode, Resonance, fast_modes_with, predicted_resonances};
use crate::error::{Error, Result};
use crate::run::prepare::{self, RunRequest};
use crate::settings::{RunSpec, Value};
use crate::units::Units;

#[derive(Args, Debug)]
pub struct ModesArgs {
    /// Scene file (TOML), or a topology in its place (AMBER .prmtop/.parm7, GROMACS .top)
    /// with its coordinates (.inpcrd/.rst7, .gro) beside it, same name, or given by
    /// --coordinates.
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
    /// No progress bar (there is one only on a terminal).
    #[arg(long)]
    pub quiet: bool,
    /// Draw the spectrum (periods as sticks) with the predicted resonant outer steps
    /// marked, as PNG.
    #[arg(long, value_name = "FILE")]
    pub png: Option<PathBuf>,
    /// The same picture as SVG.
    #[arg(long, value_name = "FILE")]
    pub svg: Option<PathBuf>,
    /// Start from the positions of this structure file (e.g. from `minimize --save`): same
    /// atoms in the same order; the scene's force field, velocities and box are kept.
    #[arg(long, value_name = "FILE")]
    pub start: Option<PathBuf>,
    #[command(flatten)]
    pub source: super::common::SceneArgs,
    #[command(flatten)]
    pub iterative: super::modes_lanczos::LanczosArgs,
}

/// `LO:HI` → (lo, hi), in the scene's time units when it has them.
fn parse_range(text: &str, what: &str, units: Units) -> Result<(f64, f64)> {
    let parts: Vec<&str> = text.split(':').collect();
    let [lo, hi] = parts.as_slice() else {
        return Err(Error::flag(what, format!("{what} expects LO:HI")).got(format!("\"{text}\"")));
    };
    let value = |s: &str| -> Result<f64> {
        s.parse::<Value>()
            .map_err(|_| {
                Error::flag(what, format!("bad number in {what}"))
                    .expected("a number LO:HI")
                    .got(format!("\"{s}\""))
            })?
            .evaluate_time(&Default::default(), what, units.time_units())
    };
    let (lo, hi) = (value(lo)?, value(hi)?);
    if lo >= hi {
        return Err(Error::flag(what, format!("{what}: {lo} is not below {hi}")));
    }
    Ok((lo, hi))
}

pub fn modes_command(args: &ModesArgs) -> Result<()> {
    if args.iterative.wanted() {
        return modes_iterative(args);
    }
    let mut scene = prepare::load(&RunRequest {
        flags: args.source.flags()?,
        start: args.start.as_deref(),
        ..RunRequest::new(&args.scene, &args.set, &RunSpec::default())
    })?;
    let minimized = if args.minimize {
        Some(minimize(&mut scene.system, &MinimizeOptions::default()))
    } else {
        None
    };
    let bar = super::common::counted_bar(0, args.quiet, "modes", "Hessian columns");
    let modes = fast_modes_with(&mut scene.system, &mut super::common::follow(&bar));
    bar.finish_and_clear();
    let fastest = modes.iter().map(|m| m.frequency).fold(0.0, f64::max);
    let (lo, hi) = match &args.h_range {
        Some(range) => parse_range(range, "--h-range", scene.units)?,
        None if fastest > 0.0 => (0.0, 4.0 * std::f64::consts::TAU / fastest),
        None => (0.0, 0.0),
    };
    let resonances = predicted_resonances(&modes, lo, hi, args.top);
    for path in [&args.png, &args.svg].into_iter().flatten() {
        super::draw::draw_modes(path, &scene.name, &modes, &resonances, hi, scene.units)?;
        if !args.json {
            println!("picture    {}", path.display());
        }
    }
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
    if let Some(report) = &minimized {
        println!("minimised  {}", report.text(scene.units));
    }
    print_curvature_warning(&modes, minimized.is_some());
    print_modes(&modes, scene.units);
    print_resonances(&resonances, lo, hi, scene.units);
    Ok(())
}

/// `modes` with --lanczos, constraints or HMR: the iterative path (`cli/modes_lanczos.rs`).
fn modes_iterative(args: &ModesArgs) -> Result<()> {
    let request = super::modes_lanczos::LanczosRequest {
        scene: &args.scene,
        set: &args.set,
        start: args.start.as_deref(),
        flags: args.source.flags()?,
        args: &args.iterative,
        h_range: args.h_range.as_deref(),
        top: args.top,
        json: args.json,
        quiet: args.quiet,
        pictures: [&args.png, &args.svg]
            .into_iter()
            .flatten()
            .cloned()
            .collect(),
    };
    if args.minimize {
        return Err(Error::flag(
            "--minimize",
            "the iterative modes (--lanczos, constraints, HMR) are those of the structure as \
             it runs; minimise first with `longstep minimize --save` and give it as --start",
        ));
    }
    super::modes_lanczos::lanczos_modes(&request, &|range, units| {
        parse_range(range, "--h-range", units)
    })
}

/// Modes of negative curvature predict no resonance; the warning says why they are there.
fn print_curvature_warning(modes: &[Mode], minimized: bool) {
    let unstable = modes.iter().filter(|m| m.unstable).count();
    if unstable > 0 && minimized {
        // The minimiser minimises all forces; the modes are those of the fast ones alone.
        println!(
            "warning    {unstable} modes have negative curvature: the minimum of all forces \
             is not a minimum of the fast forces alone (the slow forces hold it there); \
             these modes do not oscillate and predict no resonance"
        );
    } else if unstable > 0 {
        println!(
            "warning    {unstable} modes have negative curvature: the geometry is not at a \
             minimum of the fast forces (try --minimize)"
        );
    }
}

/// Speed of light in cm/fs, for wavenumbers ω / (2π c).
const LIGHT_CM_PER_FS: f64 = 2.997_924_58e-5;

/// The table of the twelve fastest oscillating modes; in a real scene ω in rad/fs, the
/// period in fs and the wavenumber in cm⁻¹.
fn print_modes(modes: &[Mode], units: Units) {
    let real = units == Units::Real;
    println!("fastest modes of the fast subsystem (level 0):");
    let (omega, period) = if real {
        ("omega (rad/fs)", "period (fs)")
    } else {
        ("omega", "period")
    };
    let wavenumber = if real { "      cm^-1" } else { "" };
    println!(
        "  {:>4}  {omega:>14}  {period:>14}{wavenumber}  {:>9}",
        "#", "component"
    );
    for (i, mode) in modes
        .iter()
        .filter(|m| m.frequency > 0.0)
        .take(12)
        .enumerate()
    {
        let cm = if real {
            let wavenumber = mode.frequency / (std::f64::consts::TAU * LIGHT_CM_PER_FS);
            format!("  {wavenumber:>9.1}")
        } else {
            String::new()
        };
        println!(
            "  {:>4}  {:>14.6}  {:>14.6}{cm}  {:>9}{}",
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
}

/// The predicted resonant outer steps in `[lo, hi]` (in fs in a real scene), each with the
/// methods it affects.
fn print_resonances(resonances: &[Resonance], lo: f64, hi: f64, units: Units) {
    let unit = match units {
        Units::Real => " fs",
        Units::None => "",
    };
    println!("predicted resonant outer steps in [{lo}, {hi}]{unit}:");
    for r in resonances {
        let methods: Vec<&str> = ["impulse", "short-average", "linear-average", "long-average"]
            .into_iter()
            .filter(|m| r.kind.affects(m))
            .collect();
        let h = format!("{:.6}{unit}", r.h);
        println!(
            "  h = {h:<14} {:?} k = {}  frequencies {:?}  ({})",
            r.kind,
            r.k,
            r.frequencies,
            methods.join(", ")
        );
    }
}
