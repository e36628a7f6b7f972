//! `energy.csv` (and other tables): a header, then rows written as the run goes, flushed
//! often enough that a run stopped by a blow-up or an error keeps everything before it.

use crate::io::number::Num;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use crate::error::{Error, Result};

pub struct CsvWriter {
    path: PathBuf,
    out: BufWriter<File>,
    columns: usize,
    last_flush: Instant,
}

impl CsvWriter {
    pub fn create(path: &Path, header: &[&str]) -> Result<Self> {
        Self::create_after(path, None, header)
    }

    /// A table whose header follows a first line (a `# longstep …` study line).
    pub fn create_after(path: &Path, first_line: Option<&str>, header: &[&str]) -> Result<Self> {
        let file = File::create(path).map_err(|e| Error::io(path, e))?;
        let mut writer = CsvWriter {
            path: path.to_path_buf(),
            out: BufWriter::new(file),
            columns: header.len(),
            last_flush: Instant::now(),
        };
        if let Some(line) = first_line {
            writeln!(writer.out, "{line}").map_err(|e| Error::io(path, e))?;
        }
        writeln!(writer.out, "{}", header.join(",")).map_err(|e| Error::io(path, e))?;
        Ok(writer)
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Write one row; numbers in shortest round-trip form.
    pub fn row(&mut self, values: &[f64]) -> Result<()> {
        debug_assert_eq!(values.len(), self.columns);
        let mut first = true;
        for value in values {
            if !first {
                self.out
                    .write_all(b",")
                    .map_err(|e| Error::io(&self.path, e))?;
            }
            first = false;
            write!(self.out, "{}", Num(*value)).map_err(|e| Error::io(&self.path, e))?;
        }
        self.out
            .write_all(b"\n")
            .map_err(|e| Error::io(&self.path, e))?;
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
}

impl Drop for CsvWriter {
    fn drop(&mut self) {
        let _ = self.out.flush();
    }
}
