//! The degrees of freedom a finished run counted its kinetic temperature over, for
//! `analyze`, from the run's `manifest.json`: its `degrees_of_freedom`, which `run` writes;
//! for a run written before that field, recovered from the manifest's command as below.
//!
//! A run records `T = 2K/(n_dof k_B)` with `n_dof = 3N − N_c − 3` when its forces conserve
//! momentum (`system::velocities::DegreesOfFreedom`): `N_c` scalar constraints (h-bonds,
//! three per rigid water) and the centre-of-mass momentum removed at the start. `analyze`
//! reads only the kinetic energy, so it counts them again as the run did: the manifest's
//! command line parsed as `longstep run` parses it, and the scene (as `analyze` loads it,
//! with its own flags and `--set`) prepared with the run's settings ([`prepare`]). Cost:
//! one preparation of the scene per run directory (a force and a few Hessian-vector
//! products for the momentum check).

use std::path::Path;

use clap::Parser;

use super::common::SceneArgs;
use super::run::RunArgs;
use crate::error::{Error, Result};
use crate::io::manifest::{MANIFEST, RunManifest};
use crate::run::prepare::{RunRequest, prepare};

/// `longstep run`'s arguments, parsed from a manifest's command line.
#[derive(Parser, Debug)]
struct RunCommand {
    #[command(flatten)]
    run: RunArgs,
}

/// The degrees of freedom of the run in `dir`, as it counted them: `None` when it has no
/// manifest (a peer's run directory), its command is not `longstep run` (a scan's point),
/// or the scene has no temperature to count (a dimensionless scene without one).
pub fn run_dof(
    dir: &Path,
    scene: &Path,
    source: &SceneArgs,
    set: &[String],
) -> Result<Option<f64>> {
    let Some(manifest) = RunManifest::read(dir)? else {
        return Ok(None);
    };
    if let Some(count) = manifest.degrees_of_freedom {
        return Ok(Some(count as f64));
    }
    // command[0] is the program, command[1] the subcommand: clap takes the latter as the
    // program name of `RunCommand`.
    if manifest.command.get(1).map(String::as_str) != Some("run") {
        return Ok(None);
    }
    let path = dir.join(MANIFEST);
    let refused = |why: String| Error::Structure {
        path: path.clone(),
        message: format!(
            "{why}: cannot count the degrees of freedom its kinetic temperature was recorded \
             over (give them with --dof N)"
        ),
    };
    let parsed = RunCommand::try_parse_from(&manifest.command[1..])
        .map_err(|e| refused(format!("its command is not a `longstep run` line: {e}")))?;
    let run = &parsed.run;
    let request = RunRequest {
        scene,
        set,
        overrides: &run.run,
        seed_source: "--seed",
        start: None,
        precision: run.precision.as_deref(),
        flags: source.flags()?,
        restart: None,
    };
    let prepared = prepare(&request).map_err(|e| {
        refused(format!(
            "its settings do not prepare on {}: {e}",
            scene.display()
        ))
    })?;
    Ok(prepared.degrees_of_freedom.map(|d| d.count as f64))
}
