//! Scene files: TOML, schema version 1, documented in `docs/scenes.md`.
//!
//! A scene names its dimension, parameters, particles (listed, or read from a structure
//! file through chemfiles), fixed anchors, force terms with their level, and the run.
//! Parsing is strict: an unknown key, a missing particle, a non-positive mass or a vector
//! of the wrong length is an error naming the file, the line and the key.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

use super::expr;
use super::forcefield::{
    FfAtom, ForcefieldInput, ForcefieldSpec, build_forcefield, closest_overlap,
};
use super::structure::{Structure, read_structure, read_structure_with};
use crate::analysis::exact::{ExactSolution, ExpressionSolution, TwoMediaWave};
use crate::error::{Error, Result};
use crate::forces::angle::{AngleBend, HarmonicAngles};
use crate::forces::external_field::{ExternalField, FieldShape};
use crate::forces::field::UniformField;
use crate::forces::gravity::{CentralMass, gravity};
use crate::forces::inverse_power::{InversePower, inverse_power_pairs};
use crate::forces::lennard_jones::{LennardJones, lennard_jones_pairs};
use crate::forces::magnetic::{MagneticTerm, VectorPotential};
use crate::forces::pendulum::Pendulum;
use crate::forces::quartic::{QuarticBond, quartic_springs};
use crate::forces::spring::{HarmonicBond, harmonic_springs};
use crate::forces::string::FemString;
use crate::forces::{ForceTerm, Site};
use crate::settings::{RunSpec, Value};
use crate::split::{Assignment, ForceSplit};
use crate::system::{MassMatrix, Particles, PeriodicBox, State, System};
use crate::units::Units;

/// The scene-file format version this build reads.
pub const SCENE_VERSION: u32 = 1;

/// Atoms of a molecule scene closer than this (Å) are an error naming the pair.
pub const OVERLAP_LIMIT: f64 = 0.5;

// ---------------------------------------------------------------------------------------
// The file as written
// ---------------------------------------------------------------------------------------

/// A particle by 0-based index or by name; a name may also be an anchor's.
#[derive(Clone, Debug, Deserialize)]
#[serde(untagged)]
pub enum Reference {
    Index(usize),
    Name(String),
}

impl std::fmt::Display for Reference {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Reference::Index(i) => write!(f, "particle {i}"),
            Reference::Name(name) => write!(f, "\"{name}\""),
        }
    }
}

#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Group {
    Fast,
    Slow,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    pub version: u32,
    pub name: String,
    #[serde(default)]
    pub description: String,
    pub dim: usize,
    /// `"real"` (Å, fs, amu, kcal/mol, e) or `"none"` (dimensionless, the default).
    pub units: Option<Spanned<String>>,
    #[serde(default)]
    pub parameters: BTreeMap<String, Value>,
    #[serde(default)]
    pub anchors: BTreeMap<String, Vec<Value>>,
    #[serde(default)]
    pub particles: Vec<Spanned<ParticleSpec>>,
    pub structure: Option<Spanned<StructureSpec>>,
    #[serde(rename = "box")]
    pub periodic_box: Option<Spanned<Vec<Value>>>,
    #[serde(default)]
    pub terms: Vec<Spanned<TermSpec>>,
    #[serde(default)]
    pub run: RunSpec,
    #[serde(default)]
    pub output: OutputSpec,
    /// A non-diagonal mass matrix (the particles' masses are its diagonal).
    pub mass_matrix: Option<Spanned<MassMatrixSpec>>,
    /// An exact solution to measure the run's error against.
    pub exact: Option<Spanned<ExactSpec>>,
    /// A molecular force field over the structure's atoms and bonds.
    pub forcefield: Option<Spanned<ForcefieldSpec>>,
}

/// `[mass_matrix]`: symmetric off-diagonal entries `M_ij = M_ji`, the same on every axis.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MassMatrixSpec {
    /// The value of every listed entry (`"dx/6"` for P1 elements).
    pub off_diagonal: Value,
    /// `"chain"` (every consecutive pair `i, i + 1`) or a list of pairs.
    pub pairs: MassPairs,
    /// Lump the matrix: add each row's off-diagonal entries to its diagonal, so every
    /// method can run it (default false: solve with the full matrix).
    pub lump: Option<bool>,
}

#[derive(Debug, Deserialize)]
#[serde(untagged)]
pub enum MassPairs {
    Keyword(String),
    List(Vec<[Reference; 2]>),
}

/// `[exact]`: an exact solution (see [`crate::analysis::exact`]).
#[derive(Debug, Deserialize)]
#[serde(tag = "type", rename_all = "kebab-case", deny_unknown_fields)]
pub enum ExactSpec {
    /// One expression per axis in `t`, the particle index `i` and the parameters.
    Expression { position: Vec<String> },
    /// MEMM18 4.3.2's pulse through an interface between two wave speeds.
    TwoMediaWave {
        c1: Value,
        c2: Value,
        interface: Value,
        /// `u₀(x)`, an expression in `x`.
        pulse: String,
        /// `u₀` is zero outside `[a, b]`.
        support: [Value; 2],
        /// Rest position of particle `i`, an expression in `i`.
        node: String,
    },
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParticleSpec {
    /// Generate this many particles; their expressions see the index `i` = 0, 1, …
    /// and `{i}` in the name is replaced by it. A number, or an expression in the
    /// parameters (`"n - 1"`) that evaluates to a whole number.
    pub count: Option<Value>,
    pub name: Option<String>,
    pub mass: Value,
    pub position: Vec<Value>,
    pub momentum: Option<Vec<Value>>,
    pub velocity: Option<Vec<Value>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StructureSpec {
    /// Path relative to the scene file.
    pub file: String,
    /// One mass for every particle; by default each atom's element gives its mass.
    pub mass: Option<Value>,
    /// A file of the same layout whose coordinates are velocities (length/time).
    pub velocities: Option<String>,
    /// Perceive bonds with chemfiles when the file lists none (default: with a force field).
    pub guess_bonds: Option<bool>,
    /// Bonds to add, as 0-based atom index pairs.
    pub bonds: Option<Vec<[usize; 2]>>,
    /// Apply `bonds` to every consecutive block of this many atoms (indices within a block).
    pub bond_repeat: Option<usize>,
    /// Bond consecutive atoms within every block of this many atoms (bead-spring chains).
    pub chains: Option<usize>,
}

#[derive(Debug, Deserialize)]
#[serde(tag = "type", rename_all = "kebab-case", deny_unknown_fields)]
pub enum TermSpec {
    /// Harmonic springs `(k/2)(r − L)²`.
    Spring {
        name: Option<String>,
        between: Option<[Reference; 2]>,
        pairs: Option<Vec<[Reference; 2]>>,
        stiffness: Value,
        rest_length: Option<Value>,
        group: Option<Group>,
        level: Option<usize>,
    },
    /// Harmonic springs between consecutive particles of a list (default: all).
    Chain {
        name: Option<String>,
        particles: Option<Vec<Reference>>,
        stiffness: Value,
        rest_length: Option<Value>,
        group: Option<Group>,
        level: Option<usize>,
        /// Instead of `particles`: the particles `first..=last` by index (expressions).
        range: Option<[Value; 2]>,
        /// A site (anchor or particle) linked before the first particle.
        start: Option<Reference>,
        /// A site linked after the last particle.
        end: Option<Reference>,
    },
    /// FPU springs `c (r − L)⁴`.
    QuarticSpring {
        name: Option<String>,
        between: Option<[Reference; 2]>,
        pairs: Option<Vec<[Reference; 2]>>,
        coefficient: Value,
        rest_length: Option<Value>,
        group: Option<Group>,
        level: Option<usize>,
    },
    /// Harmonic angles `(k/2)(θ − θ₀)²` at the middle particle of each triple.
    Angle {
        name: Option<String>,
        between: Option<[Reference; 3]>,
        triples: Option<Vec<[Reference; 3]>>,
        stiffness: Value,
        rest_angle: Option<Value>,
        group: Option<Group>,
        level: Option<usize>,
    },
    /// Lennard-Jones 12-6 between all pairs of a particle list (default: all).
    LennardJones {
        name: Option<String>,
        particles: Option<Vec<Reference>>,
        epsilon: Value,
        sigma: Value,
        cutoff: Option<Value>,
        shift: Option<bool>,
        #[serde(default)]
        exclude: Vec<[Reference; 2]>,
        group: Option<Group>,
        level: Option<usize>,
    },
    /// Newtonian gravity among particles and towards an optional fixed central mass.
    Gravity {
        name: Option<String>,
        particles: Option<Vec<Reference>>,
        constant: Option<Value>,
        center: Option<String>,
        center_mass: Option<Value>,
        group: Option<Group>,
        level: Option<usize>,
    },
    /// A uniform force `f` on each listed particle (default: all): `V = −Σ f·q_i`.
    Field {
        name: Option<String>,
        particles: Option<Vec<Reference>>,
        force: Vec<Value>,
        group: Option<Group>,
        level: Option<usize>,
    },
    /// The P1 finite-element nonlinear string of MEMM18 3.3 over consecutive sites.
    FemString {
        name: Option<String>,
        particles: Option<Vec<Reference>>,
        range: Option<[Value; 2]>,
        start: Option<Reference>,
        end: Option<Reference>,
        element_length: Value,
        alpha: Value,
        group: Option<Group>,
        level: Option<usize>,
    },
    /// `k(1 − cos x)` on one coordinate of each particle.
    Pendulum {
        name: Option<String>,
        particles: Option<Vec<Reference>>,
        strength: Value,
        axis: Option<usize>,
        group: Option<Group>,
        level: Option<usize>,
    },
    /// `c (r + a)^(−n)` between pairs: singular walls (HL97 (3.5)), softened Coulomb.
    InversePower {
        name: Option<String>,
        between: Option<[Reference; 2]>,
        pairs: Option<Vec<[Reference; 2]>>,
        coefficient: Value,
        power: Value,
        softening: Option<Value>,
        group: Option<Group>,
        level: Option<usize>,
    },
    /// A static magnetic field through its vector potential, on charged particles
    /// (CFM25 5.7); only the structural schemes integrate it.
    Magnetic {
        name: Option<String>,
        particles: Option<Vec<Reference>>,
        /// `"uniform"` (`A = (0, B x₁, 0)`) or `"cfm25-singular"`.
        field: String,
        /// `B` of the uniform field.
        strength: Option<Value>,
        /// The particles' charge `e` (default 1).
        charge: Option<Value>,
        group: Option<Group>,
        level: Option<usize>,
    },
    /// A fixed external potential `e φ(x)` on 3-D particles (CFM25 5.7.3).
    ExternalField {
        name: Option<String>,
        particles: Option<Vec<Reference>>,
        /// `"cfm25-trigonometric"`.
        field: String,
        /// The particles' charge `e` (default 1).
        charge: Option<Value>,
        group: Option<Group>,
        level: Option<usize>,
    },
}

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// Output directory, relative to the working directory.
    pub dir: Option<String>,
    /// Write a row of `energy.csv` every this many steps.
    pub energy_every: Option<usize>,
    /// Trajectory file name in the output directory (format by extension, default
    /// `trajectory.xyz`).
    pub trajectory: Option<String>,
    /// Write a trajectory frame every this many steps (default: no trajectory).
    pub trajectory_every: Option<usize>,
}

// ---------------------------------------------------------------------------------------
// The built scene
// ---------------------------------------------------------------------------------------

pub struct Scene {
    pub name: String,
    pub description: String,
    pub path: PathBuf,
    pub parameters: BTreeMap<String, f64>,
    pub system: System,
    /// The scene's `[run]` table, unevaluated (the command line overrides it).
    pub run: RunSpec,
    pub output: OutputSpec,
    /// The scene's exact solution, when it gives one (`[exact]`).
    pub exact: Option<Box<dyn ExactSolution>>,
    pub units: Units,
    /// Element (or name) of each particle, for trajectories and force tables.
    pub elements: Vec<String>,
    /// Which force-field parameter came from where (empty without `[forcefield]`).
    pub forcefield_report: Vec<String>,
    /// Every force-field parameter per interaction (`None` without `[forcefield]`).
    pub forcefield_parameters: Option<serde_json::Value>,
}

/// Read and build a scene; `overrides` are `name=value` settings of its parameters.
pub fn load_scene(path: &Path, overrides: &[String]) -> Result<Scene> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    build_scene(&text, path, overrides)
}

/// Build a scene from its text (`path` names it in messages and anchors relative files).
pub fn build_scene(text: &str, path: &Path, overrides: &[String]) -> Result<Scene> {
    let file = parse_scene(text, path)?;
    build_parsed_scene(&file, text, path, overrides)
}

/// Parse a scene's text without building it, for studies that build the same scene many
/// times with different parameters ([`build_parsed_scene`]); `path` names it in messages.
pub fn parse_scene(text: &str, path: &Path) -> Result<SceneFile> {
    let builder = Builder { text, path };
    toml::from_str(text).map_err(|e| {
        let location = match e.span() {
            Some(span) => builder.location(span.start),
            None => path.display().to_string(),
        };
        Error::Scene {
            location,
            message: e.message().to_string(),
        }
    })
}

/// Build a scene from a file parsed by [`parse_scene`] from `text` (kept for the line
/// numbers of messages), with `overrides` of its parameters.
pub fn build_parsed_scene(
    file: &SceneFile,
    text: &str,
    path: &Path,
    overrides: &[String],
) -> Result<Scene> {
    Builder { text, path }.build(file, overrides)
}

struct Builder<'a> {
    text: &'a str,
    path: &'a Path,
}

/// A particle or anchor name resolved to a site.
struct Names {
    sites: BTreeMap<String, Site>,
    n_particles: usize,
}

impl Builder<'_> {
    fn location(&self, offset: usize) -> String {
        let line = self.text[..offset.min(self.text.len())]
            .bytes()
            .filter(|&b| b == b'\n')
            .count()
            + 1;
        format!("{}:{line}", self.path.display())
    }

    fn error_at(&self, offset: usize, message: impl Into<String>) -> Error {
        Error::Scene {
            location: self.location(offset),
            message: message.into(),
        }
    }

    fn error(&self, message: impl Into<String>) -> Error {
        Error::Scene {
            location: self.path.display().to_string(),
            message: message.into(),
        }
    }

    fn build(&self, file: &SceneFile, overrides: &[String]) -> Result<Scene> {
        if file.version != SCENE_VERSION {
            return Err(self.error(format!(
                "scene version {} is not supported; this longstep reads version {SCENE_VERSION}",
                file.version
            )));
        }
        let dim = file.dim;
        if !(1..=3).contains(&dim) {
            return Err(self.error(format!("dim must be 1, 2 or 3, got {dim}")));
        }
        let units = match &file.units {
            Some(spanned) => Units::parse(spanned.get_ref())
                .map_err(|e| self.error_at(spanned.span().start, e))?,
            None => Units::None,
        };
        if let Some(spanned) = &file.forcefield {
            if units != Units::Real {
                return Err(self.error_at(
                    spanned.span().start,
                    "[forcefield] needs units = \"real\" (Å, fs, amu, kcal/mol, e)",
                ));
            }
            if dim != 3 || file.structure.is_none() {
                return Err(self.error_at(
                    spanned.span().start,
                    "[forcefield] needs dim = 3 and the atoms from a [structure] file",
                ));
            }
        }
        let parameters = self.resolve_parameters(&file.parameters, overrides)?;
        let value = |v: &Value, what: &str, offset: usize| -> Result<f64> {
            self.evaluate(v, &parameters, what, offset)
        };

        // Particles: listed, or read from a structure file.
        let mut names = Vec::new();
        let mut masses = Vec::new();
        let mut q = Vec::new();
        let mut p = Vec::new();
        let mut structure_positions: Option<Structure> = None;
        match (&file.structure, file.particles.is_empty()) {
            (Some(_), false) => {
                return Err(self.error(
                    "give particles either as [[particles]] or through [structure], not both",
                ));
            }
            (None, true) => return Err(self.error("the scene has no particles")),
            (None, false) => {
                for spanned in &file.particles {
                    let offset = spanned.span().start;
                    let spec = spanned.get_ref();
                    let count = match &spec.count {
                        Some(v) => {
                            let x = value(v, "particle count", offset)?;
                            if x < 1.0 || x.fract() != 0.0 {
                                return Err(self.error_at(
                                    offset,
                                    format!("particle count must be a whole number ≥ 1, got {x}"),
                                ));
                            }
                            x as usize
                        }
                        None => 1,
                    };
                    // A generated block evaluates its expressions with `i` = 0, 1, … count − 1.
                    let mut local = parameters.clone();
                    for i in 0..count {
                        let index = masses.len();
                        if spec.count.is_some() {
                            local.insert("i".to_string(), i as f64);
                        }
                        let name = match &spec.name {
                            Some(name) => name.replace("{i}", &i.to_string()),
                            None => format!("p{index}"),
                        };
                        let label = format!("particle {index} (\"{name}\")");
                        let mass =
                            self.evaluate(&spec.mass, &local, &format!("mass of {label}"), offset)?;
                        if mass <= 0.0 {
                            return Err(self.error_at(
                                offset,
                                format!("mass of {label} must be positive, got {mass}"),
                            ));
                        }
                        let position = self.vector(
                            &spec.position,
                            dim,
                            &local,
                            &format!("position of {label}"),
                            offset,
                        )?;
                        let momentum = match (&spec.momentum, &spec.velocity) {
                            (Some(_), Some(_)) => {
                                return Err(self.error_at(
                                    offset,
                                    format!("{label} gives both momentum and velocity; give one"),
                                ));
                            }
                            (Some(momentum), None) => self.vector(
                                momentum,
                                dim,
                                &local,
                                &format!("momentum of {label}"),
                                offset,
                            )?,
                            (None, Some(velocity)) => self
                                .vector(
                                    velocity,
                                    dim,
                                    &local,
                                    &format!("velocity of {label}"),
                                    offset,
                                )?
                                .iter()
                                .map(|v| v * mass)
                                .collect(),
                            (None, None) => vec![0.0; dim],
                        };
                        names.push(name);
                        masses.push(mass);
                        q.extend(position);
                        p.extend(momentum);
                    }
                }
            }
            (Some(spanned), true) => {
                let offset = spanned.span().start;
                let spec = spanned.get_ref();
                let structure_path = self
                    .path
                    .parent()
                    .unwrap_or(Path::new("."))
                    .join(&spec.file);
                let guess = spec.guess_bonds.unwrap_or(file.forcefield.is_some());
                let structure = read_structure_with(&structure_path, guess)?;
                let uniform_mass = match &spec.mass {
                    Some(mass) => {
                        let mass = value(mass, "structure mass", offset)?;
                        if mass <= 0.0 {
                            return Err(self.error_at(
                                offset,
                                format!("structure mass must be positive, got {mass}"),
                            ));
                        }
                        Some(mass)
                    }
                    None => None,
                };
                for (i, atom) in structure.atoms.iter().enumerate() {
                    let mass = match uniform_mass {
                        Some(mass) => mass,
                        None if atom.mass > 0.0 => atom.mass,
                        // The force field gives masses of types that are no element.
                        None if file.forcefield.is_some() => 0.0,
                        None => {
                            return Err(Error::Structure {
                                path: structure_path.clone(),
                                message: format!(
                                    "atom {i} has unknown element \"{}\" (no mass): give \
                                     `mass` in the scene's [structure] section",
                                    atom.name
                                ),
                            });
                        }
                    };
                    for (axis, &x) in atom.position.iter().enumerate() {
                        if axis < dim {
                            q.push(x);
                        } else if x != 0.0 {
                            return Err(Error::Structure {
                                path: structure_path.clone(),
                                message: format!(
                                    "atom {i} has coordinate {axis} = {x}, but the scene has \
                                     dim = {dim}: use dim = 3 or a file in the first {dim} \
                                     coordinates"
                                ),
                            });
                        }
                    }
                    names.push(atom.name.clone());
                    masses.push(mass);
                    p.extend(std::iter::repeat_n(0.0, dim));
                }
                structure_positions = Some(structure);
            }
        }
        let n_particles = masses.len();

        // Names of particles and anchors share one namespace.
        let mut sites = BTreeMap::new();
        if structure_positions.is_none() {
            for (i, name) in names.iter().enumerate() {
                if sites.insert(name.clone(), Site::Particle(i)).is_some() {
                    return Err(self.error(format!("two particles are named \"{name}\"")));
                }
            }
        }
        for (name, coordinates) in &file.anchors {
            let position = self.vector(
                coordinates,
                dim,
                &parameters,
                &format!("anchor \"{name}\""),
                0,
            )?;
            let mut fixed = [0.0; 3];
            fixed[..dim].copy_from_slice(&position);
            if sites.insert(name.clone(), Site::Fixed(fixed)).is_some() {
                return Err(self.error(format!(
                    "anchor \"{name}\" has the name of a particle; names must be unique"
                )));
            }
        }
        let names_table = Names { sites, n_particles };

        let periodic_box = match &file.periodic_box {
            Some(spanned) => {
                let lengths = self.vector(
                    spanned.get_ref(),
                    dim,
                    &parameters,
                    "box",
                    spanned.span().start,
                )?;
                if lengths.iter().any(|&l| l <= 0.0) {
                    return Err(self.error_at(spanned.span().start, "box lengths must be positive"));
                }
                let mut all = [f64::INFINITY; 3];
                all[..dim].copy_from_slice(&lengths);
                Some(PeriodicBox { lengths: all })
            }
            // A cell in the structure file (extended XYZ `Lattice=`, PDB `CRYST1`).
            None => structure_positions
                .as_ref()
                .and_then(|s| s.cell)
                .filter(|_| dim == 3)
                .map(|lengths| PeriodicBox { lengths }),
        };

        // A non-diagonal mass matrix, or its lumped diagonal.
        let mass_matrix = match &file.mass_matrix {
            Some(spanned) => {
                self.mass_matrix(spanned, dim, &mut masses, &names_table, &parameters)?
            }
            None => None,
        };

        // Terms.
        let mut terms: Vec<(String, Box<dyn ForceTerm>, Assignment)> = Vec::new();
        for (index, spanned) in file.terms.iter().enumerate() {
            let term = self.build_term(
                spanned,
                index,
                dim,
                &parameters,
                &names_table,
                &q,
                &masses,
                periodic_box,
            )?;
            terms.push(term);
        }

        // The molecular force field, and the masses and velocities it settles.
        let mut elements: Vec<String> = names.clone();
        let mut forcefield_report = Vec::new();
        let mut forcefield_parameters = None;
        if let (Some(ff), Some(structure)) = (&file.forcefield, &structure_positions) {
            let offset = ff.span().start;
            let structure_spec = file.structure.as_ref().map(|s| s.get_ref());
            let bonds = self.structure_bonds(structure, structure_spec, n_particles)?;
            if let Some((i, j, r)) = closest_overlap(&q, periodic_box, OVERLAP_LIMIT) {
                return Err(self.error(format!(
                    "atoms {i} ({}) and {j} ({}) overlap: they are {r:.4} Å apart (closer than \
                     {OVERLAP_LIMIT} Å)",
                    names[i], names[j]
                )));
            }
            let atoms: Vec<FfAtom> = structure
                .atoms
                .iter()
                .map(|a| FfAtom {
                    type_name: a.name.clone(),
                    element: a.element.clone(),
                    element_mass: a.mass,
                })
                .collect();
            let built = build_forcefield(&ForcefieldInput {
                spec: ff.get_ref(),
                units,
                atoms: &atoms,
                q: &q,
                bonds: &bonds,
                periodic_box,
            })
            .map_err(|e| self.error_at(offset, e))?;
            masses = built.masses;
            elements = built.elements;
            forcefield_report = built.report;
            forcefield_parameters = Some(built.parameters);
            forcefield_report.insert(
                0,
                format!(
                    "force field: {} atoms, {} bonds ({}), box {}; units real: Å, fs, amu, kcal/mol, e",
                    n_particles,
                    bonds.len(),
                    if structure.bonds.is_empty() {
                        "none perceived or listed"
                    } else {
                        "from the file or perceived by chemfiles"
                    },
                    match periodic_box {
                        Some(b) => format!("{:?}", b.lengths),
                        None => "none".into(),
                    }
                ),
            );
            terms.extend(built.terms);
        }
        // Internal masses (real units: kcal/mol·fs²/Å², see `units`); momenta scale with them.
        for m in &mut masses {
            *m = units.mass(*m);
        }
        for pk in &mut p {
            *pk = units.mass(*pk);
        }
        if let Some(spec) = file.structure.as_ref().map(|s| s.get_ref())
            && let Some(velocities) = &spec.velocities
        {
            let path = self
                .path
                .parent()
                .unwrap_or(Path::new("."))
                .join(velocities);
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
        }
        let forces = ForceSplit::new(terms).map_err(|e| self.error(e.to_string()))?;

        let state = State { t: 0.0, q, p };
        let mut system = System::new(
            dim,
            Particles { names, masses },
            state,
            forces,
            periodic_box,
        );
        if let Some(mass_matrix) = mass_matrix {
            system = system.with_mass_matrix(mass_matrix);
        }
        self.check_finite_start(&system)?;
        let exact = match &file.exact {
            Some(spanned) => Some(self.exact_solution(spanned, dim, &parameters)?),
            None => None,
        };

        Ok(Scene {
            name: file.name.clone(),
            description: file.description.clone(),
            path: self.path.to_path_buf(),
            parameters,
            system,
            run: file.run.clone(),
            output: file.output.clone(),
            exact,
            units,
            elements,
            forcefield_report,
            forcefield_parameters,
        })
    }

    /// The `[mass_matrix]` table: the full matrix, or `None` after lumping it into `masses`.
    fn mass_matrix(
        &self,
        spanned: &Spanned<MassMatrixSpec>,
        dim: usize,
        masses: &mut [f64],
        names: &Names,
        parameters: &BTreeMap<String, f64>,
    ) -> Result<Option<MassMatrix>> {
        let offset = spanned.span().start;
        let spec = spanned.get_ref();
        let what = "[mass_matrix]";
        let value = self.evaluate(
            &spec.off_diagonal,
            parameters,
            "[mass_matrix] off_diagonal",
            offset,
        )?;
        let pairs: Vec<(usize, usize)> = match &spec.pairs {
            MassPairs::Keyword(word) if word == "chain" => {
                (1..masses.len()).map(|i| (i - 1, i)).collect()
            }
            MassPairs::Keyword(other) => {
                return Err(self.error_at(
                    offset,
                    format!("{what}: pairs must be \"chain\" or a list of pairs, got \"{other}\""),
                ));
            }
            MassPairs::List(list) => list
                .iter()
                .map(|[a, b]| {
                    Ok((
                        self.particle(a, names, what, offset)?,
                        self.particle(b, names, what, offset)?,
                    ))
                })
                .collect::<Result<_>>()?,
        };
        let entries: Vec<(usize, usize, f64)> = pairs.iter().map(|&(i, j)| (i, j, value)).collect();
        let matrix = MassMatrix::new(dim, masses, &entries)
            .map_err(|e| self.error_at(offset, format!("{what}: {e}")))?;
        if spec.lump.unwrap_or(false) {
            let lumped = matrix.row_sums();
            if let Some(i) = lumped.iter().position(|&m| m.is_nan() || m <= 0.0) {
                return Err(self.error_at(
                    offset,
                    format!(
                        "{what}: lumped mass of particle {i} is {} (not positive)",
                        lumped[i]
                    ),
                ));
            }
            masses.copy_from_slice(&lumped);
            return Ok(None);
        }
        Ok(Some(matrix))
    }

    fn exact_solution(
        &self,
        spanned: &Spanned<ExactSpec>,
        dim: usize,
        parameters: &BTreeMap<String, f64>,
    ) -> Result<Box<dyn ExactSolution>> {
        let offset = spanned.span().start;
        let solution: Box<dyn ExactSolution> = match spanned.get_ref() {
            ExactSpec::Expression { position } => {
                if position.len() != dim {
                    return Err(self.error_at(
                        offset,
                        format!(
                            "[exact] position has {} components, but the scene has dim = {dim}",
                            position.len()
                        ),
                    ));
                }
                Box::new(ExpressionSolution {
                    dim,
                    position: position.clone(),
                    parameters: parameters.clone(),
                })
            }
            ExactSpec::TwoMediaWave {
                c1,
                c2,
                interface,
                pulse,
                support,
                node,
            } => {
                let positive = |v: &Value, key: &str| -> Result<f64> {
                    let x = self.evaluate(v, parameters, &format!("[exact] {key}"), offset)?;
                    if x <= 0.0 {
                        return Err(self
                            .error_at(offset, format!("[exact] {key} must be positive, got {x}")));
                    }
                    Ok(x)
                };
                let support = (
                    self.evaluate(&support[0], parameters, "[exact] support", offset)?,
                    self.evaluate(&support[1], parameters, "[exact] support", offset)?,
                );
                Box::new(TwoMediaWave {
                    c1: positive(c1, "c1")?,
                    c2: positive(c2, "c2")?,
                    interface: positive(interface, "interface")?,
                    pulse: pulse.clone(),
                    support,
                    node: node.clone(),
                    parameters: parameters.clone(),
                })
            }
        };
        // Evaluate once now, so a typo is a scene error and not a failure after the run.
        let mut probe = vec![0.0; dim];
        solution
            .positions(0.0, &mut probe)
            .map_err(|e| self.error_at(offset, e.to_string()))?;
        Ok(solution)
    }

    /// The bonds of a structure: listed in the file or perceived by chemfiles, plus the
    /// scene's `bonds` (repeated over blocks of `bond_repeat` atoms) and `chains`.
    fn structure_bonds(
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

    /// `[parameters]` with the `--set` overrides applied, each evaluated once (they may
    /// refer to one another, without cycles).
    fn resolve_parameters(
        &self,
        raw: &BTreeMap<String, Value>,
        overrides: &[String],
    ) -> Result<BTreeMap<String, f64>> {
        let mut raw = raw.clone();
        for setting in overrides {
            let Some((name, text)) = setting.split_once('=') else {
                return Err(Error::input(format!(
                    "--set expects name=value, got \"{setting}\""
                )));
            };
            let name = name.trim();
            if !raw.contains_key(name) {
                let known: Vec<&str> = raw.keys().map(String::as_str).collect();
                return Err(Error::input(format!(
                    "--set {name}: the scene {} has no parameter \"{name}\" (it has: {})",
                    self.path.display(),
                    if known.is_empty() {
                        "none".to_string()
                    } else {
                        known.join(", ")
                    }
                )));
            }
            let text = text.trim();
            let value = match text.parse::<f64>() {
                Ok(number) => Value::Number(number),
                Err(_) => Value::Expression(text.to_string()),
            };
            raw.insert(name.to_string(), value);
        }
        let mut resolved = BTreeMap::new();
        for name in raw.keys() {
            self.resolve_parameter(name, &raw, &mut resolved, &mut Vec::new())?;
        }
        Ok(resolved)
    }

    fn resolve_parameter(
        &self,
        name: &str,
        raw: &BTreeMap<String, Value>,
        resolved: &mut BTreeMap<String, f64>,
        stack: &mut Vec<String>,
    ) -> Result<f64> {
        if let Some(&value) = resolved.get(name) {
            return Ok(value);
        }
        if stack.iter().any(|n| n == name) {
            stack.push(name.to_string());
            return Err(self.error(format!(
                "parameters refer to each other in a cycle: {}",
                stack.join(" -> ")
            )));
        }
        let value = match &raw[name] {
            Value::Number(x) => *x,
            Value::Expression(text) => {
                stack.push(name.to_string());
                let dependencies = expr::referenced_names(text)
                    .map_err(|e| self.error(format!("parameter \"{name}\": {e}")))?;
                for dependency in dependencies {
                    if raw.contains_key(&dependency) {
                        self.resolve_parameter(&dependency, raw, resolved, stack)?;
                    }
                }
                stack.pop();
                expr::evaluate(text, resolved)
                    .map_err(|e| self.error(format!("parameter \"{name}\": {e}")))?
            }
        };
        if !value.is_finite() {
            return Err(self.error(format!("parameter \"{name}\" is not finite ({value})")));
        }
        resolved.insert(name.to_string(), value);
        Ok(value)
    }

    fn evaluate(
        &self,
        v: &Value,
        parameters: &BTreeMap<String, f64>,
        what: &str,
        offset: usize,
    ) -> Result<f64> {
        let value = match v {
            Value::Number(x) => *x,
            Value::Expression(text) => expr::evaluate(text, parameters)
                .map_err(|e| self.error_at(offset, format!("{what}: {e}")))?,
        };
        if !value.is_finite() {
            return Err(self.error_at(offset, format!("{what} is not finite ({value})")));
        }
        Ok(value)
    }

    fn vector(
        &self,
        values: &[Value],
        dim: usize,
        parameters: &BTreeMap<String, f64>,
        what: &str,
        offset: usize,
    ) -> Result<Vec<f64>> {
        if values.len() != dim {
            return Err(self.error_at(
                offset,
                format!(
                    "{what} has {} components, but the scene has dim = {dim}",
                    values.len()
                ),
            ));
        }
        values
            .iter()
            .map(|v| self.evaluate(v, parameters, what, offset))
            .collect()
    }

    fn site(
        &self,
        reference: &Reference,
        names: &Names,
        what: &str,
        offset: usize,
    ) -> Result<Site> {
        match reference {
            Reference::Index(i) if *i < names.n_particles => Ok(Site::Particle(*i)),
            Reference::Index(i) => Err(self.error_at(
                offset,
                format!(
                    "{what} names particle {i}, but the scene has {} particles (0 to {})",
                    names.n_particles,
                    names.n_particles.saturating_sub(1)
                ),
            )),
            Reference::Name(name) => names.sites.get(name).copied().ok_or_else(|| {
                self.error_at(
                    offset,
                    format!("{what} names \"{name}\", which is no particle or anchor"),
                )
            }),
        }
    }

    fn particle(
        &self,
        reference: &Reference,
        names: &Names,
        what: &str,
        offset: usize,
    ) -> Result<usize> {
        match self.site(reference, names, what, offset)? {
            Site::Particle(i) => Ok(i),
            Site::Fixed(_) => Err(self.error_at(
                offset,
                format!("{what}: {reference} is an anchor, but a particle is needed here"),
            )),
        }
    }

    /// The sites of a chain-like term: `start`, then `particles` (or `range`, or every
    /// particle), then `end`; consecutive sites are linked.
    #[allow(clippy::too_many_arguments)]
    fn chain_sites(
        &self,
        particles: &Option<Vec<Reference>>,
        range: &Option<[Value; 2]>,
        start: &Option<Reference>,
        end: &Option<Reference>,
        names: &Names,
        parameters: &BTreeMap<String, f64>,
        what: &str,
        offset: usize,
    ) -> Result<Vec<Site>> {
        let members = match (particles, range) {
            (Some(_), Some(_)) => {
                return Err(self.error_at(
                    offset,
                    format!("{what} gives both particles and range; give one"),
                ));
            }
            (_, Some([first, last])) => {
                let index = |v: &Value, key: &str| -> Result<usize> {
                    let x =
                        self.evaluate(v, parameters, &format!("{what}: range {key}"), offset)?;
                    if x < 0.0 || x.fract() != 0.0 || x as usize >= names.n_particles {
                        return Err(self.error_at(
                            offset,
                            format!(
                                "{what}: range {key} = {x} is not a particle index (0 to {})",
                                names.n_particles.saturating_sub(1)
                            ),
                        ));
                    }
                    Ok(x as usize)
                };
                let (first, last) = (index(first, "first")?, index(last, "last")?);
                if last < first {
                    return Err(
                        self.error_at(offset, format!("{what}: range [{first}, {last}] is empty"))
                    );
                }
                (first..=last).collect()
            }
            (list, None) => self.particle_list(list, names, what, offset)?,
        };
        let mut sites = Vec::with_capacity(members.len() + 2);
        if let Some(reference) = start {
            sites.push(self.site(reference, names, what, offset)?);
        }
        sites.extend(members.into_iter().map(Site::Particle));
        if let Some(reference) = end {
            sites.push(self.site(reference, names, what, offset)?);
        }
        Ok(sites)
    }

    fn particle_list(
        &self,
        list: &Option<Vec<Reference>>,
        names: &Names,
        what: &str,
        offset: usize,
    ) -> Result<Vec<usize>> {
        match list {
            None => Ok((0..names.n_particles).collect()),
            Some(list) => list
                .iter()
                .map(|r| self.particle(r, names, what, offset))
                .collect(),
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn build_term(
        &self,
        spanned: &Spanned<TermSpec>,
        index: usize,
        dim: usize,
        parameters: &BTreeMap<String, f64>,
        names: &Names,
        q: &[f64],
        masses: &[f64],
        periodic_box: Option<PeriodicBox>,
    ) -> Result<(String, Box<dyn ForceTerm>, Assignment)> {
        let offset = spanned.span().start;
        let spec = spanned.get_ref();
        let (name, group, level) = match spec {
            TermSpec::Spring {
                name, group, level, ..
            }
            | TermSpec::Chain {
                name, group, level, ..
            }
            | TermSpec::QuarticSpring {
                name, group, level, ..
            }
            | TermSpec::Angle {
                name, group, level, ..
            }
            | TermSpec::Field {
                name, group, level, ..
            }
            | TermSpec::LennardJones {
                name, group, level, ..
            }
            | TermSpec::Gravity {
                name, group, level, ..
            }
            | TermSpec::Pendulum {
                name, group, level, ..
            }
            | TermSpec::InversePower {
                name, group, level, ..
            }
            | TermSpec::Magnetic {
                name, group, level, ..
            }
            | TermSpec::ExternalField {
                name, group, level, ..
            }
            | TermSpec::FemString {
                name, group, level, ..
            } => (name, *group, *level),
        };
        let label = name.clone().unwrap_or_else(|| format!("term {index}"));
        let what = format!("term \"{label}\"");
        let assignment = match (group, level) {
            (Some(_), Some(_)) => {
                return Err(self.error_at(
                    offset,
                    format!("{what} gives both group and level; give one"),
                ));
            }
            (Some(Group::Fast), None) => Assignment::Fast,
            (Some(Group::Slow), None) => Assignment::Slow,
            (None, Some(level)) => Assignment::Level(level),
            (None, None) => Assignment::Default,
        };
        let number =
            |v: &Value, key: &str| self.evaluate(v, parameters, &format!("{what}: {key}"), offset);
        let non_negative = |v: &Value, key: &str| -> Result<f64> {
            let x = number(v, key)?;
            if x < 0.0 {
                return Err(self.error_at(offset, format!("{what}: {key} must be ≥ 0, got {x}")));
            }
            Ok(x)
        };
        let position = |site: &Site| -> [f64; 3] {
            match *site {
                Site::Particle(i) => {
                    let mut x = [0.0; 3];
                    x[..dim].copy_from_slice(&q[i * dim..(i + 1) * dim]);
                    x
                }
                Site::Fixed(x) => x,
            }
        };
        let distance = |a: &Site, b: &Site| -> f64 {
            let (xa, xb) = (position(a), position(b));
            (0..dim)
                .map(|k| {
                    let mut d = xb[k] - xa[k];
                    if let Some(pb) = &periodic_box {
                        d = pb.wrap(k, d);
                    }
                    d * d
                })
                .sum::<f64>()
                .sqrt()
        };
        // "geometry" (the default) takes a rest length from the starting positions.
        let rest_length =
            |value: &Option<Value>, a: &Site, b: &Site, default_geometry: bool| -> Result<f64> {
                match value {
                    Some(Value::Expression(text)) if text == "geometry" => Ok(distance(a, b)),
                    Some(v) => non_negative(v, "rest_length"),
                    None if default_geometry => Ok(distance(a, b)),
                    None => Ok(0.0),
                }
            };
        let pairs_of = |between: &Option<[Reference; 2]>,
                        pairs: &Option<Vec<[Reference; 2]>>|
         -> Result<Vec<(Site, Site)>> {
            let list: Vec<&[Reference; 2]> = match (between, pairs) {
                (Some(one), None) => vec![one],
                (None, Some(many)) => many.iter().collect(),
                _ => {
                    return Err(self.error_at(
                        offset,
                        format!("{what} needs exactly one of `between` or `pairs`"),
                    ));
                }
            };
            list.into_iter()
                .map(|[a, b]| {
                    let sa = self.site(a, names, &what, offset)?;
                    let sb = self.site(b, names, &what, offset)?;
                    if matches!((sa, sb), (Site::Fixed(_), Site::Fixed(_))) {
                        return Err(self.error_at(
                            offset,
                            format!(
                                "{what} joins two anchors ({a} and {b}); one end must be a particle"
                            ),
                        ));
                    }
                    if sa.particle().is_some() && sa == sb {
                        return Err(self.error_at(offset, format!("{what} joins {a} to itself")));
                    }
                    Ok((sa, sb))
                })
                .collect()
        };

        // The pairs of a spring-like term with their rest lengths.
        let pairs_at_rest = |between: &Option<[Reference; 2]>,
                             pairs: &Option<Vec<[Reference; 2]>>,
                             rest: &Option<Value>|
         -> Result<Vec<(Site, Site, f64)>> {
            pairs_of(between, pairs)?
                .into_iter()
                .map(|(a, b)| Ok((a, b, rest_length(rest, &a, &b, false)?)))
                .collect()
        };
        let term: Box<dyn ForceTerm> = match spec {
            TermSpec::Spring {
                between,
                pairs,
                stiffness,
                rest_length: rest,
                ..
            } => {
                let stiffness = non_negative(stiffness, "stiffness")?;
                let springs = pairs_at_rest(between, pairs, rest)?
                    .into_iter()
                    .map(|(a, b, rest_length)| {
                        let bond = HarmonicBond {
                            stiffness,
                            rest_length,
                        };
                        (a, b, bond)
                    })
                    .collect();
                Box::new(harmonic_springs(dim, springs, periodic_box))
            }
            TermSpec::Chain {
                particles,
                stiffness,
                rest_length: rest,
                range,
                start,
                end,
                ..
            } => {
                let chain = self.chain_sites(
                    particles, range, start, end, names, parameters, &what, offset,
                )?;
                if chain.len() < 2 {
                    return Err(self.error_at(
                        offset,
                        format!("{what}: a chain needs at least two particles"),
                    ));
                }
                // The stiffness may vary along the chain: it sees the link index `i`.
                let mut local = parameters.clone();
                let springs = chain
                    .windows(2)
                    .enumerate()
                    .map(|(i, link)| {
                        local.insert("i".to_string(), i as f64);
                        let stiffness = self.evaluate(
                            stiffness,
                            &local,
                            &format!("{what}: stiffness"),
                            offset,
                        )?;
                        if stiffness < 0.0 {
                            return Err(self.error_at(
                                offset,
                                format!(
                                    "{what}: stiffness of link {i} must be ≥ 0, got {stiffness}"
                                ),
                            ));
                        }
                        let (a, b) = (link[0], link[1]);
                        let rest_length = rest_length(rest, &a, &b, true)?;
                        Ok((
                            a,
                            b,
                            HarmonicBond {
                                stiffness,
                                rest_length,
                            },
                        ))
                    })
                    .collect::<Result<Vec<_>>>()?;
                Box::new(harmonic_springs(dim, springs, periodic_box))
            }
            TermSpec::QuarticSpring {
                between,
                pairs,
                coefficient,
                rest_length: rest,
                ..
            } => {
                let coefficient = non_negative(coefficient, "coefficient")?;
                let springs = pairs_at_rest(between, pairs, rest)?
                    .into_iter()
                    .map(|(a, b, rest_length)| {
                        let bond = QuarticBond {
                            coefficient,
                            rest_length,
                        };
                        (a, b, bond)
                    })
                    .collect();
                Box::new(quartic_springs(dim, springs, periodic_box))
            }
            TermSpec::Angle {
                between,
                triples,
                stiffness,
                rest_angle,
                ..
            } => {
                if dim < 2 {
                    return Err(self.error_at(
                        offset,
                        format!("{what}: angles need dim = 2 or 3 (in 1-D every angle is 0 or π)"),
                    ));
                }
                let stiffness = non_negative(stiffness, "stiffness")?;
                let list: Vec<&[Reference; 3]> = match (between, triples) {
                    (Some(one), None) => vec![one],
                    (None, Some(many)) => many.iter().collect(),
                    _ => {
                        return Err(self.error_at(
                            offset,
                            format!("{what} needs exactly one of `between` or `triples`"),
                        ));
                    }
                };
                let angles = list
                    .into_iter()
                    .map(|triple| {
                        let sites = [
                            self.site(&triple[0], names, &what, offset)?,
                            self.site(&triple[1], names, &what, offset)?,
                            self.site(&triple[2], names, &what, offset)?,
                        ];
                        let rest_angle = match rest_angle {
                            Some(Value::Expression(text)) if text == "geometry" => geometric_angle(
                                position(&sites[0]),
                                position(&sites[1]),
                                position(&sites[2]),
                            ),
                            Some(v) => number(v, "rest_angle")?,
                            None => geometric_angle(
                                position(&sites[0]),
                                position(&sites[1]),
                                position(&sites[2]),
                            ),
                        };
                        Ok(AngleBend {
                            sites,
                            stiffness,
                            rest_angle,
                        })
                    })
                    .collect::<Result<Vec<_>>>()?;
                Box::new(HarmonicAngles::new(dim, angles, periodic_box))
            }
            TermSpec::LennardJones {
                particles,
                epsilon,
                sigma,
                cutoff,
                shift,
                exclude,
                ..
            } => {
                let epsilon = non_negative(epsilon, "epsilon")?;
                let sigma = number(sigma, "sigma")?;
                if sigma <= 0.0 {
                    return Err(self.error_at(
                        offset,
                        format!("{what}: sigma must be positive, got {sigma}"),
                    ));
                }
                let cutoff = match cutoff {
                    Some(v) => {
                        let c = number(v, "cutoff")?;
                        if c <= 0.0 {
                            return Err(self.error_at(
                                offset,
                                format!("{what}: cutoff must be positive, got {c}"),
                            ));
                        }
                        c
                    }
                    None => f64::INFINITY,
                };
                let members = self.particle_list(particles, names, &what, offset)?;
                let excluded = exclude
                    .iter()
                    .map(|[a, b]| {
                        Ok((
                            self.particle(a, names, &what, offset)?,
                            self.particle(b, names, &what, offset)?,
                        ))
                    })
                    .collect::<Result<Vec<_>>>()?;
                Box::new(lennard_jones_pairs(
                    dim,
                    &members,
                    &excluded,
                    LennardJones::new(epsilon, sigma, cutoff, shift.unwrap_or(true)),
                    periodic_box,
                ))
            }
            TermSpec::Gravity {
                particles,
                constant,
                center,
                center_mass,
                ..
            } => {
                let g = match constant {
                    Some(v) => non_negative(v, "constant")?,
                    None => 1.0,
                };
                let members = self.particle_list(particles, names, &what, offset)?;
                let center = match (center, center_mass) {
                    (Some(anchor), mass) => {
                        let position = match names.sites.get(anchor) {
                            Some(Site::Fixed(x)) => *x,
                            _ => {
                                return Err(self.error_at(
                                    offset,
                                    format!("{what}: center \"{anchor}\" is not an anchor"),
                                ));
                            }
                        };
                        let mass = match mass {
                            Some(v) => non_negative(v, "center_mass")?,
                            None => 1.0,
                        };
                        Some(CentralMass { position, mass })
                    }
                    (None, Some(_)) => {
                        return Err(self.error_at(
                            offset,
                            format!("{what}: center_mass needs a center anchor"),
                        ));
                    }
                    (None, None) => None,
                };
                Box::new(gravity(dim, g, &members, masses, center))
            }
            TermSpec::Field {
                particles, force, ..
            } => {
                let members = self.particle_list(particles, names, &what, offset)?;
                let vector =
                    self.vector(force, dim, parameters, &format!("{what}: force"), offset)?;
                let mut force = [0.0; 3];
                force[..dim].copy_from_slice(&vector);
                Box::new(UniformField::new(dim, members, force))
            }
            TermSpec::FemString {
                particles,
                range,
                start,
                end,
                element_length,
                alpha,
                ..
            } => {
                let sites = self.chain_sites(
                    particles, range, start, end, names, parameters, &what, offset,
                )?;
                if sites.len() < 2 {
                    return Err(
                        self.error_at(offset, format!("{what}: a string needs at least two sites"))
                    );
                }
                let length = number(element_length, "element_length")?;
                if length <= 0.0 {
                    return Err(self.error_at(
                        offset,
                        format!("{what}: element_length must be positive, got {length}"),
                    ));
                }
                let alpha = number(alpha, "alpha")?;
                if !(0.0..1.0).contains(&alpha) {
                    return Err(self.error_at(
                        offset,
                        format!("{what}: alpha must be in [0, 1) (convex energy), got {alpha}"),
                    ));
                }
                Box::new(FemString::new(dim, sites, length, alpha))
            }
            TermSpec::Pendulum {
                particles,
                strength,
                axis,
                ..
            } => {
                let strength = number(strength, "strength")?;
                let axis = axis.unwrap_or(0);
                if axis >= dim {
                    return Err(self.error_at(
                        offset,
                        format!("{what}: axis {axis} does not exist in dim = {dim}"),
                    ));
                }
                let members = self.particle_list(particles, names, &what, offset)?;
                Box::new(Pendulum::new(
                    dim,
                    members.into_iter().map(|i| (i, axis, strength)).collect(),
                ))
            }
            TermSpec::InversePower {
                between,
                pairs,
                coefficient,
                power,
                softening,
                ..
            } => {
                let coefficient = number(coefficient, "coefficient")?;
                let power = number(power, "power")?;
                if power <= 0.0 {
                    return Err(self.error_at(
                        offset,
                        format!("{what}: power must be positive, got {power}"),
                    ));
                }
                let softening = match softening {
                    Some(v) => non_negative(v, "softening")?,
                    None => 0.0,
                };
                let interactions = pairs_of(between, pairs)?
                    .into_iter()
                    .map(|(a, b)| {
                        (
                            a,
                            b,
                            InversePower {
                                coefficient,
                                power,
                                softening,
                            },
                        )
                    })
                    .collect();
                Box::new(inverse_power_pairs(dim, interactions, periodic_box))
            }
            TermSpec::Magnetic {
                particles,
                field,
                strength,
                charge,
                ..
            } => {
                let vector_potential = match (field.as_str(), strength) {
                    ("uniform", Some(b)) => VectorPotential::Uniform {
                        strength: number(b, "strength")?,
                    },
                    ("uniform", None) => {
                        return Err(self.error_at(
                            offset,
                            format!("{what}: the uniform field needs its strength B"),
                        ));
                    }
                    ("cfm25-singular", None) => VectorPotential::Cfm25Singular,
                    ("cfm25-singular", Some(_)) => {
                        return Err(self.error_at(
                            offset,
                            format!("{what}: the cfm25-singular field takes no strength"),
                        ));
                    }
                    (other, _) => {
                        return Err(self.error_at(
                            offset,
                            format!(
                                "{what}: unknown magnetic field \"{other}\"; known: \
                                 uniform, cfm25-singular"
                            ),
                        ));
                    }
                };
                let needed = match vector_potential {
                    VectorPotential::Uniform { .. } => 2,
                    VectorPotential::Cfm25Singular => 3,
                };
                if dim < needed {
                    return Err(self.error_at(
                        offset,
                        format!("{what}: the {field} magnetic field needs dim ≥ {needed}"),
                    ));
                }
                let charge = match charge {
                    Some(v) => number(v, "charge")?,
                    None => 1.0,
                };
                let members = self.particle_list(particles, names, &what, offset)?;
                Box::new(MagneticTerm::new(
                    dim,
                    vector_potential,
                    members.into_iter().map(|i| (i, charge)).collect(),
                ))
            }
            TermSpec::ExternalField {
                particles,
                field,
                charge,
                ..
            } => {
                let shape = match field.as_str() {
                    "cfm25-trigonometric" => FieldShape::Cfm25Trigonometric,
                    other => {
                        return Err(self.error_at(
                            offset,
                            format!(
                                "{what}: unknown external field \"{other}\"; known: \
                                 cfm25-trigonometric"
                            ),
                        ));
                    }
                };
                if dim != 3 {
                    return Err(
                        self.error_at(offset, format!("{what}: the {field} field needs dim = 3"))
                    );
                }
                let charge = match charge {
                    Some(v) => number(v, "charge")?,
                    None => 1.0,
                };
                let members = self.particle_list(particles, names, &what, offset)?;
                Box::new(ExternalField::new(
                    shape,
                    members.into_iter().map(|i| (i, charge)).collect(),
                ))
            }
        };
        Ok((label, term, assignment))
    }

    /// The initial energy and forces of every term must be finite (overlapping particles,
    /// a zero-length spring with a rest length, a particle on a gravitating centre).
    fn check_finite_start(&self, system: &System) -> Result<()> {
        let q = &system.state.q;
        let mut gradient = vec![0.0; q.len()];
        for term in system.forces.terms() {
            gradient.fill(0.0);
            term.term.add_gradient(q, &mut gradient);
            let energy = term.term.energy(q);
            if !energy.is_finite() || gradient.iter().any(|g| !g.is_finite()) {
                return Err(self.error(format!(
                    "{} \"{}\" has a non-finite energy or force at the starting positions \
                     (overlapping particles?)",
                    term.term.kind(),
                    term.name
                )));
            }
        }
        Ok(())
    }
}

fn geometric_angle(a: [f64; 3], vertex: [f64; 3], c: [f64; 3]) -> f64 {
    let u: Vec<f64> = (0..3).map(|k| a[k] - vertex[k]).collect();
    let w: Vec<f64> = (0..3).map(|k| c[k] - vertex[k]).collect();
    let dot: f64 = u.iter().zip(&w).map(|(x, y)| x * y).sum();
    let cross = [
        u[1] * w[2] - u[2] * w[1],
        u[2] * w[0] - u[0] * w[2],
        u[0] * w[1] - u[1] * w[0],
    ];
    let cross_norm = cross.iter().map(|x| x * x).sum::<f64>().sqrt();
    cross_norm.atan2(dot)
}
