//! The GROMACS topology preprocessor (a subset of cpp, as `grompp` applies it): `#include
//! "file"` (searched beside the including file, then in each folder of `GMXLIB`, then in
//! the installed `share/gromacs/top`), `#define NAME [value]`, `#undef NAME`,
//! `#ifdef`/`#ifndef`/`#else`/`#endif`, comments after `;`, lines continued by a trailing
//! `\`, and defined names replaced by their values in data lines (whole fields only). Its
//! output is the active data lines, each with the file and line it came from. Cost: one
//! pass over every included line.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// Where installed GROMACS keeps its force fields, tried after `GMXLIB`.
const INSTALLED_TOP: &[&str] = &[
    "/usr/local/gromacs/share/gromacs/top",
    "/usr/share/gromacs/top",
];
/// Deeper than this, an `#include` is taken for a cycle.
const MAX_INCLUDE_DEPTH: usize = 32;

/// One active data line with its origin.
#[derive(Clone, Debug)]
pub struct Line {
    /// Index into [`Source::files`].
    pub file: usize,
    /// 1-based, the first physical line of a continued line.
    pub number: usize,
    /// The fields, macros replaced.
    pub fields: Vec<String>,
}

/// The preprocessed topology.
#[derive(Debug, Default)]
pub struct Source {
    pub files: Vec<PathBuf>,
    pub lines: Vec<Line>,
}

impl Source {
    /// `file:line` of `line`.
    pub fn location(&self, line: &Line) -> String {
        format!("{}:{}", self.files[line.file].display(), line.number)
    }
}

/// One `#if…` level: whether its lines are read, and whether `#else` was seen.
struct Conditional {
    active: bool,
    parent_active: bool,
    in_else: bool,
}

struct Preprocessor {
    defines: HashMap<String, String>,
    conditions: Vec<Conditional>,
    source: Source,
}

/// Preprocess `path` with `defines` (`NAME` or `NAME=value`) given beforehand, as
/// `grompp`'s `define = -DNAME` does.
pub fn preprocess(path: &Path, defines: &[String]) -> Result<Source> {
    let mut pre = Preprocessor {
        defines: defines
            .iter()
            .map(|d| match d.split_once('=') {
                Some((name, value)) => (name.trim().to_string(), value.trim().to_string()),
                None => (d.trim().to_string(), String::new()),
            })
            .collect(),
        conditions: Vec::new(),
        source: Source::default(),
    };
    pre.file(path, 0)?;
    if !pre.conditions.is_empty() {
        return Err(Error::topology(
            path,
            "an #ifdef/#ifndef is not closed by #endif",
        ));
    }
    Ok(pre.source)
}

/// The physical lines of `text` joined where one ends with `\`: (first line number, text).
fn logical_lines(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut pending: Option<(usize, String)> = None;
    for (k, raw) in text.lines().enumerate() {
        let (start, mut joined) = pending.take().unwrap_or((k + 1, String::new()));
        let trimmed = raw.trim_end();
        match trimmed.strip_suffix('\\') {
            Some(head) => {
                joined.push_str(head);
                joined.push(' ');
                pending = Some((start, joined));
            }
            None => {
                joined.push_str(trimmed);
                out.push((start, joined));
            }
        }
    }
    out.extend(pending);
    out
}

impl Preprocessor {
    fn active(&self) -> bool {
        self.conditions.last().is_none_or(|c| c.active)
    }

    fn file(&mut self, path: &Path, depth: usize) -> Result<()> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let index = self.source.files.len();
        self.source.files.push(path.to_path_buf());
        for (number, line) in logical_lines(&text) {
            let content = line.split(';').next().unwrap_or("").trim();
            let at = || format!("{}:{number}", path.display());
            if let Some(directive) = content.strip_prefix('#') {
                self.directive(directive.trim(), path, depth, &at)?;
            } else if !content.is_empty() && self.active() {
                let fields = content
                    .split_whitespace()
                    .flat_map(|f| match self.defines.get(f) {
                        Some(value) => value.split_whitespace().map(String::from).collect(),
                        None => vec![f.to_string()],
                    })
                    .collect();
                self.source.lines.push(Line {
                    file: index,
                    number,
                    fields,
                });
            }
        }
        Ok(())
    }

    fn directive(
        &mut self,
        directive: &str,
        path: &Path,
        depth: usize,
        at: &dyn Fn() -> String,
    ) -> Result<()> {
        let error = |message: String| Error::topology_at(&at(), message);
        let (keyword, rest) = directive
            .split_once(char::is_whitespace)
            .map_or((directive, ""), |(k, r)| (k, r.trim()));
        let name = || {
            rest.split_whitespace()
                .next()
                .ok_or_else(|| error(format!("#{keyword} needs a name")))
        };
        match keyword {
            "ifdef" | "ifndef" => {
                let defined = self.defines.contains_key(name()?);
                let parent_active = self.active();
                self.conditions.push(Conditional {
                    active: parent_active && (defined == (keyword == "ifdef")),
                    parent_active,
                    in_else: false,
                });
            }
            "else" => {
                let top = self
                    .conditions
                    .last_mut()
                    .filter(|c| !c.in_else)
                    .ok_or_else(|| error("#else without #ifdef/#ifndef".into()))?;
                top.active = top.parent_active && !top.active;
                top.in_else = true;
            }
            "endif" => {
                self.conditions
                    .pop()
                    .ok_or_else(|| error("#endif without #ifdef/#ifndef".into()))?;
            }
            _ if !self.active() => {}
            "define" => {
                let name = name()?.to_string();
                let value = rest[name.len()..].trim().to_string();
                self.defines.insert(name, value);
            }
            "undef" => {
                self.defines.remove(name()?);
            }
            "include" => {
                let wanted = rest.trim_matches(|c| c == '"' || c == '<' || c == '>');
                if wanted.is_empty() {
                    return Err(error("#include needs a file name".into()));
                }
                if depth >= MAX_INCLUDE_DEPTH {
                    return Err(error(format!(
                        "#include \"{wanted}\" nests too deep (a cycle?)"
                    )));
                }
                let found = find_include(wanted, path).ok_or_else(|| {
                    error(format!(
                        "#include \"{wanted}\": not found beside {}, in GMXLIB or in {}",
                        path.display(),
                        INSTALLED_TOP.join(", ")
                    ))
                })?;
                self.file(&found, depth + 1)?;
            }
            other => {
                return Err(error(format!(
                    "#{other}: not a preprocessor directive longstep reads (#include, \
                     #define, #undef, #ifdef, #ifndef, #else, #endif)"
                )));
            }
        }
        Ok(())
    }
}

/// `wanted` beside `from`, then in `GMXLIB`'s folders, then in the installed top folder.
fn find_include(wanted: &str, from: &Path) -> Option<PathBuf> {
    let wanted_path = Path::new(wanted);
    if wanted_path.is_absolute() {
        return wanted_path.is_file().then(|| wanted_path.to_path_buf());
    }
    let mut folders: Vec<PathBuf> = vec![from.parent().unwrap_or(Path::new(".")).to_path_buf()];
    if let Some(gmxlib) = std::env::var_os("GMXLIB") {
        folders.extend(std::env::split_paths(&gmxlib));
    }
    folders.extend(INSTALLED_TOP.iter().map(PathBuf::from));
    folders
        .into_iter()
        .map(|f| f.join(wanted_path))
        .find(|p| p.is_file())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn continued_lines_join_and_keep_their_first_number() {
        let lines = logical_lines("a \\\n b\nc\n");
        let words: Vec<(usize, Vec<&str>)> = lines
            .iter()
            .map(|(n, l)| (*n, l.split_whitespace().collect()))
            .collect();
        assert_eq!(words, vec![(1, vec!["a", "b"]), (3, vec!["c"])]);
    }
}
