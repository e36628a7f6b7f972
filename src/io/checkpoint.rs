//! Checkpoint files (`run --checkpoint-every T`, `run --restart FILE`): one JSON object
//! holding everything a run needs to continue as if it had never stopped — the format
//! version, a fingerprint of the model and settings (a restart with others is refused,
//! naming what differs), the outer step count, the time, positions, momenta and the
//! integrator's hidden state ([`Integrator::save_state`]), and each force term's pair-list
//! state ([`ForceTerm::list_state`]), so the continued run sums over the same pairs in the
//! same order without the run that wrote the checkpoint rebuilding anything.
//!
//! Every `f64` is written as its shortest round-trip decimal, which `serde_json` (built
//! with `float_roundtrip`) reads back to the same bits. A checkpoint is written to a
//! temporary name beside the final one and renamed over it, so a crash leaves either the
//! previous checkpoint or the new one, never half a file.
//!
//! [`Integrator::save_state`]: crate::integrators::Integrator::save_state
//! [`ForceTerm::list_state`]: crate::forces::ForceTerm::list_state

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::io::number::Num;
use crate::io::scene::Scene;
use crate::settings::{MethodSettings, Parameter};

/// The file name in a run's output directory.
pub const CHECKPOINT_FILE: &str = "checkpoint.json";

/// What the `format` key says, so another JSON file is recognised as not a checkpoint.
const FORMAT: &str = "longstep checkpoint";

/// The format version this build writes and reads (4: a checksum; 3: settings in the
/// fingerprint resolved and written with their units; 2: the pair-list states; version 1 had none,
/// and its runs rebuilt the lists at every checkpoint).
pub const VERSION: u32 = 4;

/// What a checkpoint must match to be continued from: the scene file (by name and
/// CRC-32 of its text), the `--set` values and scene flags, the atoms (count, dimension,
/// masses by CRC-32 of their bits), the force levels, the precision, and every method
/// setting except the end time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Fingerprint {
    pub scene: String,
    pub scene_crc32: String,
    pub set: Vec<String>,
    pub flags: String,
    pub precision: Option<String>,
    pub atoms: usize,
    pub dim: usize,
    pub masses_crc32: String,
    pub levels: String,
    pub settings: BTreeMap<String, String>,
}

/// What of a run request, besides the scene and settings, goes into a [`Fingerprint`].
pub struct RequestParts<'a> {
    pub set: &'a [String],
    /// The scene flags as `key = value` (topology coordinates, `--coulomb`, PME):
    /// [`SceneFlags::describe`](crate::io::scene::SceneFlags::describe).
    pub flags: String,
    pub precision: Option<&'a str>,
}

impl Fingerprint {
    /// The fingerprint of a prepared run.
    pub fn of(scene: &Scene, settings: &MethodSettings, request: RequestParts) -> Result<Self> {
        let (_, scene_crc) = crate::io::manifest::fingerprint(&scene.path)?;
        let system = &scene.system;
        let mut masses = crc32fast::Hasher::new();
        for w in &system.inverse_mass {
            masses.update(&w.to_bits().to_le_bytes());
        }
        Ok(Fingerprint {
            scene: scene.name.clone(),
            scene_crc32: format!("{scene_crc:08x}"),
            set: request.set.to_vec(),
            flags: request.flags,
            precision: request.precision.map(str::to_string),
            atoms: system.n_particles(),
            dim: system.dim,
            masses_crc32: format!("{:08x}", masses.finalize()),
            levels: system.forces.level_table(),
            settings: settings_fields(settings),
        })
    }

    /// What differs between the checkpoint's fingerprint (`self`) and this run's, one
    /// phrase each; empty when they match.
    pub fn differences(&self, run: &Fingerprint) -> Vec<String> {
        let mut out = Vec::new();
        let mut differ = |what: &str, saved: String, now: String| {
            if saved != now {
                out.push(format!("{what}: {saved} in the checkpoint, {now} now"));
            }
        };
        differ("scene", self.scene.clone(), run.scene.clone());
        differ(
            "scene file (CRC-32)",
            self.scene_crc32.clone(),
            run.scene_crc32.clone(),
        );
        let set = |s: &[String]| {
            if s.is_empty() {
                "none".to_string()
            } else {
                s.join(" ")
            }
        };
        differ("--set", set(&self.set), set(&run.set));
        differ("scene flags", self.flags.clone(), run.flags.clone());
        let precision = |p: &Option<String>| p.clone().unwrap_or_else(|| "the default".to_string());
        differ(
            "--precision",
            precision(&self.precision),
            precision(&run.precision),
        );
        differ("atoms", self.atoms.to_string(), run.atoms.to_string());
        differ("dimension", self.dim.to_string(), run.dim.to_string());
        differ(
            "masses (CRC-32)",
            self.masses_crc32.clone(),
            run.masses_crc32.clone(),
        );
        if self.levels != run.levels {
            differ(
                "force levels",
                "one table".to_string(),
                "another (see the level table)".to_string(),
            );
        }
        let keys: std::collections::BTreeSet<&String> =
            self.settings.keys().chain(run.settings.keys()).collect();
        for key in keys {
            let value = |m: &BTreeMap<String, String>| m.get(key).cloned().unwrap_or_default();
            differ(key, value(&self.settings), value(&run.settings));
        }
        out
    }
}

/// Every method setting but the end time (`--t-end` is the end of the whole run), by name,
/// resolved (the defaults its method fills in written out,
/// [`with_defaults`](crate::integrators::registry::with_defaults)) and written as a value
/// with its unit (`0.001 /fs`, `2013`, `not set`), shortest round-trip decimals for numbers.
fn settings_fields(s: &MethodSettings) -> BTreeMap<String, String> {
    let s = crate::integrators::registry::with_defaults(s);
    let unit = UnitNames::of(s.units);
    macro_rules! parameters {
        ($s:ident; $($field:ident: $kind:ident),* $(,)?) => {{
            // Every field named: a new one fails to compile here until it is a method
            // parameter (`settings::method_parameters!`) or a run-wide setting of
            // `run_fields`.
            let MethodSettings {
                method: _,
                h: _,
                t_end: _,
                blowup: _,
                temperature: _,
                seed: _,
                constraints: _,
                rigid_water: _,
                constraint_tolerance: _,
                hydrogen_mass: _,
                units: _,
                $($field),*
            } = &$s;
            [$((stringify!($field), Parameter::$kind($field.clone()))),*]
        }};
    }
    let parameters = crate::settings::method_parameters!(parameters, s);
    run_fields(&s, &unit)
        .into_iter()
        .chain(parameters.map(|(name, value)| (name, unit.show(value))))
        .map(|(k, v)| (k.to_string(), v))
        .collect()
}

/// The unit names a setting's value is shown with.
struct UnitNames {
    time: String,
    per_time: String,
    mass: &'static str,
}

impl UnitNames {
    fn of(units: crate::units::Units) -> Self {
        let time = units.time_name().to_string();
        let per_time = if time.is_empty() {
            String::new()
        } else {
            format!("/{time}")
        };
        let mass = if time.is_empty() { "" } else { "amu" };
        UnitNames {
            time,
            per_time,
            mass,
        }
    }

    /// A method parameter's value with its unit.
    fn show(&self, value: Parameter) -> String {
        match value {
            Parameter::Count(x) => shown(x, ""),
            Parameter::Steps(x) => {
                let steps = x.map(|l| l.iter().map(usize::to_string).collect::<Vec<_>>());
                shown(steps.map(|l| l.join(",")), "")
            }
            Parameter::Text(x) => shown(x, ""),
            Parameter::Number(x) => number(&x, ""),
            Parameter::Time(x) => number(&x, &self.time),
            Parameter::PerTime(x) => number(&x, &self.per_time),
        }
    }
}

fn number(x: &Option<f64>, unit: &str) -> String {
    shown(x.map(Num), unit)
}

/// The settings of the run beyond the method parameters: the method, its step, the bath,
/// the constraints, the units.
fn run_fields(s: &MethodSettings, u: &UnitNames) -> Vec<(&'static str, String)> {
    vec![
        ("method", s.method.clone()),
        ("h", number(&Some(s.h), &u.time)),
        ("blowup", Num(s.blowup).to_string()),
        (
            "temperature",
            number(&s.temperature, s.units.temperature_name()),
        ),
        ("seed", shown(s.seed.as_ref(), "")),
        ("constraints", format!("{:?}", s.constraints).to_lowercase()),
        ("rigid_water", s.rigid_water.to_string()),
        ("constraint_tolerance", number(&s.constraint_tolerance, "")),
        ("hydrogen_mass", number(&s.hydrogen_mass, u.mass)),
        ("units", s.units.name().to_string()),
    ]
}

/// A setting's value and unit for a message, `not set` when absent.
fn shown<T: std::fmt::Display>(value: Option<T>, unit: &str) -> String {
    match value {
        Some(v) if unit.is_empty() => v.to_string(),
        Some(v) => format!("{v} {unit}"),
        None => "not set".to_string(),
    }
}

/// A checkpoint: borrowed from the run when written, owned when read.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Checkpoint<'a> {
    pub format: String,
    pub version: u32,
    pub fingerprint: Cow<'a, Fingerprint>,
    /// Outer steps between checkpoints: the continued run's interval unless it asks for
    /// another (only where `rebuilt_lists` must it keep this one).
    pub every: u64,
    /// Outer steps since the start of the whole run.
    pub step: u64,
    /// The time the whole run started at (step 0).
    pub t0: f64,
    pub t: f64,
    /// The kinetic and per-level potential energies at `t0`: the blow-up monitor's
    /// reference, so a continued run stops where the whole run would.
    pub initial_kinetic: f64,
    pub initial_potentials: Vec<f64>,
    pub q: Cow<'a, [f64]>,
    pub p: Cow<'a, [f64]>,
    /// [`Integrator::save_state`](crate::integrators::Integrator::save_state).
    pub integrator: serde_json::Value,
    /// Each force term's [`ForceSplit::list_states`](crate::split::ForceSplit::list_states),
    /// in term order (`null` for a term without lists).
    pub lists: Vec<Option<serde_json::Value>>,
    /// Whether the writing run rebuilt some term's lists at this checkpoint (a term that
    /// keeps lists but cannot save them,
    /// [`ForceSplit::rebuild_lists_without_state`](crate::split::ForceSplit::rebuild_lists_without_state)):
    /// then a continued run matches only with checkpoints at the same steps.
    pub rebuilt_lists: bool,
    /// CRC-32 (8 hex digits) of the checkpoint written compactly with this field empty:
    /// an edited number (still valid JSON) is refused ([`Checkpoint::checksum_of`]).
    #[serde(default)]
    pub checksum: String,
}

impl<'a> Checkpoint<'a> {
    /// The CRC-32 of `self` as compact JSON with an empty `checksum`: the same text for
    /// the same numbers however the file is laid out, since every `f64` is written as its
    /// shortest round-trip decimal and read back to the same bits. One serialisation.
    pub fn checksum_of(&self) -> std::result::Result<String, serde_json::Error> {
        let mut unsealed = self.clone();
        unsealed.checksum.clear();
        let text = serde_json::to_string(&unsealed)?;
        Ok(format!("{:08x}", crc32fast::hash(text.as_bytes())))
    }

    /// A checkpoint of the current state, borrowing the positions and momenta.
    pub fn new(fingerprint: &'a Fingerprint, q: &'a [f64], p: &'a [f64]) -> Self {
        Checkpoint {
            format: FORMAT.to_string(),
            version: VERSION,
            fingerprint: Cow::Borrowed(fingerprint),
            every: 0,
            step: 0,
            t0: 0.0,
            t: 0.0,
            initial_kinetic: 0.0,
            initial_potentials: Vec::new(),
            q: Cow::Borrowed(q),
            p: Cow::Borrowed(p),
            integrator: serde_json::Value::Null,
            lists: Vec::new(),
            rebuilt_lists: false,
            checksum: String::new(),
        }
    }

    /// Write to `path` atomically, sealed with its checksum: to `path` + `.tmp`, flushed
    /// to disk, then renamed.
    pub fn write(&self, path: &Path) -> Result<()> {
        let cannot = |e: serde_json::Error| Error::Checkpoint {
            path: path.to_path_buf(),
            message: format!("cannot write the checkpoint: {e}"),
        };
        let mut sealed = self.clone();
        sealed.checksum = self.checksum_of().map_err(cannot)?;
        let mut temporary = path.as_os_str().to_owned();
        temporary.push(".tmp");
        let temporary = PathBuf::from(temporary);
        let file = std::fs::File::create(&temporary).map_err(|e| Error::io(&temporary, e))?;
        let mut writer = std::io::BufWriter::new(file);
        serde_json::to_writer(&mut writer, &sealed).map_err(cannot)?;
        writer.flush().map_err(|e| Error::io(&temporary, e))?;
        let file = writer
            .into_inner()
            .map_err(|e| Error::io(&temporary, e.into_error()))?;
        file.sync_all().map_err(|e| Error::io(&temporary, e))?;
        std::fs::rename(&temporary, path).map_err(|e| Error::io(path, e))
    }
}

/// A checkpoint read back, with where it came from.
#[derive(Clone, Debug)]
pub struct Restart {
    pub path: PathBuf,
    pub checkpoint: Checkpoint<'static>,
}

impl Restart {
    /// Read and check a checkpoint file: a longstep checkpoint, of this format version,
    /// whole and consistent (as many momenta as positions, finite numbers).
    pub fn read(path: &Path) -> Result<Self> {
        let bad = |message: String| Error::Checkpoint {
            path: path.to_path_buf(),
            message,
        };
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let value: serde_json::Value = serde_json::from_str(&text).map_err(|e| {
            bad(format!(
                "not a readable checkpoint (truncated or corrupted?): {e}"
            ))
        })?;
        if value.get("format").and_then(|f| f.as_str()) != Some(FORMAT) {
            return Err(bad(format!(
                "not a longstep checkpoint (no \"format\": \"{FORMAT}\")"
            )));
        }
        match value.get("version").and_then(|v| v.as_u64()) {
            Some(v) if v == u64::from(VERSION) => {}
            Some(v) => {
                return Err(bad(format!(
                    "checkpoint format version {v}; this longstep reads version {VERSION} \
                     only (rerun from the start to write a checkpoint of this version)"
                )));
            }
            None => return Err(bad("no format version".to_string())),
        }
        let checkpoint: Checkpoint<'static> = Checkpoint::deserialize(&value)
            .map_err(|e| bad(format!("malformed checkpoint: {e}")))?;
        check_consistent(&checkpoint).map_err(bad)?;
        let checksum = checkpoint
            .checksum_of()
            .map_err(|e| bad(format!("cannot check the checksum: {e}")))?;
        if checkpoint.checksum != checksum {
            return Err(bad(format!(
                "its checksum {:?} is not that of its contents ({checksum}): the file was \
                 edited or damaged after it was written; continue from an untouched \
                 checkpoint",
                checkpoint.checksum
            )));
        }
        Ok(Restart {
            path: path.to_path_buf(),
            checkpoint,
        })
    }

    /// Refuse a checkpoint of another model or settings, naming every difference.
    pub fn check_matches(&self, run: &Fingerprint) -> Result<()> {
        let differences = self.checkpoint.fingerprint.differences(run);
        if differences.is_empty() {
            return Ok(());
        }
        Err(Error::Checkpoint {
            path: self.path.clone(),
            message: format!(
                "written by another scene or other settings; a restart needs the original \
                 command's scene, flags and settings (only --t-end may change). Differences: {}",
                differences.join("; ")
            ),
        })
    }
}

/// Sizes and numbers that a whole checkpoint has.
fn check_consistent(c: &Checkpoint) -> std::result::Result<(), String> {
    let n = c.fingerprint.atoms * c.fingerprint.dim;
    if c.q.len() != n || c.p.len() != n {
        return Err(format!(
            "{} positions and {} momenta for {} atoms in {} D (expected {n} each)",
            c.q.len(),
            c.p.len(),
            c.fingerprint.atoms,
            c.fingerprint.dim
        ));
    }
    if c.every == 0 || c.step == 0 {
        return Err(format!(
            "step {} of a checkpoint every {} steps: both must be at least 1",
            c.step, c.every
        ));
    }
    let finite = [c.t0, c.t, c.initial_kinetic]
        .iter()
        .chain(&c.initial_potentials)
        .chain(c.q.iter())
        .chain(c.p.iter())
        .all(|x| x.is_finite());
    if !finite {
        return Err("holds a number that is not finite".to_string());
    }
    Ok(())
}
