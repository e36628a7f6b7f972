//! Trajectory output through chemfiles: XYZ by default, any format chemfiles writes by the
//! file's extension (`.pdb`, `.gro`, `.xyz` as extended XYZ with the cell, …).
//!
//! Every frame is written by opening the file for appending, writing and closing it, so what
//! is on disk is always whole frames: a run that blows up or is killed leaves a valid file
//! with every frame up to then. A frame carries the step, the time (property `time`, in the
//! scene's time unit) and, for a periodic box, the cell.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::system::PeriodicBox;

pub struct TrajectoryWriter {
    path: PathBuf,
    frame: chemfiles::Frame,
    dim: usize,
    frames: usize,
}

fn trajectory_error(path: &Path, message: String) -> Error {
    Error::Structure {
        path: path.to_path_buf(),
        message,
    }
}

impl TrajectoryWriter {
    /// A writer for particles with these names (element symbols), truncating `path`.
    pub fn create(
        path: &Path,
        names: &[String],
        dim: usize,
        periodic_box: Option<PeriodicBox>,
    ) -> Result<Self> {
        let mut frame = chemfiles::Frame::new();
        for name in names {
            frame.add_atom(&chemfiles::Atom::new(name.as_str()), [0.0; 3], None);
        }
        if let Some(b) = periodic_box
            && dim == 3
            && b.lengths.iter().all(|l| l.is_finite())
        {
            frame.set_cell(&chemfiles::UnitCell::new(b.lengths));
        }
        // Create (truncate) the file now, so a bad path or format fails before the run.
        chemfiles::Trajectory::open(path, 'w').map_err(|e| {
            trajectory_error(path, format!("cannot write a trajectory: {}", e.message))
        })?;
        Ok(TrajectoryWriter {
            path: path.to_path_buf(),
            frame,
            dim,
            frames: 0,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    pub fn frames(&self) -> usize {
        self.frames
    }

    /// Append one frame of positions `q` (`n × dim`; missing coordinates are 0).
    pub fn write(&mut self, q: &[f64], step: u64, time: f64) -> Result<()> {
        let dim = self.dim;
        for (i, position) in self.frame.positions_mut().iter_mut().enumerate() {
            for (a, x) in position.iter_mut().enumerate() {
                *x = if a < dim { q[i * dim + a] } else { 0.0 };
            }
        }
        self.frame.set_step(step as usize);
        self.frame.set("time", time);
        let mode = if self.frames == 0 { 'w' } else { 'a' };
        let mut file = chemfiles::Trajectory::open(&self.path, mode).map_err(|e| {
            trajectory_error(
                &self.path,
                format!("cannot open for writing: {}", e.message),
            )
        })?;
        file.write(&self.frame).map_err(|e| {
            trajectory_error(&self.path, format!("cannot write frame: {}", e.message))
        })?;
        // Dropping the file closes and flushes it.
        drop(file);
        self.frames += 1;
        Ok(())
    }
}
