//! `longstep modes --lanczos K` (and `modes` with constraints or HMR): the highest modes of
//! one force level of a topology as it runs — constraints projected, masses repartitioned —
//! by Lanczos iterations on Hessian-vector products (`analysis::lanczos`), the atoms that
//! carry each, and the outer steps where they resonate (GSS98 section 3).

use std::path::{Path, PathBuf};

use clap::Args;

use crate::analysis::dihedrals::scene_topology;
use crate::analysis::lanczos::{
    ConstrainedHessian, LanczosOptions, RitzPair, lanczos_highest_with,
};
use crate::analysis::modes::{Mode, Resonance, predicted_resonances};
use crate::error::{Error, Result};
use crate::io::scene::Scene;
use crate::io::scene::SceneFlags;
use crate::run::prepare::{self, RunRequest};
use crate::settings::{RunSpec, Value};
use crate::units::Units;

/// The flags `modes` takes for the iterative path.
#[derive(Args, Debug, Clone, Default)]
pub struct LanczosArgs {
    /// Highest modes by at most K Lanczos iterations on Hessian-vector products (no dense
    /// Hessian), constraints projected out; 150 when only constraints or HMR are given.
    #[arg(long, value_name = "K")]
    pub lanczos: Option<usize>,
    /// The force level whose modes these are (0: the innermost).
    #[arg(long, default_value_t = 0, value_name = "LEVEL")]
    pub level: usize,
    /// Constrained bonds, as `run --constraints`: none, h-bonds or all-bonds.
    #[arg(long)]
    pub constraints: Option<String>,
    /// Rigid three-site water (SETTLE), as `run --rigid-water`.
    #[arg(long, num_args = 0..=1, default_missing_value = "true", value_name = "BOOL")]
    pub rigid_water: Option<bool>,
    /// Hydrogen mass repartitioning, as `run --hydrogen-mass` (e.g. 3amu).
    #[arg(long, allow_negative_numbers = true)]
    pub hydrogen_mass: Option<Value>,
}

impl LanczosArgs {
    /// Whether `modes` takes the iterative path.
    pub fn wanted(&self) -> bool {
        self.lanczos.is_some()
            || self.constraints.is_some()
            || self.rigid_water.is_some()
            || self.hydrogen_mass.is_some()
    }
}

/// Everything `modes` hands the iterative path.
pub struct LanczosRequest<'a> {
    pub scene: &'a Path,
    pub set: &'a [String],
    pub start: Option<&'a Path>,
    pub flags: SceneFlags,
    pub args: &'a LanczosArgs,
    pub h_range: Option<&'a str>,
    /// How many distinct frequencies enter the predictions (`--top`).
    pub top: usize,
    pub json: bool,
    /// No progress bar.
    pub quiet: bool,
    pub pictures: Vec<PathBuf>,
}

/// One converged mode with the atoms that carry it.
#[derive(Clone, Debug, serde::Serialize)]
struct LanczosMode {
    frequency: f64,
    period: f64,
    /// A bound on |ω − ω_exact| from the Ritz residual.
    frequency_error: f64,
    /// The atoms with the largest share of the mode's kinetic energy (`x_a²` of the unit
    /// mass-weighted vector), largest first, and their shares.
    atoms: Vec<(String, f64)>,
    /// Share of the kinetic energy on water atoms.
    water_share: f64,
}

/// Reads a `LO:HI` range of outer steps in the scene's units.
pub type RangeParser<'a> = &'a dyn Fn(&str, Units) -> Result<(f64, f64)>;

/// `longstep modes` on the iterative path; `parse_range` reads `--h-range` in the scene's
/// units.
pub fn lanczos_modes(request: &LanczosRequest, parse_range: RangeParser) -> Result<()> {
    let args = request.args;
    let mut scene = load_as_it_runs(request)?;
    let options = LanczosOptions {
        iterations: args.lanczos.unwrap_or(150),
        wanted: (2 * request.top).max(8),
        ..LanczosOptions::default()
    };
    let mut operator = ConstrainedHessian::new(&mut scene.system, args.level)?;
    let most = options.iterations.min(operator.len()) as u64;
    let bar =
        super::common::counted_bar(most, request.quiet, "modes", "Lanczos iterations (at most)");
    let result = lanczos_highest_with(
        &mut operator,
        &mut scene.system.forces,
        &options,
        &mut super::common::follow(&bar),
    );
    bar.finish_and_clear();
    let labels = atom_labels(&scene)?;
    let modes: Vec<LanczosMode> = result
        .pairs
        .iter()
        .filter(|p| p.value > 0.0)
        .map(|p| describe(p, &labels, scene.system.dim))
        .collect();
    let plain: Vec<Mode> = modes
        .iter()
        .map(|m| Mode {
            frequency: m.frequency,
            period: m.period,
            component: 0,
            unstable: false,
        })
        .collect();
    let fastest = plain.first().map_or(0.0, |m| m.frequency);
    let (lo, hi) = match request.h_range {
        Some(range) => parse_range(range, scene.units)?,
        None if fastest > 0.0 => (0.0, 4.0 * std::f64::consts::TAU / fastest),
        None => (0.0, 0.0),
    };
    let resonances = predicted_resonances(&plain, lo, hi, request.top);
    for path in &request.pictures {
        super::draw::draw_modes(path, &scene.name, &plain, &resonances, hi, scene.units)?;
        if !request.json {
            println!("picture    {}", path.display());
        }
    }
    if request.json {
        let json = serde_json::json!({
            "scene": scene.name,
            "level": args.level,
            "constraints": operator.constraint_count(),
            "lanczos_iterations": result.iterations,
            "modes": modes,
            "h_range": [lo, hi],
            "resonances": resonances,
        });
        let text = serde_json::to_string_pretty(&json).map_err(|e| Error::input(e.to_string()))?;
        println!("{text}");
        return Ok(());
    }
    println!(
        "level {} of {}: {} coordinates, {} constrained distances projected out, {} Lanczos \
         iterations",
        args.level,
        scene.name,
        operator.len(),
        operator.constraint_count(),
        result.iterations
    );
    print_table(&modes, scene.units);
    print_resonances(&resonances, lo, hi);
    Ok(())
}

/// The scene with the constraints and masses it runs with (its `[run]` table under the
/// flags), the constraints satisfied at the start positions.
fn load_as_it_runs(request: &LanczosRequest) -> Result<Scene> {
    let mut scene = prepare::load(&RunRequest {
        flags: request.flags.clone(),
        start: request.start,
        ..RunRequest::new(request.scene, request.set, &RunSpec::default())
    })?;
    let args = request.args;
    let molecular = RunSpec {
        constraints: args.constraints.clone(),
        rigid_water: args.rigid_water,
        hydrogen_mass: args.hydrogen_mass.clone(),
        ..RunSpec::default()
    };
    let settings = scene
        .run
        .overridden_by(&molecular)
        .resolve_with_units(&scene.parameters, scene.units)?;
    let mut notices = Vec::new();
    scene.apply_molecular_settings(&settings, &mut notices)?;
    for notice in notices {
        println!("notice     {notice}");
    }
    Ok(scene)
}

/// `RES12:NAME` for each atom of a topology scene, else the particle's name.
fn atom_labels(scene: &Scene) -> Result<Vec<String>> {
    let n = scene.system.n_particles();
    match scene_topology(&scene.path)? {
        Some(topology) if topology.atoms.len() == n => Ok(topology
            .atoms
            .iter()
            .map(|a| {
                let residue = &topology.residues[a.residue];
                format!("{}{}:{}", residue.name, a.residue + 1, a.name)
            })
            .collect()),
        _ => Ok(scene.system.particles.names.clone()),
    }
}

/// Residue names of water models.
const WATER: [&str; 4] = ["WAT", "HOH", "SOL", "TIP3"];

fn describe(pair: &RitzPair, labels: &[String], dim: usize) -> LanczosMode {
    let frequency = pair.value.sqrt();
    let upper = (pair.value + pair.residual).sqrt();
    let lower = (pair.value - pair.residual).max(0.0).sqrt();
    let mut shares: Vec<(usize, f64)> = pair
        .vector
        .chunks(dim)
        .map(|x| x.iter().map(|v| v * v).sum::<f64>())
        .enumerate()
        .collect();
    let water_share = shares
        .iter()
        .filter(|(a, _)| {
            let residue = labels[*a].split(':').next().unwrap_or("");
            WATER.iter().any(|w| residue.starts_with(w))
        })
        .map(|s| s.1)
        .sum();
    shares.sort_by(|a, b| b.1.total_cmp(&a.1));
    LanczosMode {
        frequency,
        period: std::f64::consts::TAU / frequency,
        frequency_error: (upper - frequency).max(frequency - lower),
        atoms: shares
            .iter()
            .take(5)
            .map(|&(a, s)| (labels[a].clone(), s))
            .collect(),
        water_share,
    }
}

/// Speed of light in cm/fs, for wavenumbers ω / (2π c).
const LIGHT_CM_PER_FS: f64 = 2.997_924_58e-5;

fn print_table(modes: &[LanczosMode], units: Units) {
    let real = units == Units::Real;
    println!(
        "highest modes (ω{}, ± from the Ritz residual; T/2: the first impulse resonance):",
        if real { " in cm^-1, periods in fs" } else { "" }
    );
    println!(
        "  {:>3}  {:>9}  {:>7}  {:>8}  {:>7}  {:>6}  atoms (share of the mode's kinetic energy)",
        "#", "omega", "±", "period", "T/2", "water"
    );
    let scale = if real {
        1.0 / (std::f64::consts::TAU * LIGHT_CM_PER_FS)
    } else {
        1.0
    };
    for (i, m) in modes.iter().enumerate() {
        let atoms: Vec<String> = m
            .atoms
            .iter()
            .take(4)
            .map(|(name, share)| format!("{name} {share:.2}"))
            .collect();
        println!(
            "  {:>3}  {:>9.1}  {:>7.1e}  {:>8.3}  {:>7.3}  {:>6.2}  {}",
            i + 1,
            m.frequency * scale,
            m.frequency_error * scale,
            m.period,
            m.period / 2.0,
            m.water_share,
            atoms.join(", ")
        );
    }
}

fn print_resonances(resonances: &[Resonance], lo: f64, hi: f64) {
    println!("predicted resonant outer steps in [{lo}, {hi}] (GSS98 section 3):");
    for r in resonances {
        let periods: Vec<String> = r
            .frequencies
            .iter()
            .map(|w| format!("{:.3}", std::f64::consts::TAU / w))
            .collect();
        println!(
            "  h = {:>8.3}  {:?} k = {}  (periods {})",
            r.h,
            r.kind,
            r.k,
            periods.join(" + ")
        );
    }
}
