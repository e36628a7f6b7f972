//! Particles: listed or generated in `[[particles]]`, or read from a `[structure]` file
//! with its bonds and velocities.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use toml::Spanned;

use super::{Builder, ParticleSpec, SceneFile, StructureSpec};
use crate::error::{Error, Result};
use crate::io::structure::{Atom, Structure, read_structure, read_structure_with};

/// The particles as the scene gives them, before the force field: names, masses and
/// momenta in the scene's units, and the structure they were read from.
pub(super) struct Start {
    pub names: Vec<String>,
    pub masses: Vec<f64>,
    pub q: Vec<f64>,
    pub p: Vec<f64>,
    pub structure: Option<Structure>,
}

/// Most particles a scene may hold (about 100 bytes each before any force term's
/// buffers): beyond it a scene is refused before anything is allocated.
pub const MAX_PARTICLES: usize = 10_000_000;

impl Builder<'_> {
    /// The particles: listed in `[[particles]]` or read through `[structure]`, not both.
    pub(super) fn particles(
        &self,
        file: &SceneFile,
        dim: usize,
        parameters: &BTreeMap<String, f64>,
    ) -> Result<Start> {
        match (&file.structure, file.particles.is_empty()) {
            (Some(_), false) => Err(self
                .error("give particles either as [[particles]] or through [structure], not both")),
            (None, true) => Err(self.error("the scene has no particles")),
            (None, false) => {
                let mut start = Start {
                    names: Vec::new(),
                    masses: Vec::new(),
                    q: Vec::new(),
                    p: Vec::new(),
                    structure: None,
                };
                for spanned in &file.particles {
                    self.particle_block(spanned, dim, parameters, &mut start)?;
                }
                Ok(start)
            }
            (Some(spanned), true) => {
                let with_forcefield = file.forcefield.is_some();
                self.structure_particles(spanned, with_forcefield, dim, parameters)
            }
        }
    }

    /// One `[[particles]]` entry: one particle, or `count` of them.
    fn particle_block(
        &self,
        spanned: &Spanned<ParticleSpec>,
        dim: usize,
        parameters: &BTreeMap<String, f64>,
        start: &mut Start,
    ) -> Result<()> {
        let offset = spanned.span().start;
        let spec = spanned.get_ref();
        let count = match &spec.count {
            Some(v) => {
                let x = self.evaluate(v, parameters, "particle count", offset)?;
                if x < 1.0 || x.fract() != 0.0 {
                    return Err(self
                        .error_at(offset, "particle count must be a whole number ≥ 1")
                        .key("count")
                        .expected("a whole number ≥ 1")
                        .got(x.to_string()));
                }
                // Every particle holds a name, a mass and 2·dim numbers before any force
                // term sizes its buffers: refuse what memory cannot hold before allocating.
                if x + start.masses.len() as f64 > MAX_PARTICLES as f64 {
                    return Err(self
                        .error_at(
                            offset,
                            format!(
                                "particle count {x} would make more than the {MAX_PARTICLES} \
                                 particles a scene may hold"
                            ),
                        )
                        .key("count"));
                }
                x as usize
            }
            None => 1,
        };
        // A generated block evaluates its expressions with `i` = 0, 1, … count − 1.
        let mut local = parameters.clone();
        for i in 0..count {
            let index = start.masses.len();
            if spec.count.is_some() {
                local.insert("i".to_string(), i as f64);
            }
            let name = match &spec.name {
                Some(name) => name.replace("{i}", &i.to_string()),
                None => format!("p{index}"),
            };
            let label = format!("particle {index} (\"{name}\")");
            let (mass, position, momentum) =
                self.particle_state(spec, dim, &local, &label, offset)?;
            start.names.push(name);
            start.masses.push(mass);
            start.q.extend(position);
            start.p.extend(momentum);
        }
        Ok(())
    }

    /// Mass, position and momentum (given, or from a velocity) of one listed particle.
    fn particle_state(
        &self,
        spec: &ParticleSpec,
        dim: usize,
        local: &BTreeMap<String, f64>,
        label: &str,
        offset: usize,
    ) -> Result<(f64, Vec<f64>, Vec<f64>)> {
        let mass = self
            .evaluate(&spec.mass, local, &format!("mass of {label}"), offset)
            .map_err(|e| e.key("mass"))?;
        if mass <= 0.0 {
            return Err(self
                .error_at(offset, format!("mass of {label} must be positive"))
                .key("mass")
                .expected("a positive number")
                .got(mass.to_string()));
        }
        let vector = |values: &[_], what: &str| {
            self.vector(values, dim, local, &format!("{what} of {label}"), offset)
        };
        let position = vector(&spec.position, "position")?;
        let momentum = match (&spec.momentum, &spec.velocity) {
            (Some(_), Some(_)) => {
                return Err(self.error_at(
                    offset,
                    format!("{label} gives both momentum and velocity; give one"),
                ));
            }
            (Some(momentum), None) => vector(momentum, "momentum")?,
            (None, Some(velocity)) => vector(velocity, "velocity")?
                .iter()
                .map(|v| v * mass)
                .collect(),
            (None, None) => vec![0.0; dim],
        };
        Ok((mass, position, momentum))
    }

    /// A path relative to the scene file.
    pub(super) fn beside_scene(&self, file: &str) -> std::path::PathBuf {
        self.path.parent().unwrap_or(Path::new(".")).join(file)
    }

    /// The atoms of a structure file: names, masses (one for all, by element, or left to
    /// the force field), positions in the first `dim` coordinates, momenta zero.
    fn structure_particles(
        &self,
        spanned: &Spanned<StructureSpec>,
        with_forcefield: bool,
        dim: usize,
        parameters: &BTreeMap<String, f64>,
    ) -> Result<Start> {
        let offset = spanned.span().start;
        let spec = spanned.get_ref();
        let (structure_path, structure) = self.read_scene_structure(spanned, with_forcefield)?;
        let uniform_mass = self.structure_mass(spec, parameters, offset)?;
        let (mut names, mut masses, mut q, mut p) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for (i, atom) in structure.atoms.iter().enumerate() {
            let mass = atom_mass(atom, i, uniform_mass, with_forcefield, &structure_path)?;
            push_position(&mut q, atom, i, dim, &structure_path)?;
            names.push(atom.name.clone());
            masses.push(mass);
            p.extend(std::iter::repeat_n(0.0, dim));
        }
        Ok(Start {
            names,
            masses,
            q,
            p,
            structure: Some(structure),
        })
    }

    /// The `[structure]` file beside the scene, read (bonds guessed unless told, by
    /// default when a force field needs them) and refused when missing, empty or too big.
    fn read_scene_structure(
        &self,
        spanned: &Spanned<StructureSpec>,
        with_forcefield: bool,
    ) -> Result<(PathBuf, Structure)> {
        let offset = spanned.span().start;
        let spec = spanned.get_ref();
        let structure_path = self.beside_scene(&spec.file);
        if !structure_path.is_file() {
            return Err(self
                .error_at(
                    offset,
                    format!(
                        "[structure] file {}: no such file",
                        structure_path.display()
                    ),
                )
                .key("file"));
        }
        let guess = spec.guess_bonds.unwrap_or(with_forcefield);
        let structure = read_structure_with(&structure_path, guess)?;
        if structure.atoms.is_empty() {
            return Err(self.error_at(
                offset,
                format!(
                    "[structure] file {}: its first frame has no atoms",
                    structure_path.display()
                ),
            ));
        }
        if structure.atoms.len() > MAX_PARTICLES {
            return Err(self.error_at(
                offset,
                format!(
                    "[structure] file {} has {} atoms, more than the {MAX_PARTICLES} particles \
                     a scene may hold",
                    structure_path.display(),
                    structure.atoms.len()
                ),
            ));
        }
        Ok((structure_path, structure))
    }

    /// The `[structure]` section's `mass` for every atom, if given (must be positive).
    fn structure_mass(
        &self,
        spec: &StructureSpec,
        parameters: &BTreeMap<String, f64>,
        offset: usize,
    ) -> Result<Option<f64>> {
        match &spec.mass {
            Some(mass) => {
                let mass = self
                    .evaluate(mass, parameters, "structure mass", offset)
                    .map_err(|e| e.key("mass"))?;
                if mass <= 0.0 {
                    return Err(self
                        .error_at(offset, "structure mass must be positive")
                        .key("mass")
                        .expected("a positive number")
                        .got(mass.to_string()));
                }
                Ok(Some(mass))
            }
            None => Ok(None),
        }
    }

    /// Momenta from a `velocities` file of the same layout (`p = m v`, masses internal).
    pub(super) fn structure_velocities(
        &self,
        spec: Option<&StructureSpec>,
        masses: &[f64],
        p: &mut [f64],
        dim: usize,
    ) -> Result<()> {
        let Some(velocities) = spec.and_then(|s| s.velocities.as_ref()) else {
            return Ok(());
        };
        let n_particles = masses.len();
        let path = self.beside_scene(velocities);
        if !path.is_file() {
            return Err(self.error(format!(
                "[structure] velocities {}: no such file",
                path.display()
            )));
        }
        let file_velocities = read_structure(&path)?;
        if file_velocities.atoms.len() != n_particles {
            return Err(Error::Structure {
                path,
                message: format!(
                    "has {} velocities for {n_particles} atoms",
                    file_velocities.atoms.len()
                ),
            });
        }
        for (i, atom) in file_velocities.atoms.iter().enumerate() {
            for a in 0..dim {
                p[i * dim + a] = masses[i] * atom.position[a];
            }
        }
        Ok(())
    }

    /// The bonds of a structure: listed in the file or perceived by chemfiles, plus the
    /// scene's `bonds` (repeated over blocks of `bond_repeat` atoms) and `chains`.
    pub(super) fn structure_bonds(
        &self,
        structure: &Structure,
        spec: Option<&StructureSpec>,
        n: usize,
    ) -> Result<Vec<[usize; 2]>> {
        let mut bonds = structure.bonds.clone();
        let Some(spec) = spec else {
            return Ok(bonds);
        };
        let block = |size: usize, key: &str| -> Result<usize> {
            if size == 0 || !n.is_multiple_of(size) {
                return Err(self.error(format!(
                    "[structure] {key} = {size} does not divide the {n} atoms into whole blocks"
                )));
            }
            Ok(n / size)
        };
        if let Some(list) = &spec.bonds {
            let (size, blocks) = match spec.bond_repeat {
                Some(size) => (size, block(size, "bond_repeat")?),
                None => (n, 1),
            };
            for &[a, b] in list {
                if a >= size || b >= size || a == b {
                    return Err(self.error(format!(
                        "[structure] bond [{a}, {b}] must join two different atoms among {size}"
                    )));
                }
                for k in 0..blocks {
                    bonds.push([k * size + a, k * size + b]);
                }
            }
        } else if spec.bond_repeat.is_some() {
            return Err(self.error("[structure] bond_repeat needs a bonds list"));
        }
        if let Some(size) = spec.chains {
            for k in 0..block(size, "chains")? {
                for i in 0..size.saturating_sub(1) {
                    bonds.push([k * size + i, k * size + i + 1]);
                }
            }
        }
        Ok(bonds)
    }
}

/// Atom `i`'s mass: the scene's uniform one, else its element's, else 0 for the force
/// field to give (types that are no element); without a force field that is an error.
fn atom_mass(
    atom: &Atom,
    i: usize,
    uniform_mass: Option<f64>,
    with_forcefield: bool,
    structure_path: &Path,
) -> Result<f64> {
    match uniform_mass {
        Some(mass) => Ok(mass),
        None if atom.mass > 0.0 => Ok(atom.mass),
        // The force field gives masses of types that are no element.
        None if with_forcefield => Ok(0.0),
        None => Err(Error::Structure {
            path: structure_path.to_path_buf(),
            message: format!(
                "atom {i} has unknown element \"{}\" (no mass): give \
                 `mass` in the scene's [structure] section",
                atom.name
            ),
        }),
    }
}

/// Appends atom `i`'s first `dim` coordinates to `q`; the others must be zero.
fn push_position(
    q: &mut Vec<f64>,
    atom: &Atom,
    i: usize,
    dim: usize,
    structure_path: &Path,
) -> Result<()> {
    for (axis, &x) in atom.position.iter().enumerate() {
        if axis < dim {
            q.push(x);
        } else if x != 0.0 {
            return Err(Error::Structure {
                path: structure_path.to_path_buf(),
                message: format!(
                    "atom {i} has coordinate {axis} = {x}, but the scene has \
                     dim = {dim}: use dim = 3 or a file in the first {dim} \
                     coordinates"
                ),
            });
        }
    }
    Ok(())
}
