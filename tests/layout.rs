//! The layout rules of DEVELOPERS.md that a reader can check by eye, checked here so they
//! stay true: imports between top-level modules point one way (down the layers), no two
//! modules of one room (the files and folders of one directory of `src/`) import each
//! other in a circle, and no function in `src/` is over 80 lines.
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

/// A module of `src/` by its path from the crate root: `src/forces/distance_split/model.rs`
/// is `forces::distance_split::model`, `src/forces/mod.rs` is `forces`, `src/lib.rs` the
/// root (empty); `src/main.rs` is left out (the binary, not the library).
fn module_path(path: &Path) -> Option<Vec<String>> {
    let relative = path.strip_prefix("src").ok()?;
    let mut parts: Vec<String> = relative
        .components()
        .map(|c| c.as_os_str().to_str().unwrap().to_string())
        .collect();
    let last = parts.pop()?.strip_suffix(".rs")?.to_string();
    match last.as_str() {
        "main" if parts.is_empty() => return None,
        "lib" if parts.is_empty() => {}
        "mod" => {}
        _ => parts.push(last),
    }
    Some(parts)
}

/// A line without its `//` comment (a `//` inside a string literal is kept).
fn without_comment(line: &str) -> &str {
    let mut in_string = false;
    let mut previous = ' ';
    for (at, c) in line.char_indices() {
        match c {
            '"' if previous != '\\' && previous != '\'' => in_string = !in_string,
            '/' if !in_string && line[at + 1..].starts_with('/') => return &line[..at],
            _ => {}
        }
        previous = c;
    }
    line
}

fn is_ident_char(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

/// The paths of a `use` tree (the text after `use`, without the `;`), each with the name it
/// brings in (its last segment, or its alias): `a::{b::C, d as e, self}` gives `a::b::C` as
/// `C`, `a::d` as `e` and `a` as `a`; a glob `a::*` gives `a::*` as `*`.
fn use_tree_paths(tree: &str) -> Vec<(Vec<String>, String)> {
    let mut tokens = Vec::new();
    let mut rest = tree.trim();
    while !rest.is_empty() {
        let end = if rest.starts_with("::") {
            2
        } else if rest.starts_with(|c: char| "{},*".contains(c)) {
            1
        } else {
            rest.find(|c: char| !is_ident_char(c)).unwrap_or(rest.len())
        };
        if end == 0 {
            rest = &rest[rest.chars().next().unwrap().len_utf8()..]; // whitespace
        } else {
            tokens.push(&rest[..end]);
            rest = &rest[end..];
        }
        rest = rest.trim_start();
    }
    let mut paths = Vec::new();
    parse_use_tree(&tokens, &mut 0, &mut Vec::new(), &mut paths);
    paths
}

fn parse_use_tree(
    tokens: &[&str],
    at: &mut usize,
    prefix: &mut Vec<String>,
    out: &mut Vec<(Vec<String>, String)>,
) {
    let depth = prefix.len();
    while *at < tokens.len() {
        match tokens[*at] {
            "{" => {
                *at += 1;
                while *at < tokens.len() && tokens[*at] != "}" {
                    parse_use_tree(tokens, at, prefix, out);
                    if tokens.get(*at) == Some(&",") {
                        *at += 1;
                    }
                }
                *at += 1; // the closing brace
                break;
            }
            "*" => {
                *at += 1;
                let mut path = prefix.clone();
                path.push("*".into());
                out.push((path, "*".into()));
                break;
            }
            "::" => *at += 1,
            segment => {
                *at += 1;
                if segment != "self" {
                    prefix.push(segment.to_string());
                }
                if tokens.get(*at) == Some(&"::") {
                    continue;
                }
                let mut name = prefix.last().cloned().unwrap_or_default();
                if tokens.get(*at) == Some(&"as") {
                    name = tokens.get(*at + 1).unwrap_or(&"_").to_string();
                    *at += 2;
                }
                out.push((prefix.clone(), name));
                break;
            }
        }
    }
    prefix.truncate(depth);
}

/// What the circle checker reads of `src/`: every module (files and inline `mod x {`), the
/// names each brings in with `use`, and every path each names (in `use` and in code, from
/// `crate::`, `super::` or `self::`), as written, with the module it is written in.
#[derive(Default)]
struct SourceTree {
    modules: BTreeSet<Vec<String>>,
    /// By module and name: the path a `use` brings in under that name.
    imports: BTreeMap<(Vec<String>, String), Written>,
    paths: Vec<Written>,
}

/// A path as written (`super::model::Model`) and the module it is written in.
type Written = (Vec<String>, Vec<String>);

impl SourceTree {
    fn read(src: &Path) -> SourceTree {
        let mut files = Vec::new();
        rust_files(src, &mut files);
        let mut tree = SourceTree::default();
        for path in &files {
            let relative = Path::new("src").join(path.strip_prefix(src).unwrap());
            if let Some(module) = module_path(&relative) {
                tree.add_file(module, &std::fs::read_to_string(path).unwrap());
            }
        }
        tree
    }

    /// Reads one file of module `module`.
    fn add_file(&mut self, module: Vec<String>, text: &str) {
        let mut ancestors = module.clone();
        while self.modules.insert(ancestors.clone()) && ancestors.pop().is_some() {}
        // Inline modules open: (the closing line, the module's path).
        let mut inline: Vec<(String, Vec<String>)> = Vec::new();
        let mut statement = String::new();
        for line in text.lines() {
            let code = without_comment(line);
            let trimmed = code.trim();
            let context = inline.last().map_or(&module, |(_, m)| m).clone();
            if inline.last().is_some_and(|(end, _)| code.trim_end() == end) {
                inline.pop();
                continue;
            }
            let declaration = trimmed
                .trim_start_matches("pub ")
                .trim_start_matches("pub(crate) ");
            if let Some(name) = declaration
                .strip_prefix("mod ")
                .and_then(|r| r.strip_suffix(" {"))
            {
                let indent = &code[..code.len() - code.trim_start().len()];
                let mut child = context.clone();
                child.push(name.to_string());
                self.modules.insert(child.clone());
                inline.push((format!("{indent}}}"), child));
                continue;
            }
            let visibility = ["pub(crate) ", "pub(super) ", "pub "];
            let unqualified = visibility
                .iter()
                .find_map(|v| trimmed.strip_prefix(v))
                .unwrap_or(trimmed);
            if statement.is_empty() && unqualified.starts_with("use ") {
                statement.push_str(&unqualified[4..]);
            } else if !statement.is_empty() {
                statement.push(' ');
                statement.push_str(trimmed);
            } else {
                self.code_paths(&context, code);
                continue;
            }
            if let Some(tree) = statement.strip_suffix(';') {
                for (path, name) in use_tree_paths(tree) {
                    self.paths.push((context.clone(), path.clone()));
                    self.imports
                        .insert((context.clone(), name), (context.clone(), path));
                }
                statement.clear();
            }
        }
    }

    /// The paths from `crate::`, `super::` or `self::` on a line of code.
    fn code_paths(&mut self, context: &[String], line: &str) {
        for start in ["crate::", "super::", "self::"] {
            let mut from = 0;
            while let Some(found) = line[from..].find(start) {
                let at = from + found;
                from = at + start.len();
                if line[..at].chars().next_back().is_some_and(is_ident_char) {
                    continue;
                }
                let rest = &line[at..];
                let end = rest
                    .find(|c: char| !(is_ident_char(c) || c == ':'))
                    .unwrap_or(rest.len());
                let path: Vec<String> = rest[..end]
                    .split("::")
                    .filter(|s| !s.is_empty())
                    .map(str::to_string)
                    .collect();
                self.paths.push((context.to_vec(), path));
            }
        }
    }

    /// The module a path written in `context` refers to (through the names modules bring
    /// in with `use`, so a re-export leads to the module that defines the item); `None` for
    /// a path outside the crate.
    fn target(&self, context: &[String], path: &[String], depth: usize) -> Option<Vec<String>> {
        if depth > 16 {
            return None; // a `use` that names itself
        }
        let mut absolute = context.to_vec();
        let mut segments = path.iter().peekable();
        match segments.peek().map(|s| s.as_str()) {
            Some("crate") => {
                absolute.clear();
                segments.next();
            }
            Some("self") => {
                segments.next();
            }
            Some("super") => {
                while segments.peek().is_some_and(|s| *s == "super") {
                    absolute.pop()?;
                    segments.next();
                }
            }
            Some(first) => {
                let mut child = absolute.clone();
                child.push(first.to_string());
                if !self.modules.contains(&child) {
                    let (from, imported) = self.imports.get(&(context.to_vec(), first.into()))?;
                    let mut joined = imported.clone();
                    joined.extend(path[1..].iter().cloned());
                    return self.target(from, &joined, depth + 1);
                }
            }
            None => return None,
        }
        let rest: Vec<String> = segments.cloned().collect();
        for (k, segment) in rest.iter().enumerate() {
            let mut child = absolute.clone();
            child.push(segment.clone());
            if self.modules.contains(&child) {
                absolute = child;
                continue;
            }
            // An item of `absolute`, or a name it brings in from elsewhere.
            if let Some((from, imported)) = self.imports.get(&(absolute.clone(), segment.clone())) {
                let mut joined = imported.clone();
                joined.extend(rest[k + 1..].iter().cloned());
                return self
                    .target(from, &joined, depth + 1)
                    .or(Some(absolute.clone()));
            }
            break;
        }
        Some(absolute)
    }

    /// Each room's import graph: for every directory of modules (`forces`,
    /// `forces::distance_split`, the crate root), which of its modules import which,
    /// a module standing for everything below it. A module naming its parent or its own
    /// submodules adds no edge (that is the room above or below).
    fn rooms(&self) -> BTreeMap<Vec<String>, BTreeMap<String, BTreeSet<String>>> {
        let mut rooms: BTreeMap<Vec<String>, BTreeMap<String, BTreeSet<String>>> = BTreeMap::new();
        for (context, path) in &self.paths {
            let Some(target) = self.target(context, path, 0) else {
                continue;
            };
            let common = context
                .iter()
                .zip(&target)
                .take_while(|(a, b)| a == b)
                .count();
            if let (Some(from), Some(to)) = (context.get(common), target.get(common)) {
                rooms
                    .entry(context[..common].to_vec())
                    .or_default()
                    .entry(from.clone())
                    .or_default()
                    .insert(to.clone());
            }
        }
        rooms
    }
}

/// Every circle of each room: the groups of modules that import each other (strongly
/// connected components of more than one module), each with one circle through them.
fn circles(tree: &SourceTree) -> Vec<String> {
    let mut found = Vec::new();
    for (room, graph) in tree.rooms() {
        let mut done = BTreeSet::new();
        for node in graph.keys() {
            if done.contains(node) {
                continue;
            }
            let reach = |from: &str| {
                let mut seen = BTreeSet::from([from.to_string()]);
                let mut stack = vec![from.to_string()];
                while let Some(n) = stack.pop() {
                    for next in graph.get(&n).into_iter().flatten() {
                        if seen.insert(next.clone()) {
                            stack.push(next.clone());
                        }
                    }
                }
                seen
            };
            let group: BTreeSet<String> = reach(node)
                .into_iter()
                .filter(|other| reach(other).contains(node))
                .collect();
            if group.len() > 1 {
                let sub: BTreeMap<String, BTreeSet<String>> = group
                    .iter()
                    .map(|n| (n.clone(), &graph[n] & &group))
                    .collect();
                let circle = find_circle(&sub).unwrap_or_default();
                let room = if room.is_empty() {
                    "src".to_string()
                } else {
                    format!("src/{}", room.join("/"))
                };
                found.push(format!("{room}: {}", circle.join(" → ")));
            }
            done.extend(group);
        }
    }
    found
}

#[test]
fn no_import_circle_in_any_room_of_src() {
    let tree = SourceTree::read(Path::new("src"));
    let rooms = tree.rooms();
    let forces = &rooms[&vec!["forces".to_string()]];
    assert!(
        forces.len() > 5 && forces["distance_split"].contains("nonbonded"),
        "the checker reads the forces room: {forces:?}"
    );
    let found = circles(&tree);
    assert!(
        found.is_empty(),
        "modules of one room import each other in a circle (what both need moves into a \
         module of its own that imports neither):\n{}",
        found.join("\n")
    );
}

#[test]
fn the_circle_checker_follows_uses_paths_and_re_exports() {
    // forces/a imports b (a grouped `use` over two lines), b names c in code, and c
    // imports `Y` through the parent's re-export of `a::Y`: a circle a → b → c → a.
    let tree = |c: &str| {
        let mut tree = SourceTree::default();
        let files = [
            (
                vec!["forces"],
                "pub mod a;\npub mod b;\npub mod c;\npub use a::Y;\npub struct Z;",
            ),
            (
                vec!["forces", "a"],
                "use super::{\n    b::X,\n    Z,\n};\npub struct Y;",
            ),
            (
                vec!["forces", "b"],
                "pub struct X;\nfn f() {\n    crate::forces::c::g(); // crate::forces::a\n}",
            ),
            (vec!["forces", "c"], c),
            (vec!["io"], "use crate::forces::b::X;"),
        ];
        for (module, text) in files {
            tree.add_file(module.iter().map(|m| m.to_string()).collect(), text);
        }
        tree
    };
    let circular = tree("use super::Y;\npub fn g() {}");
    let rooms = circular.rooms();
    let forces = &rooms[&vec!["forces".to_string()]];
    let names = |list: &[&str]| list.iter().map(|n| n.to_string()).collect::<BTreeSet<_>>();
    assert_eq!(forces["a"], names(&["b"]), "`Z` is the parent's own item");
    assert_eq!(forces["b"], names(&["c"]), "a comment is not a path");
    assert_eq!(forces["c"], names(&["a"]), "the re-export leads to `a`");
    assert_eq!(rooms[&Vec::new()]["io"], names(&["forces"]));
    assert_eq!(circles(&circular), ["src/forces: a → b → c → a"]);
    // The same through an inline test module (`super` is then the file itself).
    let in_tests = tree("pub fn g() {}\n\n#[cfg(test)]\nmod tests {\n    use super::super::Y;\n}");
    assert_eq!(circles(&in_tests).len(), 1);
    let acyclic = tree("use super::Z;\npub fn g() {}\nmod tests {\n    use super::g;\n}");
    assert_eq!(circles(&acyclic), Vec::<String>::new());
    assert_eq!(
        use_tree_paths("a::{b::{self, C}, d as e, *}"),
        [
            (vec!["a".into(), "b".into()], "b".into()),
            (vec!["a".into(), "b".into(), "C".into()], "C".into()),
            (vec!["a".into(), "d".into()], "e".into()),
            (vec!["a".into(), "*".into()], "*".into()),
        ]
    );
}

/// Every directory below `src/` (each file included).
fn directories(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            out.push(path.clone());
            directories(&path, out);
        }
    }
}

#[test]
fn a_module_with_submodules_is_a_folder_with_mod_rs() {
    let mut folders = Vec::new();
    directories(Path::new("src"), &mut folders);
    assert!(
        folders.len() > 5,
        "the checker reads the folders: {folders:?}"
    );
    let mixed: Vec<String> = folders
        .iter()
        .filter(|d| d.with_extension("rs").is_file() || !d.join("mod.rs").is_file())
        .map(|d| d.display().to_string())
        .collect();
    assert!(
        mixed.is_empty(),
        "one module convention (DEVELOPERS.md): `foo/mod.rs`, never `foo.rs` beside `foo/`; \
         these folders break it: {mixed:?}"
    );
}
