//! One error type for everything a user can get wrong, and for I/O.
//!
//! Every variant names what is wrong and where (file, line, key, particle), so the
//! command-line tool can print it as is and exit non-zero without a panic.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A scene file that does not parse or does not make sense. `location` is
    /// `path:line` when the line is known.
    #[error("{location}: {message}")]
    Scene { location: String, message: String },

    /// A bad value from the command line or from a combination of options.
    #[error("{0}")]
    Input(String),

    /// A structure file (XYZ, PDB, …) that chemfiles could not read, or that
    /// does not fit the scene.
    #[error("{path}: {message}")]
    Structure { path: PathBuf, message: String },

    /// A topology or its coordinate file (AMBER prmtop, inpcrd) that does not parse or
    /// holds what longstep does not model. `location` is `path:line`.
    #[error("{location}: {message}")]
    Topology { location: String, message: String },

    /// A checkpoint file (`run --restart`) that does not parse, is of another format
    /// version, or belongs to another scene, method or setting.
    #[error("{path}: {message}")]
    Checkpoint { path: PathBuf, message: String },

    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

impl Error {
    pub fn input(message: impl Into<String>) -> Self {
        Error::Input(message.into())
    }

    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
}

pub type Result<T, E = Error> = std::result::Result<T, E>;
