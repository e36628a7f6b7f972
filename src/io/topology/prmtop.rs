//! AMBER prmtop (the `%FLAG`/`%FORMAT` format of AMBER 7 and later, as tleap, ParmEd and
//! CHARMM-GUI write it) into a [`Topology`].
//!
//! Units in the file: charges in e × 18.2223 (so that `q_i q_j / r` is kcal/mol with r in
//! Å), masses in amu, bond and angle constants `K` of `K (x − x₀)²` in kcal/mol/Å² and
//! kcal/mol/rad² (longstep's `k = 2K`), angles and phases in radians, LJ `A`, `B` in
//! kcal/mol·Å¹² and kcal/mol·Å⁶. Atom indices in the bond, angle and dihedral lists are
//! `3 × (atom − 1)`; in a dihedral a negative third index means the 1-4 pair is not
//! computed for it (a second cosine of the quartet, or a ring), a negative fourth one an
//! improper. 1-4 pairs are scaled by 1/SCEE (Coulomb) and 1/SCNB (LJ) per dihedral type,
//! 1.2 and 2.0 when the file has no `SCEE_SCALE_FACTOR`/`SCNB_SCALE_FACTOR`.
//!
//! Refused, with the section named: CMAP (ff19SB, CHARMM), CHARMM's extra terms (chamber
//! files), non-zero 10-12 hydrogen-bond terms, the 12-6-4 `LENNARD_JONES_CCOEF`,
//! polarisabilities, extra points, perturbation and cap data, non-orthogonal boxes.
//! Every section's length is checked against `POINTERS`; an error names the file and the
//! line of the section's `%FLAG`.
//!
//! Cost: one pass over the text, O(atoms + interactions).

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use super::fortran::{self, FieldKind, Format};
use super::{
    Angle, Bond, DihedralTerm, LjTable, Pair14, Residue, Topology, TopologyAtom, element_of_mass,
    element_of_number,
};
use crate::error::{Error, Result};

/// AMBER's charge unit: e × 18.2223 (√332.0522…).
pub const CHARGE_FACTOR: f64 = 18.2223;
const SCEE_DEFAULT: f64 = 1.2;
const SCNB_DEFAULT: f64 = 2.0;

/// Read a prmtop file.
pub fn read_prmtop(path: &Path) -> Result<Topology> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    parse_prmtop(&text, path)
}

/// One `%FLAG` section: its name, the line of its flag (1-based), its format and its lines.
struct Section<'a> {
    name: &'a str,
    line: usize,
    format: Format,
    lines: Vec<(usize, &'a str)>,
}

/// The file split into sections, with the path for messages.
struct Sections<'a> {
    path: &'a Path,
    map: BTreeMap<&'a str, Section<'a>>,
    last_line: usize,
}

fn error_at(path: &Path, line: usize, message: impl Into<String>) -> Error {
    Error::topology(path, message).line(line)
}

/// An error in the section `%FLAG flag`, at `line`: `%FLAG flag: message`, the flag as
/// the key.
fn flag_error(path: &Path, line: usize, flag: &str, message: impl std::fmt::Display) -> Error {
    error_at(path, line, format!("%FLAG {flag}: {message}")).key(flag)
}

/// Close the last section (it must have had its `%FORMAT`) and check that there was one.
fn finish_sections<'a>(
    map: &mut BTreeMap<&'a str, Section<'a>>,
    current: Option<Section<'a>>,
    awaiting_format: bool,
    path: &Path,
) -> Result<()> {
    if let Some(section) = current {
        if awaiting_format {
            return Err(error_at(
                path,
                section.line,
                format!(
                    "%FLAG {} has no %FORMAT line (file truncated?)",
                    section.name
                ),
            )
            .key(section.name));
        }
        insert(map, section, path)?;
    }
    if map.is_empty() {
        return Err(error_at(path, 1, "no %FLAG sections: not an AMBER prmtop"));
    }
    Ok(())
}

impl<'a> Sections<'a> {
    fn split(text: &'a str, path: &'a Path) -> Result<Self> {
        let mut map: BTreeMap<&str, Section> = BTreeMap::new();
        let mut current: Option<Section> = None;
        let mut last_line = 0;
        let mut awaiting_format = false;
        for (index, line) in text.lines().enumerate() {
            let number = index + 1;
            last_line = number;
            if let Some(rest) = line.strip_prefix("%FLAG") {
                if awaiting_format {
                    return Err(error_at(path, number - 1, "%FLAG without a %FORMAT line"));
                }
                if let Some(done) = current.take() {
                    insert(&mut map, done, path)?;
                }
                let name = rest.trim();
                if name.is_empty() {
                    return Err(error_at(path, number, "%FLAG without a section name"));
                }
                current = Some(Section {
                    name,
                    line: number,
                    format: Format {
                        per_line: 1,
                        kind: FieldKind::Text,
                        width: 80,
                    },
                    lines: Vec::new(),
                });
                awaiting_format = true;
            } else if let Some(rest) = line.strip_prefix("%FORMAT") {
                let Some(section) = current.as_mut() else {
                    return Err(error_at(path, number, "%FORMAT before any %FLAG"));
                };
                section.format = fortran::parse_format(rest)
                    .map_err(|e| flag_error(path, number, section.name, e))?;
                awaiting_format = false;
            } else if line.starts_with("%VERSION") || line.starts_with("%COMMENT") {
                continue;
            } else if line.starts_with('%') {
                return Err(error_at(
                    path,
                    number,
                    format!("unknown directive \"{line}\""),
                ));
            } else if let Some(section) = current.as_mut() {
                if awaiting_format {
                    return Err(error_at(
                        path,
                        section.line,
                        format!("%FLAG {} has no %FORMAT line", section.name),
                    )
                    .key(section.name));
                }
                section.lines.push((number, line));
            } else if !line.trim().is_empty() {
                return Err(error_at(
                    path,
                    number,
                    "text before the first %FLAG: not an AMBER prmtop (the %FLAG format of \
                     AMBER 7 and later)",
                ));
            }
        }
        finish_sections(&mut map, current, awaiting_format, path)?;
        Ok(Sections {
            path,
            map,
            last_line,
        })
    }

    fn has(&self, name: &str) -> bool {
        self.map.contains_key(name)
    }

    fn section(&self, name: &str) -> Result<&Section<'a>> {
        self.map.get(name).ok_or_else(|| {
            error_at(
                self.path,
                self.last_line,
                format!("no %FLAG {name} section (a required section; file truncated?)"),
            )
            .key(name)
        })
    }

    fn error(&self, section: &Section, message: impl std::fmt::Display) -> Error {
        flag_error(self.path, section.line, section.name, message)
    }

    /// The fields of a section of `kind`, exactly `expected` of them when given.
    fn fields(
        &self,
        name: &str,
        kind: FieldKind,
        expected: Option<usize>,
    ) -> Result<Vec<(usize, &'a str)>> {
        let section = self.section(name)?;
        if section.format.kind != kind {
            return Err(self.error(
                section,
                format!(
                    "format {:?} where {kind:?} fields are expected",
                    section.format.kind
                ),
            ));
        }
        let mut out = Vec::new();
        for &(number, line) in &section.lines {
            let fields = fortran::fields(line, &section.format)
                .map_err(|e| flag_error(self.path, number, name, e))?;
            out.extend(fields.into_iter().map(|f| (number, f)));
        }
        if let Some(expected) = expected
            && out.len() != expected
        {
            return Err(self.error(
                section,
                format!(
                    "has {} values, POINTERS says {expected} (file truncated or corrupt?)",
                    out.len()
                ),
            ));
        }
        Ok(out)
    }

    fn integers(&self, name: &str, expected: Option<usize>) -> Result<Vec<i64>> {
        self.fields(name, FieldKind::Integer, expected)?
            .into_iter()
            .map(|(number, f)| {
                fortran::integer(f).map_err(|e| flag_error(self.path, number, name, e))
            })
            .collect()
    }

    fn reals(&self, name: &str, expected: Option<usize>) -> Result<Vec<f64>> {
        self.fields(name, FieldKind::Real, expected)?
            .into_iter()
            .map(|(number, f)| fortran::real(f).map_err(|e| flag_error(self.path, number, name, e)))
            .collect()
    }

    fn texts(&self, name: &str, expected: Option<usize>) -> Result<Vec<String>> {
        Ok(self
            .fields(name, FieldKind::Text, expected)?
            .into_iter()
            .map(|(_, f)| f.trim().to_string())
            .collect())
    }

    /// An atom index of a bond/angle/dihedral list: `3 × (atom − 1)`, sign dropped.
    fn atom(&self, name: &str, value: i64, n_atoms: usize) -> Result<usize> {
        let raw = value.unsigned_abs() as usize;
        if !raw.is_multiple_of(3) || raw / 3 >= n_atoms {
            let section = self.section(name)?;
            return Err(self.error(
                section,
                format!("atom index {value} is not 3 × (atom − 1) for one of the {n_atoms} atoms"),
            ));
        }
        Ok(raw / 3)
    }

    /// A 1-based parameter index into a table of `len` entries.
    fn parameter(&self, name: &str, value: i64, len: usize) -> Result<usize> {
        if value < 1 || value as usize > len {
            let section = self.section(name)?;
            return Err(self.error(
                section,
                format!("parameter index {value} outside 1..={len}"),
            ));
        }
        Ok(value as usize - 1)
    }
}

fn insert<'a>(
    map: &mut BTreeMap<&'a str, Section<'a>>,
    section: Section<'a>,
    path: &Path,
) -> Result<()> {
    if let Some(first) = map.get(section.name) {
        return Err(error_at(
            path,
            section.line,
            format!(
                "%FLAG {} appears twice (first at line {})",
                section.name, first.line
            ),
        )
        .key(section.name));
    }
    map.insert(section.name, section);
    Ok(())
}

/// The counts of `POINTERS` this reader uses.
struct Pointers {
    natom: usize,
    ntypes: usize,
    nbonh: usize,
    mbona: usize,
    ntheth: usize,
    mtheta: usize,
    nphih: usize,
    mphia: usize,
    nnb: usize,
    nres: usize,
    numbnd: usize,
    numang: usize,
    nptra: usize,
    nphb: usize,
    ifpert: usize,
    ifbox: usize,
    ifcap: usize,
    numextra: usize,
}

fn pointers(sections: &Sections) -> Result<Pointers> {
    let values = sections.integers("POINTERS", None)?;
    let section = sections.section("POINTERS")?;
    if values.len() < 30 {
        return Err(sections.error(
            section,
            format!("has {} values, at least 30 expected", values.len()),
        ));
    }
    if let Some(bad) = values.iter().find(|&&v| v < 0) {
        return Err(sections.error(section, format!("negative count {bad}")));
    }
    let at = |k: usize| values.get(k).map_or(0, |&v| v as usize);
    Ok(Pointers {
        natom: at(0),
        ntypes: at(1),
        nbonh: at(2),
        mbona: at(3),
        ntheth: at(4),
        mtheta: at(5),
        nphih: at(6),
        mphia: at(7),
        nnb: at(10),
        nres: at(11),
        numbnd: at(15),
        numang: at(16),
        nptra: at(17),
        nphb: at(19),
        ifpert: at(20),
        ifbox: at(27),
        ifcap: at(29),
        numextra: at(30),
    })
}

/// Parse prmtop text; `path` names the file in messages.
pub fn parse_prmtop(text: &str, path: &Path) -> Result<Topology> {
    let sections = Sections::split(text, path)?;
    let p = pointers(&sections)?;
    refuse_unsupported(&sections, &p)?;
    let mut topology = Topology {
        source: path.to_path_buf(),
        format: "AMBER prmtop",
        title: title(&sections)?,
        ..Topology::default()
    };
    topology.residues = residues(&sections, &p)?;
    topology.atoms = atoms(&sections, &p, &topology.residues, &mut topology.notes)?;
    topology.lj = lennard_jones(&sections, &p)?;
    bonds(&sections, &p, &mut topology)?;
    angles(&sections, &p, &mut topology)?;
    dihedrals(&sections, &p, &mut topology)?;
    topology.exclusions = exclusions(&sections, &p, &topology.pairs_14)?;
    topology.periodic_box = periodic_box(&sections, &p)?;
    Ok(topology)
}

fn title(sections: &Sections) -> Result<String> {
    for name in ["TITLE", "CTITLE"] {
        if sections.has(name) {
            return Ok(sections.texts(name, None)?.concat().trim().to_string());
        }
    }
    Ok(String::new())
}

/// Sections and settings of what longstep does not model: an error naming the first.
fn refuse_unsupported(sections: &Sections, p: &Pointers) -> Result<()> {
    let refuse = |name: &str, what: &str| -> Result<()> {
        let section = sections.section(name)?;
        Err(sections.error(section, format!("{what}: longstep does not model it")))
    };
    for name in sections.map.keys() {
        if name.contains("CMAP") {
            return refuse(name, "CMAP correction maps (ff19SB, CHARMM)");
        }
        if name.starts_with("CHARMM_") || name.starts_with("LENNARD_JONES_14_") {
            return refuse(name, "a CHARMM term (a chamber topology)");
        }
    }
    if sections.has("LENNARD_JONES_CCOEF") {
        return refuse("LENNARD_JONES_CCOEF", "the 12-6-4 r⁻⁴ Lennard-Jones term");
    }
    if sections.has("POLARIZABILITY")
        && sections
            .reals("POLARIZABILITY", None)?
            .iter()
            .any(|&a| a != 0.0)
    {
        return refuse("POLARIZABILITY", "non-zero atomic polarisabilities");
    }
    if sections.has("IPOL") && sections.integers("IPOL", None)?.iter().any(|&v| v != 0) {
        return refuse("IPOL", "a polarisable force field (IPOL ≠ 0)");
    }
    for name in ["HBOND_ACOEF", "HBOND_BCOEF"] {
        if sections.has(name)
            && sections
                .reals(name, Some(p.nphb))?
                .iter()
                .any(|&c| c != 0.0)
        {
            return refuse(name, "non-zero 10-12 hydrogen-bond terms");
        }
    }
    let flags = [
        (p.ifpert, "perturbation data (IFPERT ≠ 0)"),
        (p.ifcap, "a water cap (IFCAP ≠ 0)"),
        (p.numextra, "extra points / virtual sites (NUMEXTRA ≠ 0)"),
    ];
    for (value, what) in flags {
        if value != 0 {
            return refuse("POINTERS", what);
        }
    }
    if p.ifbox > 1 {
        return refuse("POINTERS", "a truncated-octahedron box (IFBOX = 2)");
    }
    Ok(())
}

fn residues(sections: &Sections, p: &Pointers) -> Result<Vec<Residue>> {
    let names = sections.texts("RESIDUE_LABEL", Some(p.nres))?;
    let pointers = sections.integers("RESIDUE_POINTER", Some(p.nres))?;
    let section = sections.section("RESIDUE_POINTER")?;
    let mut residues = Vec::with_capacity(p.nres);
    let mut previous = 0;
    for (name, &first) in names.into_iter().zip(&pointers) {
        if first < 1 || first as usize > p.natom || (first as usize) <= previous {
            return Err(sections.error(
                section,
                format!(
                    "residue start {first} not increasing within 1..={}",
                    p.natom
                ),
            ));
        }
        previous = first as usize;
        residues.push(Residue {
            name,
            first_atom: first as usize - 1,
        });
    }
    if p.natom > 0 && residues.first().is_none_or(|r| r.first_atom != 0) {
        return Err(sections.error(section, "the first residue does not start at atom 1"));
    }
    Ok(residues)
}

fn atoms(
    sections: &Sections,
    p: &Pointers,
    residues: &[Residue],
    notes: &mut Vec<String>,
) -> Result<Vec<TopologyAtom>> {
    let n = p.natom;
    let names = sections.texts("ATOM_NAME", Some(n))?;
    let charges = sections.reals("CHARGE", Some(n))?;
    let masses = sections.reals("MASS", Some(n))?;
    let types = sections.integers("ATOM_TYPE_INDEX", Some(n))?;
    let numbers = if sections.has("ATOMIC_NUMBER") {
        Some(sections.integers("ATOMIC_NUMBER", Some(n))?)
    } else {
        notes.push("elements: no ATOMIC_NUMBER section, named from the masses".into());
        None
    };
    let mass_section = sections.section("MASS")?;
    if let Some(bad) = masses.iter().position(|&m| m <= 0.0) {
        return Err(sections.error(
            mass_section,
            format!(
                "atom {} has mass {} (massless particles are not modelled)",
                bad + 1,
                masses[bad]
            ),
        ));
    }
    let mut residue = 0;
    let mut atoms = Vec::with_capacity(n);
    for i in 0..n {
        while residue + 1 < residues.len() && residues[residue + 1].first_atom <= i {
            residue += 1;
        }
        let lj_type = sections.parameter("ATOM_TYPE_INDEX", types[i], p.ntypes)?;
        let by_number = numbers.as_ref().map_or("", |z| element_of_number(z[i]));
        let element = if by_number.is_empty() {
            element_of_mass(masses[i])
        } else {
            by_number
        };
        atoms.push(TopologyAtom {
            name: names[i].clone(),
            residue,
            element: element.to_string(),
            mass: masses[i],
            charge: charges[i] / CHARGE_FACTOR,
            lj_type,
        });
    }
    Ok(atoms)
}

/// The `n_types × n_types` table through `NONBONDED_PARM_INDEX`; a negative index is a
/// 10-12 pair, zero here (non-zero 10-12 terms were refused).
fn lennard_jones(sections: &Sections, p: &Pointers) -> Result<LjTable> {
    let nt = p.ntypes;
    let index = sections.integers("NONBONDED_PARM_INDEX", Some(nt * nt))?;
    let len = nt * (nt + 1) / 2;
    let a = sections.reals("LENNARD_JONES_ACOEF", Some(len))?;
    let b = sections.reals("LENNARD_JONES_BCOEF", Some(len))?;
    let mut table = LjTable {
        n_types: nt,
        c12: vec![0.0; nt * nt],
        c6: vec![0.0; nt * nt],
    };
    for (k, &entry) in index.iter().enumerate() {
        if entry < 0 {
            continue;
        }
        let e = sections.parameter("NONBONDED_PARM_INDEX", entry, len)?;
        table.c12[k] = a[e];
        table.c6[k] = b[e];
    }
    for x in 0..nt {
        for y in 0..x {
            if table.pair(x, y) != table.pair(y, x) {
                let section = sections.section("NONBONDED_PARM_INDEX")?;
                return Err(sections.error(
                    section,
                    format!(
                        "types {} and {} index different coefficients each way",
                        y + 1,
                        x + 1
                    ),
                ));
            }
        }
    }
    Ok(table)
}

/// A harmonic force constant must not be negative (the term would push its atoms apart
/// without bound): the first that is, by its number in `section`.
fn not_negative(sections: &Sections, section: &str, k: &[f64]) -> Result<()> {
    let Some(bad) = k.iter().position(|&x| x.is_nan() || x < 0.0) else {
        return Ok(());
    };
    Err(sections.error(
        sections.section(section)?,
        format!(
            "force constant {} (entry {}) is negative: the term would push its atoms apart \
             without bound",
            k[bad],
            bad + 1
        ),
    ))
}

fn bonds(sections: &Sections, p: &Pointers, topology: &mut Topology) -> Result<()> {
    let k = sections.reals("BOND_FORCE_CONSTANT", Some(p.numbnd))?;
    not_negative(sections, "BOND_FORCE_CONSTANT", &k)?;
    let r0 = sections.reals("BOND_EQUIL_VALUE", Some(p.numbnd))?;
    let n = topology.atoms.len();
    for (name, count) in [
        ("BONDS_INC_HYDROGEN", p.nbonh),
        ("BONDS_WITHOUT_HYDROGEN", p.mbona),
    ] {
        let list = sections.integers(name, Some(3 * count))?;
        for entry in list.chunks_exact(3) {
            let atoms = [
                sections.atom(name, entry[0], n)?,
                sections.atom(name, entry[1], n)?,
            ];
            let t = sections.parameter(name, entry[2], p.numbnd)?;
            topology.bonds.push(Bond {
                atoms,
                k: 2.0 * k[t],
                r0: r0[t],
            });
        }
    }
    topology.bonds_with_hydrogen = p.nbonh;
    Ok(())
}

fn angles(sections: &Sections, p: &Pointers, topology: &mut Topology) -> Result<()> {
    let k = sections.reals("ANGLE_FORCE_CONSTANT", Some(p.numang))?;
    not_negative(sections, "ANGLE_FORCE_CONSTANT", &k)?;
    let theta0 = sections.reals("ANGLE_EQUIL_VALUE", Some(p.numang))?;
    let n = topology.atoms.len();
    for (name, count) in [
        ("ANGLES_INC_HYDROGEN", p.ntheth),
        ("ANGLES_WITHOUT_HYDROGEN", p.mtheta),
    ] {
        let list = sections.integers(name, Some(4 * count))?;
        for entry in list.chunks_exact(4) {
            let atoms = [
                sections.atom(name, entry[0], n)?,
                sections.atom(name, entry[1], n)?,
                sections.atom(name, entry[2], n)?,
            ];
            let t = sections.parameter(name, entry[3], p.numang)?;
            topology.angles.push(Angle {
                atoms,
                k: 2.0 * k[t],
                theta0: theta0[t],
            });
        }
    }
    Ok(())
}

/// SCEE and SCNB per dihedral type, the defaults when the file has none.
fn scale_factors(
    sections: &Sections,
    p: &Pointers,
    notes: &mut Vec<String>,
) -> Result<[Vec<f64>; 2]> {
    let mut out = [Vec::new(), Vec::new()];
    for (slot, (name, default)) in [
        ("SCEE_SCALE_FACTOR", SCEE_DEFAULT),
        ("SCNB_SCALE_FACTOR", SCNB_DEFAULT),
    ]
    .into_iter()
    .enumerate()
    {
        out[slot] = if sections.has(name) {
            sections.reals(name, Some(p.nptra))?
        } else {
            notes.push(format!(
                "1-4 scaling: no {name} section, {default} for every dihedral"
            ));
            vec![default; p.nptra]
        };
    }
    Ok(out)
}

/// Dihedral cosines and the 1-4 pairs of those whose third index is not negative.
fn dihedrals(sections: &Sections, p: &Pointers, topology: &mut Topology) -> Result<()> {
    let k = sections.reals("DIHEDRAL_FORCE_CONSTANT", Some(p.nptra))?;
    let n_fold = sections.reals("DIHEDRAL_PERIODICITY", Some(p.nptra))?;
    let phase = sections.reals("DIHEDRAL_PHASE", Some(p.nptra))?;
    let [scee, scnb] = scale_factors(sections, p, &mut topology.notes)?;
    let n = topology.atoms.len();
    let mut pairs: BTreeMap<(usize, usize), Pair14> = BTreeMap::new();
    for (name, count) in [
        ("DIHEDRALS_INC_HYDROGEN", p.nphih),
        ("DIHEDRALS_WITHOUT_HYDROGEN", p.mphia),
    ] {
        let list = sections.integers(name, Some(5 * count))?;
        for entry in list.chunks_exact(5) {
            let atoms: [usize; 4] = [
                sections.atom(name, entry[0], n)?,
                sections.atom(name, entry[1], n)?,
                sections.atom(name, entry[2], n)?,
                sections.atom(name, entry[3], n)?,
            ];
            let t = sections.parameter(name, entry[4], p.nptra)?;
            topology.dihedrals.push(DihedralTerm {
                atoms,
                k: k[t],
                periodicity: n_fold[t],
                phase: phase[t],
                improper: entry[3] < 0,
            });
            if entry[2] >= 0 {
                let key = (atoms[0].min(atoms[3]), atoms[0].max(atoms[3]));
                let scale = |s: f64| if s == 0.0 { 0.0 } else { 1.0 / s };
                pairs.entry(key).or_insert(Pair14 {
                    atoms: [key.0, key.1],
                    coulomb_scale: scale(scee[t]),
                    lj_scale: scale(scnb[t]),
                    lj: None,
                });
            }
        }
    }
    topology.pairs_14 = pairs.into_values().collect();
    Ok(())
}

/// `EXCLUDED_ATOMS_LIST`, `NUMBER_EXCLUDED_ATOMS` entries per atom (a lone 0: none), and
/// the 1-4 pairs, which are computed in their own terms.
fn exclusions(
    sections: &Sections,
    p: &Pointers,
    pairs_14: &[Pair14],
) -> Result<Vec<(usize, usize)>> {
    let counts = sections.integers("NUMBER_EXCLUDED_ATOMS", Some(p.natom))?;
    let list = sections.integers("EXCLUDED_ATOMS_LIST", Some(p.nnb))?;
    let section = sections.section("EXCLUDED_ATOMS_LIST")?;
    let total: i64 = counts.iter().sum();
    if counts.iter().any(|&c| c < 0) || total as usize != p.nnb {
        return Err(sections.error(
            sections.section("NUMBER_EXCLUDED_ATOMS")?,
            format!(
                "the counts add up to {total}, POINTERS says NNB = {}",
                p.nnb
            ),
        ));
    }
    let mut excluded: BTreeSet<(usize, usize)> = BTreeSet::new();
    let mut at = 0;
    for (i, &count) in counts.iter().enumerate() {
        for &j in &list[at..at + count as usize] {
            if j == 0 {
                continue;
            }
            if j < 0 || j as usize > p.natom || j as usize - 1 == i {
                return Err(sections.error(
                    section,
                    format!(
                        "atom {} excludes {j}, not another of the {} atoms",
                        i + 1,
                        p.natom
                    ),
                ));
            }
            let j = j as usize - 1;
            excluded.insert((i.min(j), i.max(j)));
        }
        at += count as usize;
    }
    excluded.extend(pairs_14.iter().map(|pair| (pair.atoms[0], pair.atoms[1])));
    Ok(excluded.into_iter().collect())
}

/// The orthorhombic box of `BOX_DIMENSIONS` (β, a, b, c) when IFBOX = 1.
fn periodic_box(sections: &Sections, p: &Pointers) -> Result<Option<[f64; 3]>> {
    if p.ifbox == 0 {
        return Ok(None);
    }
    let values = sections.reals("BOX_DIMENSIONS", Some(4))?;
    let section = sections.section("BOX_DIMENSIONS")?;
    if (values[0] - 90.0).abs() > 1e-6 {
        return Err(sections.error(
            section,
            format!(
                "angle β = {}°: a non-orthogonal box, longstep does not model it",
                values[0]
            ),
        ));
    }
    let lengths = [values[1], values[2], values[3]];
    if lengths.iter().any(|&l| l <= 0.0) {
        return Err(sections.error(section, format!("box lengths {lengths:?} must be positive")));
    }
    Ok(Some(lengths))
}
