//! The directives of a preprocessed GROMACS topology, read into tables in GROMACS's units
//! (nm, kJ/mol, degrees): `[defaults]`, the type tables (`[atomtypes]`, `[bondtypes]`,
//! `[angletypes]`, `[dihedraltypes]`, `[pairtypes]`), each `[moleculetype]` with its
//! `[atoms]`, `[bonds]`, `[angles]`, `[dihedrals]`, `[pairs]`, `[exclusions]`, `[settles]`,
//! and `[system]`, `[molecules]`. Anything else is refused with its file and line. One
//! pass over the lines.

use super::preprocess::{Line, Source};
use crate::error::{Error, Result};

#[derive(Clone, Debug)]
pub struct Defaults {
    pub comb_rule: u32,
    pub gen_pairs: bool,
    pub fudge_lj: f64,
    pub fudge_qq: f64,
}

#[derive(Clone, Debug)]
pub struct AtomType {
    pub name: String,
    /// The name the bonded type tables use (the type's own when the line gives none).
    pub bond_type: String,
    pub atomic_number: Option<i64>,
    pub mass: f64,
    pub charge: f64,
    /// σ (nm), ε (kJ/mol) for combination rules 2 and 3; c6, c12 for rule 1.
    pub v: f64,
    pub w: f64,
}

/// A type-table line: its atom type names (`X` a wildcard), function and parameters.
#[derive(Clone, Debug)]
pub struct TypeEntry {
    pub types: Vec<String>,
    pub function: u32,
    pub params: Vec<f64>,
    pub at: usize,
}

/// One listed interaction of a molecule: 0-based atoms, function, inline parameters, line.
#[derive(Clone, Debug)]
pub struct Interaction {
    pub atoms: Vec<usize>,
    pub function: u32,
    pub params: Vec<f64>,
    /// Index into [`Parsed::lines`] for messages.
    pub at: usize,
}

#[derive(Clone, Debug)]
pub struct MolAtom {
    pub type_name: String,
    pub residue_number: String,
    pub residue: String,
    pub name: String,
    pub charge: Option<f64>,
    pub mass: Option<f64>,
    pub at: usize,
}

#[derive(Clone, Debug, Default)]
pub struct MoleculeType {
    pub name: String,
    pub nrexcl: usize,
    pub atoms: Vec<MolAtom>,
    pub bonds: Vec<Interaction>,
    pub angles: Vec<Interaction>,
    pub dihedrals: Vec<Interaction>,
    pub pairs: Vec<Interaction>,
    pub exclusions: Vec<Interaction>,
    /// `[settles]`: the oxygen (atoms, 0-based: O, O+1, O+2), function, d_OH, d_HH.
    pub settles: Vec<Interaction>,
}

#[derive(Debug, Default)]
pub struct Parsed {
    pub defaults: Option<Defaults>,
    pub atomtypes: Vec<AtomType>,
    pub bondtypes: Vec<TypeEntry>,
    pub angletypes: Vec<TypeEntry>,
    pub dihedraltypes: Vec<TypeEntry>,
    pub pairtypes: Vec<TypeEntry>,
    pub molecules: Vec<MoleculeType>,
    pub system: String,
    pub counts: Vec<(String, usize, usize)>,
    /// `file:line` of each line the tables point to.
    pub lines: Vec<String>,
}

pub fn error(location: &str, message: impl Into<String>) -> Error {
    Error::topology_at(location, message)
}

/// A field as a number: `nan` and `inf` (which Rust's parser reads) are refused, and a
/// negative count says so rather than "not a number".
fn number<T: std::str::FromStr>(field: &str, what: &str, at: &str) -> Result<T> {
    if let Ok(value) = field.parse::<T>() {
        if field.parse::<f64>().is_ok_and(|v| !v.is_finite()) {
            return Err(error(at, format!("{what} is not a finite number")).got(field));
        }
        return Ok(value);
    }
    if field.parse::<i64>().is_ok_and(|v| v < 0) {
        return Err(error(at, format!("{what} is negative"))
            .expected("a whole number, 0 or more")
            .got(field));
    }
    Err(error(at, format!("{what} is not a number")).got(field))
}

fn numbers(fields: &[String], at: &str) -> Result<Vec<f64>> {
    fields.iter().map(|f| number(f, "parameter", at)).collect()
}

/// Read the directives of `source`.
pub fn parse(source: &Source) -> Result<Parsed> {
    let mut parsed = Parsed::default();
    let mut directive = String::new();
    for line in &source.lines {
        let at = source.location(line);
        let joined = line.fields.join(" ");
        if let Some(name) = joined.strip_prefix('[') {
            let name = name.trim_end_matches(']').trim().to_ascii_lowercase();
            directive = open(&mut parsed, &name, &at).map_err(|e| e.key(name))?;
            continue;
        }
        parsed.lines.push(at.clone());
        let index = parsed.lines.len() - 1;
        // The directive a data line is in is the key of its errors.
        data_line(&mut parsed, &directive, line, index, &at).map_err(|e| {
            match e.location().and_then(|l| l.key.as_ref()) {
                Some(_) => e,
                None => e.key(&directive),
            }
        })?;
    }
    Ok(parsed)
}

/// Check a directive's name as it opens.
fn open(parsed: &mut Parsed, name: &str, at: &str) -> Result<String> {
    const KNOWN: &[&str] = &[
        "defaults",
        "atomtypes",
        "bondtypes",
        "angletypes",
        "dihedraltypes",
        "pairtypes",
        "moleculetype",
        "atoms",
        "bonds",
        "angles",
        "dihedrals",
        "pairs",
        "exclusions",
        "settles",
        "system",
        "molecules",
    ];
    if !KNOWN.contains(&name) {
        return Err(error(
            at,
            format!(
                "[ {name} ]: a directive longstep does not read (it reads {})",
                KNOWN.join(", ")
            ),
        ));
    }
    let molecular = [
        "atoms",
        "bonds",
        "angles",
        "dihedrals",
        "pairs",
        "exclusions",
        "settles",
    ];
    if molecular.contains(&name) && parsed.molecules.is_empty() {
        return Err(error(at, format!("[ {name} ] before any [ moleculetype ]")));
    }
    Ok(name.to_string())
}

fn data_line(
    parsed: &mut Parsed,
    directive: &str,
    line: &Line,
    index: usize,
    at: &str,
) -> Result<()> {
    let f = &line.fields;
    match directive {
        "" => Err(error(at, "data before any [ directive ]")),
        "defaults" => defaults(parsed, f, at),
        "atomtypes" => atomtype(parsed, f, at),
        "bondtypes" => type_entry(&mut parsed.bondtypes, f, 2, index, at),
        "angletypes" => type_entry(&mut parsed.angletypes, f, 3, index, at),
        "pairtypes" => type_entry(&mut parsed.pairtypes, f, 2, index, at),
        "dihedraltypes" => dihedraltype(parsed, f, index, at),
        "moleculetype" => {
            let nrexcl = match f.get(1) {
                Some(n) => number(n, "nrexcl", at)?,
                None => return Err(error(at, "[ moleculetype ] needs a name and nrexcl")),
            };
            if parsed.molecules.iter().any(|m| m.name == f[0]) {
                return Err(error(
                    at,
                    format!(
                        "[ moleculetype ] {} is defined twice (grompp refuses it too): which \
                         one [ molecules ] means is not known",
                        f[0]
                    ),
                ));
            }
            parsed.molecules.push(MoleculeType {
                name: f[0].clone(),
                nrexcl,
                ..MoleculeType::default()
            });
            Ok(())
        }
        "atoms" => molecule_atom(parsed, f, index, at),
        "settles" => settle(parsed, f, index, at),
        "system" => {
            parsed.system = f.join(" ");
            Ok(())
        }
        "molecules" => {
            let count = match f.get(1) {
                Some(n) => number(n, "molecule count", at)?,
                None => return Err(error(at, "[ molecules ] needs a name and a count")),
            };
            parsed.counts.push((f[0].clone(), count, index));
            Ok(())
        }
        _ => interaction(parsed, directive, f, index, at),
    }
}

fn defaults(parsed: &mut Parsed, f: &[String], at: &str) -> Result<()> {
    let nbfunc: u32 = number(&f[0], "nbfunc", at)?;
    if nbfunc != 1 {
        return Err(error(
            at,
            format!("[ defaults ] nbfunc {nbfunc}: only 1 (Lennard-Jones) is read"),
        ));
    }
    let comb_rule: u32 = match f.get(1) {
        Some(c) => number(c, "comb-rule", at)?,
        None => 1,
    };
    if !(1..=3).contains(&comb_rule) {
        return Err(error(
            at,
            format!("[ defaults ] comb-rule {comb_rule}: not 1, 2 or 3"),
        ));
    }
    let gen_pairs = f.get(2).is_some_and(|g| g.eq_ignore_ascii_case("yes"));
    let fudge =
        |k: usize, what: &str| -> Result<f64> { f.get(k).map_or(Ok(1.0), |v| number(v, what, at)) };
    parsed.defaults = Some(Defaults {
        comb_rule,
        gen_pairs,
        fudge_lj: fudge(3, "fudgeLJ")?,
        fudge_qq: fudge(4, "fudgeQQ")?,
    });
    Ok(())
}

/// `name [bond_type] [at.num] mass charge ptype V W`.
fn atomtype(parsed: &mut Parsed, f: &[String], at: &str) -> Result<()> {
    let n = f.len();
    if n == 2 && f[1].parse::<u32>().is_ok() {
        return Err(error(
            at,
            "a `name nrexcl` line under [ atomtypes ]: is the [ moleculetype ] header above it \
             missing?",
        )
        .key("moleculetype"));
    }
    if !(6..=8).contains(&n) {
        return Err(error(
            at,
            "[ atomtypes ] line: expected name [bond_type] [at.num] mass charge ptype V W",
        ));
    }
    if f[n - 3] != "A" {
        return Err(error(
            at,
            format!(
                "[ atomtypes ] ptype {}: only A (atom) is modelled",
                f[n - 3]
            ),
        ));
    }
    let middle = &f[1..n - 5];
    let (bond_type, atomic_number) = match middle {
        [] => (f[0].clone(), None),
        [one] => match one.parse::<i64>() {
            Ok(z) => (f[0].clone(), Some(z)),
            Err(_) => (one.clone(), None),
        },
        [b, z] => (b.clone(), Some(number(z, "at.num", at)?)),
        _ => unreachable!("at most two fields between name and mass"),
    };
    parsed.atomtypes.push(AtomType {
        name: f[0].clone(),
        bond_type,
        atomic_number,
        mass: number(&f[n - 5], "mass", at)?,
        charge: number(&f[n - 4], "charge", at)?,
        v: number(&f[n - 2], "V", at)?,
        w: number(&f[n - 1], "W", at)?,
    });
    Ok(())
}

fn type_entry(
    table: &mut Vec<TypeEntry>,
    f: &[String],
    n_atoms: usize,
    index: usize,
    at: &str,
) -> Result<()> {
    if f.len() <= n_atoms {
        return Err(error(at, "a type line needs its atom types and a function"));
    }
    table.push(TypeEntry {
        types: f[..n_atoms].to_vec(),
        function: number(&f[n_atoms], "function", at)?,
        params: numbers(&f[n_atoms + 1..], at)?,
        at: index,
    });
    Ok(())
}

/// Four types, or the old two: `j k` of a proper (1, 3, 9), `i l` of an improper (2, 4).
fn dihedraltype(parsed: &mut Parsed, f: &[String], index: usize, at: &str) -> Result<()> {
    let two = f.len() > 2 && f[2].parse::<u32>().is_ok();
    if !two {
        return type_entry(&mut parsed.dihedraltypes, f, 4, index, at);
    }
    let function: u32 = number(&f[2], "function", at)?;
    let x = || "X".to_string();
    let types = if matches!(function, 2 | 4) {
        vec![f[0].clone(), x(), x(), f[1].clone()]
    } else {
        vec![x(), f[0].clone(), f[1].clone(), x()]
    };
    parsed.dihedraltypes.push(TypeEntry {
        types,
        function,
        params: numbers(&f[3..], at)?,
        at: index,
    });
    Ok(())
}

/// `nr type resnr residue atom cgnr [charge [mass]]`.
fn molecule_atom(parsed: &mut Parsed, f: &[String], index: usize, at: &str) -> Result<()> {
    if f.len() < 5 {
        return Err(error(
            at,
            "[ atoms ] line: expected nr type resnr residue atom cgnr [charge [mass]]",
        ));
    }
    if f.len() > 8 {
        return Err(error(
            at,
            "[ atoms ] B-state (free-energy) columns: longstep models one state",
        ));
    }
    let molecule = parsed.molecules.last_mut().expect("checked as it opened");
    let nr: usize = number(&f[0], "atom number", at)?;
    if nr != molecule.atoms.len() + 1 {
        return Err(error(
            at,
            format!(
                "atom number {nr}: expected {} (atoms are numbered 1, 2, … in order)",
                molecule.atoms.len() + 1
            ),
        ));
    }
    let optional = |k: usize, what: &str| -> Result<Option<f64>> {
        f.get(k).map(|v| number(v, what, at)).transpose()
    };
    molecule.atoms.push(MolAtom {
        type_name: f[1].clone(),
        residue_number: f[2].clone(),
        residue: f[3].clone(),
        name: f[4].clone(),
        charge: optional(6, "charge")?,
        mass: optional(7, "mass")?,
        at: index,
    });
    Ok(())
}

/// `[settles]`: `O funct d_OH d_HH`, the oxygen and the two atoms after it in the
/// molecule; one line per molecule type (GROMACS allows one).
fn settle(parsed: &mut Parsed, f: &[String], index: usize, at: &str) -> Result<()> {
    let molecule = parsed.molecules.last_mut().expect("checked as it opened");
    if !molecule.settles.is_empty() {
        return Err(error(
            at,
            format!(
                "[ settles ]: a second line in molecule {}; GROMACS takes one (a molecule \
                 type is one water)",
                molecule.name
            ),
        ));
    }
    if f.len() < 2 {
        return Err(error(
            at,
            "[ settles ] line: expected the oxygen, a function and d_OH, d_HH",
        ));
    }
    let o: usize = number(&f[0], "atom number", at)?;
    let n = molecule.atoms.len();
    if o == 0 || o + 2 > n {
        return Err(error(
            at,
            format!(
                "[ settles ] oxygen {o}: SETTLE needs atoms {o}, {}, {} and molecule {} has \
                 atoms 1 to {n}",
                o + 1,
                o + 2,
                molecule.name
            ),
        ));
    }
    molecule.settles.push(Interaction {
        atoms: vec![o - 1],
        function: number(&f[1], "function", at)?,
        params: numbers(&f[2..], at)?,
        at: index,
    });
    Ok(())
}

/// A `[bonds]`, `[angles]`, `[dihedrals]`, `[pairs]` or `[exclusions]` line.
fn interaction(
    parsed: &mut Parsed,
    directive: &str,
    f: &[String],
    index: usize,
    at: &str,
) -> Result<()> {
    let molecule = parsed.molecules.last_mut().expect("checked as it opened");
    let n_atoms = match directive {
        "bonds" | "pairs" => 2,
        "angles" => 3,
        "dihedrals" => 4,
        _ => f.len(),
    };
    if f.len() < n_atoms || (directive != "exclusions" && f.len() == n_atoms) {
        return Err(error(
            at,
            format!("[ {directive} ] line: expected {n_atoms} atoms and a function"),
        ));
    }
    let mut atoms = Vec::with_capacity(n_atoms);
    for field in &f[..n_atoms] {
        let k: usize = number(field, "atom number", at)?;
        if k == 0 || k > molecule.atoms.len() {
            return Err(error(
                at,
                format!(
                    "atom {k}: molecule {} has atoms 1 to {}",
                    molecule.name,
                    molecule.atoms.len()
                ),
            ));
        }
        atoms.push(k - 1);
    }
    let (function, params) = if directive == "exclusions" {
        (0, Vec::new())
    } else {
        (
            number(&f[n_atoms], "function", at)?,
            numbers(&f[n_atoms + 1..], at)?,
        )
    };
    let item = Interaction {
        atoms,
        function,
        params,
        at: index,
    };
    match directive {
        "bonds" => molecule.bonds.push(item),
        "angles" => molecule.angles.push(item),
        "dihedrals" => molecule.dihedrals.push(item),
        "pairs" => molecule.pairs.push(item),
        _ => molecule.exclusions.push(item),
    }
    Ok(())
}
