//! GROMACS topologies (`.top` with its `.itp` includes) into a [`Topology`]: the
//! [`preprocess`]or, the [`directives`] read into tables, and here the molecules laid out
//! in `[molecules]` order with their parameters (inline, or looked up in the type tables
//! as `grompp` does, `X` a wildcard) converted from GROMACS's units (nm, kJ/mol, degrees)
//! to longstep's (Å, kcal/mol, radians).
//!
//! Terms read: bonds 1 `½k(r − r₀)²`; angles 1 `½k(θ − θ₀)²` and 5 (Urey–Bradley: the
//! angle plus a harmonic 1-3 bond); dihedrals 1, 9 (several cosines per quartet) and 4
//! (improper) `k(1 + cos(nφ − φₛ))`; dihedrals 2 (harmonic improper `½k(ξ − ξ₀)²`, the
//! difference in (−π, π]); dihedrals 3 (Ryckaert–Bellemans `Σₙ Cₙ cosⁿψ`, ψ = φ − 180°,
//! n ≤ 5), rewritten exactly as a cosine series in φ (see [`ryckaert_bellemans`]); pairs 1
//! with `fudgeQQ` and their own 1-4 LJ (inline, else `[pairtypes]`, as given: what ParmEd
//! and acpype write with `gen-pairs no`, `fudgeLJ 1`), else with `gen-pairs yes` `fudgeLJ`
//! × the atom types' LJ; exclusions from the bond graph up to `nrexcl` bonds plus `[exclusions]`;
//! `[settles]` (rigid water: no bonded terms, the O-H and H-H distances held by SETTLE in
//! a run, its three pairs excluded). Restraints, constraints, virtual sites and
//! `[nonbond_params]` are refused with their file and line. Cost: linear in the listed
//! interactions (the type lookups scan their table).

pub mod directives;
pub mod preprocess;

use std::collections::{BTreeSet, HashMap};
use std::path::Path;

use super::{
    Angle, Bond, DihedralTerm, HarmonicDihedral, LjTable, Pair14, Residue, Settle, Topology,
    TopologyAtom, element_of_mass, element_of_number,
};
use crate::error::Result;
use directives::{AtomType, Defaults, Interaction, MoleculeType, Parsed, TypeEntry, error};

/// kJ per kcal.
const KJ_PER_KCAL: f64 = 4.184;
/// Å per nm.
const ANGSTROM_PER_NM: f64 = 10.0;

/// Read `path` with `defines` (`NAME` or `NAME=value`, as `grompp -DNAME`).
pub fn read_gromacs_top(path: &Path, defines: &[String]) -> Result<Topology> {
    let source = preprocess::preprocess(path, defines)?;
    let parsed = directives::parse(&source)?;
    let location = path.display().to_string();
    let defaults = parsed
        .defaults
        .clone()
        .ok_or_else(|| error(&location, "no [ defaults ] directive"))?;
    if parsed.counts.is_empty() {
        return Err(error(
            &location,
            "no [ molecules ]: the system has no atoms",
        ));
    }
    let mut topology = Topology {
        source: path.to_path_buf(),
        format: "GROMACS top",
        title: parsed.system.clone(),
        ..Topology::default()
    };
    let types = lj_types(&parsed, &mut topology)?;
    let mut ryckaert_bellemans = 0;
    for (name, count, at) in &parsed.counts {
        let molecule = parsed
            .molecules
            .iter()
            .find(|m| &m.name == name)
            .ok_or_else(|| {
                error(
                    &parsed.lines[*at],
                    format!("[ molecules ] {name}: no [ moleculetype ] of that name"),
                )
            })?;
        let layout = Layout::new(&parsed, &defaults, &types, molecule)?;
        for _ in 0..*count {
            layout.append(&mut topology);
        }
        ryckaert_bellemans += layout.ryckaert_bellemans * count;
    }
    if ryckaert_bellemans > 0 {
        topology.notes.push(format!(
            "Ryckaert-Bellemans dihedrals (function 3): {ryckaert_bellemans}, each written \
             exactly as its cosine series in φ among the proper dihedrals (term \"torsions\")"
        ));
    }
    finish(&mut topology, &defaults);
    Ok(topology)
}

/// The atom types the molecules use, numbered in order of first use, and their LJ table.
fn lj_types(parsed: &Parsed, topology: &mut Topology) -> Result<HashMap<String, usize>> {
    let mut used: Vec<&AtomType> = Vec::new();
    let mut index = HashMap::new();
    for molecule in &parsed.molecules {
        for atom in &molecule.atoms {
            if index.contains_key(&atom.type_name) {
                continue;
            }
            let t = parsed
                .atomtypes
                .iter()
                .find(|t| t.name == atom.type_name)
                .ok_or_else(|| {
                    error(
                        &parsed.lines[atom.at],
                        format!("atom type {}: not in [ atomtypes ]", atom.type_name),
                    )
                })?;
            index.insert(atom.type_name.clone(), used.len());
            used.push(t);
        }
    }
    let comb = parsed.defaults.as_ref().map_or(2, |d| d.comb_rule);
    let n = used.len();
    let mut lj = LjTable {
        n_types: n,
        c12: vec![0.0; n * n],
        c6: vec![0.0; n * n],
    };
    for (a, ta) in used.iter().enumerate() {
        for (b, tb) in used.iter().enumerate() {
            let (c12, c6) = combine(comb, ta, tb);
            lj.c12[a * n + b] = c12;
            lj.c6[a * n + b] = c6;
        }
    }
    topology.lj = lj;
    Ok(index)
}

/// `(c12, c6)` in kcal/mol·Å¹², kcal/mol·Å⁶ of two atom types by combination rule `comb`.
fn combine(comb: u32, a: &AtomType, b: &AtomType) -> (f64, f64) {
    let length6 = ANGSTROM_PER_NM.powi(6);
    if comb == 1 {
        let c6 = (a.v * b.v).sqrt() * length6 / KJ_PER_KCAL;
        let c12 = (a.w * b.w).sqrt() * length6 * length6 / KJ_PER_KCAL;
        return (c12, c6);
    }
    let sigma = if comb == 2 {
        0.5 * (a.v + b.v)
    } else {
        (a.v * b.v).sqrt()
    } * ANGSTROM_PER_NM;
    let epsilon = (a.w * b.w).sqrt() / KJ_PER_KCAL;
    let s6 = sigma.powi(6);
    (4.0 * epsilon * s6 * s6, 4.0 * epsilon * s6)
}

/// One molecule type's atoms and terms, 0-based within the molecule, in longstep units.
struct Layout {
    atoms: Vec<TopologyAtom>,
    residues: Vec<Residue>,
    bonds: Vec<Bond>,
    angles: Vec<Angle>,
    dihedrals: Vec<DihedralTerm>,
    harmonic_dihedrals: Vec<HarmonicDihedral>,
    pairs: Vec<Pair14>,
    exclusions: Vec<(usize, usize)>,
    settles: Vec<Settle>,
    /// How many of the dihedrals are Ryckaert–Bellemans (function 3), for the report.
    ryckaert_bellemans: usize,
}

impl Layout {
    fn new(
        parsed: &Parsed,
        defaults: &Defaults,
        types: &HashMap<String, usize>,
        molecule: &MoleculeType,
    ) -> Result<Layout> {
        let (atoms, residues) = molecule_atoms(parsed, types, molecule)?;
        let bond_types: Vec<&str> = molecule
            .atoms
            .iter()
            .map(|a| {
                parsed
                    .atomtypes
                    .iter()
                    .find(|t| t.name == a.type_name)
                    .map_or(a.type_name.as_str(), |t| t.bond_type.as_str())
            })
            .collect();
        let mut layout = Layout {
            atoms,
            residues,
            bonds: Vec::new(),
            angles: Vec::new(),
            dihedrals: Vec::new(),
            harmonic_dihedrals: Vec::new(),
            pairs: Vec::new(),
            exclusions: Vec::new(),
            settles: Vec::new(),
            ryckaert_bellemans: 0,
        };
        let ctx = Context {
            parsed,
            bond_types: &bond_types,
        };
        for item in &molecule.bonds {
            layout.bonds.push(ctx.bond(item)?);
        }
        for item in &molecule.angles {
            ctx.angle(item, &mut layout)?;
        }
        for item in &molecule.dihedrals {
            ctx.dihedral(item, &mut layout)?;
        }
        for item in &molecule.pairs {
            layout.pairs.push(ctx.pair(item, defaults)?);
        }
        for item in &molecule.settles {
            layout.settles.push(ctx.settle(item, &layout.atoms)?);
        }
        layout.exclusions = exclusions(molecule);
        Ok(layout)
    }

    /// This molecule once more at the end of `topology`.
    fn append(&self, topology: &mut Topology) {
        let o = topology.atoms.len();
        let r = topology.residues.len();
        topology
            .atoms
            .extend(self.atoms.iter().map(|a| TopologyAtom {
                residue: a.residue + r,
                ..a.clone()
            }));
        topology
            .residues
            .extend(self.residues.iter().map(|res| Residue {
                name: res.name.clone(),
                first_atom: res.first_atom + o,
            }));
        let shift = |atoms: &[usize]| atoms.iter().map(|a| a + o).collect::<Vec<_>>();
        for b in &self.bonds {
            let a = shift(&b.atoms);
            topology.bonds.push(Bond {
                atoms: [a[0], a[1]],
                ..*b
            });
        }
        for x in &self.angles {
            let a = shift(&x.atoms);
            topology.angles.push(Angle {
                atoms: [a[0], a[1], a[2]],
                ..*x
            });
        }
        for d in &self.dihedrals {
            let a = shift(&d.atoms);
            topology.dihedrals.push(DihedralTerm {
                atoms: [a[0], a[1], a[2], a[3]],
                ..*d
            });
        }
        for d in &self.harmonic_dihedrals {
            let a = shift(&d.atoms);
            topology.harmonic_dihedrals.push(HarmonicDihedral {
                atoms: [a[0], a[1], a[2], a[3]],
                ..*d
            });
        }
        for w in &self.settles {
            let a = shift(&w.atoms);
            topology.settles.push(Settle {
                atoms: [a[0], a[1], a[2]],
                ..*w
            });
        }
        for p in &self.pairs {
            topology.pairs_14.push(Pair14 {
                atoms: [p.atoms[0] + o, p.atoms[1] + o],
                ..*p
            });
        }
        topology
            .exclusions
            .extend(self.exclusions.iter().map(|(i, j)| (i + o, j + o)));
    }
}

/// The molecule's atoms (charge and mass from `[atoms]`, else from the type) and residues.
fn molecule_atoms(
    parsed: &Parsed,
    types: &HashMap<String, usize>,
    molecule: &MoleculeType,
) -> Result<(Vec<TopologyAtom>, Vec<Residue>)> {
    let mut atoms = Vec::with_capacity(molecule.atoms.len());
    let mut residues: Vec<Residue> = Vec::new();
    let mut last_residue: Option<(&str, &str)> = None;
    for (k, a) in molecule.atoms.iter().enumerate() {
        let t = parsed
            .atomtypes
            .iter()
            .find(|t| t.name == a.type_name)
            .ok_or_else(|| {
                error(
                    &parsed.lines[a.at],
                    format!("atom type {}: not in [ atomtypes ]", a.type_name),
                )
            })?;
        let key = (a.residue_number.as_str(), a.residue.as_str());
        if last_residue != Some(key) {
            residues.push(Residue {
                name: a.residue.clone(),
                first_atom: k,
            });
            last_residue = Some(key);
        }
        let mass = a.mass.unwrap_or(t.mass);
        if !(mass.is_finite() && mass > 0.0) {
            return Err(error(
                &parsed.lines[a.at],
                format!(
                    "atom {} ({}): mass {mass} ({}): an atom's mass must be positive",
                    k + 1,
                    a.name,
                    if a.mass.is_some() {
                        "[ atoms ]"
                    } else {
                        "its [ atomtypes ] entry"
                    }
                ),
            ));
        }
        let element = match t.atomic_number {
            Some(z) if z > 0 => element_of_number(z),
            _ => element_of_mass(mass),
        };
        atoms.push(TopologyAtom {
            name: a.name.clone(),
            residue: residues.len() - 1,
            element: element.to_string(),
            mass,
            charge: a.charge.unwrap_or(t.charge),
            lj_type: types[&a.type_name],
        });
    }
    Ok((atoms, residues))
}

/// Pairs within `nrexcl` bonds of each other, and the listed exclusions, `(i < j)`.
fn exclusions(molecule: &MoleculeType) -> Vec<(usize, usize)> {
    let n = molecule.atoms.len();
    let mut neighbours = vec![Vec::new(); n];
    for b in &molecule.bonds {
        neighbours[b.atoms[0]].push(b.atoms[1]);
        neighbours[b.atoms[1]].push(b.atoms[0]);
    }
    let mut set = BTreeSet::new();
    for start in 0..n {
        let mut frontier = vec![start];
        let mut seen = BTreeSet::from([start]);
        for _ in 0..molecule.nrexcl {
            let next: Vec<usize> = frontier
                .iter()
                .flat_map(|&a| neighbours[a].iter().copied())
                .filter(|b| seen.insert(*b))
                .collect();
            frontier = next;
        }
        set.extend(seen.into_iter().filter(|&b| b > start).map(|b| (start, b)));
    }
    for w in &molecule.settles {
        let (o, h1, h2) = (w.atoms[0], w.atoms[0] + 1, w.atoms[0] + 2);
        set.extend([(o, h1), (o, h2), (h1, h2)]);
    }
    for e in &molecule.exclusions {
        for &other in &e.atoms[1..] {
            let (i, j) = (e.atoms[0].min(other), e.atoms[0].max(other));
            if i != j {
                set.insert((i, j));
            }
        }
    }
    set.into_iter().collect()
}

/// Sort and deduplicate the exclusions; count the bonds with hydrogen; note the defaults.
fn finish(topology: &mut Topology, defaults: &Defaults) {
    topology.exclusions.sort_unstable();
    topology.exclusions.dedup();
    let is_h = |a: usize| topology.atoms[a].element == "H";
    topology.bonds_with_hydrogen = topology
        .bonds
        .iter()
        .filter(|b| is_h(b.atoms[0]) || is_h(b.atoms[1]))
        .count();
    topology.notes.push(format!(
        "GROMACS [ defaults ]: comb-rule {}, gen-pairs {}, fudgeLJ {}, fudgeQQ {}",
        defaults.comb_rule,
        if defaults.gen_pairs { "yes" } else { "no" },
        defaults.fudge_lj,
        defaults.fudge_qq
    ));
}

/// The lookups of one molecule's interactions.
struct Context<'a> {
    parsed: &'a Parsed,
    bond_types: &'a [&'a str],
}

impl Context<'_> {
    fn at(&self, item: &Interaction) -> &str {
        &self.parsed.lines[item.at]
    }

    fn unsupported(&self, item: &Interaction, what: &str) -> crate::error::Error {
        error(
            self.at(item),
            format!(
                "[ {what} ] function {}: not a term longstep models",
                item.function
            ),
        )
    }

    /// The inline parameters, or those of the best matching type entries (all lines of
    /// the best match, for dihedral function 9).
    fn params(
        &self,
        item: &Interaction,
        table: &[TypeEntry],
        functions: &[u32],
        what: &str,
    ) -> Result<Vec<Vec<f64>>> {
        if !item.params.is_empty() {
            return Ok(vec![item.params.clone()]);
        }
        let names: Vec<&str> = item.atoms.iter().map(|&a| self.bond_types[a]).collect();
        let found = lookup(table, &names, functions);
        if found.is_empty() {
            return Err(error(
                self.at(item),
                format!(
                    "[ {what} ] of types {}: no parameters inline and none in [ {what}types ]",
                    names.join(" ")
                ),
            ));
        }
        Ok(found.into_iter().map(|e| e.params.clone()).collect())
    }

    fn need(&self, item: &Interaction, p: &[f64], n: usize, what: &str) -> Result<()> {
        if p.len() < n {
            return Err(error(
                self.at(item),
                format!(
                    "[ {what} ] function {}: needs {n} parameters",
                    item.function
                ),
            ));
        }
        Ok(())
    }

    /// A harmonic force constant must not be negative: the term would push its atoms
    /// apart without bound.
    fn not_negative(&self, item: &Interaction, k: f64, what: &str) -> Result<()> {
        if k >= 0.0 {
            return Ok(());
        }
        Err(error(
            self.at(item),
            format!(
                "[ {what} ] force constant {k}: negative (the term would push its atoms \
                 apart without bound)"
            ),
        ))
    }

    fn bond(&self, item: &Interaction) -> Result<Bond> {
        if item.function != 1 {
            return Err(self.unsupported(item, "bonds"));
        }
        let p = self
            .params(item, &self.parsed.bondtypes, &[1], "bond")?
            .remove(0);
        self.need(item, &p, 2, "bonds")?;
        self.not_negative(item, p[1], "bonds")?;
        Ok(harmonic_bond([item.atoms[0], item.atoms[1]], p[0], p[1]))
    }

    fn angle(&self, item: &Interaction, layout: &mut Layout) -> Result<()> {
        if !matches!(item.function, 1 | 5) {
            return Err(self.unsupported(item, "angles"));
        }
        let p = self
            .params(item, &self.parsed.angletypes, &[item.function], "angle")?
            .remove(0);
        let n = if item.function == 5 { 4 } else { 2 };
        self.need(item, &p, n, "angles")?;
        self.not_negative(item, p[1], "angles")?;
        let a = &item.atoms;
        layout.angles.push(Angle {
            atoms: [a[0], a[1], a[2]],
            k: p[1] / KJ_PER_KCAL,
            theta0: p[0].to_radians(),
        });
        if item.function == 5 && p[3] != 0.0 {
            layout.bonds.push(harmonic_bond([a[0], a[2]], p[2], p[3]));
        }
        Ok(())
    }

    fn dihedral(&self, item: &Interaction, layout: &mut Layout) -> Result<()> {
        let functions: &[u32] = match item.function {
            1 | 9 => &[1, 9],
            2..=4 => &[item.function],
            _ => return Err(self.unsupported(item, "dihedrals")),
        };
        let a = [item.atoms[0], item.atoms[1], item.atoms[2], item.atoms[3]];
        for p in self.params(item, &self.parsed.dihedraltypes, functions, "dihedral")? {
            match item.function {
                2 => {
                    self.need(item, &p, 2, "dihedrals")?;
                    layout.harmonic_dihedrals.push(HarmonicDihedral {
                        atoms: a,
                        k: p[1] / KJ_PER_KCAL,
                        xi0: p[0].to_radians(),
                    });
                }
                3 => {
                    self.need(item, &p, 6, "dihedrals")?;
                    let c: [f64; 6] = std::array::from_fn(|n| p[n] / KJ_PER_KCAL);
                    layout.dihedrals.extend(ryckaert_bellemans(a, &c));
                    layout.ryckaert_bellemans += 1;
                }
                _ => {
                    self.need(item, &p, 3, "dihedrals")?;
                    layout.dihedrals.push(DihedralTerm {
                        atoms: a,
                        k: p[1] / KJ_PER_KCAL,
                        periodicity: p[2],
                        phase: p[0].to_radians(),
                        improper: item.function == 4,
                    });
                }
            }
        }
        Ok(())
    }

    /// A rigid water: `[settles]` `O funct d_OH d_HH` (nm) of atoms O, O+1, O+2, which
    /// must be an oxygen and two hydrogens, the distances a triangle.
    fn settle(&self, item: &Interaction, atoms: &[TopologyAtom]) -> Result<Settle> {
        if item.function != 1 {
            return Err(self.unsupported(item, "settles"));
        }
        if item.params.len() != 2 {
            return Err(error(
                self.at(item),
                format!(
                    "[ settles ] needs the oxygen, the function and two distances (d_OH, d_HH, \
                     nm), got {} numbers after the function",
                    item.params.len()
                ),
            ));
        }
        let (oh, hh) = (
            item.params[0] * ANGSTROM_PER_NM,
            item.params[1] * ANGSTROM_PER_NM,
        );
        if !(oh > 0.0 && hh > 0.0 && hh < 2.0 * oh) {
            return Err(error(
                self.at(item),
                format!(
                    "[ settles ] d_OH {} nm, d_HH {} nm: not the sides of a water triangle \
                     (both > 0, d_HH < 2 d_OH)",
                    item.params[0], item.params[1]
                ),
            ));
        }
        let o = item.atoms[0];
        let elements: Vec<&str> = (o..o + 3).map(|k| atoms[k].element.as_str()).collect();
        if elements != ["O", "H", "H"] {
            return Err(error(
                self.at(item),
                format!(
                    "[ settles ] atoms {}-{} are {}: SETTLE holds an oxygen and the two \
                     hydrogens after it",
                    o + 1,
                    o + 3,
                    elements
                        .iter()
                        .map(|e| if e.is_empty() { "?" } else { e })
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ));
        }
        Ok(Settle {
            atoms: [o, o + 1, o + 2],
            oh,
            hh,
        })
    }

    /// A 1-4 pair: fudgeQQ, and its own LJ (inline, else from `[pairtypes]`, used as
    /// given, as `grompp` does), else with gen-pairs yes fudgeLJ × the atom types' LJ.
    fn pair(&self, item: &Interaction, d: &Defaults) -> Result<Pair14> {
        if item.function != 1 {
            return Err(self.unsupported(item, "pairs"));
        }
        let [i, j] = [item.atoms[0], item.atoms[1]];
        let explicit = if item.params.is_empty() {
            let names = [self.bond_types[i], self.bond_types[j]];
            lookup(&self.parsed.pairtypes, &names, &[1])
                .first()
                .map(|e| e.params.clone())
        } else {
            Some(item.params.clone())
        };
        let lj = match explicit {
            Some(p) => {
                self.need(item, &p, 2, "pairs")?;
                Some(explicit_lj(d.comb_rule, p[0], p[1]))
            }
            None if !d.gen_pairs => {
                return Err(error(
                    self.at(item),
                    "[ pairs ] without parameters, no [ pairtypes ] entry, and gen-pairs no",
                ));
            }
            None => None,
        };
        Ok(Pair14 {
            atoms: [i, j],
            coulomb_scale: d.fudge_qq,
            lj_scale: d.fudge_lj,
            lj,
        })
    }
}

/// `(c12, c6)` (kcal/mol·Å¹², ·Å⁶) of a pair's own parameters: c6, c12 (rule 1) or σ, ε.
fn explicit_lj(comb: u32, v: f64, w: f64) -> (f64, f64) {
    let length6 = ANGSTROM_PER_NM.powi(6);
    if comb == 1 {
        return (
            w * length6 * length6 / KJ_PER_KCAL,
            v * length6 / KJ_PER_KCAL,
        );
    }
    let s6 = (v * ANGSTROM_PER_NM).powi(6);
    let epsilon = w / KJ_PER_KCAL;
    (4.0 * epsilon * s6 * s6, 4.0 * epsilon * s6)
}

/// A Ryckaert–Bellemans dihedral `V = Σₙ Cₙ cosⁿψ` (n = 0…5, ψ = φ − π, kcal/mol) as
/// cosines of φ: with `aₙ = (−1)ⁿ Cₙ` (cos ψ = −cos φ) and the power-reduction formulas
/// (cos²φ = (1 + cos 2φ)/2, cos³φ = (3 cos φ + cos 3φ)/4, cos⁴φ = (3 + 4 cos 2φ + cos 4φ)/8,
/// cos⁵φ = (10 cos φ + 5 cos 3φ + cos 5φ)/16), `V = b₀ + Σₘ bₘ cos mφ`. Each `bₘ cos mφ`
/// is `|bₘ| (1 + cos(mφ − δ)) − |bₘ|` (δ = 0, or π for bₘ < 0), and the constant
/// `b₀ − Σ|bₘ|` a cosine of periodicity 0 and phase π/2 (`k (1 + cos(−π/2))` = k to 6e-17
/// relative): the same energy and forces as GROMACS's and OpenMM's `RBTorsionForce` to
/// round-off. Proper dihedrals; zero coefficients are left out.
fn ryckaert_bellemans(atoms: [usize; 4], c: &[f64; 6]) -> Vec<DihedralTerm> {
    let a: [f64; 6] = std::array::from_fn(|n| if n % 2 == 0 { c[n] } else { -c[n] });
    let b = [
        a[0] + a[2] / 2.0 + 3.0 * a[4] / 8.0,
        a[1] + 3.0 * a[3] / 4.0 + 5.0 * a[5] / 8.0,
        a[2] / 2.0 + a[4] / 2.0,
        a[3] / 4.0 + 5.0 * a[5] / 16.0,
        a[4] / 8.0,
        a[5] / 16.0,
    ];
    let term = |k: f64, periodicity: f64, phase: f64| DihedralTerm {
        atoms,
        k,
        periodicity,
        phase,
        improper: false,
    };
    let mut terms = Vec::new();
    let mut constant = b[0];
    for (m, &bm) in b.iter().enumerate().skip(1) {
        if bm != 0.0 {
            let phase = if bm < 0.0 { std::f64::consts::PI } else { 0.0 };
            terms.push(term(bm.abs(), m as f64, phase));
            constant -= bm.abs();
        }
    }
    if constant != 0.0 {
        terms.push(term(constant, 0.0, std::f64::consts::FRAC_PI_2));
    }
    terms
}

/// `½k(r − r₀)²` from GROMACS's b₀ (nm), k (kJ/mol/nm²).
fn harmonic_bond(atoms: [usize; 2], b0: f64, k: f64) -> Bond {
    Bond {
        atoms,
        k: k / (KJ_PER_KCAL * ANGSTROM_PER_NM * ANGSTROM_PER_NM),
        r0: b0 * ANGSTROM_PER_NM,
    }
}

/// The entries of `table` of one of `functions` matching `names` forwards or backwards,
/// with the most non-wildcard types (the first such, and the lines that follow it with
/// the same types: a function 9 dihedral's several cosines).
fn lookup<'t>(table: &'t [TypeEntry], names: &[&str], functions: &[u32]) -> Vec<&'t TypeEntry> {
    let score = |e: &TypeEntry| -> Option<usize> {
        if !functions.contains(&e.function) || e.types.len() != names.len() {
            return None;
        }
        let matches = |order: &mut dyn Iterator<Item = &&str>| {
            e.types.iter().zip(order).all(|(t, n)| t == "X" || t == *n)
        };
        let fits = matches(&mut names.iter()) || matches(&mut names.iter().rev());
        fits.then(|| e.types.iter().filter(|t| *t != "X").count())
    };
    let mut best: Option<(usize, usize)> = None;
    for (k, e) in table.iter().enumerate() {
        if let Some(s) = score(e)
            && best.is_none_or(|(b, _)| s > b)
        {
            best = Some((s, k));
        }
    }
    let Some((_, first)) = best else {
        return Vec::new();
    };
    let types = &table[first].types;
    table[first..]
        .iter()
        .take_while(|e| &e.types == types && functions.contains(&e.function))
        .collect()
}
