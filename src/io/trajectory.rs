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

/// What one frame read back carries besides its positions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameInfo {
    /// 0-based index of the frame in the file.
    pub index: usize,
    /// The frame's `time` property (written by [`TrajectoryWriter`]), if any.
    pub time: Option<f64>,
    /// Orthorhombic cell lengths, if the frame has a cell.
    pub cell: Option<[f64; 3]>,
}

/// Frames of a trajectory file read one at a time (through chemfiles, any format it reads),
/// so a long trajectory is never held in memory.
pub struct TrajectoryReader {
    path: PathBuf,
    file: chemfiles::Trajectory,
    frame: chemfiles::Frame,
    frames: usize,
    next: usize,
}

impl TrajectoryReader {
    pub fn open(path: &Path) -> Result<Self> {
        if !path.exists() {
            return Err(trajectory_error(path, "no such file".into()));
        }
        let mut file = chemfiles::Trajectory::open(path, 'r')
            .map_err(|e| trajectory_error(path, format!("cannot open: {}", e.message)))?;
        let frames = file.nsteps();
        if frames == 0 {
            return Err(trajectory_error(path, "has no frame".into()));
        }
        Ok(TrajectoryReader {
            path: path.to_path_buf(),
            file,
            frame: chemfiles::Frame::new(),
            frames,
            next: 0,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    pub fn frames(&self) -> usize {
        self.frames
    }

    /// Atom names of the frame read last.
    pub fn names(&self) -> Vec<String> {
        (0..self.frame.size())
            .map(|i| self.frame.atom(i).name())
            .collect()
    }

    /// Read the next frame's positions into `q` (`n × 3`); `None` after the last frame.
    pub fn read_next(&mut self, q: &mut Vec<f64>) -> Result<Option<FrameInfo>> {
        if self.next >= self.frames {
            return Ok(None);
        }
        let index = self.next;
        self.file.read(&mut self.frame).map_err(|e| {
            trajectory_error(
                &self.path,
                format!("cannot read frame {index}: {}", e.message),
            )
        })?;
        self.next += 1;
        q.clear();
        for (i, position) in self.frame.positions().iter().enumerate() {
            if position.iter().any(|x| !x.is_finite()) {
                return Err(trajectory_error(
                    &self.path,
                    format!("frame {index}: atom {i} has a non-finite position"),
                ));
            }
            q.extend_from_slice(position);
        }
        let time = match self.frame.get("time") {
            Some(chemfiles::Property::Double(t)) => Some(t),
            Some(chemfiles::Property::String(s)) => s.trim().parse().ok(),
            _ => None,
        };
        let cell = self.frame.cell();
        let cell = match cell.shape() {
            chemfiles::CellShape::Orthorhombic => Some(cell.lengths()),
            chemfiles::CellShape::Infinite => None,
            chemfiles::CellShape::Triclinic => {
                return Err(trajectory_error(
                    &self.path,
                    format!(
                        "frame {index} has a triclinic cell; only orthorhombic boxes are analysed"
                    ),
                ));
            }
        };
        Ok(Some(FrameInfo { index, time, cell }))
    }
}
