//! The layout rules of DEVELOPERS.md that a reader can check by eye, checked here so they
//! stay true: imports between top-level modules point one way (down the layers), and no
//! function in `src/` is over 80 lines.
//!
//! The source is read as text, formatted by `cargo fmt` (which `make test` checks first):
//! a function ends at the first line that is its closing brace at its own indentation.

use std::collections::{BTreeMap, BTreeSet};
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
    "studies",
    "cli",
];

/// The limit of DEVELOPERS.md: a function's lines from its `fn` to its closing brace.
const MAX_FUNCTION_LINES: usize = 80;

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
    path_references(line, "crate::")
}

/// Every name that follows `prefix` on a line (`prefix` ending in `::`), also inside a
/// group `prefix{a::…, b::…}`.
fn path_references(line: &str, prefix: &str) -> Vec<String> {
    let mut names = Vec::new();
    let mut rest = line;
    while let Some(at) = rest.find(prefix) {
        let before = rest[..at].chars().next_back();
        rest = &rest[at + prefix.len()..];
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            continue; // the end of a longer name: `my_run::` is not `run::`
        }
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
fn no_function_in_src_is_over_80_lines() {
    let mut files = Vec::new();
    rust_files(Path::new("src"), &mut files);
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

/// The name of the `src/cli/` module a file belongs to: its first component below
/// `src/cli/` without `.rs`; the root `src/cli/mod.rs` is `cli`.
fn cli_module(path: &Path) -> String {
    let relative = path.strip_prefix("src/cli").unwrap_or(path);
    let first = relative
        .components()
        .next()
        .and_then(|c| c.as_os_str().to_str())
        .unwrap_or("");
    match first.strip_suffix(".rs") {
        Some("mod") => "cli".to_string(),
        Some(stem) => stem.to_string(),
        None => first.to_string(),
    }
}

/// The `src/cli/` modules each module refers to: `crate::cli::x` anywhere; `super::x` in a
/// file just below `src/cli/` (an item of `mod.rs`, `super::Item`, refers to the root
/// `cli`); `x::` in `mod.rs`, which names its modules directly. A file is read up to its
/// first inline module (`mod tests {`), inside which `super` is the file itself.
fn cli_imports(files: &[(String, usize, String)]) -> BTreeMap<String, BTreeSet<String>> {
    let modules: BTreeSet<&str> = files.iter().map(|(m, _, _)| m.as_str()).collect();
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (module, depth, text) in files {
        let targets = graph.entry(module.clone()).or_default();
        for (_, line) in code_lines(text) {
            let trimmed = line.trim_start();
            if trimmed.starts_with("mod ") && trimmed.trim_end().ends_with('{') {
                break;
            }
            let mut names = path_references(line, "crate::cli::");
            if *depth == 1 {
                for name in path_references(line, "super::") {
                    let is_module = modules.contains(name.as_str());
                    names.push(if is_module { name } else { "cli".into() });
                }
            }
            if module == "cli" {
                names.extend(
                    modules
                        .iter()
                        .filter(|m| !path_references(line, &format!("{m}::")).is_empty())
                        .map(|m| m.to_string()),
                );
            }
            targets.extend(
                names
                    .into_iter()
                    .filter(|n| n != module && modules.contains(n.as_str())),
            );
        }
    }
    graph
}

/// A circle of the graph (its modules in order, the first repeated at the end), if any.
fn find_circle(graph: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn visit(
        node: &str,
        graph: &BTreeMap<String, BTreeSet<String>>,
        path: &mut Vec<String>,
        done: &mut BTreeSet<String>,
    ) -> Option<Vec<String>> {
        if let Some(at) = path.iter().position(|n| n == node) {
            let mut circle = path[at..].to_vec();
            circle.push(node.to_string());
            return Some(circle);
        }
        if done.contains(node) {
            return None;
        }
        path.push(node.to_string());
        for next in graph.get(node).into_iter().flatten() {
            if let Some(circle) = visit(next, graph, path, done) {
                return Some(circle);
            }
        }
        path.pop();
        done.insert(node.to_string());
        None
    }
    let mut done = BTreeSet::new();
    graph
        .keys()
        .find_map(|node| visit(node, graph, &mut Vec::new(), &mut done))
}

#[test]
fn no_import_circle_among_the_cli_modules() {
    let mut paths = Vec::new();
    rust_files(Path::new("src/cli"), &mut paths);
    let files: Vec<(String, usize, String)> = paths
        .iter()
        .map(|path| {
            let depth = path.strip_prefix("src/cli").unwrap().components().count();
            let text = std::fs::read_to_string(path).unwrap();
            (cli_module(path), depth, text)
        })
        .collect();
    let graph = cli_imports(&files);
    assert!(
        graph.len() > 5 && graph["cli"].contains("run"),
        "the checker reads the cli modules: {graph:?}"
    );
    if let Some(circle) = find_circle(&graph) {
        panic!(
            "the cli modules import each other in a circle: {} (what several commands share \
             belongs in cli/common.rs, which imports none of them)",
            circle.join(" → ")
        );
    }
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
    // The circle checker: a made-up tree whose `charts` imports `studies` (through
    // `crate::cli::`) while `studies` imports `charts` (through `super::`), or whose
    // `common` names an item of the root, which names every module.
    let tree = |charts: &str, common: &str| {
        let files = [
            (
                "cli",
                0,
                "mod charts;\nfn main() { studies::run(); charts::draw(); }",
            ),
            ("charts", 1, charts),
            (
                "studies",
                1,
                "use super::common::x;\nfn f() { super::charts::draw(); }",
            ),
            ("common", 1, common),
        ];
        let files: Vec<(String, usize, String)> = files
            .iter()
            .map(|(m, d, t)| (m.to_string(), *d, t.to_string()))
            .collect();
        cli_imports(&files)
    };
    let names = |list: &[&str]| list.iter().map(|n| n.to_string()).collect::<BTreeSet<_>>();
    let circular = tree(
        "use crate::cli::{studies::parse, common::x};",
        "use crate::io::scene;",
    );
    assert_eq!(circular["cli"], names(&["charts", "studies"]));
    assert_eq!(circular["charts"], names(&["common", "studies"]));
    assert_eq!(
        circular["common"],
        names(&[]),
        "crate::io is not a cli module"
    );
    assert_eq!(
        find_circle(&circular),
        Some(vec!["charts".into(), "studies".into(), "charts".into()])
    );
    let acyclic = tree("use super::common::x;", "use crate::io::scene;");
    assert_eq!(find_circle(&acyclic), None);
    let through_root = tree("use super::common::x;", "use super::Cli;");
    assert_eq!(through_root["common"], names(&["cli"]));
    assert!(find_circle(&through_root).is_some());
    assert_eq!(cli_module(Path::new("src/cli/mod.rs")), "cli");
    assert_eq!(cli_module(Path::new("src/cli/scene/terms.rs")), "scene");
}
