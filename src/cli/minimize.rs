//! `longstep minimize`: the scene's potential energy minimised (FIRE), and the minimised
//! positions saved for `run --start`.

use std::path::PathBuf;

use clap::Args;

use crate::analysis::minimize::{MinimizeOptions, minimize};
use crate::error::Result;
use crate::run::prepare::{self, RunRequest};
use crate::settings::RunSpec;

#[derive(Args, Debug)]
pub struct MinimizeArgs {
    /// Scene file (TOML).
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
    #[command(flatten)]
    pub source: super::common::SceneArgs,
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
    println!("{}", report.text(scene.units));
    if let Some(path) = &args.save {
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
