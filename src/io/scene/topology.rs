//! The `[topology]` section: the atoms, their coordinates (and velocities, when the file
//! has them), the box and every force term from a topology file ([`crate::io::topology`]).

use std::path::{Path, PathBuf};

use super::molecule::Molecule;
use super::particles::Start;
use super::{Builder, SceneFile, Terms};
use crate::error::{Error, Result};
use crate::forces::ewald::EwaldRequest;
use crate::io::forcefield::inverse_length;
use crate::io::topology::gro::read_gro_for;
use crate::io::topology::gromacs::read_gromacs_top;
use crate::io::topology::inpcrd::{Coordinates, read_inpcrd};
use crate::io::topology::prmtop::read_prmtop;
use crate::io::topology::{Coulomb, NonbondedOptions, Topology, build_terms};
use crate::system::PeriodicBox;
use crate::system::topology::{Angle as BondedAngle, Bond as BondedBond, BondedTopology};
use crate::units::Units;

/// Extensions read as AMBER prmtop.
pub const PRMTOP_EXTENSIONS: &[&str] = &["prmtop", "parm7", "top7"];
/// Extensions read as a GROMACS topology.
pub const GROMACS_EXTENSIONS: &[&str] = &["top"];
/// Extensions of coordinates (AMBER's, then GROMACS's `.gro`), tried in this order beside
/// an AMBER topology; a GROMACS topology tries `.gro` first.
pub const COORDINATE_EXTENSIONS: &[&str] = &["inpcrd", "rst7", "crd", "gro"];

fn extension_in(path: &Path, list: &[&str]) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| list.contains(&e.to_ascii_lowercase().as_str()))
}

/// Whether `path` names a topology file the scene loader reads in place of a scene.
pub fn is_topology_path(path: &Path) -> bool {
    extension_in(path, PRMTOP_EXTENSIONS) || extension_in(path, GROMACS_EXTENSIONS)
}

/// The coordinates beside a topology: its name with the first coordinate extension
/// that exists (`.gro` first for a GROMACS topology).
pub fn default_coordinates(topology: &Path) -> Option<PathBuf> {
    let gro_first = extension_in(topology, GROMACS_EXTENSIONS);
    let gro = std::iter::once("gro").filter(|_| gro_first);
    gro.chain(COORDINATE_EXTENSIONS.iter().copied())
        .map(|e| topology.with_extension(e))
        .find(|p| p.is_file())
}

/// A topology with its coordinates and the non-bonded options of the section.
pub(super) struct Loaded {
    topology: Topology,
    coordinates: Coordinates,
    options: NonbondedOptions,
}

impl Loaded {
    pub fn periodic_box(&self) -> Option<PeriodicBox> {
        self.topology
            .periodic_box
            .map(|lengths| PeriodicBox { lengths })
    }

    /// The particles: names, masses (amu), positions and momenta (amu·Å/fs).
    pub fn start(&self) -> Start {
        let atoms = &self.topology.atoms;
        let p = match &self.coordinates.velocities {
            Some(v) => v
                .iter()
                .enumerate()
                .map(|(k, v)| atoms[k / 3].mass * v)
                .collect(),
            None => vec![0.0; 3 * atoms.len()],
        };
        Start {
            names: atoms.iter().map(|a| a.name.clone()).collect(),
            masses: atoms.iter().map(|a| a.mass).collect(),
            q: self.coordinates.positions.clone(),
            p,
            structure: None,
        }
    }
}

impl Builder<'_> {
    /// Read `[topology]`, if the scene has one, and its coordinates.
    pub(super) fn read_topology(&self, file: &SceneFile) -> Result<Option<Loaded>> {
        let Some(spanned) = &file.topology else {
            return Ok(None);
        };
        let offset = spanned.span().start;
        if file.structure.is_some()
            || !file.particles.is_empty()
            || file.forcefield.is_some()
            || file.periodic_box.is_some()
        {
            return Err(self.error_at(
                offset,
                "[topology] gives the atoms, their force field and the box: leave out \
                 [structure], [[particles]], [forcefield] and box",
            ));
        }
        let spec = spanned.get_ref();
        let path = self.beside_scene(&spec.file);
        let defines = spec.defines.clone().unwrap_or_default();
        let mut topology = read_topology_file(&path, &defines)?;
        let coordinates_path = match &spec.coordinates {
            Some(c) => self.beside_scene(c),
            None => default_coordinates(&path).ok_or_else(|| {
                self.error_at(
                    offset,
                    format!(
                        "[topology] no coordinates: none of {} beside {} (give coordinates = \
                         \"…\", or --coordinates FILE)",
                        COORDINATE_EXTENSIONS.join(", "),
                        path.display()
                    ),
                )
            })?,
        };
        let mut coordinates = read_coordinates(&coordinates_path, &topology)?;
        if let Some(file) = &spec.velocities {
            coordinates.velocities = Some(read_velocities(&self.beside_scene(file), &topology)?);
        }
        box_from_coordinates(&mut topology, &coordinates, &coordinates_path)?;
        let coulomb = match &spec.coulomb {
            Some(name) => Some(
                Coulomb::parse(name)
                    .map_err(|e| self.error_at(offset, format!("[topology] {e}")))?,
            ),
            None => None,
        };
        let alpha = match &spec.ewald_alpha {
            Some(value) => Some(
                inverse_length(value, Units::Real)
                    .map_err(|e| self.error_at(offset, format!("[topology] ewald_alpha {e}")))?,
            ),
            None => None,
        };
        let options = NonbondedOptions {
            cutoff: spec.cutoff,
            coulomb,
            epsilon_rf: spec.epsilon_rf,
            dsf_alpha: spec.dsf_alpha,
            skin: spec.skin,
            inner_buffer: spec.inner_buffer,
            lj_shift: spec.lj_shift,
            ewald: EwaldRequest {
                tolerance: spec.ewald_tolerance,
                spacing: spec.fourier_spacing,
                alpha,
                grid: spec.pme_grid,
                order: spec.pme_order,
            },
            pme_level: spec.pme_level,
            nonbonded_level: spec.nonbonded_level,
            split: spec.split.clone(),
        };
        Ok(Some(Loaded {
            topology,
            coordinates,
            options,
        }))
    }

    /// The topology's terms into `terms`; its elements and report.
    pub(super) fn apply_topology(
        &self,
        file: &SceneFile,
        loaded: &Loaded,
        terms: &mut Terms,
    ) -> Result<Molecule> {
        let offset = file.topology.as_ref().map_or(0, |t| t.span().start);
        let built = build_terms(
            &loaded.topology,
            &loaded.coordinates.positions,
            &loaded.options,
        )
        .map_err(|e| self.error_at(offset, format!("[topology] {e}")))?;
        let mut report = built.report;
        report.insert(
            1,
            format!(
                "coordinates: {} atoms{}",
                loaded.coordinates.n_atoms(),
                if loaded.coordinates.velocities.is_some() {
                    ", with velocities"
                } else {
                    ""
                }
            ),
        );
        report.push(if loaded.topology.format == GROMACS_FORMAT {
            "refused: nothing (the reader refuses unknown directives, restraints, constraints, \
             virtual sites and triclinic boxes by file and line)"
                .into()
        } else {
            "refused: nothing (the reader refuses CMAP, 10-12 terms, polarisabilities, extra \
             points and non-orthogonal boxes by section)"
                .into()
        });
        terms.extend(built.terms);
        let bonded = bonded_topology(&loaded.topology, &built.elements)
            .map_err(|e| self.error_at(offset, format!("[topology] {e}")))?;
        Ok(Molecule {
            elements: built.elements,
            report,
            parameters: None,
            bonded: Some(bonded),
        })
    }
}

/// [`Topology::format`] of a GROMACS topology.
const GROMACS_FORMAT: &str = "GROMACS top";

/// A topology file by its extension (`defines`: a GROMACS topology's `-D` names).
pub fn read_topology_file(path: &Path, defines: &[String]) -> Result<Topology> {
    if !path.is_file() {
        return Err(Error::topology(path, "no such file"));
    }
    if extension_in(path, GROMACS_EXTENSIONS) {
        read_gromacs_top(path, defines)
    } else if extension_in(path, PRMTOP_EXTENSIONS) {
        if let Some(name) = defines.first() {
            return Err(Error::topology(
                path,
                "defines (--define, [topology] defines) are for a GROMACS .top's \
                 preprocessor; an AMBER prmtop has none",
            )
            .key("--define")
            .got(name.clone()));
        }
        read_prmtop(path)
    } else {
        Err(Error::topology(
            path,
            format!(
                "not a topology format longstep reads (AMBER prmtop: {}; GROMACS: {})",
                PRMTOP_EXTENSIONS.join(", "),
                GROMACS_EXTENSIONS.join(", ")
            ),
        ))
    }
}

/// The coordinates, with as many atoms as the topology.
fn read_coordinates(path: &Path, topology: &Topology) -> Result<Coordinates> {
    if !path.is_file() {
        return Err(Error::topology(path, "no such coordinate file"));
    }
    if extension_in(path, &["gro"]) {
        return read_gro_for(path, topology);
    }
    let coordinates = read_inpcrd(path)?;
    if coordinates.n_atoms() != topology.atoms.len() {
        return Err(Error::topology(
            path,
            format!(
                "has {} atoms, the topology {} has {}",
                coordinates.n_atoms(),
                topology.source.display(),
                topology.atoms.len()
            ),
        )
        .line(2));
    }
    Ok(coordinates)
}

/// The velocities of the coordinate file `path` (`[topology] velocities`, `--velocities`),
/// which must have them, for the atoms of `topology`.
fn read_velocities(path: &Path, topology: &Topology) -> Result<Vec<f64>> {
    read_coordinates(path, topology)?.velocities.ok_or_else(|| {
        Error::topology(
            path,
            "has no velocities (a restart .rst7/.inpcrd with a velocity block, or a .gro \
             with velocity columns, gives them)",
        )
    })
}

/// A periodic topology takes the coordinates' box when they give one (a restart's current
/// box), a GROMACS topology (which has no box) the box of its coordinates; it must be
/// orthogonal.
fn box_from_coordinates(
    topology: &mut Topology,
    coordinates: &Coordinates,
    path: &Path,
) -> Result<()> {
    if let Some(angles) = coordinates.box_angles
        && angles.iter().any(|a| (a - 90.0).abs() > 1e-6)
    {
        return Err(Error::topology(
            path,
            format!("box angles {angles:?}: a non-orthogonal box, longstep does not model it"),
        ));
    }
    let takes_box = topology.periodic_box.is_some() || topology.format == GROMACS_FORMAT;
    if takes_box && let Some(lengths) = coordinates.box_lengths {
        topology.periodic_box = Some(lengths);
    }
    if topology.format == GROMACS_FORMAT && topology.periodic_box.is_none() {
        // A solvated system read without its box would silently become a droplet in
        // vacuum with plain Coulomb over every pair.
        let water = |name: &str| ["HOH", "SOL", "WAT", "TIP3"].contains(&name);
        let solvated = !topology.settles.is_empty()
            || topology.residues.iter().any(|r| water(r.name.as_str()));
        topology.notes.push(format!(
            "{}{} gives no box (a .gro's 0 0 0): read in vacuum, no cutoff, plain Coulomb \
             over every pair{}",
            if solvated { "warning: " } else { "" },
            path.display(),
            if solvated {
                "; the system holds water: give the .gro its box for a periodic run"
            } else {
                ""
            }
        ));
    }
    Ok(())
}

/// The topology's bonds and angles with their rest values, for constraints and hydrogen
/// mass repartitioning ([`Scene::bonded_topology`](super::Scene::bonded_topology)); a
/// `[settles]` water as its two O-H bonds and its H-H bond at the SETTLE distances, and
/// rigid water then required.
fn bonded_topology(topology: &Topology, elements: &[String]) -> Result<BondedTopology> {
    let bond = |i: usize, j: usize, length: f64| BondedBond { i, j, length };
    let bonds = topology
        .bonds
        .iter()
        .map(|b| bond(b.atoms[0], b.atoms[1], b.r0))
        .chain(topology.settles.iter().flat_map(|w| {
            let [o, h1, h2] = w.atoms;
            [bond(o, h1, w.oh), bond(o, h2, w.oh), bond(h1, h2, w.hh)]
        }))
        .collect();
    let angles = topology
        .angles
        .iter()
        .map(|a| BondedAngle {
            i: a.atoms[0],
            centre: a.atoms[1],
            k: a.atoms[2],
            theta0: a.theta0,
        })
        .collect();
    let mut bonded = BondedTopology::new(elements.to_vec(), bonds, angles)?;
    bonded.rigid_water_required = !topology.settles.is_empty();
    Ok(bonded)
}
