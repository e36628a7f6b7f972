//! What the commands share: the argument blocks several commands take, the parsers of
//! their values (numbers, outer steps, shards), the check of a study's methods, progress
//! bars, and the settings line of a study table. It imports none of the command modules,
//! so every command may import it.

use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::path::Path;

use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};

use crate::error::{Error, Result};
use crate::expr;
use crate::io::forcefield::{ElectrostaticsOverrides, InverseLength, SplitSection};
use crate::io::scene::{Scene, SceneFlags, load_scene_with};
use crate::settings::{MethodSettings, RunSpec, Value};

pub use crate::studies::points::{parse_shard, parse_steps};

/// The file names of the study tables, which `merge` looks for in a shard's directory.
pub const WORK_PRECISION: &str = "work-precision.csv";
pub const WALL_TIME: &str = "wall-time.csv";
pub use crate::studies::SCAN_STEPS;
pub const SCAN_STIFFNESS: &str = "scan-stiffness.csv";

/// Exit code of bad input or an I/O error.
pub const EXIT_ERROR: i32 = 1;
/// Exit code of a run that went unstable or whose method failed.
pub const EXIT_UNSTABLE: i32 = 3;

/// The inner step of the multiple-time-step methods a study runs, as `run` takes it.
#[derive(Args, Debug)]
pub struct InnerSteps {
    /// Inner steps K per outer step.
    #[arg(long = "inner", value_name = "K")]
    pub inner_steps: Option<usize>,
    /// A fixed inner step dt instead of --inner.
    #[arg(long, allow_negative_numbers = true)]
    pub dt: Option<Value>,
    /// Jacobian mode of the mollified methods.
    #[arg(long)]
    pub jacobian: Option<String>,
}

impl InnerSteps {
    /// The run settings these flags give; the rest default.
    pub fn spec(&self) -> RunSpec {
        RunSpec {
            inner_steps: self.inner_steps,
            dt: self.dt.clone(),
            jacobian: self.jacobian.clone(),
            ..Default::default()
        }
    }
}

/// The methods and outer steps of a study that runs every method at every step (`scan
/// stiffness`, `scan growth`). The methods are `--methods` (or `--method`), comma-separated
/// or repeated, as in every command that takes a list of them.
#[derive(Args, Debug)]
pub struct MethodSteps {
    /// Method(s), comma-separated.
    #[arg(long, alias = "method", value_delimiter = ',', required = true)]
    pub methods: Vec<String>,
    /// Outer step(s) h, comma-separated (numbers or expressions).
    #[arg(
        long = "h",
        value_delimiter = ',',
        required = true,
        allow_negative_numbers = true
    )]
    pub h: Vec<String>,
    #[command(flatten)]
    pub inner: InnerSteps,
    /// Length of each run.
    #[arg(long, allow_negative_numbers = true)]
    pub t_end: String,
}

impl MethodSteps {
    /// The outer steps (--h) as numbers.
    pub fn steps(&self) -> Result<Vec<f64>> {
        self.h.iter().map(|text| number(text, "--h")).collect()
    }

    /// The run length (--t-end) as a number.
    pub fn t_end(&self) -> Result<f64> {
        number(&self.t_end, "--t-end")
    }
}

/// A number or expression of a flag (`10*pi`), finite.
pub fn number(text: &str, what: &str) -> Result<f64> {
    let value = expr::evaluate(text.trim(), &BTreeMap::new())
        .map_err(|e| Error::flag(what, format!("{what}: {e}")))?;
    if !value.is_finite() {
        return Err(Error::flag(what, format!("{what} is not finite ({value})")));
    }
    Ok(value)
}

/// Build every (method, h) once on `scene`, so a bad combination fails before any time is
/// spent on runs.
pub fn check_methods(
    scene: &Scene,
    base: &RunSpec,
    methods: &[String],
    steps: &[f64],
) -> Result<()> {
    for method in methods {
        for &h in steps {
            let settings = point_settings(scene, base, method, h)?;
            crate::run::prepare::check_settings(&settings)
                .map_err(|e| e.context(&format!("{method} at h = {h}")))?;
        }
    }
    Ok(())
}

/// The settings of one point of a study: the scene's `[run]` table overridden by `base`,
/// then by the point's method and outer step `h`.
pub fn point_settings(
    scene: &Scene,
    base: &RunSpec,
    method: &str,
    h: f64,
) -> Result<MethodSettings> {
    let mut spec = base.clone();
    spec.method = Some(method.to_string());
    spec.h = Some(Value::Number(h));
    scene
        .run
        .overridden_by(&spec)
        .resolve_with_units(&scene.parameters, scene.units)
}

/// A setting for a study table's first line: its value, or `default` when not given.
pub fn or_default<T: std::fmt::Display>(value: Option<T>) -> String {
    value.map_or("default".into(), |v| v.to_string())
}

/// A study table's settings from (name, value) pairs; a comma in a value becomes `;`, as
/// the table's first line separates its settings by commas.
pub fn meta_of(pairs: &[(&str, String)]) -> BTreeMap<String, String> {
    pairs
        .iter()
        .map(|(k, v)| (k.to_string(), v.replace(',', ";")))
        .collect()
}

/// A bar on a terminal's stderr drawn by `template` (with `chars` for its bar, else
/// indicatif's), hidden when quiet or not a terminal.
pub fn terminal_bar(total: u64, quiet: bool, template: &str, chars: Option<&str>) -> ProgressBar {
    if quiet || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(total);
    if let Ok(style) = ProgressStyle::with_template(template) {
        bar.set_style(match chars {
            Some(chars) => style.progress_chars(chars),
            None => style,
        });
    }
    bar
}

/// Refuse an `--out` that names a folder where the command writes one file (`--help`
/// says `--out <FILE>` there, `--out <DIR>` where the command writes a folder).
pub fn check_out_file(path: &Path, command: &str) -> Result<()> {
    if !path.is_dir() {
        return Ok(());
    }
    Err(Error::flag(
        "--out",
        format!(
            "{} is a folder; `{command} --out` names the CSV file to write (for example {})",
            path.display(),
            path.join(format!("{}.csv", command.replace(' ', "-")))
                .display()
        ),
    )
    .expected("a file name")
    .got_named(path.display().to_string()))
}

/// A bar of `total` `unit`s (`"runs"`, `"outer steps"`) labelled `label`, with the time
/// elapsed and left, on a terminal's stderr; hidden when quiet or not a terminal. The
/// one progress display of every command that runs longer than a moment.
pub fn counted_bar(total: u64, quiet: bool, label: &str, unit: &str) -> ProgressBar {
    let template =
        format!("{{msg}} [{{bar:40}}] {{pos}}/{{len}} {unit}, {{elapsed}} elapsed, ~{{eta}} left");
    // The label set before the first draw (a set_message would draw an empty bar).
    terminal_bar(total, quiet, &template, Some("=> ")).with_message(label.to_string())
}

/// A progress bar of a study's runs on a terminal, nothing otherwise.
pub fn progress_bar(total: u64, quiet: bool, label: &str) -> ProgressBar {
    counted_bar(total, quiet, label, "runs")
}

/// `progress(done, total)` → the bar's position and length (a callback of the analyses,
/// which know their total only once they start).
pub fn follow(bar: &ProgressBar) -> impl FnMut(usize, usize) + '_ {
    |done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    }
}

/// Where the scene comes from, for `run`, `check`, `forces` and `scan steps`: a
/// topology's coordinates and non-bonded settings, and the electrostatics, each over its
/// key of the scene's `[forcefield]` or the topology's `[topology]`.
#[derive(Args, Clone, Debug, Default)]
pub struct SceneArgs {
    /// The coordinates of a topology given in place of a scene (.inpcrd, .rst7); default:
    /// beside it, same name.
    #[arg(long, value_name = "FILE")]
    pub coordinates: Option<std::path::PathBuf>,
    /// Start velocities of a topology from this file (.rst7 with velocities, .gro with
    /// velocity columns); default: the coordinates' own, if they have them.
    #[arg(long, value_name = "FILE")]
    pub velocities: Option<std::path::PathBuf>,
    /// Non-bonded cutoff of a topology (length; default 9 Å).
    #[arg(long, value_name = "LENGTH")]
    pub cutoff: Option<f64>,
    /// Reaction-field dielectric of a topology (default 78.3, as OpenMM).
    #[arg(long, value_name = "EPS")]
    pub epsilon_rf: Option<f64>,
    /// Coulomb form, overriding [forcefield] coulomb: pme, dsf, reaction-field, plain or none.
    #[arg(long, value_name = "FORM")]
    pub coulomb: Option<String>,
    /// PME splitting coefficient α: a number in the scene's 1/length, or 0.347/Å, 3.47/nm.
    #[arg(long, value_name = "ALPHA", allow_negative_numbers = true)]
    pub ewald_alpha: Option<String>,
    /// PME grid points per axis, NX,NY,NZ.
    #[arg(long, value_name = "NX,NY,NZ")]
    pub pme_grid: Option<String>,
    /// PME B-spline order (4 to 6).
    #[arg(long, value_name = "N")]
    pub pme_order: Option<usize>,
    /// α from erfc(α r_c) = TOL (GROMACS ewald-rtol), when --ewald-alpha is not given.
    #[arg(long, value_name = "TOL", allow_negative_numbers = true)]
    pub ewald_tolerance: Option<f64>,
    /// PME grid spacing (length) when --pme-grid is not given.
    #[arg(long, value_name = "LENGTH", allow_negative_numbers = true)]
    pub fourier_spacing: Option<f64>,
    /// The force level of the pme-reciprocal term (default: the slowest); a level above
    /// the others makes the reciprocal sum its own MTS level.
    #[arg(long, value_name = "LEVEL")]
    pub pme_level: Option<usize>,
    /// The force level of the cutoff (real-space) non-bonded term (default: the slowest):
    /// `--nonbonded-level 0 --pme-level 1` is GROMACS's `mts-level2-forces =
    /// longrange-nonbonded`.
    #[arg(long, value_name = "LEVEL")]
    pub nonbonded_level: Option<usize>,
    /// Split the cutoff term by distance into a short-range part and a remainder on two
    /// levels: the keys of `[forcefield.split]`/`[topology.split]` as KEY=VALUE pairs,
    /// e.g. `r_in=5,r_out=6,short_level=0,remainder_level=1` (replaces the scene's split).
    #[arg(long, value_name = "KEY=VALUE,...")]
    pub split: Option<String>,
    /// A GROMACS topology's preprocessor define, as `grompp -DNAME[=VALUE]` (repeatable;
    /// e.g. `--define FLEXIBLE` for flexible water): added to `[topology] defines`.
    #[arg(long = "define", value_name = "NAME[=VALUE]")]
    pub defines: Vec<String>,
}

impl SceneArgs {
    /// The flags as overrides of the scene's (or topology's) keys.
    pub fn flags(&self) -> Result<SceneFlags> {
        Ok(SceneFlags {
            coordinates: self.coordinates.clone(),
            velocities: self.velocities.clone(),
            cutoff: self.cutoff,
            epsilon_rf: self.epsilon_rf,
            electrostatics: self.electrostatics()?,
            defines: self.defines.clone(),
        })
    }

    fn electrostatics(&self) -> Result<ElectrostaticsOverrides> {
        let pme_grid = match &self.pme_grid {
            None => None,
            Some(text) => {
                let parts: Vec<usize> = text
                    .split(',')
                    .map(|p| p.trim().parse::<usize>())
                    .collect::<std::result::Result<_, _>>()
                    .map_err(|_| grid_error(text))?;
                let grid: [usize; 3] = parts.try_into().map_err(|_| grid_error(text))?;
                Some(grid)
            }
        };
        Ok(ElectrostaticsOverrides {
            coulomb: self.coulomb.clone(),
            ewald_tolerance: self.ewald_tolerance,
            fourier_spacing: self.fourier_spacing,
            ewald_alpha: self
                .ewald_alpha
                .as_ref()
                .map(|text| match text.trim().parse() {
                    Ok(x) => InverseLength::Number(x),
                    Err(_) => InverseLength::Text(text.clone()),
                }),
            pme_grid,
            pme_order: self.pme_order,
            pme_level: self.pme_level,
            nonbonded_level: self.nonbonded_level,
            split: match &self.split {
                Some(text) => Some(SplitSection::from_flag(text).map_err(Error::input)?),
                None => None,
            },
        })
    }

    /// The scene at `path` with `--set` values and these overrides.
    pub fn load(&self, path: &Path, set: &[String]) -> Result<Scene> {
        load_scene_with(path, &self.flags()?, set)
    }
}

fn grid_error(text: &str) -> Error {
    let expected = "three whole numbers NX,NY,NZ (e.g. 16,16,16)";
    Error::flag("--pme-grid", format!("--pme-grid takes {expected}"))
        .expected(expected)
        .got(format!("\"{text}\""))
}
