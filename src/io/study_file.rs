//! Study files of `longstep scan steps SCENE --study FILE`: the configurations of one scan,
//! each a method with its own outer steps and its own run settings.
//!
//! ```toml
//! [[config]]
//! label = "verlet-hbonds"          # names the configuration in scan.csv and the summary
//! method = "verlet"
//! h = ["1fs", "2fs", "2.5fs"]      # or "LO:HI:STEP", as --h
//! constraints = "h-bonds"          # any key of a scene's [run] table (its own parser)
//! rigid_water = true
//! level_dt = ["0.5fs"]             # as --level-dt (optional)
//! pme_level = 1                    # as --pme-level / --nonbonded-level (optional)
//! split = { r_in = 5, r_out = 6, short_level = 0, remainder_level = 1 }  # as --split
//! set = ["k=2"]                    # as --set, after the command line's (optional)
//! starts = 3                       # as --starts: independent starts per point (optional)
//! ```
//!
//! Every key but `label`, `h`, `level_dt`, `pme_level`, `nonbonded_level`, `split`, `set`
//! and `starts` goes to
//! [`RunSpec`], the parser of a scene's `[run]` table, so a study accepts exactly the run
//! settings a scene does. Each key is checked on its own, so a message names the key.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::io::forcefield::SplitSection;
use crate::settings::{RunSpec, Value};

/// The keys of a configuration that are not `[run]` keys.
const STUDY_KEYS: [&str; 8] = [
    "label",
    "h",
    "level_dt",
    "pme_level",
    "nonbonded_level",
    "split",
    "set",
    "starts",
];

/// Most independent starts of one scan point (`--starts`, a study's `starts`; a bound on a
/// user-given count).
pub const MAX_STARTS: usize = 64;

/// Most configurations of one study (a bound on a user-given size).
pub const MAX_CONFIGS: usize = 1000;

/// One configuration of a study, unevaluated (its times are evaluated in the scene's units).
#[derive(Clone, Debug, Default)]
pub struct StudyConfig {
    pub label: String,
    /// Its run settings; `method` is given, `h` is not (see `steps`).
    pub run: RunSpec,
    /// Its outer steps as `--h` takes them: `LO:HI:STEP` or a comma-separated list.
    pub steps: String,
    /// The steps of its inner levels, as `--level-dt` (empty: the command line's).
    pub level_dt: Vec<Value>,
    /// Scene parameters set after the command line's `--set`.
    pub set: Vec<String>,
    pub pme_level: Option<usize>,
    pub nonbonded_level: Option<usize>,
    /// The cutoff term split by distance (as `--split`; `None`: the command line's).
    pub split: Option<SplitSection>,
    /// Independent starts per point (`None`: the command line's `--starts`).
    pub starts: Option<usize>,
}

/// A study file: its configurations in file order, and a fingerprint of its text so the
/// shards of different studies never merge.
#[derive(Clone, Debug)]
pub struct StudyFile {
    pub path: PathBuf,
    pub fingerprint: String,
    pub configs: Vec<StudyConfig>,
}

/// Read and check a study file: unknown keys, a configuration without `label`, `method` or
/// `h`, duplicate labels and values `[run]` refuses are errors naming the file, the
/// configuration and the key.
pub fn read_study(path: &Path) -> Result<StudyFile> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let bad = |message: String| Error::Structure {
        path: path.to_path_buf(),
        message,
    };
    let table: toml::Table = toml::from_str(&text).map_err(|e| bad(e.message().to_string()))?;
    if let Some(key) = table.keys().find(|k| k.as_str() != "config") {
        return Err(bad(format!(
            "unknown key `{key}`: a study file holds only [[config]] tables"
        )));
    }
    let list = match table.get("config") {
        Some(toml::Value::Array(list)) if !list.is_empty() => list,
        _ => return Err(bad("no configuration: add [[config]] tables".into())),
    };
    if list.len() > MAX_CONFIGS {
        return Err(bad(format!(
            "{} configurations; a study holds at most {MAX_CONFIGS}",
            list.len()
        )));
    }
    let mut labels = BTreeSet::new();
    let mut configs = Vec::with_capacity(list.len());
    for (k, entry) in list.iter().enumerate() {
        let config = read_config(entry, k + 1).map_err(&bad)?;
        if !labels.insert(config.label.clone()) {
            return Err(bad(format!(
                "configuration {}: the label \"{}\" is given twice; each label names one \
                 configuration",
                k + 1,
                config.label
            )));
        }
        configs.push(config);
    }
    Ok(StudyFile {
        path: path.to_path_buf(),
        fingerprint: fingerprint(&text),
        configs,
    })
}

/// The 64-bit FNV-1a hash of a study's text, in hex: stable across machines and builds.
fn fingerprint(text: &str) -> String {
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    for byte in text.bytes() {
        hash ^= u64::from(byte);
        hash = hash.wrapping_mul(0x0100_0000_01b3);
    }
    format!("{hash:016x}")
}

/// The `number`-th `[[config]]` table (1-based); an error message names it and the key.
fn read_config(entry: &toml::Value, number: usize) -> std::result::Result<StudyConfig, String> {
    let toml::Value::Table(table) = entry else {
        return Err(format!("configuration {number} is not a table"));
    };
    let label = match table.get("label") {
        Some(toml::Value::String(s))
            if !s.trim().is_empty() && !s.contains([',', ';', '"', '\n']) =>
        {
            s.trim().to_string()
        }
        Some(_) => {
            return Err(format!(
                "configuration {number}: `label` takes a non-empty string without , ; or quotes"
            ));
        }
        None => return Err(format!("configuration {number} has no `label`")),
    };
    let named = |message: String| format!("configuration \"{label}\": {message}");
    let run = read_run(table).map_err(named)?;
    if run.method.is_none() {
        return Err(named("no `method`".into()));
    }
    let steps = read_steps(table.get("h")).map_err(named)?;
    Ok(StudyConfig {
        run,
        steps,
        level_dt: read_values(table.get("level_dt"), "level_dt").map_err(named)?,
        set: read_strings(table.get("set"), "set").map_err(named)?,
        pme_level: read_level(table.get("pme_level"), "pme_level").map_err(named)?,
        nonbonded_level: read_level(table.get("nonbonded_level"), "nonbonded_level")
            .map_err(named)?,
        starts: read_starts(table.get("starts")).map_err(named)?,
        split: read_split(table.get("split")).map_err(named)?,
        label,
    })
}

/// `split = { r_in = …, r_out = …, … }`: the keys of `[topology.split]`.
fn read_split(value: Option<&toml::Value>) -> std::result::Result<Option<SplitSection>, String> {
    match value {
        None => Ok(None),
        Some(toml::Value::Table(table)) => toml::Value::Table(table.clone())
            .try_into()
            .map(Some)
            .map_err(|e: toml::de::Error| format!("`split`: {}", e.message().trim())),
        Some(_) => Err("`split` takes a table: { r_in = 5, r_out = 6, … }".into()),
    }
}

/// The `[run]` keys of a configuration through [`RunSpec`]'s own parser, one key at a time
/// (so a refusal names its key), then all together.
fn read_run(table: &toml::Table) -> std::result::Result<RunSpec, String> {
    let mut run = toml::Table::new();
    for (key, value) in table {
        if STUDY_KEYS.contains(&key.as_str()) {
            continue;
        }
        let mut one = toml::Table::new();
        one.insert(key.clone(), value.clone());
        toml::Value::Table(one).try_into::<RunSpec>().map_err(|e| {
            match e.message().starts_with("unknown field") {
                true => format!(
                    "unknown key `{key}`: a configuration takes the keys of a scene's [run] \
                     table and {}",
                    STUDY_KEYS.join(", ")
                ),
                false => format!("`{key}`: {}", e.message().trim_end()),
            }
        })?;
        run.insert(key.clone(), value.clone());
    }
    toml::Value::Table(run)
        .try_into::<RunSpec>()
        .map_err(|e| e.message().trim_end().to_string())
}

/// `h`: a string (`LO:HI:STEP`, or one step) or a list of steps, as `--h` text.
fn read_steps(value: Option<&toml::Value>) -> std::result::Result<String, String> {
    match value {
        None => Err("no `h`: give its outer steps, e.g. h = [\"1fs\", \"2fs\"]".into()),
        Some(toml::Value::String(s)) if !s.trim().is_empty() => Ok(s.trim().to_string()),
        Some(toml::Value::Array(list)) if !list.is_empty() => {
            let values = read_values(value, "h")?;
            debug_assert_eq!(values.len(), list.len());
            Ok(values
                .iter()
                .map(|v| v.to_string())
                .collect::<Vec<_>>()
                .join(","))
        }
        Some(other) => Err(format!(
            "`h` takes \"LO:HI:STEP\" or a non-empty list of steps, got {other}"
        )),
    }
}

/// A list of numbers or expressions (`["2fs", 0.5]`).
fn read_values(value: Option<&toml::Value>, key: &str) -> std::result::Result<Vec<Value>, String> {
    match value {
        None => Ok(Vec::new()),
        Some(v) => v
            .clone()
            .try_into::<Vec<Value>>()
            .map_err(|e| format!("`{key}` takes a list of numbers or times: {}", e.message())),
    }
}

fn read_strings(
    value: Option<&toml::Value>,
    key: &str,
) -> std::result::Result<Vec<String>, String> {
    match value {
        None => Ok(Vec::new()),
        Some(v) => v
            .clone()
            .try_into::<Vec<String>>()
            .map_err(|_| format!("`{key}` takes a list of strings such as [\"NAME=VALUE\"]")),
    }
}

fn read_level(
    value: Option<&toml::Value>,
    key: &str,
) -> std::result::Result<Option<usize>, String> {
    match value {
        None => Ok(None),
        Some(toml::Value::Integer(n)) if (0..=16).contains(n) => Ok(Some(*n as usize)),
        Some(other) => Err(format!(
            "`{key}` takes a force level, a whole number from 0 to 16, got {other}"
        )),
    }
}

fn read_starts(value: Option<&toml::Value>) -> std::result::Result<Option<usize>, String> {
    match value {
        None => Ok(None),
        Some(toml::Value::Integer(n)) if (1..=MAX_STARTS as i64).contains(n) => {
            Ok(Some(*n as usize))
        }
        Some(other) => Err(format!(
            "`starts` takes a whole number of starts from 1 to {MAX_STARTS}, got {other}"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config(text: &str) -> std::result::Result<StudyConfig, String> {
        let table: toml::Table = toml::from_str(text).unwrap();
        read_config(&toml::Value::Table(table), 1)
    }

    #[test]
    fn run_keys_go_through_the_run_parser() {
        let c = config(
            "label = \"c\"\nmethod = \"verlet\"\nh = [\"1fs\", 2]\nconstraints = \"h-bonds\"\n\
             rigid_water = true\npme_level = 1",
        )
        .unwrap();
        assert_eq!(c.run.constraints.as_deref(), Some("h-bonds"));
        assert_eq!(c.run.rigid_water, Some(true));
        assert_eq!(c.steps, "1fs,2");
        assert_eq!(c.pme_level, Some(1));
        assert_eq!(c.starts, None);
        let three = config("label = \"c\"\nmethod = \"verlet\"\nh = \"1\"\nstarts = 3");
        assert_eq!(three.unwrap().starts, Some(3));
        let many = config("label = \"c\"\nmethod = \"verlet\"\nh = \"1\"\nstarts = 65");
        assert!(many.unwrap_err().contains("`starts`"));
    }

    #[test]
    fn refusals_name_the_configuration_and_the_key() {
        let unknown = config("label = \"c\"\nmethod = \"verlet\"\nh = \"1:2:1\"\nbogus = 1");
        let message = unknown.unwrap_err();
        assert!(
            message.contains("\"c\"") && message.contains("`bogus`"),
            "{message}"
        );
        let typed = config("label = \"c\"\nmethod = \"verlet\"\nh = \"1\"\ninner_steps = \"x\"");
        let message = typed.unwrap_err();
        assert!(message.contains("`inner_steps`"), "{message}");
        assert!(
            config("label = \"c\"\nh = \"1\"")
                .unwrap_err()
                .contains("method")
        );
        assert!(
            config("label = \"c\"\nmethod = \"verlet\"")
                .unwrap_err()
                .contains("`h`")
        );
        assert!(
            config("method = \"verlet\"\nh = \"1\"")
                .unwrap_err()
                .contains("label")
        );
    }

    #[test]
    fn the_fingerprint_is_fnv1a() {
        // FNV-1a of "a" is af63dc4c8601ec8c (the published test vector).
        assert_eq!(fingerprint("a"), "af63dc4c8601ec8c");
    }
}
