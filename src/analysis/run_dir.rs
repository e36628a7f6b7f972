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
    };
    for (path, hint) in [
        (&files.energy, "energy.csv"),
        (
            &files.trajectory,
            "a trajectory: run with --trajectory-every N",
        ),
    ] {
        if !path.is_file() {
            return Err(Error::Structure {
                path: dir.to_path_buf(),
                message: format!(
                    "has no {} (a run directory holds {hint})",
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
