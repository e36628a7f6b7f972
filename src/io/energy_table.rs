//! Reading a run's `energy.csv` (or any table with a header) back, column by column.
//!
//! Columns are found by name through [`column_matches`], the one place that knows how a
//! header may decorate a name: `potential`, `potential [kcal/mol]`, `potential (kcal/mol)`
//! all match `potential`; `potential_fast` does not.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// Whether header cell `header` is the column `name`, possibly followed by a unit in
/// brackets or parentheses.
pub fn column_matches(header: &str, name: &str) -> bool {
    let header = header.trim();
    match header.strip_prefix(name) {
        Some("") => true,
        Some(rest) => {
            let rest = rest.trim_start();
            rest.starts_with('[') || rest.starts_with('(')
        }
        None => false,
    }
}

/// The columns of a table that were asked for, as numbers.
pub struct EnergyTable {
    pub path: PathBuf,
    pub header: Vec<String>,
    columns: Vec<Vec<f64>>,
}

impl EnergyTable {
    /// Read the columns `names` of the CSV file `path`. A missing column or a cell that is
    /// not a number is an error naming the file, the row and the column.
    pub fn read(path: &Path, names: &[&str]) -> Result<Self> {
        if !path.exists() {
            return Err(Error::Structure {
                path: path.to_path_buf(),
                message: "no such file".into(),
            });
        }
        let bad = |message: String| Error::Structure {
            path: path.to_path_buf(),
            message,
        };
        let mut reader = csv::Reader::from_path(path).map_err(|e| bad(e.to_string()))?;
        let header: Vec<String> = reader
            .headers()
            .map_err(|e| bad(format!("cannot read the header: {e}")))?
            .iter()
            .map(str::to_string)
            .collect();
        let indices: Vec<usize> = names
            .iter()
            .map(|name| {
                header
                    .iter()
                    .position(|h| column_matches(h, name))
                    .ok_or_else(|| {
                        bad(format!(
                            "has no column \"{name}\" (its columns: {})",
                            header.join(", ")
                        ))
                    })
            })
            .collect::<Result<_>>()?;
        let mut columns = vec![Vec::new(); names.len()];
        for (row, record) in reader.records().enumerate() {
            let record = record.map_err(|e| bad(format!("row {}: {e}", row + 2)))?;
            for (column, &index) in columns.iter_mut().zip(&indices) {
                let cell = record.get(index).unwrap_or("");
                let value: f64 = cell.trim().parse().map_err(|_| {
                    bad(format!(
                        "line {}: \"{cell}\" in column \"{}\" is not a number",
                        row + 2,
                        header[index]
                    ))
                })?;
                column.push(value);
            }
        }
        Ok(EnergyTable {
            path: path.to_path_buf(),
            header,
            columns,
        })
    }

    /// The `k`-th column asked for in [`EnergyTable::read`].
    pub fn column(&self, k: usize) -> &[f64] {
        &self.columns[k]
    }

    pub fn rows(&self) -> usize {
        self.columns.first().map_or(0, Vec::len)
    }
}

#[cfg(test)]
mod tests {
    use super::column_matches;

    #[test]
    fn names_match_with_units_but_not_as_prefixes() {
        assert!(column_matches("potential", "potential"));
        assert!(column_matches("potential [kcal/mol]", "potential"));
        assert!(column_matches(" potential (kcal/mol)", "potential"));
        assert!(!column_matches("potential_fast", "potential"));
        assert!(!column_matches("t", "total"));
    }
}
