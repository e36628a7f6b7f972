//! Trajectory output: XYZ by default, written here as extended XYZ (the cell as `Lattice`,
//! the time as `time`) with every coordinate in full precision (the shortest decimal that
//! reads back to the same double), and optionally the velocities beside the positions
//! (`velo:R:3` columns, [`TrajectoryWriter::with_velocities`]), which the structure reader
//! takes back as a start; any other format chemfiles writes by the file's extension
//! (`.pdb`, `.gro`, …), at that format's own precision, positions only.
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
    /// Extended XYZ written here in full precision (else chemfiles writes the frame).
    xyz: Option<XyzFrame>,
}

/// What an extended-XYZ frame repeats: the atom names and the cell, and a reused buffer.
struct XyzFrame {
    names: Vec<String>,
    lattice: Option<[f64; 3]>,
    text: String,
    /// Write velocities `v = M⁻¹p` beside the positions.
    velocities: bool,
}

/// Momenta and inverse masses of a frame, for its velocity columns.
#[derive(Clone, Copy)]
pub struct Momenta<'a> {
    pub p: &'a [f64],
    pub inverse_mass: &'a [f64],
}

impl XyzFrame {
    /// The frame of positions `q` at `time` into `self.text`.
    fn format(&mut self, q: &[f64], momenta: Option<Momenta>, dim: usize, time: f64) {
        use std::fmt::Write;
        self.text.clear();
        let _ = writeln!(self.text, "{}", self.names.len());
        self.text.push_str("Properties=species:S:1:pos:R:3");
        let momenta = momenta.filter(|_| self.velocities);
        if momenta.is_some() {
            self.text.push_str(":velo:R:3");
        }
        if let Some([a, b, c]) = self.lattice {
            let _ = write!(self.text, " Lattice=\"{a} 0 0 0 {b} 0 0 0 {c}\"");
        }
        let _ = writeln!(self.text, " time={time}");
        for (i, name) in self.names.iter().enumerate() {
            self.text.push_str(name);
            for a in 0..3 {
                let x = if a < dim { q[i * dim + a] } else { 0.0 };
                let _ = write!(self.text, " {x}");
            }
            if let Some(m) = momenta {
                for a in 0..3 {
                    let k = i * dim + a;
                    let v = if a < dim {
                        m.p[k] * m.inverse_mass[k]
                    } else {
                        0.0
                    };
                    let _ = write!(self.text, " {v}");
                }
            }
            self.text.push('\n');
        }
    }
}

fn is_xyz(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("xyz"))
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
        let xyz = is_xyz(path).then(|| XyzFrame {
            names: names.to_vec(),
            lattice: frame
                .cell()
                .shape()
                .ne(&chemfiles::CellShape::Infinite)
                .then(|| {
                    let lengths = frame.cell().lengths();
                    [lengths[0], lengths[1], lengths[2]]
                }),
            text: String::new(),
            velocities: false,
        });
        Ok(TrajectoryWriter {
            path: path.to_path_buf(),
            frame,
            dim,
            frames: 0,
            xyz,
        })
    }

    /// Write velocities beside the positions (`velo:R:3` columns, full precision) in
    /// every frame [`TrajectoryWriter::write_state`] writes; extended XYZ only.
    pub fn with_velocities(mut self) -> Result<Self> {
        match &mut self.xyz {
            Some(xyz) => {
                xyz.velocities = true;
                Ok(self)
            }
            None => Err(trajectory_error(
                &self.path,
                "velocities are written only to an extended XYZ trajectory (.xyz)".into(),
            )),
        }
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    pub fn frames(&self) -> usize {
        self.frames
    }

    /// Have the system write the frames so far to disk (`fsync`; each frame is already
    /// handed to it as written): before a checkpoint.
    pub fn sync(&self) -> Result<()> {
        if self.frames == 0 {
            return Ok(());
        }
        std::fs::File::open(&self.path)
            .and_then(|f| f.sync_all())
            .map_err(|e| trajectory_error(&self.path, format!("cannot write to disk: {e}")))
    }

    /// Append one frame of positions `q` (`n × dim`; missing coordinates are 0).
    pub fn write(&mut self, q: &[f64], step: u64, time: f64) -> Result<()> {
        self.write_state(q, None, step, time)
    }

    /// Append one frame of positions, with the velocities of `momenta` when the writer
    /// was asked for them ([`TrajectoryWriter::with_velocities`]).
    pub fn write_state(
        &mut self,
        q: &[f64],
        momenta: Option<Momenta>,
        step: u64,
        time: f64,
    ) -> Result<()> {
        if let Some(xyz) = &mut self.xyz {
            xyz.format(q, momenta, self.dim, time);
            append(&self.path, xyz.text.as_bytes())?;
            self.frames += 1;
            return Ok(());
        }
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

/// Append `bytes` (one whole frame) to the file at `path` and close it.
fn append(path: &Path, bytes: &[u8]) -> Result<()> {
    use std::io::Write;
    let mut file = std::fs::OpenOptions::new()
        .append(true)
        .open(path)
        .map_err(|e| trajectory_error(path, format!("cannot open for writing: {e}")))?;
    file.write_all(bytes)
        .map_err(|e| trajectory_error(path, format!("cannot write frame: {e}")))
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
