//! The files of a finished run's directory, found and checked once for `analyze` and for
//! the reference of the sampling criterion.

use std::path::Path;

use super::run_analysis::RunFiles;
use crate::error::{Error, Result};

/// The files of one run directory; missing ones, or ones that its manifest says come from
/// different runs ([`crate::io::manifest::check_same_run`]), are errors naming the directory.
pub fn run_files(dir: &Path, trajectory: &str) -> Result<RunFiles> {
    if !dir.exists() {
        return Err(Error::Structure {
            path: dir.to_path_buf(),
            message: "is not a run directory or a trajectory file: no such path".into(),
        });
    }
    if !dir.is_dir() {
        return Err(Error::Structure {
            path: dir.to_path_buf(),
            message: "is not a run directory".into(),
        });
    }
    let files = RunFiles {
        energy: dir.join("energy.csv"),
        trajectory: dir.join(trajectory),
        dof: None,
    };
    // A run writes frames only when asked (a topology's run, unlike the water box scene,
    // writes none by default): say how to get them.
    for (path, hint) in [
        (&files.energy, " (a run directory holds energy.csv)"),
        (
            &files.trajectory,
            ": the run wrote no frames (only `run --trajectory-every N` or a scene's \
             [run] trajectory_every writes them); rerun it with --trajectory-every N, for \
             example 100 for a frame every 100 outer steps",
        ),
    ] {
        if !path.is_file() {
            return Err(Error::Structure {
                path: dir.to_path_buf(),
                message: format!(
                    "has no {}{hint}",
                    path.file_name()
                        .map_or("file".into(), |n| n.to_string_lossy())
                ),
            });
        }
    }
    if !dir.join(crate::io::manifest::MANIFEST).is_file() {
        eprintln!(
            "notice: {} has no manifest.json (a peer code's run, or an older longstep's): \
             its energy.csv and {} are taken as one run's without a check",
            dir.display(),
            files
                .trajectory
                .file_name()
                .map_or("trajectory".into(), |n| n.to_string_lossy())
        );
    }
    crate::io::manifest::check_same_run(dir, &[&files.energy, &files.trajectory])?;
    Ok(files)
}
