//! The scene file as written: every table and key of schema version 1 (`docs/scenes.md`).

use std::collections::BTreeMap;

use serde::Deserialize;
use toml::Spanned;

use crate::io::forcefield::{ElectrostaticsOverrides, ForcefieldSpec};
use crate::settings::{RunSpec, Value};

/// A particle by 0-based index or by name; a name may also be an anchor's.
#[derive(Clone, Debug)]
pub enum Reference {
    Index(usize),
    Name(String),
}

/// By hand, so a wrong type says what a reference is (not serde's "untagged enum").
impl<'de> Deserialize<'de> for Reference {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl serde::de::Visitor<'_> for Visitor {
            type Value = Reference;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a particle index (0, 1, …) or a particle name in quotes")
            }
            fn visit_u64<E: serde::de::Error>(self, i: u64) -> Result<Reference, E> {
                usize::try_from(i)
                    .map(Reference::Index)
                    .map_err(|_| E::invalid_value(serde::de::Unexpected::Unsigned(i), &self))
            }
            fn visit_i64<E: serde::de::Error>(self, i: i64) -> Result<Reference, E> {
                u64::try_from(i)
                    .map_err(|_| E::invalid_value(serde::de::Unexpected::Signed(i), &self))
                    .and_then(|i| self.visit_u64(i))
            }
            fn visit_str<E>(self, name: &str) -> Result<Reference, E> {
                Ok(Reference::Name(name.to_string()))
            }
        }
        deserializer.deserialize_any(Visitor)
    }
}

impl std::fmt::Display for Reference {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Reference::Index(i) => write!(f, "particle {i}"),
            Reference::Name(name) => write!(f, "\"{name}\""),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Group {
    Fast,
    Slow,
}

/// By hand, so a wrong value reads "expected \"fast\" or \"slow\"".
impl<'de> Deserialize<'de> for Group {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl serde::de::Visitor<'_> for Visitor {
            type Value = Group;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("\"fast\" or \"slow\" (a term's `group`)")
            }
            fn visit_str<E: serde::de::Error>(self, text: &str) -> Result<Group, E> {
                match text {
                    "fast" => Ok(Group::Fast),
                    "slow" => Ok(Group::Slow),
                    _ => Err(E::invalid_value(serde::de::Unexpected::Str(text), &self)),
                }
            }
        }
        deserializer.deserialize_any(Visitor)
    }
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
    /// A complete force field and its atoms from a topology file (AMBER prmtop).
    pub topology: Option<Spanned<TopologySpec>>,
}

/// `[topology]`: the atoms, their coordinates and every force-field term from a
/// simulation package's files (`src/io/topology`), in place of `[structure]` and
/// `[forcefield]`.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TopologySpec {
    /// The topology (`.prmtop`, `.parm7`; GROMACS `.top`), relative to the scene file.
    pub file: String,
    /// Its coordinates (`.inpcrd`, `.rst7`, `.crd`, `.gro`); default: the topology's name
    /// with one of these extensions (`.gro` first for a `.top`).
    pub coordinates: Option<String>,
    /// Start velocities from this file (`.rst7`/`.inpcrd` with velocities, or a `.gro` with
    /// velocity columns) instead of the coordinates' own; same atoms in the same order.
    pub velocities: Option<String>,
    /// Non-bonded cutoff (Å); default none in vacuum with plain Coulomb, else 9.
    pub cutoff: Option<f64>,
    /// `none` (plain Coulomb without cutoff, vacuum), `reaction-field` or `dsf`; default
    /// none without a box, reaction field with one.
    pub coulomb: Option<String>,
    /// Reaction-field dielectric, default 78.3 (OpenMM's).
    pub epsilon_rf: Option<f64>,
    /// DSF damping α (1/Å), default 0.
    pub dsf_alpha: Option<f64>,
    /// Neighbour-list skin (Å), default 6 (`io::topology::build::DEFAULT_SKIN`).
    pub skin: Option<f64>,
    /// The pruned inner list's buffer (Å, at most the skin), default a third of the skin,
    /// 2 Å of the default 6 (`io::topology::build::DEFAULT_INNER_FRACTION`).
    pub inner_buffer: Option<f64>,
    /// Shift the Lennard-Jones energy to zero at the cutoff; default false (OpenMM).
    pub lj_shift: Option<bool>,
    /// PME (`coulomb = "pme"`): as the `[forcefield]` keys of the same names.
    pub ewald_tolerance: Option<f64>,
    pub fourier_spacing: Option<f64>,
    pub ewald_alpha: Option<crate::io::forcefield::InverseLength>,
    pub pme_grid: Option<[usize; 3]>,
    pub pme_order: Option<usize>,
    /// The level of the `pme-reciprocal` term (default: the slowest).
    pub pme_level: Option<usize>,
    /// The level of the cutoff (real-space) term (default: the slowest).
    pub nonbonded_level: Option<usize>,
    /// The cutoff term split by distance across two levels (`[topology.split]`, the
    /// keys of `[forcefield.split]`; by atom pair unless `by = "molecule"`).
    pub split: Option<crate::io::forcefield::SplitSection>,
    /// A GROMACS topology's preprocessor defines (`"FLEXIBLE"`, `"NAME=value"`), as
    /// `grompp`'s `define = -DFLEXIBLE`.
    pub defines: Option<Vec<String>>,
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

#[derive(Debug)]
pub enum MassPairs {
    Keyword(String),
    List(Vec<[Reference; 2]>),
}

/// By hand, so a wrong type says what `pairs` takes.
impl<'de> Deserialize<'de> for MassPairs {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl<'de> serde::de::Visitor<'de> for Visitor {
            type Value = MassPairs;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("\"chain\" or a list of particle pairs such as [[0, 1], [1, 2]]")
            }
            fn visit_str<E>(self, keyword: &str) -> Result<MassPairs, E> {
                Ok(MassPairs::Keyword(keyword.to_string()))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                seq: A,
            ) -> Result<MassPairs, A::Error> {
                Deserialize::deserialize(serde::de::value::SeqAccessDeserializer::new(seq))
                    .map(MassPairs::List)
            }
        }
        deserializer.deserialize_any(Visitor)
    }
}

/// `[exact]`: an exact solution (see [`crate::system::exact`]).
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
#[serde(tag = "type", rename_all = "kebab-case")]
pub enum TermSpec {
    /// Harmonic springs `(k/2)(r − L)²`.
    Spring(SpringSpec),
    /// Harmonic springs between consecutive particles of a list (default: all).
    Chain(ChainSpec),
    /// FPU springs `c (r − L)⁴`.
    QuarticSpring(QuarticSpringSpec),
    /// Harmonic angles `(k/2)(θ − θ₀)²` at the middle particle of each triple.
    Angle(AngleSpec),
    /// Lennard-Jones 12-6 between all pairs of a particle list (default: all).
    LennardJones(LennardJonesSpec),
    /// Newtonian gravity among particles and towards an optional fixed central mass.
    Gravity(GravitySpec),
    /// A uniform force `f` on each listed particle (default: all): `V = −Σ f·q_i`.
    Field(FieldSpec),
    /// The P1 finite-element nonlinear string of MEMM18 3.3 over consecutive sites.
    FemString(FemStringSpec),
    /// `k(1 − cos x)` on one coordinate of each particle.
    Pendulum(PendulumSpec),
    /// `c (r + a)^(−n)` between pairs: singular walls (HL97 (3.5)), softened Coulomb.
    InversePower(InversePowerSpec),
    /// A static magnetic field through its vector potential, on charged particles
    /// (CFM25 5.7); only the structural schemes integrate it.
    Magnetic(MagneticSpec),
    /// A fixed external potential `e φ(x)` on 3-D particles (CFM25 5.7.3).
    ExternalField(ExternalFieldSpec),
}

impl TopologySpec {
    /// Replace the keys given in `overrides` (the flags over a scene that reads a
    /// topology), as [`ElectrostaticsOverrides::apply`] does over a `[forcefield]`.
    pub fn apply_electrostatics(&mut self, overrides: &ElectrostaticsOverrides) {
        let mut forcefield = ForcefieldSpec {
            coulomb: self.coulomb.clone(),
            dsf_alpha: self.dsf_alpha,
            rf_dielectric: self.epsilon_rf,
            ewald_tolerance: self.ewald_tolerance,
            fourier_spacing: self.fourier_spacing,
            ewald_alpha: self.ewald_alpha.clone(),
            pme_grid: self.pme_grid,
            pme_order: self.pme_order,
            pme_level: self.pme_level,
            nonbonded_level: self.nonbonded_level,
            split: self.split.clone(),
            ..ForcefieldSpec::default()
        };
        overrides.apply(&mut forcefield);
        self.coulomb = forcefield.coulomb;
        self.dsf_alpha = forcefield.dsf_alpha;
        self.epsilon_rf = forcefield.rf_dielectric;
        self.ewald_tolerance = forcefield.ewald_tolerance;
        self.fourier_spacing = forcefield.fourier_spacing;
        self.ewald_alpha = forcefield.ewald_alpha;
        self.pme_grid = forcefield.pme_grid;
        self.pme_order = forcefield.pme_order;
        self.pme_level = forcefield.pme_level;
        self.nonbonded_level = forcefield.nonbonded_level;
        self.split = forcefield.split;
    }
}

impl TermSpec {
    /// The keys every term has: its name, and its group or level.
    pub fn placement(&self) -> (&Option<String>, Option<Group>, Option<usize>) {
        match self {
            TermSpec::Spring(s) => (&s.name, s.group, s.level),
            TermSpec::Chain(s) => (&s.name, s.group, s.level),
            TermSpec::QuarticSpring(s) => (&s.name, s.group, s.level),
            TermSpec::Angle(s) => (&s.name, s.group, s.level),
            TermSpec::LennardJones(s) => (&s.name, s.group, s.level),
            TermSpec::Gravity(s) => (&s.name, s.group, s.level),
            TermSpec::Field(s) => (&s.name, s.group, s.level),
            TermSpec::FemString(s) => (&s.name, s.group, s.level),
            TermSpec::Pendulum(s) => (&s.name, s.group, s.level),
            TermSpec::InversePower(s) => (&s.name, s.group, s.level),
            TermSpec::Magnetic(s) => (&s.name, s.group, s.level),
            TermSpec::ExternalField(s) => (&s.name, s.group, s.level),
        }
    }
}

/// Harmonic springs `(k/2)(r − L)²`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpringSpec {
    pub name: Option<String>,
    pub between: Option<[Reference; 2]>,
    pub pairs: Option<Vec<[Reference; 2]>>,
    pub stiffness: Value,
    pub rest_length: Option<Value>,
    pub group: Option<Group>,
    pub level: Option<usize>,
}

/// Harmonic springs between consecutive particles of a list (default: all).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChainSpec {
    pub name: Option<String>,
    pub particles: Option<Vec<Reference>>,
    pub stiffness: Value,
    pub rest_length: Option<Value>,
    pub group: Option<Group>,
    pub level: Option<usize>,
    /// Instead of `particles`: the particles `first..=last` by index (expressions).
    pub range: Option<[Value; 2]>,
    /// A site (anchor or particle) linked before the first particle.
    pub start: Option<Reference>,
    /// A site linked after the last particle.
    pub end: Option<Reference>,
}

/// FPU springs `c (r − L)⁴`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct QuarticSpringSpec {
    pub name: Option<String>,
    pub between: Option<[Reference; 2]>,
    pub pairs: Option<Vec<[Reference; 2]>>,
    pub coefficient: Value,
    pub rest_length: Option<Value>,
    pub group: Option<Group>,
    pub level: Option<usize>,
}

/// Harmonic angles `(k/2)(θ − θ₀)²` at the middle particle of each triple.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AngleSpec {
    pub name: Option<String>,
    pub between: Option<[Reference; 3]>,
    pub triples: Option<Vec<[Reference; 3]>>,
    pub stiffness: Value,
    pub rest_angle: Option<Value>,
    pub group: Option<Group>,
    pub level: Option<usize>,
}

/// Lennard-Jones 12-6 between all pairs of a particle list (default: all).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LennardJonesSpec {
    pub name: Option<String>,
    pub particles: Option<Vec<Reference>>,
    pub epsilon: Value,
    pub sigma: Value,
    pub cutoff: Option<Value>,
    pub shift: Option<bool>,
    #[serde(default)]
    pub exclude: Vec<[Reference; 2]>,
    pub group: Option<Group>,
    pub level: Option<usize>,
}

/// Newtonian gravity among particles and towards an optional fixed central mass.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GravitySpec {
    pub name: Option<String>,
    pub particles: Option<Vec<Reference>>,
    pub constant: Option<Value>,
    pub center: Option<String>,
    pub center_mass: Option<Value>,
    pub group: Option<Group>,
    pub level: Option<usize>,
}

/// A uniform force `f` on each listed particle (default: all): `V = −Σ f·q_i`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FieldSpec {
    pub name: Option<String>,
    pub particles: Option<Vec<Reference>>,
    pub force: Vec<Value>,
    pub group: Option<Group>,
    pub level: Option<usize>,
}

/// The P1 finite-element nonlinear string of MEMM18 3.3 over consecutive sites.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FemStringSpec {
    pub name: Option<String>,
    pub particles: Option<Vec<Reference>>,
    pub range: Option<[Value; 2]>,
    pub start: Option<Reference>,
    pub end: Option<Reference>,
    pub element_length: Value,
    pub alpha: Value,
    pub group: Option<Group>,
    pub level: Option<usize>,
}

/// `k(1 − cos x)` on one coordinate of each particle.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PendulumSpec {
    pub name: Option<String>,
    pub particles: Option<Vec<Reference>>,
    pub strength: Value,
    pub axis: Option<usize>,
    pub group: Option<Group>,
    pub level: Option<usize>,
}

/// `c (r + a)^(−n)` between pairs: singular walls (HL97 (3.5)), softened Coulomb.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InversePowerSpec {
    pub name: Option<String>,
    pub between: Option<[Reference; 2]>,
    pub pairs: Option<Vec<[Reference; 2]>>,
    pub coefficient: Value,
    pub power: Value,
    pub softening: Option<Value>,
    pub group: Option<Group>,
    pub level: Option<usize>,
}

/// A static magnetic field through its vector potential, on charged particles
/// (CFM25 5.7); only the structural schemes integrate it.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MagneticSpec {
    pub name: Option<String>,
    pub particles: Option<Vec<Reference>>,
    /// `"uniform"` (`A = (0, B x₁, 0)`) or `"cfm25-singular"`.
    pub field: String,
    /// `B` of the uniform field.
    pub strength: Option<Value>,
    /// The particles' charge `e` (default 1).
    pub charge: Option<Value>,
    pub group: Option<Group>,
    pub level: Option<usize>,
}

/// A fixed external potential `e φ(x)` on 3-D particles (CFM25 5.7.3).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExternalFieldSpec {
    pub name: Option<String>,
    pub particles: Option<Vec<Reference>>,
    /// `"cfm25-trigonometric"`.
    pub field: String,
    /// The particles' charge `e` (default 1).
    pub charge: Option<Value>,
    pub group: Option<Group>,
    pub level: Option<usize>,
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
