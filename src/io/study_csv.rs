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
use crate::io::csv::write_table;
use crate::io::energy_table::column_matches;

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

    /// The column named `name`, with or without a unit (`h` finds `h` and `h[fs]`, so
    /// tables written before the headers carried units read as well).
    pub fn column(&self, name: &str) -> Result<usize> {
        self.header
            .iter()
            .position(|h| column_matches(h, name))
            .ok_or_else(|| Error::input(format!("study {} has no column {name}", self.study)))
    }

    /// Put units on header fields in a scene with real units, as `energy.csv` writes them
    /// (`h[fs]`, `drift[kT/ns/dof]`): each `(name, unit)` renames the field `name`; an
    /// empty unit (a dimensionless scene) leaves it as it is.
    pub fn with_units(mut self, units: &[(&str, &str)]) -> Self {
        for field in &mut self.header {
            if let Some((name, unit)) = units.iter().find(|(name, _)| field == name)
                && !unit.is_empty()
            {
                *field = format!("{name}[{unit}]");
            }
        }
        self
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

    /// Write the table through the `csv` crate: fields holding a comma or a quote are
    /// quoted; every other byte is as given.
    pub fn write(&self, path: &Path) -> Result<()> {
        write_table(path, Some(&self.first_line()), &self.header, &self.rows)
    }

    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let bad = |message: &str| Error::Structure {
            path: path.to_path_buf(),
            message: message.to_string(),
        };
        let (first, body) = text.split_once('\n').unwrap_or((&text, ""));
        let (study, meta) = first
            .trim_end_matches('\r')
            .strip_prefix("# longstep ")
            .ok_or_else(|| bad("not a longstep study table (no `# longstep` first line)"))
            .and_then(|first| parse_first_line(first).map_err(|e| bad(&e)))?;
        let mut reader = ::csv::ReaderBuilder::new()
            .flexible(true)
            .from_reader(body.as_bytes());
        // Line numbers in messages count the file's first line, which the reader never saw.
        let at = |e: ::csv::Error| {
            let line = e.position().map_or(0, |p| p.line() + 1);
            bad(&format!("line {line}: {e}"))
        };
        let header: Vec<String> = reader
            .headers()
            .map_err(at)?
            .iter()
            .map(String::from)
            .collect();
        if header.is_empty() {
            return Err(bad("no header line"));
        }
        let mut rows = Vec::new();
        for (n, record) in reader.records().enumerate() {
            let row: Vec<String> = record.map_err(at)?.iter().map(String::from).collect();
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

/// `<study>, key = value, …` (the first line after `# longstep `) as the study and its
/// settings.
fn parse_first_line(
    first: &str,
) -> std::result::Result<(String, BTreeMap<String, String>), String> {
    let mut parts = first.split(", ");
    let study = parts.next().unwrap_or_default().to_string();
    let mut meta = BTreeMap::new();
    for part in parts {
        let (key, value) = part
            .split_once(" = ")
            .ok_or_else(|| format!("bad metadata entry \"{part}\""))?;
        meta.insert(key.to_string(), value.to_string());
    }
    Ok((study, meta))
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
            ))
            .key(key));
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

    /// A method holding a comma and a label holding quotes: the old reader, which split
    /// lines on `,`, found four fields in this row and refused the table.
    #[test]
    fn fields_with_commas_and_quotes_round_trip() {
        let mut meta = BTreeMap::new();
        meta.insert("points".into(), "1".into());
        let mut table = StudyTable::new("demo", meta, &["index", "method", "label", "x"]);
        let method = "equilibrium-molly --molly-constraints bonds,angles";
        table.rows = vec![vec![
            "0".into(),
            method.into(),
            "the \"slow\" one".into(),
            "0.5".into(),
        ]];
        let path = std::env::temp_dir().join("longstep-study-table-quoting-test.csv");
        table.write(&path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(
            text.lines().nth(2),
            Some(format!("0,\"{method}\",\"the \"\"slow\"\" one\",0.5").as_str())
        );
        assert_eq!(StudyTable::read(&path).unwrap(), table);
    }

    #[test]
    fn a_short_row_is_refused_with_its_number() {
        let path = std::env::temp_dir().join("longstep-study-table-short-row-test.csv");
        std::fs::write(&path, "# longstep demo, points = 2\nindex,x\n0,1\n1\n").unwrap();
        let error = StudyTable::read(&path).unwrap_err().to_string();
        assert!(
            error.contains("row 2 has 1 fields, the header 2"),
            "{error}"
        );
        assert!(
            error.contains("longstep-study-table-short-row-test.csv"),
            "{error}"
        );
    }

    #[test]
    fn missing_or_doubled_points_are_refused() {
        let error = merge(vec![named(shard(&[1, 3], 2)), named(shard(&[0], 1))]).unwrap_err();
        assert!(error.to_string().contains("point 2 is missing"), "{error}");
        let error = merge(vec![named(shard(&[0, 1, 3], 2)), named(shard(&[0, 2], 1))]).unwrap_err();
        assert!(error.to_string().contains("appears twice"), "{error}");
    }
}
