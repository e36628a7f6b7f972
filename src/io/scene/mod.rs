//! Scene files: TOML, schema version 1, documented in `docs/scenes.md`.
//!
//! A scene names its dimension, parameters, particles (listed, or read from a structure
//! file through chemfiles), fixed anchors, force terms with their level, and the run.
//! Parsing is strict: an unknown key, a missing particle, a non-positive mass or a vector
//! of the wrong length is an error naming the file, the line and the key.
//!
//! The file as written is [`schema`]; the builder is one file per part of the scene:
//! parameters and values, particles, sites, the box, mass matrix and exact solution, the
//! molecular force field, and the terms (one builder function per term kind).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

mod bonds;
mod fields;
mod molecular;
mod molecule;
mod pairs;
mod particles;
mod schema;
mod sites;
mod system;
mod terms;
mod topology;
mod values;

pub use schema::*;
pub use topology::{
    COORDINATE_EXTENSIONS, default_coordinates, is_topology_path, read_topology_file,
};

use crate::error::{Error, Result};
use crate::forces::ForceTerm;
use crate::io::forcefield::ElectrostaticsOverrides;
use crate::settings::RunSpec;
use crate::split::{Assignment, ForceSplit};
use crate::system::exact::ExactSolution;
use crate::system::{MassMatrix, Particles, PeriodicBox, State, System};
use crate::units::Units;
use particles::Start;
use terms::SceneSoFar;

/// The scene-file format version this build reads.
pub const SCENE_VERSION: u32 = 1;

/// Atoms of a molecule scene closer than this (Å) are an error naming the pair.
pub const OVERLAP_LIMIT: f64 = 0.5;

/// The scene's terms with their names and levels, in the order they are built.
type Terms = Vec<(String, Box<dyn ForceTerm>, Assignment)>;

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
    /// Elements, bonds and angles with their rest values from a topology file (`None`
    /// otherwise: a `[forcefield]` scene's come from `forcefield_parameters`).
    pub bonded: Option<crate::system::topology::BondedTopology>,
    /// The `[structure] velocities` file the start momenta came from, if any.
    pub velocities_file: Option<PathBuf>,
}

/// Read and build a scene; `overrides` are `name=value` settings of its parameters. A
/// topology file (`.prmtop`, `.top`, [`is_topology_path`]) is read as the scene
/// [`topology_scene_text`] writes for it, with the coordinates beside it.
pub fn load_scene(path: &Path, overrides: &[String]) -> Result<Scene> {
    load_scene_with_coordinates(path, None, overrides)
}

/// [`load_scene`], with the coordinates of a topology given (`--coordinates FILE`); a
/// scene file takes none.
pub fn load_scene_with_coordinates(
    path: &Path,
    coordinates: Option<&Path>,
    overrides: &[String],
) -> Result<Scene> {
    let flags = SceneFlags {
        coordinates: coordinates.map(Path::to_path_buf),
        ..SceneFlags::default()
    };
    load_scene_with(path, &flags, overrides)
}

/// The refusal of a folder given as the scene, naming the scenes and topologies in it.
fn folder_error(path: &Path) -> Error {
    let mut inputs: Vec<String> = std::fs::read_dir(path)
        .into_iter()
        .flatten()
        .flatten()
        .map(|entry| entry.path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml") || is_topology_path(p))
        .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .collect();
    inputs.sort();
    let hint = match inputs.len() {
        0 => String::new(),
        n if n <= 6 => format!(" (it holds {})", inputs.join(", ")),
        n => format!(" (it holds {}, … {n} in all)", inputs[..6].join(", ")),
    };
    Error::scene(
        path,
        format!("is a folder: give the scene or topology file in it{hint}"),
    )
    .expected("a scene (.toml) or a topology (.prmtop, .top) file")
}

/// What a command line may say about where a scene comes from: a topology's coordinates
/// and non-bonded settings (`--coordinates`, `--cutoff`, `--epsilon-rf`), and the
/// electrostatics (`--coulomb`, the PME flags) over a scene's `[forcefield]` or a
/// topology's `[topology]`. `None` takes the file's own value.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SceneFlags {
    pub coordinates: Option<PathBuf>,
    pub velocities: Option<PathBuf>,
    pub cutoff: Option<f64>,
    pub epsilon_rf: Option<f64>,
    pub electrostatics: ElectrostaticsOverrides,
    /// A GROMACS topology's preprocessor defines (`--define NAME[=VALUE]`, as
    /// `grompp -D`), added to `[topology] defines`.
    pub defines: Vec<String>,
}

impl SceneFlags {
    /// The given flags as `key = value` (the `[topology]` keys they set), `none` when none
    /// is: for messages, such as a checkpoint's differences.
    pub fn describe(&self) -> String {
        let mut table = toml::Table::new();
        let path = |p: &Option<PathBuf>| p.as_ref().map(|p| p.display().to_string().into());
        for (key, value) in [
            ("coordinates", path(&self.coordinates)),
            ("velocities", path(&self.velocities)),
            ("cutoff", self.cutoff.map(toml::Value::Float)),
            ("epsilon_rf", self.epsilon_rf.map(toml::Value::Float)),
            (
                "defines",
                (!self.defines.is_empty()).then(|| self.defines.clone().into()),
            ),
        ] {
            if let Some(value) = value {
                table.insert(key.into(), value);
            }
        }
        self.electrostatics.write_to(&mut table);
        if table.is_empty() {
            return "none".into();
        }
        table
            .iter()
            .map(|(k, v)| format!("{k} = {v}"))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// [`load_scene`] with the command line's flags: a topology file takes its coordinates and
/// non-bonded settings; a scene file takes only the electrostatics, over its
/// `[forcefield]`.
pub fn load_scene_with(path: &Path, flags: &SceneFlags, overrides: &[String]) -> Result<Scene> {
    if path.is_dir() {
        return Err(folder_error(path));
    }
    if is_topology_path(path) {
        let text = topology_scene_text(path, flags)?;
        return build_scene(&text, path, overrides);
    }
    if flags.coordinates.is_some()
        || flags.velocities.is_some()
        || flags.cutoff.is_some()
        || flags.epsilon_rf.is_some()
    {
        let flag = ["--coordinates", "--velocities", "--cutoff", "--epsilon-rf"]
            .into_iter()
            .zip([
                flags.coordinates.is_some(),
                flags.velocities.is_some(),
                flags.cutoff.is_some(),
                flags.epsilon_rf.is_some(),
            ])
            .find_map(|(flag, given)| given.then_some(flag))
            .unwrap_or("--coordinates");
        return Err(Error::flag(
            flag,
            format!(
                "--coordinates, --velocities, --cutoff and --epsilon-rf are for a topology file \
                 (.prmtop, .top); {} is a scene, whose [topology], [structure] or [forcefield] \
                 says them",
                path.display()
            ),
        ));
    }
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    if flags.electrostatics.is_empty() && flags.defines.is_empty() {
        return build_scene(&text, path, overrides);
    }
    let mut file = parse_scene(&text, path)?;
    if !flags.defines.is_empty() {
        let Some(topology) = file.topology.as_mut() else {
            return Err(Error::flag(
                "--define",
                format!(
                    "--define is for a GROMACS topology (.top); {} is a scene without \
                     [topology]",
                    path.display()
                ),
            ));
        };
        (topology.get_mut().defines.get_or_insert_with(Vec::new)).extend(flags.defines.clone());
    }
    if flags.electrostatics.is_empty() {
        return build_parsed_scene(&file, &text, path, overrides);
    }
    match file.forcefield.as_mut() {
        Some(spec) => flags.electrostatics.apply(spec.get_mut()),
        None if file.topology.is_some() => {
            if let Some(topology) = file.topology.as_mut() {
                topology
                    .get_mut()
                    .apply_electrostatics(&flags.electrostatics);
            }
        }
        None => {
            return Err(Error::scene(
                path,
                "--coulomb and the PME flags need a scene with a [forcefield] section \
                 (or a topology file given in place of the scene)",
            )
            .key("--coulomb"));
        }
    }
    build_parsed_scene(&file, &text, path, overrides).map_err(|e| match e {
        Error::Scene(_) => e.append(" (with the command line's electrostatics flags)"),
        other => other,
    })
}

/// The scene a topology file stands for: `[topology]` with its coordinates (given, or
/// beside it) and the flags, and the run defaults of a molecular system (impulse,
/// h = 2 fs, 4 inner steps: bonded terms at 0.5 fs, non-bonded at 2 fs).
pub fn topology_scene_text(path: &Path, flags: &SceneFlags) -> Result<String> {
    let absolute = |p: &Path| -> Result<String> {
        std::path::absolute(p)
            .map(|a| a.display().to_string())
            .map_err(|e| Error::io(p, e))
    };
    let coordinates = match &flags.coordinates {
        Some(c) => c.clone(),
        None => default_coordinates(path).ok_or_else(|| {
            let beside = COORDINATE_EXTENSIONS
                .iter()
                .map(|e| format!(".{e}"))
                .collect::<Vec<_>>()
                .join(", ");
            Error::topology(
                path,
                format!("no coordinates beside it ({beside}); give --coordinates FILE"),
            )
            .key("--coordinates")
        })?,
    };
    let stem = path
        .file_stem()
        .map_or("topology".into(), |s| s.to_string_lossy().to_string());
    let mut topology = toml::Table::new();
    topology.insert("file".into(), absolute(path)?.into());
    topology.insert("coordinates".into(), absolute(&coordinates)?.into());
    if let Some(velocities) = &flags.velocities {
        topology.insert("velocities".into(), absolute(velocities)?.into());
    }
    if let Some(cutoff) = flags.cutoff {
        topology.insert("cutoff".into(), cutoff.into());
    }
    if !flags.defines.is_empty() {
        topology.insert("defines".into(), flags.defines.clone().into());
    }
    flags.electrostatics.write_to(&mut topology);
    if let Some(epsilon_rf) = flags.epsilon_rf {
        topology.insert("epsilon_rf".into(), epsilon_rf.into());
    }
    let mut run = toml::Table::new();
    run.insert("method".into(), "impulse".into());
    run.insert("h".into(), "2fs".into());
    run.insert("inner_steps".into(), 4.into());
    let mut scene = toml::Table::new();
    scene.insert("version".into(), (SCENE_VERSION as i64).into());
    scene.insert("name".into(), stem.into());
    scene.insert(
        "description".into(),
        format!(
            "topology {} with coordinates {}",
            path.display(),
            coordinates.display()
        )
        .into(),
    );
    scene.insert("dim".into(), 3.into());
    scene.insert("units".into(), "real".into());
    scene.insert("topology".into(), topology.into());
    scene.insert("run".into(), run.into());
    toml::to_string(&scene).map_err(|e| Error::input(format!("cannot write the scene: {e}")))
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
        let (line, key) = match e.span() {
            Some(span) => (
                Some(builder.line_of(span.start)),
                key_before(text, span.start).or_else(|| unknown_field(e.message())),
            ),
            None => (None, None),
        };
        let error = plain_error(path, e.message(), key).maybe_line(line);
        match key {
            Some(key) => error.key(key),
            None => error,
        }
    })
}

/// The key whose value starts at `offset`: the name before the last `=` on its line.
fn key_before(text: &str, offset: usize) -> Option<&str> {
    let before = text.get(..offset)?;
    let line = &before[before.rfind('\n').map_or(0, |i| i + 1)..];
    let key = line.rsplit_once('=')?.0.trim_end();
    let start = key
        .rfind(|c: char| !(c.is_alphanumeric() || c == '_' || c == '-'))
        .map_or(0, |i| i + 1);
    Some(&key[start..]).filter(|k| !k.is_empty())
}

/// The key serde names in "unknown field `mas`, expected one of …".
fn unknown_field(message: &str) -> Option<&str> {
    let rest = message.strip_prefix("unknown field `")?;
    rest.split_once('`').map(|(key, _)| key)
}

/// serde's wording in the user's terms: "invalid type: string \"two\", expected usize"
/// becomes "`dim` takes a whole number, got string \"two\"", the expected and got values
/// as the error's fields.
fn plain_error(path: &Path, message: &str, key: Option<&str>) -> Error {
    let kind = |expected: &str| -> String {
        match expected.trim() {
            "usize" | "u64" | "u32" | "u16" | "u8" => "a whole number (0, 1, 2, …)".into(),
            "i64" | "i32" => "a whole number".into(),
            "f64" | "f32" => "a number".into(),
            "a boolean" => "true or false".into(),
            "a string" => "a string in quotes".into(),
            "a sequence" => "a list [ … ]".into(),
            other => other.to_string(),
        }
    };
    let split = message
        .strip_prefix("invalid type: ")
        .or_else(|| message.strip_prefix("invalid value: "))
        .and_then(|rest| rest.split_once(", expected "));
    match split {
        // With the key, "`key` takes EXPECTED, got GOT" is what the fields print.
        Some((got, expected)) => {
            let expected = kind(expected);
            let message = match key {
                Some(_) => String::new(),
                None => format!("a value in the table starting here takes {expected}"),
            };
            Error::scene(path, message).expected(expected).got(got)
        }
        None => Error::scene(path, message.trim_end()),
    }
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

impl Builder<'_> {
    /// The line (1-based) of the byte `offset` of the scene's text.
    fn line_of(&self, offset: usize) -> usize {
        self.text[..offset.min(self.text.len())]
            .bytes()
            .filter(|&b| b == b'\n')
            .count()
            + 1
    }

    /// An error at the line of `offset`; add `.key(…)`, `.got(…)` where known.
    fn error_at(&self, offset: usize, message: impl Into<String>) -> Error {
        self.error(message).line(self.line_of(offset))
    }

    /// An error in the scene file, at no one line.
    fn error(&self, message: impl Into<String>) -> Error {
        Error::scene(self.path, message)
    }

    fn build(&self, file: &SceneFile, overrides: &[String]) -> Result<Scene> {
        let (dim, units) = self.header(file)?;
        let parameters = self.resolve_parameters(&file.parameters, overrides)?;
        let topology = self.read_topology(file)?;
        let mut start = match &topology {
            Some(loaded) => loaded.start(),
            None => self.particles(file, dim, &parameters)?,
        };
        let names = self.names(file, &start, dim, &parameters)?;
        let periodic_box = match &topology {
            Some(loaded) => loaded.periodic_box(),
            None => self.periodic_box(
                file.periodic_box.as_ref(),
                dim,
                &parameters,
                start.structure.as_ref(),
            )?,
        };
        // A non-diagonal mass matrix, or its lumped diagonal.
        let mass_matrix = match &file.mass_matrix {
            Some(spanned) => {
                self.mass_matrix(spanned, dim, &mut start.masses, &names, &parameters)?
            }
            None => None,
        };
        let scene = SceneSoFar {
            dim,
            parameters: &parameters,
            names: &names,
            q: &start.q,
            masses: &start.masses,
            periodic_box,
        };
        let mut terms = self.build_terms(file, &scene)?;
        let molecule = match &topology {
            Some(loaded) => self.apply_topology(file, loaded, &mut terms)?,
            None => self.apply_forcefield(file, &mut start, periodic_box, units, &mut terms)?,
        };
        if terms.is_empty() {
            return Err(self.error(
                "the scene has no force terms, so nothing acts on its particles: add \
                 [[terms]] (docs/scenes.md) or a [forcefield]",
            ));
        }
        to_internal_masses(units, &mut start);
        let structure_spec = file.structure.as_ref().map(|s| s.get_ref());
        self.structure_velocities(structure_spec, &start.masses, &mut start.p, dim)?;
        let system = self.system(start, terms, dim, periodic_box, mass_matrix)?;
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
            run: run_with_rigid_water(file, molecule.bonded.as_ref()),
            output: file.output.clone(),
            exact,
            units,
            elements: molecule.elements,
            forcefield_report: molecule.report,
            forcefield_parameters: molecule.parameters,
            bonded: molecule.bonded,
            velocities_file: structure_spec
                .and_then(|s| s.velocities.as_ref())
                .map(|v| self.path.parent().unwrap_or(Path::new(".")).join(v)),
        })
    }

    /// The `[[terms]]`, in the order of the file.
    fn build_terms(&self, file: &SceneFile, scene: &SceneSoFar) -> Result<Terms> {
        file.terms
            .iter()
            .enumerate()
            .map(|(index, spanned)| self.build_term(spanned, index, scene))
            .collect::<Result<Terms>>()
    }

    /// The system from the particles (internal units) and the terms; the force terms
    /// must be finite at its start.
    fn system(
        &self,
        start: Start,
        terms: Terms,
        dim: usize,
        periodic_box: Option<PeriodicBox>,
        mass_matrix: Option<MassMatrix>,
    ) -> Result<System> {
        let forces = ForceSplit::new(terms).map_err(|e| self.error(e.to_string()))?;

        let state = State {
            t: 0.0,
            q: start.q,
            p: start.p,
        };
        let particles = Particles {
            names: start.names,
            masses: start.masses,
        };
        let mut system = System::new(dim, particles, state, forces, periodic_box);
        if let Some(mass_matrix) = mass_matrix {
            system = system.with_mass_matrix(mass_matrix);
        }
        self.check_finite_start(&system)?;
        Ok(system)
    }

    /// The version, the dimension and the units; a force field needs real units, 3-D and
    /// a structure file.
    fn header(&self, file: &SceneFile) -> Result<(usize, Units)> {
        if file.version != SCENE_VERSION {
            return Err(self
                .error(format!(
                    "scene version {} is not supported; this longstep reads version \
                     {SCENE_VERSION}",
                    file.version
                ))
                .key("version")
                .expected(SCENE_VERSION.to_string()));
        }
        let dim = file.dim;
        if !(1..=3).contains(&dim) {
            return Err(self
                .error("dim must be 1, 2 or 3")
                .key("dim")
                .expected("1, 2 or 3")
                .got(dim.to_string()));
        }
        let units = match &file.units {
            Some(spanned) => Units::parse(spanned.get_ref())
                .map_err(|e| self.error_at(spanned.span().start, e).key("units"))?,
            None => Units::None,
        };
        if let Some(spanned) = &file.topology
            && (units != Units::Real || dim != 3)
        {
            return Err(self.error_at(
                spanned.span().start,
                "[topology] needs units = \"real\" (Å, fs, amu, kcal/mol, e) and dim = 3",
            ));
        }
        if let (Some(_), Some(spanned)) = (&file.topology, &file.forcefield) {
            return Err(self
                .error_at(
                    spanned.span().start,
                    "a scene takes its force field either from [topology] (a topology file) or \
                     from [forcefield] (over a [structure] file), not both",
                )
                .key("forcefield"));
        }
        if let Some(spanned) = &file.forcefield {
            if units != Units::Real {
                return Err(self.error_at(
                    spanned.span().start,
                    "[forcefield] needs units = \"real\" (Å, fs, amu, kcal/mol, e)",
                ));
            }
            if dim != 3 {
                return Err(self
                    .error_at(spanned.span().start, "[forcefield] needs dim = 3")
                    .key("dim")
                    .got(dim.to_string()));
            }
            if file.structure.is_none() {
                return Err(self.error_at(
                    spanned.span().start,
                    "[forcefield] needs the atoms from a [structure] file",
                ));
            }
        }
        Ok((dim, units))
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
                let error = self.error(format!(
                    "{} \"{}\" has a non-finite energy or force at the starting positions",
                    term.term.kind(),
                    term.name
                ));
                if let Some(k) = q.iter().position(|x| !x.is_finite()) {
                    let particle = k / system.dim;
                    return Err(error
                        .append(&format!(
                            "; atom {} (particle {particle} from 0) has a non-finite position",
                            particle + 1
                        ))
                        .got(q[k].to_string()));
                }
                return Err(match closest_pair(q, system.dim) {
                    Some((i, j, d)) => error
                        .append(&format!(
                            "; the closest atoms are {} and {} (numbered from 1; particles {i} \
                             and {j} from 0), at distance {d}",
                            i + 1,
                            j + 1
                        ))
                        .got(format!("atoms {} and {} at distance {d}", i + 1, j + 1)),
                    None => error.append(" (a zero-length spring with a rest length?)"),
                });
            }
        }
        Ok(())
    }
}

/// The closest two particles of positions `q` (`dim` per particle) and their distance:
/// what most often makes a starting energy non-finite. Cost: O(n²) distances, only on that
/// error.
fn closest_pair(q: &[f64], dim: usize) -> Option<(usize, usize, f64)> {
    let n = q.len() / dim.max(1);
    let mut best: Option<(usize, usize, f64)> = None;
    for i in 0..n {
        for j in i + 1..n {
            let r2: f64 = (0..dim)
                .map(|a| (q[i * dim + a] - q[j * dim + a]).powi(2))
                .sum();
            if best.is_none_or(|(_, _, b)| r2 < b) {
                best = Some((i, j, r2));
            }
        }
    }
    best.map(|(i, j, r2)| (i, j, r2.sqrt()))
}

/// Internal masses (real units: kcal/mol·fs²/Å², see `units`); momenta scale with them.
/// The scene's `[run]`, with rigid water on by default when the topology's water is a
/// GROMACS `[settles]` (as GROMACS runs it); an explicit `rigid_water` stays.
fn run_with_rigid_water(
    file: &SceneFile,
    bonded: Option<&crate::system::topology::BondedTopology>,
) -> RunSpec {
    let mut run = file.run.clone();
    if bonded.is_some_and(|b| b.rigid_water_required) && run.rigid_water.is_none() {
        run.rigid_water = Some(true);
    }
    run
}

fn to_internal_masses(units: Units, start: &mut Start) {
    for m in &mut start.masses {
        *m = units.mass(*m);
    }
    for pk in &mut start.p {
        *pk = units.mass(*pk);
    }
}
