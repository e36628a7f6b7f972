//! The layout rules of DEVELOPERS.md that a reader can check by eye, checked here so they
//! stay true: imports between top-level modules point one way (down the layers), and no
//! function in `src/io/` or `src/cli/` is over 100 lines.
//!
//! The source is read as text, formatted by `cargo fmt` (which `make test` checks first):
//! a function ends at the first line that is its closing brace at its own indentation.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The top-level modules from the bottom up: each may import only those before it.
/// `io` and `integrators` are siblings (neither imports the other); `io` comes after so
/// that scenes may name what integrators need.
const LAYERS: &[&str] = &[
    "error",
    "units",
    "expr",
    "plot",
    "settings",
    "forces",
    "split",
    "system",
    "integrators",
    "io",
    "run",
    "analysis",
    "cli",
];

/// The hard limit of DEVELOPERS.md (aim for ~80).
const MAX_FUNCTION_LINES: usize = 100;

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("read {}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for path in entries {
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The top-level module a file of `src/` belongs to (`None` for lib.rs and main.rs).
fn top_module(path: &Path) -> Option<String> {
    let relative = path.strip_prefix("src").ok()?;
    let first = relative.components().next()?.as_os_str().to_str()?;
    let name = first.strip_suffix(".rs").unwrap_or(first);
    (name != "lib" && name != "main").then(|| name.to_string())
}

/// Lines of code: comments (line and doc comments) left out.
fn code_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .filter(|(_, line)| !line.trim_start().starts_with("//"))
}

/// Every `crate::name` a line refers to, also inside `use crate::{a::…, b::…}`.
fn crate_references(line: &str) -> Vec<String> {
    let mut names = Vec::new();
    let mut rest = line;
    while let Some(at) = rest.find("crate::") {
        rest = &rest[at + "crate::".len()..];
        if let Some(group) = rest.strip_prefix('{') {
            let inside = &group[..group.find('}').unwrap_or(group.len())];
            for item in inside.split(',') {
                let head = item.trim().split("::").next().unwrap_or("");
                names.push(head.to_string());
            }
        } else {
            let end = rest
                .find(|c: char| !(c.is_alphanumeric() || c == '_'))
                .unwrap_or(rest.len());
            names.push(rest[..end].to_string());
        }
    }
    names.retain(|n| !n.is_empty());
    names
}

#[test]
fn imports_between_top_level_modules_point_down_the_layers() {
    let rank: BTreeMap<&str, usize> = LAYERS.iter().enumerate().map(|(i, m)| (*m, i)).collect();
    let mut files = Vec::new();
    rust_files(Path::new("src"), &mut files);
    let mut upward = Vec::new();
    for path in &files {
        let Some(module) = top_module(path) else {
            continue;
        };
        let Some(&own) = rank.get(module.as_str()) else {
            panic!(
                "{}: top-level module `{module}` has no layer in tests/layout.rs",
                path.display()
            );
        };
        let text = std::fs::read_to_string(path).unwrap();
        for (index, line) in code_lines(&text) {
            for target in crate_references(line) {
                let Some(&theirs) = rank.get(target.as_str()) else {
                    continue; // a re-export at the crate root (`crate::Result`)
                };
                if theirs > own {
                    upward.push(format!(
                        "{}:{}: `{module}` imports `{target}`, a layer above it",
                        path.display(),
                        index + 1
                    ));
                }
            }
        }
    }
    assert!(
        upward.is_empty(),
        "upward imports (layers, bottom up: {}):\n{}",
        LAYERS.join(" < "),
        upward.join("\n")
    );
}

/// Functions of a file over `limit` lines, as `(first line, name, length)`.
fn long_functions(text: &str, limit: usize) -> Vec<(usize, String, usize)> {
    let lines: Vec<&str> = text.lines().collect();
    let mut long = Vec::new();
    for (start, line) in lines.iter().enumerate() {
        let trimmed = line.trim_start();
        let indent = &line[..line.len() - trimmed.len()];
        let mut signature = trimmed;
        for qualifier in ["pub ", "const ", "async ", "unsafe "] {
            signature = signature.strip_prefix(qualifier).unwrap_or(signature);
            if let Some((_, r)) = signature
                .strip_prefix("pub(")
                .and_then(|r| r.split_once(") "))
            {
                signature = r;
            }
        }
        let Some(after) = signature.strip_prefix("fn ") else {
            continue;
        };
        if line.trim_end().ends_with('}') || line.trim_end().ends_with(';') {
            continue; // one line, or a declaration without a body
        }
        let name: String = after
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        let closing = format!("{indent}}}");
        let end = lines[start + 1..]
            .iter()
            .position(|l| l.trim_end() == closing)
            .map_or(lines.len(), |offset| start + 1 + offset);
        let length = end - start + 1;
        if length > limit {
            long.push((start + 1, name, length));
        }
    }
    long
}

#[test]
fn no_function_in_io_or_cli_is_over_100_lines() {
    let mut files = Vec::new();
    rust_files(Path::new("src/io"), &mut files);
    let mut long = Vec::new();
    for path in &files {
        let text = std::fs::read_to_string(path).unwrap();
        for (line, name, length) in long_functions(&text, MAX_FUNCTION_LINES) {
            long.push(format!(
                "{}:{line}: fn {name} is {length} lines",
                path.display()
            ));
        }
    }
    assert!(
        long.is_empty(),
        "functions over {MAX_FUNCTION_LINES} lines:\n{}",
        long.join("\n")
    );
}

#[test]
fn the_checks_see_what_they_check() {
    // The scanners themselves: a grouped import, a comment, a long function.
    assert_eq!(
        crate_references("use crate::{cli::x, error::Result};"),
        ["cli", "error"]
    );
    assert_eq!(
        code_lines("// crate::cli\nuse crate::io;").count(),
        1,
        "comments are not imports"
    );
    let body = "    let x = 1;\n".repeat(MAX_FUNCTION_LINES);
    let text = format!("fn long() {{\n{body}}}\n\nfn short() {{\n}}\n");
    let found = long_functions(&text, MAX_FUNCTION_LINES);
    assert_eq!(found.len(), 1);
    assert_eq!(
        (found[0].1.as_str(), found[0].2),
        ("long", MAX_FUNCTION_LINES + 2)
    );
}
