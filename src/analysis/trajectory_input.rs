//! A trajectory file analysed on its own (`longstep analyze MODEL FILE`): longstep's own or
//! another engine's, read through chemfiles, with the scene (or topology) as the model.
//!
//! * **Formats and units.** An extended-XYZ file (`.xyz`) is longstep's own: positions and
//!   times in the scene's units, atom names checked against the scene's. Every other format
//!   chemfiles reads (GROMACS `.xtc` and `.trr`, OpenMM/CHARMM `.dcd`, AMBER `.nc`, `.pdb`,
//!   `.gro`, …) is another engine's: chemfiles hands its positions over in ångström whatever
//!   the file holds (nm in `.xtc`, `.trr`, `.gro`), so the model must be in real units (Å);
//!   a dimensionless scene cannot tell what length an ångström is, and is refused.
//! * **Times.** `.xtc` and `.trr` frames carry their time in ps (converted to the scene's
//!   time unit). A `.dcd` header's time step is unreliable (OpenMM's is in AKMA units and
//!   multiplied by the interval; others write none) and `.nc` carries none in chemfiles:
//!   those frames are counted, at `--frame-time` apart when given, else in frames (then a
//!   `--skip` must be 0, as a time cannot be placed).
//! * **Atoms.** The frame's atom count must be the model's. A file with no atom names (xtc,
//!   dcd) cannot show a different order by name, so the first frame's bonds are checked
//!   instead: a bond stretched beyond [`ORDER_STRETCH`] times its rest length says the atoms
//!   are not in the topology's order.
//! * **Box.** A periodic model needs every frame's box: a frame without one is an error.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::forces::{PeriodicBox, RestGeometry};
use crate::io::scene::Scene;
use crate::units::Units;

/// A bond longer than `(1 + ORDER_STRETCH)` or shorter than `(1 − ORDER_STRETCH)` times its
/// rest length in a trajectory's first frame means the atoms are not the model's, in its
/// order: thermal motion stretches a bond by `√(k_B T/k)` ≈ 0.03 Å at 300 K for the softest
/// Amber bond (k ≈ 2 × 200 kcal/mol/Å²), a few per cent, far from a half.
pub const ORDER_STRETCH: f64 = 0.5;

/// How a frame's time is known.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FrameClock {
    /// The frame's `time` property, times `scale` (to the scene's time unit).
    Property { scale: f64 },
    /// Frames counted: frame `k` at `k × interval` (scene time), or at `k` frames.
    Counted { interval: Option<f64> },
}

/// A trajectory file to be analysed without a run directory.
#[derive(Clone, Debug)]
pub struct TrajectoryInput {
    pub path: PathBuf,
    /// longstep's own extended XYZ (names checked, scene units).
    pub own: bool,
    pub clock: FrameClock,
}

fn bad(path: &Path, message: String) -> Error {
    Error::Structure {
        path: path.to_path_buf(),
        message,
    }
}

impl TrajectoryInput {
    /// How `path` is read for the model `scene`; `frame_time` is `--frame-time` (scene units).
    pub fn new(path: &Path, scene: &Scene, frame_time: Option<f64>) -> Result<Self> {
        let extension = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .unwrap_or_default();
        if extension == "xyz" {
            return Ok(TrajectoryInput {
                path: path.to_path_buf(),
                own: true,
                clock: FrameClock::Property { scale: 1.0 },
            });
        }
        if scene.units != Units::Real {
            return Err(bad(
                path,
                format!(
                    "cannot tell its units: chemfiles reads a .{extension} file in ångström, but \
                     the model {} has no units (units = \"none\"); give a scene in real units",
                    scene.path.display()
                ),
            ));
        }
        let ps = scene
            .units
            .time_units()
            .iter()
            .find(|(suffix, _)| *suffix == "ps")
            .map_or(1000.0, |(_, value)| *value);
        let clock = match extension.as_str() {
            "xtc" | "trr" => FrameClock::Property { scale: ps },
            _ => FrameClock::Counted {
                interval: frame_time,
            },
        };
        Ok(TrajectoryInput {
            path: path.to_path_buf(),
            own: false,
            clock,
        })
    }

    /// Times are in the scene's time unit (not frame counts).
    pub fn has_times(&self) -> bool {
        !matches!(self.clock, FrameClock::Counted { interval: None })
    }

    /// The time of frame `index` whose `time` property is `property`.
    pub fn time(&self, index: usize, property: Option<f64>) -> Result<f64> {
        match self.clock {
            FrameClock::Property { scale } => property.map(|t| t * scale).ok_or_else(|| {
                bad(
                    &self.path,
                    format!(
                        "frame {index} has no time (longstep writes it in extended XYZ, GROMACS \
                         in .xtc and .trr)"
                    ),
                )
            }),
            FrameClock::Counted { interval } => Ok(index as f64 * interval.unwrap_or(1.0)),
        }
    }
}

/// The first frame `q` of another engine's trajectory must have the model's bonds
/// ([`ORDER_STRETCH`]); `rest` are the model's rest geometries.
pub fn check_order(
    path: &Path,
    model: &Path,
    q: &[f64],
    periodic_box: Option<&PeriodicBox>,
    rest: &[RestGeometry],
) -> Result<()> {
    for geometry in rest {
        let RestGeometry::Distance { sites, length } = geometry else {
            continue;
        };
        let (Some(i), Some(j)) = (sites[0].particle(), sites[1].particle()) else {
            continue;
        };
        let mut d = [0.0; 3];
        for (a, x) in d.iter_mut().enumerate() {
            let delta = q[3 * j + a] - q[3 * i + a];
            *x = periodic_box.map_or(delta, |b| b.wrap(a, delta));
        }
        let r = d.iter().map(|x| x * x).sum::<f64>().sqrt();
        if (r - length).abs() > ORDER_STRETCH * length {
            return Err(bad(
                path,
                format!(
                    "its atoms are not in the order of the model {}: in the first frame the bond \
                     between atoms {} and {} is {r:.3} Å long, its rest length {length:.3} Å",
                    model.display(),
                    i + 1,
                    j + 1
                ),
            ));
        }
    }
    Ok(())
}
