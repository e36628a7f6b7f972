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
            .ok_or_else(|| {
                Error::input(format!("study {} has no `points` count", self.study))
                    .key("points")
                    .expected("a whole number of points")
            })
    }

    /// The column named `name`, with or without a unit (`h` finds `h` and `h[fs]`, so
    /// tables written before the headers carried units read as well).
    pub fn column(&self, name: &str) -> Result<usize> {
        self.header
            .iter()
            .position(|h| column_matches(h, name))
            .ok_or_else(|| {
                Error::input(format!("study {} has no column {name}", self.study))
                    .key(name)
                    .expected(format!("a column {name}"))
            })
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
        Located::read(path).map(|located| located.table)
    }
}

/// Where a row of a study table was read: its file and line (1-based).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RowSource {
    pub file: String,
    pub line: usize,
}

impl RowSource {
    /// A problem with this row, placed at its file and line.
    pub fn error(&self, message: impl Into<String>) -> Error {
        Error::input(message).file(&self.file).line(self.line)
    }
}

/// A study table with the file it was read from (`name`) and where each row came from:
/// what `longstep merge` needs to place a problem at a shard's file and line.
#[derive(Clone, Debug, PartialEq)]
pub struct Located {
    pub name: String,
    pub table: StudyTable,
    pub sources: Vec<RowSource>,
}

impl Located {
    /// `table` as the file `name` holds it: the first line, the header, then a row a line.
    pub fn new(name: String, table: StudyTable) -> Self {
        let sources = (0..table.rows.len())
            .map(|k| RowSource {
                file: name.clone(),
                line: k + 3,
            })
            .collect();
        Located {
            name,
            table,
            sources,
        }
    }

    /// Read the study table at `path`; a problem names the file and line.
    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let at = |line: usize, message: &str| Error::input(message).file(path).line(line);
        let (first, body) = text.split_once('\n').unwrap_or((&text, ""));
        let (study, meta) = first
            .trim_end_matches('\r')
            .strip_prefix("# longstep ")
            .ok_or_else(|| {
                at(1, "not a longstep study table (no `# longstep` first line)")
                    .expected("# longstep STUDY, key = value, …")
            })
            .and_then(|first| parse_first_line(first).map_err(|e| at(1, &e)))?;
        let mut reader = ::csv::ReaderBuilder::new()
            .flexible(true)
            .from_reader(body.as_bytes());
        // Line numbers count the file's first line, which the reader never saw.
        let line_of =
            |position: Option<&::csv::Position>| position.map_or(0, |p| p.line() as usize + 1);
        let csv_error = |e: ::csv::Error| at(line_of(e.position()), &e.to_string());
        let header: Vec<String> = reader
            .headers()
            .map_err(csv_error)?
            .iter()
            .map(String::from)
            .collect();
        if header.is_empty() {
            return Err(at(2, "no header line"));
        }
        let name = path.display().to_string();
        let (mut rows, mut sources) = (Vec::new(), Vec::new());
        for (n, record) in reader.records().enumerate() {
            let record = record.map_err(csv_error)?;
            let line = line_of(record.position());
            if record.len() != header.len() {
                let message = format!(
                    "row {} has {} fields, the header {}",
                    n + 1,
                    record.len(),
                    header.len()
                );
                return Err(at(line, &message)
                    .expected(format!("{} fields", header.len()))
                    .got_named(record.len().to_string()));
            }
            rows.push(record.iter().map(String::from).collect());
            sources.push(RowSource {
                file: name.clone(),
                line,
            });
        }
        let table = StudyTable {
            study,
            meta,
            header,
            rows,
        };
        Ok(Located {
            name,
            table,
            sources,
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
    let located = tables
        .into_iter()
        .map(|(name, table)| Located::new(name, table))
        .collect();
    merge_located(located).map(|merged| merged.table)
}

/// [`merge`] of tables read from files: a problem names the shard's file and line (the
/// first line for its settings, the header for its columns, a row's own line).
pub fn merge_located(tables: Vec<Located>) -> Result<Located> {
    let mut tables = tables.into_iter();
    let mut merged = tables
        .next()
        .ok_or_else(|| Error::input("nothing to merge"))?;
    for shard in tables {
        check_same_study(&merged, &shard)?;
        merged.table.rows.extend(shard.table.rows);
        merged.sources.extend(shard.sources);
    }
    merged.table.meta.remove("shard");
    let rows = std::mem::take(&mut merged.table.rows);
    let sources = std::mem::take(&mut merged.sources);
    let mut pairs: Vec<_> = rows.into_iter().zip(sources).collect();
    pairs.sort_by_key(|(row, _)| row_index(row));
    (merged.table.rows, merged.sources) = pairs.into_iter().unzip();
    check_points(&merged)?;
    Ok(merged)
}

/// A row's `index` (the first field); `usize::MAX` where it is not a number.
fn row_index(row: &[String]) -> usize {
    row.first()
        .and_then(|i| i.parse().ok())
        .unwrap_or(usize::MAX)
}

/// The shard must be of the first's study, settings (but the shard) and columns.
fn check_same_study(merged: &Located, shard: &Located) -> Result<()> {
    let (first_name, name) = (&merged.name, &shard.name);
    let (first, table) = (&merged.table, &shard.table);
    let at = |line: usize, message: String| Error::input(message).file(name).line(line);
    if table.study != first.study {
        let message = format!(
            "cannot merge a {} table with a {} table ({first_name})",
            table.study, first.study
        );
        return Err(at(1, message)
            .key("study")
            .expected(first.study.clone())
            .got_named(table.study.clone()));
    }
    if let Some((key, theirs, ours)) = differing_setting(&table.meta, &first.meta) {
        let message = format!(
            "the shards of {} differ in {key}: {theirs} in {name}, {ours} in {first_name}",
            first.study
        );
        return Err(at(1, message).key(key).expected(ours).got_named(theirs));
    }
    if table.header != first.header {
        let (theirs, ours) = (table.header.join(","), first.header.join(","));
        let message = format!(
            "the shards of {} differ in their columns: {theirs} in {name}, {ours} in \
             {first_name}",
            first.study
        );
        return Err(at(2, message)
            .key("header")
            .expected(ours)
            .got_named(theirs));
    }
    Ok(())
}

/// The merged rows, in index order, must be the points 0 … points − 1, each once.
fn check_points(merged: &Located) -> Result<()> {
    let table = &merged.table;
    let points = table.points()?;
    let uncovered = format!(
        "the shards of {} do not cover its {points} points exactly once",
        table.study
    );
    for (expected, (row, source)) in table.rows.iter().zip(&merged.sources).enumerate() {
        let found = row_index(row);
        if found > expected {
            return Err(
                Error::input(format!("{uncovered}: point {expected} is missing"))
                    .key("index")
                    .expected(expected.to_string()),
            );
        }
        if found < expected {
            return Err(source
                .error(format!("{uncovered}: point {found} appears twice"))
                .key("index")
                .got_named(found.to_string()));
        }
    }
    if table.rows.len() != points {
        let message = format!(
            "the shards of {} hold {} of its {points} points",
            table.study,
            table.rows.len()
        );
        // Too many rows: the first one past the last point.
        let error = match merged.sources.get(points) {
            Some(extra) => extra.error(message),
            None => Error::input(message),
        };
        return Err(error
            .key("index")
            .expected(format!("{points} rows"))
            .got_named(table.rows.len().to_string()));
    }
    Ok(())
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
