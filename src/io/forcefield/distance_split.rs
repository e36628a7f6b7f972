//! `[forcefield.split]` and `[topology.split]` (and `--split KEY=VALUE,…` over either): the
//! cutoff non-bonded term split by distance into a short-range part and a remainder on two
//! levels (`forces::distance_split` has the formulas):
//!
//! ```toml
//! [forcefield.split]
//! r_in = 6.0             # S = 1 below (length)
//! r_out = 7.0            # S = 0 above; 0 < r_in < r_out ≤ cutoff
//! by = "molecule"        # or "atom" (each atom pair on its own distance); default molecule
//! reference = "O"        # by molecule: the reference atom's element or type name
//! short_level = 1        # level of the short-range part (default 1)
//! remainder_level = 2    # level of the remainder (default short_level + 1)
//! short_coulomb = "bare" # the short part's Coulomb: "bare" 1/r or the term's own "model"
//!                        # form; default "bare" with PME by molecule, "model" otherwise
//! ```
//!
//! Molecules are the connected components of the bond graph. Each molecule's reference
//! atom is its first atom (in file order) whose type name or element is `reference`; without
//! `reference`, its first heaviest atom (O for water).
//!
//! A topology's split is by atom pair unless it says `by = "molecule"`: its molecules
//! include a protein, whose pairs with the water would all be switched on the distance of
//! one reference atom; with PME the real-space pairs beyond `r_in` are screened by
//! `erfc(α r)`, so the remainder by atom pair is small (erfc(0.347 × 5) = 0.014 at
//! GROMACS's default α). With PME split by molecule the short part takes the bare Coulomb
//! `1/r` by default (LAMMPS's rRESPA inner and middle levels with `coul/long` do the same, by
//! atom pair): the near-field Coulomb force, which `erfc(αr)/r` would leave to the reciprocal
//! sum, is then on the short level, and the slow level holds only a smooth remainder. By atom
//! pair the bare form's switched charge pairs cancel only over whole molecules, so the
//! default there stays the screened form. Rigid waters (`[ settles ]`) count as bonded for the molecules, and
//! the topology's 1-4 pairs go to the short part's level.

use serde::{Deserialize, Serialize};

use super::atoms::AtomTable;
use super::{ForcefieldInput, Terms};
use crate::forces::distance_split::{
    ShortCoulomb, SplitSpec, SwitchBy, molecules_from_bonds, reference_atoms, split_nonbonded,
};
use crate::forces::nonbonded::{Electrostatics, NonbondedSpec};
use crate::split::Assignment;

/// Levels a split may name, at most (the splitter sizes a table per level).
const MAX_LEVEL: usize = 15;

/// `[forcefield.split]` and `[topology.split]` (and `--split KEY=VALUE,…`).
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SplitSection {
    pub r_in: f64,
    pub r_out: f64,
    /// `"molecule"` or `"atom"`; the default is the caller's.
    pub by: Option<String>,
    /// By molecule: element or type name of each molecule's reference atom.
    pub reference: Option<String>,
    pub short_level: Option<usize>,
    pub remainder_level: Option<usize>,
    /// `"bare"` or `"model"`; the default is `"bare"` with PME, `"model"` otherwise.
    pub short_coulomb: Option<String>,
}

impl SplitSection {
    /// The section from `--split r_in=6,r_out=7,by=atom,short_level=0,remainder_level=1`:
    /// the section's keys as `KEY=VALUE` pairs separated by commas.
    pub fn from_flag(text: &str) -> Result<SplitSection, String> {
        let mut table = toml::Table::new();
        for pair in text.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            let Some((key, value)) = pair.split_once('=') else {
                return Err(format!("--split: \"{pair}\" is no KEY=VALUE pair"));
            };
            let value = value.trim();
            let value = match (value.parse::<i64>(), value.parse::<f64>()) {
                (Ok(n), _) => toml::Value::Integer(n),
                (_, Ok(x)) => toml::Value::Float(x),
                _ => toml::Value::String(value.into()),
            };
            table.insert(key.trim().into(), value);
        }
        toml::Value::Table(table)
            .try_into()
            .map_err(|e: toml::de::Error| {
                format!(
                    "--split \"{text}\": {} (keys r_in, r_out, by, reference, short_level, \
                 remainder_level, short_coulomb; e.g. r_in=5,r_out=6,short_level=0,\
                 remainder_level=1)",
                    e.message().trim()
                )
            })
    }
}

/// What a split needs of the atoms, whatever file they came from.
pub(crate) struct SplitAtoms<'a> {
    /// Bonds between atoms: molecules are the connected components.
    pub bonds: &'a [[usize; 2]],
    pub masses: &'a [f64],
    /// Whether atom `i` has the element or type name `name`.
    pub is_named: &'a dyn Fn(usize, &str) -> bool,
    /// The section's name in messages (`[forcefield.split]`, `[topology.split]`).
    pub table: &'a str,
    /// `by` when the section gives none.
    pub default_by: SwitchBy,
}

/// The short-range part and the remainder of the cutoff term `spec` of a scene's
/// force field, on their levels; one report line.
pub(super) fn terms(
    input: &ForcefieldInput,
    atoms: &AtomTable,
    section: &SplitSection,
    spec: NonbondedSpec,
    terms: &mut Terms,
    report: &mut Vec<String>,
) -> Result<(), String> {
    let is_named =
        |i: usize, name: &str| input.atoms[i].type_name == name || atoms.elements[i] == name;
    let split_atoms = SplitAtoms {
        bonds: input.bonds,
        masses: &atoms.masses,
        is_named: &is_named,
        table: "[forcefield.split]",
        default_by: SwitchBy::Molecule,
    };
    split_terms(section, &split_atoms, spec, input.q, terms, report)
}

/// The short-range part and the remainder of the cutoff term `spec` at positions `q`, as
/// `section` asks, pushed on `terms` with one report line.
pub(crate) fn split_terms(
    section: &SplitSection,
    atoms: &SplitAtoms,
    spec: NonbondedSpec,
    q: &[f64],
    terms: &mut Terms,
    report: &mut Vec<String>,
) -> Result<(), String> {
    let fail = |e: String| format!("{} {e}", atoms.table);
    let (short_level, remainder_level) = levels(section).map_err(fail)?;
    let by = match section.by.as_deref() {
        None => atoms.default_by,
        Some("molecule") => SwitchBy::Molecule,
        Some("atom") => SwitchBy::AtomPair,
        Some(other) => {
            return Err(fail(format!(
                "by = \"{other}\": use \"molecule\" or \"atom\""
            )));
        }
    };
    if by == SwitchBy::AtomPair && section.reference.is_some() {
        return Err(fail(
            "reference is for by = \"molecule\" (by = \"atom\" has no reference atoms)".into(),
        ));
    }
    let (molecule_of, reference) = match by {
        SwitchBy::Molecule => {
            let molecule_of = molecules_from_bonds(atoms.masses.len(), atoms.bonds);
            let reference = references(atoms, section, &molecule_of).map_err(fail)?;
            (molecule_of, reference)
        }
        SwitchBy::AtomPair => (Vec::new(), Vec::new()),
    };
    let short_coulomb = short_coulomb(section, &spec, by).map_err(fail)?;
    let spec_charged = spec.electrostatics != Electrostatics::None;
    let split = SplitSpec {
        r_in: section.r_in,
        r_out: section.r_out,
        by,
        short_coulomb,
        molecule_of,
        reference_atoms: reference,
    };
    let (short, remainder) = split_nonbonded(spec, &split, q).map_err(fail)?;
    let (reference_name, by_name) = match by {
        SwitchBy::Molecule => (
            format!(
                ", reference {} in each of {} molecules",
                reference_label(section),
                split.reference_atoms.len()
            ),
            format!("by molecule ({})", reference_label(section)),
        ),
        SwitchBy::AtomPair => (String::new(), "by atom pair".into()),
    };
    report.push(format!(
        "nonbonded split: short-range part on level {short_level} {}{reference_name}, \
         computed as {}; remainder (full − short) on level {remainder_level}",
        short.short_range().describe(),
        short.short_range().pair_loop()
    ));
    if spec_charged {
        report.push(coulomb_line(short_coulomb).into());
    }
    let short_name = format!(
        "short-range: switched off from r_in = {} to r_out = {} {by_name}",
        section.r_in, section.r_out
    );
    terms.push((short_name, Box::new(short), Assignment::Level(short_level)));
    terms.push((
        "remainder: nonbonded − short-range".into(),
        Box::new(remainder),
        Assignment::Level(remainder_level),
    ));
    Ok(())
}

/// The report line of the short part's Coulomb form.
fn coulomb_line(form: ShortCoulomb) -> &'static str {
    match form {
        ShortCoulomb::Bare => {
            "nonbonded split: the short part's Coulomb is bare 1/r (short_coulomb = \"bare\")"
        }
        ShortCoulomb::Model => {
            "nonbonded split: the short part's Coulomb is the term's own form \
             (short_coulomb = \"model\")"
        }
    }
}

/// The short part's Coulomb form: the section's `short_coulomb`, by default bare with PME
/// split by molecule (the near field on the short level) and the term's own form otherwise.
/// By atom pair the bare form switches each charge pair on its own distance, and the
/// pieces cancel only over whole molecules: on the solvated Trp-cage (5–6 Å) the slow
/// level's RMS force is 109 kcal/mol/Å bare against 3.5 screened.
fn short_coulomb(
    section: &SplitSection,
    spec: &NonbondedSpec,
    by: SwitchBy,
) -> Result<ShortCoulomb, String> {
    let ewald = matches!(spec.electrostatics, Electrostatics::Ewald { .. });
    match section.short_coulomb.as_deref() {
        None if ewald && by == SwitchBy::Molecule => Ok(ShortCoulomb::Bare),
        None | Some("model") => Ok(ShortCoulomb::Model),
        Some("bare") => Ok(ShortCoulomb::Bare),
        Some(other) => Err(format!(
            "short_coulomb = \"{other}\": use \"bare\" (1/r) or \"model\" (the term's own form)"
        )),
    }
}

/// `(short_level, remainder_level)`: the remainder above the short part, both bounded.
fn levels(section: &SplitSection) -> Result<(usize, usize), String> {
    let short = section.short_level.unwrap_or(1);
    let remainder = section.remainder_level.unwrap_or(short + 1);
    if remainder <= short {
        return Err(format!(
            "remainder_level = {remainder} must be above short_level = {short} (the remainder \
             is the slower part)"
        ));
    }
    if remainder > MAX_LEVEL {
        return Err(format!("levels go up to {MAX_LEVEL}, got {remainder}"));
    }
    Ok((short, remainder))
}

fn reference_label(section: &SplitSection) -> String {
    match &section.reference {
        Some(name) => name.clone(),
        None => "heaviest atom".into(),
    }
}

/// Each molecule's reference atom (module doc); errors name the reference or the molecule.
fn references(
    atoms: &SplitAtoms,
    section: &SplitSection,
    molecule_of: &[u32],
) -> Result<Vec<usize>, String> {
    let Some(name) = &section.reference else {
        return reference_atoms(molecule_of, atoms.masses, None);
    };
    let matches = |i: usize| (atoms.is_named)(i, name);
    if !(0..molecule_of.len()).any(matches) {
        return Err(format!(
            "reference = \"{name}\" is no element or type name of the structure's atoms"
        ));
    }
    reference_atoms(molecule_of, atoms.masses, Some(&matches))
        .map_err(|e| format!("reference = \"{name}\": {e}"))
}
