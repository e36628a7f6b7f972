//! One error type for everything a user can get wrong, and for I/O.
//!
//! Every variant names what is wrong and where (file, line, key, particle), so the
//! command-line tool can print it as is and exit non-zero without a panic.
//!
//! Scene, topology and command-line errors carry a [`Problem`]: where it is (a
//! [`Location`]: file, line, key or flag), what is wrong (`message`), and the value
//! expected and the value got, as fields a caller or a test can read
//! ([`Error::problem`]). They are built in one chain,
//!
//! ```
//! # use longstep::Error;
//! let e = Error::scene("box.toml", "")
//!     .line(4)
//!     .key("box")
//!     .expected("3 numbers")
//!     .got("2");
//! assert_eq!(e.to_string(), "box.toml:4: `box` takes 3 numbers, got 2");
//! assert_eq!(e.location().unwrap().key.as_deref(), Some("box"));
//! ```
//!
//! and all print the same way ([`Problem`]'s `Display`): `file:line: message, got value`.

use std::fmt;
use std::path::{Path, PathBuf};

/// Where a problem is: the file and its line (1-based), and the key, section or flag
/// (`dim`, a prmtop's `CHARGE`, `--h`). Each is `None` where it is not known or does not
/// apply (a command-line value has no file).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Location {
    pub file: Option<PathBuf>,
    pub line: Option<usize>,
    pub key: Option<String>,
}

impl Location {
    /// A location written `path:line` (or `path`), as a GROMACS topology's line table
    /// holds them.
    pub fn parse(text: &str) -> Self {
        let (file, line) = match text.rsplit_once(':') {
            Some((file, line)) if line.parse::<usize>().is_ok() => (file, line.parse().ok()),
            _ => (text, None),
        };
        Location {
            file: (!file.is_empty()).then(|| PathBuf::from(file)),
            line,
            key: None,
        }
    }
}

/// A problem with an input: where, what, and the value expected and got.
///
/// It prints as `file:line: ` (when the file is known; `:line` when the line is), then
/// `message`, or, with no message, `` `key` takes EXPECTED `` (a wrong value described
/// by its fields alone), then `, got GOT` when the value got is known and the message
/// does not name it already (`got_in_message`). The key and the expected value are not
/// printed again after a message: the message names them.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Problem {
    pub location: Location,
    pub message: String,
    pub expected: Option<String>,
    pub got: Option<String>,
    /// The message names the value got (`unknown method "nope"; …`), so it is not
    /// printed again after it.
    pub got_in_message: bool,
}

impl Problem {
    /// What is wrong, without the location and the value got: the message, or the
    /// sentence the key and the expected value make.
    pub fn body(&self) -> String {
        if !self.message.is_empty() {
            return self.message.clone();
        }
        let subject = self
            .location
            .key
            .as_ref()
            .map_or("the value".to_string(), |k| format!("`{k}`"));
        match &self.expected {
            Some(expected) => format!("{subject} takes {expected}"),
            None => format!("{subject} is not valid"),
        }
    }
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(file) = &self.location.file {
            write!(f, "{}", file.display())?;
            if let Some(line) = self.location.line {
                write!(f, ":{line}")?;
            }
            f.write_str(": ")?;
        }
        f.write_str(&self.body())?;
        if let Some(got) = self.got.as_ref().filter(|_| !self.got_in_message) {
            write!(f, ", got {got}")?;
        }
        Ok(())
    }
}

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A scene file that does not parse or does not make sense.
    #[error("{0}")]
    Scene(Box<Problem>),

    /// A bad value from the command line (the flag is the key) or from a combination of
    /// options, or a free-form message ([`Error::input`]).
    #[error("{0}")]
    Input(Box<Problem>),

    /// A structure file (XYZ, PDB, …) that chemfiles could not read, or that
    /// does not fit the scene.
    #[error("{path}: {message}")]
    Structure { path: PathBuf, message: String },

    /// A topology or its coordinate file (AMBER prmtop, inpcrd, GROMACS top, gro) that
    /// does not parse or holds what longstep does not model.
    #[error("{0}")]
    Topology(Box<Problem>),

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

fn problem(file: Option<PathBuf>, key: Option<String>, message: String) -> Box<Problem> {
    Box::new(Problem {
        location: Location {
            file,
            line: None,
            key,
        },
        message,
        expected: None,
        got: None,
        got_in_message: false,
    })
}

impl Error {
    /// A free-form message, for what no file, line or flag names better.
    pub fn input(message: impl Into<String>) -> Self {
        Error::Input(problem(None, None, message.into()))
    }

    /// A bad value of the command-line flag `flag` (`--h`): the flag is the key; the
    /// message names it as the user wrote it.
    pub fn flag(flag: impl Into<String>, message: impl Into<String>) -> Self {
        Error::Input(problem(None, Some(flag.into()), message.into()))
    }

    /// A bad value of a setting (a `[run]` key or its flag): `key` is the setting's name.
    pub fn setting(key: impl Into<String>, message: impl Into<String>) -> Self {
        Self::flag(key, message)
    }

    /// A problem with the scene file `file`; add `.line(…)`, `.key(…)`, … as known. An
    /// empty message leaves the key and the expected value to say it.
    pub fn scene(file: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Error::Scene(problem(Some(file.into()), None, message.into()))
    }

    /// A problem with the topology or coordinate file `file`.
    pub fn topology(file: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Error::Topology(problem(Some(file.into()), None, message.into()))
    }

    /// A topology problem at a `path:line` location as text (GROMACS's line table).
    pub fn topology_at(location: &str, message: impl Into<String>) -> Self {
        let mut error = Error::Topology(problem(None, None, message.into()));
        if let Some(p) = error.problem_mut() {
            p.location = Location::parse(location);
        }
        error
    }

    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }

    /// The problem of a scene, topology or command-line error (`None` for the others).
    pub fn problem(&self) -> Option<&Problem> {
        match self {
            Error::Scene(p) | Error::Input(p) | Error::Topology(p) => Some(p),
            _ => None,
        }
    }

    fn problem_mut(&mut self) -> Option<&mut Problem> {
        match self {
            Error::Scene(p) | Error::Input(p) | Error::Topology(p) => Some(p),
            _ => None,
        }
    }

    /// Where the problem is ([`Error::problem`]'s location).
    pub fn location(&self) -> Option<&Location> {
        self.problem().map(|p| &p.location)
    }

    fn with(mut self, change: impl FnOnce(&mut Problem)) -> Self {
        if let Some(p) = self.problem_mut() {
            change(p);
        }
        self
    }

    /// The line (1-based) of the file the problem is in. Like the other setters below,
    /// it leaves an error without a [`Problem`] (structure, checkpoint, I/O) as it is.
    pub fn line(self, line: usize) -> Self {
        self.with(|p| p.location.line = Some(line))
    }

    /// The line, when known.
    pub fn maybe_line(self, line: Option<usize>) -> Self {
        self.with(|p| p.location.line = line)
    }

    /// The key, section or flag.
    pub fn key(self, key: impl Into<String>) -> Self {
        self.with(|p| p.location.key = Some(key.into()))
    }

    /// What the value should have been.
    pub fn expected(self, expected: impl Into<String>) -> Self {
        self.with(|p| p.expected = Some(expected.into()))
    }

    /// The value given.
    pub fn got(self, got: impl Into<String>) -> Self {
        self.with(|p| p.got = Some(got.into()))
    }

    /// The file the problem is in (a study table, a picture): it prints first, as
    /// `file: message`.
    pub fn file(self, file: impl Into<PathBuf>) -> Self {
        self.with(|p| p.location.file = Some(file.into()))
    }

    /// The error after `prefix` (`euler at h = 0.1: …`), as `prefix: error`. A
    /// command-line problem (no file) keeps its key, expected and got values; any other
    /// error becomes a free-form message of its whole text after the prefix.
    pub fn context(self, prefix: &str) -> Self {
        match self {
            Error::Input(mut p) if p.location.file.is_none() => {
                p.message = format!("{prefix}: {}", p.body());
                Error::Input(p)
            }
            other => Error::input(format!("{prefix}: {other}")),
        }
    }

    /// The value given, where the message already names it (`unknown method "nope"`):
    /// a field to read, not printed again.
    pub fn got_named(self, got: impl Into<String>) -> Self {
        self.with(|p| {
            p.got = Some(got.into());
            p.got_in_message = true;
        })
    }

    /// The message with `note` after it (`message (note)` reads `{body}{note}`).
    pub fn append(self, note: &str) -> Self {
        self.with(|p| p.message = format!("{}{note}", p.body()))
    }

    /// The problem placed in the scene file `file` at `line`, its message after
    /// `context` (`in [run]`): a setting's error blamed on the scene's table. The key,
    /// expected and got values stay; an error without a problem becomes its text.
    pub fn in_scene(self, file: &Path, line: Option<usize>, context: &str) -> Self {
        let mut problem = match self {
            Error::Scene(p) | Error::Input(p) | Error::Topology(p) => p,
            other => problem(None, None, other.to_string()),
        };
        if problem.location.file.is_some() {
            // Another file's problem: its whole text, after the context.
            problem.message = format!("{context}: {problem}");
            problem.got = None;
        } else {
            problem.message = format!("{context}: {}", problem.body());
        }
        problem.location.file = Some(file.to_path_buf());
        problem.location.line = line;
        Error::Scene(problem)
    }
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_problem_prints_location_message_and_got() {
        let e = Error::scene("a.toml", "dim must be 1, 2 or 3")
            .line(3)
            .key("dim")
            .expected("1, 2 or 3")
            .got("4");
        assert_eq!(e.to_string(), "a.toml:3: dim must be 1, 2 or 3, got 4");
        let p = e.problem().unwrap();
        assert_eq!(p.location.file.as_deref(), Some(Path::new("a.toml")));
        assert_eq!(p.expected.as_deref(), Some("1, 2 or 3"));
        assert_eq!(Error::input("free text").to_string(), "free text");
        assert_eq!(
            Error::topology("t.prmtop", "no such file").to_string(),
            "t.prmtop: no such file"
        );
    }

    #[test]
    fn a_context_keeps_the_fields_and_the_text() {
        let e = Error::flag("--h", "--h must be positive").got("-1");
        let before = format!("euler at h = -1: {e}");
        let e = e.context("euler at h = -1");
        assert_eq!(e.to_string(), before);
        assert_eq!(e.location().unwrap().key.as_deref(), Some("--h"));
        assert_eq!(e.problem().unwrap().got.as_deref(), Some("-1"));
        let named = Error::flag("--method", "unknown method \"x\"").got_named("x");
        assert_eq!(named.to_string(), "unknown method \"x\"");
        assert_eq!(named.problem().unwrap().got.as_deref(), Some("x"));
        let scene = Error::scene("a.toml", "bad").line(2);
        let text = format!("x: {scene}");
        assert_eq!(scene.context("x").to_string(), text);
    }

    #[test]
    fn a_location_parses_from_path_and_line() {
        let l = Location::parse("dir/a.top:12");
        assert_eq!(l.file.as_deref(), Some(Path::new("dir/a.top")));
        assert_eq!(l.line, Some(12));
        assert_eq!(Location::parse("a.top").line, None);
    }

    #[test]
    fn a_setting_blamed_on_the_table_keeps_its_fields() {
        let e = Error::setting("t_end", "end time t_end must be positive")
            .got("-1")
            .in_scene(Path::new("s.toml"), Some(14), "in [run]");
        assert_eq!(
            e.to_string(),
            "s.toml:14: in [run]: end time t_end must be positive, got -1"
        );
        assert_eq!(e.location().unwrap().key.as_deref(), Some("t_end"));
    }
}
