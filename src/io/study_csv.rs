//! Study tables: the CSV behind every scan and chart.
//!
//! The first line names the study and what produced it,
//! `# longstep scan-steps, points = 120, scene = systems/x.toml, t_end = 2, …`, then a
//! header, then one row per point with its `index` first. A shard of a study (`--shard k/n`)
//! writes the same first line and its own rows, so `longstep merge` can check that shards
//! belong together, put the rows back in index order, and draw the pictures from the merged
//! table with the same code a single run uses: the outputs are identical.

use std::collections::BTreeMap;
use std::path::Path;

use crate::error::{Error, Result};

/// A study table in memory.
#[derive(Clone, Debug, PartialEq)]
pub struct StudyTable {
    /// The study's kind (`scan-steps`, `work-precision`, …).
    pub study: String,
    /// What produced it; `points` is the number of points of the whole study.
    pub meta: BTreeMap<String, String>,
    pub header: Vec<String>,
    /// Rows as text, `index` first.
    pub rows: Vec<Vec<String>>,
}

impl StudyTable {
    pub fn new(study: &str, meta: BTreeMap<String, String>, header: &[&str]) -> Self {
        StudyTable {
            study: study.to_string(),
            meta,
            header: header.iter().map(|h| h.to_string()).collect(),
            rows: Vec::new(),
        }
    }

    pub fn points(&self) -> Result<usize> {
        self.meta
            .get("points")
            .and_then(|p| p.parse().ok())
            .ok_or_else(|| Error::input(format!("study {} has no `points` count", self.study)))
    }

    /// The column named `name`.
    pub fn column(&self, name: &str) -> Result<usize> {
        self.header
            .iter()
            .position(|h| h == name)
            .ok_or_else(|| Error::input(format!("study {} has no column {name}", self.study)))
    }

    /// A numeric cell (empty cells read as NaN).
    pub fn number(&self, row: &[String], column: usize) -> f64 {
        row.get(column)
            .and_then(|cell| cell.parse::<f64>().ok())
            .unwrap_or(f64::NAN)
    }

    /// `# longstep <study>, key = value, …` in key order.
    pub fn first_line(&self) -> String {
        let meta: Vec<String> = self
            .meta
            .iter()
            .map(|(key, value)| format!("{key} = {value}"))
            .collect();
        format!("# longstep {}, {}", self.study, meta.join(", "))
    }

    pub fn to_text(&self) -> String {
        let mut text = self.first_line();
        text += "\n";
        text += &self.header.join(",");
        text += "\n";
        for row in &self.rows {
            text += &row.join(",");
            text += "\n";
        }
        text
    }

    pub fn write(&self, path: &Path) -> Result<()> {
        std::fs::write(path, self.to_text()).map_err(|e| Error::io(path, e))
    }

    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let bad = |message: &str| Error::Structure {
            path: path.to_path_buf(),
            message: message.to_string(),
        };
        let mut lines = text.lines();
        let first = lines
            .next()
            .and_then(|l| l.strip_prefix("# longstep "))
            .ok_or_else(|| bad("not a longstep study table (no `# longstep` first line)"))?;
        let mut parts = first.split(", ");
        let study = parts.next().unwrap_or_default().to_string();
        let mut meta = BTreeMap::new();
        for part in parts {
            let (key, value) = part
                .split_once(" = ")
                .ok_or_else(|| bad(&format!("bad metadata entry \"{part}\"")))?;
            meta.insert(key.to_string(), value.to_string());
        }
        let header: Vec<String> = lines
            .next()
            .ok_or_else(|| bad("no header line"))?
            .split(',')
            .map(str::to_string)
            .collect();
        let mut rows = Vec::new();
        for (n, line) in lines.enumerate() {
            let row: Vec<String> = line.split(',').map(str::to_string).collect();
            if row.len() != header.len() {
                return Err(bad(&format!(
                    "row {} has {} fields, the header {}",
                    n + 1,
                    row.len(),
                    header.len()
                )));
            }
            rows.push(row);
        }
        Ok(StudyTable {
            study,
            meta,
            header,
            rows,
        })
    }
}

/// The first setting (other than the shard) in which two shards' metadata differ, with
/// both values: `("t_end", "20", "10")`.
pub fn differing_setting(
    a: &BTreeMap<String, String>,
    b: &BTreeMap<String, String>,
) -> Option<(String, String, String)> {
    let missing = "(not given)".to_string();
    a.keys()
        .chain(b.keys())
        .filter(|key| key.as_str() != "shard")
        .find(|key| a.get(*key) != b.get(*key))
        .map(|key| {
            (
                key.clone(),
                a.get(key).unwrap_or(&missing).clone(),
                b.get(key).unwrap_or(&missing).clone(),
            )
        })
}

/// Merge shards of one study, each with the name of its file: same study and metadata (but
/// the shard), every index from 0 to points − 1 exactly once. Returns the table a single run
/// would have written.
pub fn merge(tables: Vec<(String, StudyTable)>) -> Result<StudyTable> {
    let mut tables = tables.into_iter();
    let (first_name, mut merged) = tables
        .next()
        .ok_or_else(|| Error::input("nothing to merge"))?;
    for (name, table) in tables {
        if table.study != merged.study {
            return Err(Error::input(format!(
                "cannot merge a {} table ({name}) with a {} table ({first_name})",
                table.study, merged.study
            )));
        }
        if let Some((key, theirs, ours)) = differing_setting(&table.meta, &merged.meta) {
            return Err(Error::input(format!(
                "the shards of {} differ in {key}: {theirs} in {name}, {ours} in {first_name}",
                merged.study
            )));
        }
        if table.header != merged.header {
            return Err(Error::input(format!(
                "the shards of {} differ in their columns: {} in {name}, {} in {first_name}",
                merged.study,
                table.header.join(","),
                merged.header.join(",")
            )));
        }
        merged.rows.extend(table.rows);
    }
    merged.meta.remove("shard");
    let points = merged.points()?;
    let index = |row: &Vec<String>| row[0].parse::<usize>().unwrap_or(usize::MAX);
    merged.rows.sort_by_key(index);
    for (expected, row) in merged.rows.iter().enumerate() {
        let found = index(row);
        if found != expected {
            return Err(Error::input(format!(
                "the shards of {} do not cover its {points} points exactly once: point {} {}",
                merged.study,
                expected,
                if found > expected {
                    "is missing"
                } else {
                    "appears twice"
                }
            )));
        }
    }
    if merged.rows.len() != points {
        return Err(Error::input(format!(
            "the shards of {} hold {} of its {points} points",
            merged.study,
            merged.rows.len()
        )));
    }
    Ok(merged)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shard(rows: &[usize], k: usize) -> StudyTable {
        let mut meta = BTreeMap::new();
        meta.insert("points".into(), "4".into());
        meta.insert("shard".into(), format!("{k}/2"));
        let mut table = StudyTable::new("demo", meta, &["index", "x"]);
        table.rows = rows
            .iter()
            .map(|&i| vec![i.to_string(), (i * i).to_string()])
            .collect();
        table
    }

    fn named(table: StudyTable) -> (String, StudyTable) {
        (table.meta["shard"].clone(), table)
    }

    #[test]
    fn shards_merge_in_index_order_and_round_trip() {
        let merged = merge(vec![named(shard(&[1, 3], 2)), named(shard(&[0, 2], 1))]).unwrap();
        let indices: Vec<&str> = merged.rows.iter().map(|r| r[0].as_str()).collect();
        assert_eq!(indices, ["0", "1", "2", "3"]);
        assert!(!merged.meta.contains_key("shard"));
        let path = std::env::temp_dir().join("longstep-study-table-test.csv");
        merged.write(&path).unwrap();
        assert_eq!(StudyTable::read(&path).unwrap(), merged);
    }

    #[test]
    fn missing_or_doubled_points_are_refused() {
        let error = merge(vec![named(shard(&[1, 3], 2)), named(shard(&[0], 1))]).unwrap_err();
        assert!(error.to_string().contains("point 2 is missing"), "{error}");
        let error = merge(vec![named(shard(&[0, 1, 3], 2)), named(shard(&[0, 2], 1))]).unwrap_err();
        assert!(error.to_string().contains("appears twice"), "{error}");
    }
}
