//! `longstep minimize`: the scene's potential energy minimised (FIRE), and the minimised
//! positions saved for `run --start`.

use std::path::PathBuf;

use clap::Args;

use crate::analysis::minimize::{MinimizeOptions, minimize};
use crate::error::{Error, Result};
use crate::run::prepare::{self, RunRequest};
use crate::settings::RunSpec;

#[derive(Args, Debug)]
pub struct MinimizeArgs {
    /// Scene file (TOML), or a topology in its place (AMBER .prmtop/.parm7, GROMACS .top)
    /// with its coordinates (.inpcrd/.rst7, .gro) beside it, same name, or given by
    /// --coordinates.
    pub scene: PathBuf,
    /// Set a scene parameter (repeatable).
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
    /// Stop when the largest force component is below this.
    #[arg(long, default_value_t = 1e-6)]
    pub tolerance: f64,
    /// Most FIRE iterations.
    #[arg(long, default_value_t = 100_000)]
    pub max_iterations: usize,
    /// Save the minimised positions to this structure file (format by extension, e.g.
    /// min.xyz); `longstep run SCENE --start min.xyz` starts a run from it.
    #[arg(long, value_name = "FILE")]
    pub save: Option<PathBuf>,
    /// Print the report as JSON (iterations, energies before and after, largest force,
    /// converged) instead of text.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub source: super::common::SceneArgs,
}

/// A structure format that rounds positions (PDB to 0.001 Å, GRO to 0.001 nm) loses the
/// minimum: say so, and which format keeps it.
fn warn_if_rounded(path: &std::path::Path) {
    let extension = path
        .extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    let rounding = match extension.as_str() {
        "pdb" | "ent" => "0.001 Å",
        "gro" => "0.001 nm",
        _ => return,
    };
    eprintln!(
        "warning: {} keeps positions to {rounding}: read back, the structure is no longer at \
         the minimum (its forces are those of the rounding); save as .xyz for every digit",
        path.display()
    );
}

pub fn minimize_command(args: &MinimizeArgs) -> Result<()> {
    let mut scene = prepare::load(&RunRequest {
        flags: args.source.flags()?,
        ..RunRequest::new(&args.scene, &args.set, &RunSpec::default())
    })?;
    let report = minimize(
        &mut scene.system,
        &MinimizeOptions {
            force_tolerance: args.tolerance,
            max_iterations: args.max_iterations,
        },
    );
    if args.json {
        let json = serde_json::to_string_pretty(&report)
            .map_err(|e| Error::input(format!("cannot write the report as JSON: {e}")))?;
        println!("{json}");
    } else {
        println!("{}", report.text(scene.units));
    }
    if let Some(path) = &args.save {
        warn_if_rounded(path);
        let system = &scene.system;
        let mut writer = crate::io::trajectory::TrajectoryWriter::create(
            path,
            &scene.elements,
            system.dim,
            system.periodic_box,
        )?;
        writer.write(&system.state.q, 0, system.state.t)?;
        println!(
            "saved      {} (start a run from it: longstep run {} --start {})",
            path.display(),
            args.scene.display(),
            path.display()
        );
    }
    Ok(())
}
