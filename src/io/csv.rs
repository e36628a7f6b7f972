//! `energy.csv` and the other tables, written through the `csv` crate (so a field holding a
//! comma or a quote, such as a method `equilibrium-molly --molly-constraints bonds,angles`,
//! is quoted): an optional first line (a `# longstep …` study line, which the crate cannot
//! write as it writes no comments), a header, then rows written as the run goes, flushed
//! often enough that a run stopped by a blow-up or an error keeps everything before it.

use crate::io::number::Num;
use std::fmt::Write as _;
use std::fs::File;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use crate::error::{Error, Result};

/// A `csv` crate error as ours, naming the file (the crate's message names the record and
/// line where it knows them).
pub fn csv_error(path: &Path, e: ::csv::Error) -> Error {
    if !e.is_io_error() {
        return Error::Structure {
            path: path.to_path_buf(),
            message: e.to_string(),
        };
    }
    match e.into_kind() {
        ::csv::ErrorKind::Io(source) => Error::io(path, source),
        kind => Error::Structure {
            path: path.to_path_buf(),
            message: format!("{kind:?}"),
        },
    }
}

/// Write a whole table at once: an optional first line, a header, the rows.
pub fn write_table<H, R>(path: &Path, first_line: Option<&str>, header: H, rows: R) -> Result<()>
where
    H: IntoIterator<Item: AsRef<[u8]>>,
    R: IntoIterator<Item: IntoIterator<Item: AsRef<[u8]>>>,
{
    let mut writer = CsvWriter::create_after(path, first_line, header)?;
    for row in rows {
        writer.record(row)?;
    }
    writer.flush()
}

pub struct CsvWriter {
    path: PathBuf,
    out: ::csv::Writer<File>,
    /// The text of one number, reused so that writing a row allocates nothing.
    cell: String,
    last_flush: Instant,
}

impl CsvWriter {
    pub fn create(path: &Path, header: impl IntoIterator<Item: AsRef<[u8]>>) -> Result<Self> {
        Self::create_after(path, None, header)
    }

    /// A table whose header follows a first line (a `# longstep …` study line).
    pub fn create_after(
        path: &Path,
        first_line: Option<&str>,
        header: impl IntoIterator<Item: AsRef<[u8]>>,
    ) -> Result<Self> {
        let mut writer = Self::headerless(path, first_line)?;
        writer.record(header)?;
        Ok(writer)
    }

    /// A table of rows only, after an optional first line.
    pub fn headerless(path: &Path, first_line: Option<&str>) -> Result<Self> {
        let mut file = File::create(path).map_err(|e| Error::io(path, e))?;
        if let Some(line) = first_line {
            writeln!(file, "{line}").map_err(|e| Error::io(path, e))?;
        }
        Ok(CsvWriter {
            path: path.to_path_buf(),
            out: ::csv::Writer::from_writer(file),
            cell: String::new(),
            last_flush: Instant::now(),
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Write one row of numbers in shortest round-trip form ([`Num`]).
    pub fn row(&mut self, values: &[f64]) -> Result<()> {
        for value in values {
            self.cell.clear();
            // Writing into a String cannot fail.
            let _ = write!(self.cell, "{}", Num(*value));
            self.out
                .write_field(&self.cell)
                .map_err(|e| csv_error(&self.path, e))?;
        }
        // An empty record ends the row of fields just written.
        self.record(None::<&[u8]>)
    }

    /// Write one row of text fields as given, quoted where a field needs it (rows of
    /// different lengths are refused by the crate).
    pub fn record(&mut self, fields: impl IntoIterator<Item: AsRef<[u8]>>) -> Result<()> {
        self.out
            .write_record(fields)
            .map_err(|e| csv_error(&self.path, e))?;
        // A time-based flush keeps the file current without a syscall per row.
        if self.last_flush.elapsed() > Duration::from_millis(500) {
            self.flush()?;
        }
        Ok(())
    }

    pub fn flush(&mut self) -> Result<()> {
        self.last_flush = Instant::now();
        self.out.flush().map_err(|e| Error::io(&self.path, e))
    }

    /// Flush, then have the system write the file to disk (`fsync`): before a checkpoint,
    /// so the rows before it survive a crash (a killed process or a lost machine).
    pub fn sync(&mut self) -> Result<()> {
        self.flush()?;
        self.out
            .get_ref()
            .sync_data()
            .map_err(|e| Error::io(&self.path, e))
    }
}

impl Drop for CsvWriter {
    fn drop(&mut self) {
        let _ = self.out.flush();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_with_commas_and_quotes_are_quoted_and_numbers_written_as_num() {
        let path = std::env::temp_dir().join("longstep-csv-writer-test.csv");
        {
            let mut csv = CsvWriter::create_after(
                &path,
                Some("# longstep demo, points = 1"),
                &["method", "h"],
            )
            .unwrap();
            csv.record(["molly --molly-constraints bonds,angles", "say \"hi\""])
                .unwrap();
            csv.row(&[1e300, 0.25]).unwrap();
        }
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(
            text,
            "# longstep demo, points = 1\nmethod,h\n\
             \"molly --molly-constraints bonds,angles\",\"say \"\"hi\"\"\"\n1e300,0.25\n"
        );
        let error = CsvWriter::create(&path, &["a", "b"])
            .unwrap()
            .record(["only one"])
            .unwrap_err();
        assert!(
            error.to_string().contains("longstep-csv-writer-test.csv"),
            "{error}"
        );
    }
}
