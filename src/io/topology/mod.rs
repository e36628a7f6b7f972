//! Topologies: a user's complete force field read from a simulation package's files, one
//! file per format ([`prmtop`]: AMBER prmtop; [`inpcrd`]: its coordinates; [`gromacs`]:
//! GROMACS top/itp; [`gro`]: its coordinates), into one
//! format-neutral [`Topology`], which [`build`] turns into longstep's force terms.
//!
//! Units are longstep's real units: Å, amu, kcal/mol, e, radians. Every interaction is
//! listed explicitly — nothing is perceived or looked up — so the terms are the file's:
//!
//! * bonds `(k/2)(r − r₀)²` and angles `(k/2)(θ − θ₀)²` (AMBER's `K(x − x₀)²` has `k = 2K`);
//! * dihedrals `k (1 + cos(nφ − δ))`, several cosines per quartet, proper and improper
//!   (an AMBER improper is the same cosine of the dihedral angle of its four atoms, listed
//!   with the central atom third);
//! * Lennard-Jones `c₁₂/r¹² − c₆/r⁶` per pair of atom types (AMBER's A and B coefficients,
//!   not a mixing rule), Coulomb between the atoms' charges;
//! * 1-4 pairs computed on their own, without cutoff, with Coulomb × `coulomb_scale` and
//!   Lennard-Jones × `lj_scale` (AMBER: 1/SCEE and 1/SCNB) or the pair's own Lennard-Jones
//!   (GROMACS explicit 1-4 parameters), as OpenMM's `NonbondedForce` exceptions;
//! * the exclusions: pairs the non-bonded term leaves out (1-2, 1-3 and 1-4 pairs).

pub mod build;
mod fortran;
pub mod gro;
pub mod gromacs;
pub mod inpcrd;
pub mod prmtop;

use std::path::PathBuf;

pub use build::{BuiltTopology, Coulomb, NonbondedOptions, build_terms};

/// One atom.
#[derive(Clone, Debug, PartialEq)]
pub struct TopologyAtom {
    pub name: String,
    /// Index into [`Topology::residues`].
    pub residue: usize,
    /// Element symbol (`""` when the file gives none and the mass names none).
    pub element: String,
    /// amu.
    pub mass: f64,
    /// e.
    pub charge: f64,
    /// Index into the Lennard-Jones table.
    pub lj_type: usize,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Residue {
    pub name: String,
    pub first_atom: usize,
}

/// Lennard-Jones coefficients per pair of types, `n_types × n_types`, symmetric:
/// `V = c12/r¹² − c6/r⁶` (kcal/mol·Å¹², kcal/mol·Å⁶).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LjTable {
    pub n_types: usize,
    pub c12: Vec<f64>,
    pub c6: Vec<f64>,
}

impl LjTable {
    pub fn pair(&self, a: usize, b: usize) -> (f64, f64) {
        let k = a * self.n_types + b;
        (self.c12[k], self.c6[k])
    }
}

/// `(k/2)(r − r₀)²`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bond {
    pub atoms: [usize; 2],
    pub k: f64,
    pub r0: f64,
}

/// `(k/2)(θ − θ₀)²`, θ at the middle atom, radians.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Angle {
    pub atoms: [usize; 3],
    pub k: f64,
    pub theta0: f64,
}

/// One cosine `k (1 + cos(nφ − δ))` of the dihedral angle of `atoms`; a quartet with
/// several cosines is listed once per cosine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DihedralTerm {
    pub atoms: [usize; 4],
    pub k: f64,
    pub periodicity: f64,
    /// δ, radians.
    pub phase: f64,
    pub improper: bool,
}

/// A 1-4 pair with its scale factors (AMBER: 1/SCEE, 1/SCNB), or its own Lennard-Jones.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pair14 {
    pub atoms: [usize; 2],
    pub coulomb_scale: f64,
    /// Scales the atom types' Lennard-Jones when the pair has none of its own.
    pub lj_scale: f64,
    /// The pair's own `(c12, c6)` (kcal/mol·Å¹², kcal/mol·Å⁶), used as they are (GROMACS
    /// `[ pairs ]`/`[ pairtypes ]` parameters): `lj_scale` does not apply.
    pub lj: Option<(f64, f64)>,
}

/// A rigid three-site water (GROMACS `[settles]`): no bonded terms, its O-H and H-H
/// distances held by SETTLE in a run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settle {
    /// Oxygen, hydrogen, hydrogen.
    pub atoms: [usize; 3],
    /// O-H distance (Å).
    pub oh: f64,
    /// H-H distance (Å).
    pub hh: f64,
}

/// A harmonic dihedral `(k/2)(ξ − ξ₀)²` of the dihedral angle ξ (GROMACS improper
/// function 2), the difference taken in (−π, π].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HarmonicDihedral {
    pub atoms: [usize; 4],
    /// kcal/mol/rad².
    pub k: f64,
    /// ξ₀, radians.
    pub xi0: f64,
}

/// A complete force field over a fixed list of atoms.
#[derive(Clone, Debug, Default)]
pub struct Topology {
    /// The file it was read from and its format, for messages and reports.
    pub source: PathBuf,
    pub format: &'static str,
    pub title: String,
    pub atoms: Vec<TopologyAtom>,
    pub residues: Vec<Residue>,
    pub lj: LjTable,
    pub bonds: Vec<Bond>,
    /// How many of the bonds involve hydrogen (AMBER lists them apart).
    pub bonds_with_hydrogen: usize,
    pub angles: Vec<Angle>,
    pub dihedrals: Vec<DihedralTerm>,
    /// Harmonic dihedrals (GROMACS improper function 2).
    pub harmonic_dihedrals: Vec<HarmonicDihedral>,
    pub pairs_14: Vec<Pair14>,
    /// Pairs `(i, j)`, `i < j`, sorted, each once, left out of the non-bonded term.
    pub exclusions: Vec<(usize, usize)>,
    /// Rigid waters (GROMACS `[settles]` without the FLEXIBLE define): a run holds them
    /// by SETTLE, so it needs rigid water.
    pub settles: Vec<Settle>,
    /// Orthorhombic box edges (Å).
    pub periodic_box: Option<[f64; 3]>,
    /// How the reader read what a file may leave out (defaults it used), one line each.
    pub notes: Vec<String>,
}

impl Topology {
    pub fn total_charge(&self) -> f64 {
        self.atoms.iter().map(|a| a.charge).sum()
    }
}

/// Element symbols by atomic number (1–54 and the common ions beyond).
const ELEMENTS: &[&str] = &[
    "", "H", "He", "Li", "Be", "B", "C", "N", "O", "F", "Ne", "Na", "Mg", "Al", "Si", "P", "S",
    "Cl", "Ar", "K", "Ca", "Sc", "Ti", "V", "Cr", "Mn", "Fe", "Co", "Ni", "Cu", "Zn", "Ga", "Ge",
    "As", "Se", "Br", "Kr", "Rb", "Sr", "Y", "Zr", "Nb", "Mo", "Tc", "Ru", "Rh", "Pd", "Ag", "Cd",
    "In", "Sn", "Sb", "Te", "I", "Xe", "Cs", "Ba",
];

/// Standard atomic masses (amu) of the elements most force fields use, to name an atom
/// whose file gives no atomic number.
const MASSES: &[(&str, f64)] = &[
    ("H", 1.008),
    ("C", 12.011),
    ("N", 14.007),
    ("O", 15.999),
    ("F", 18.998),
    ("Na", 22.990),
    ("Mg", 24.305),
    ("P", 30.974),
    ("S", 32.06),
    ("Cl", 35.45),
    ("K", 39.098),
    ("Ca", 40.078),
    ("Zn", 65.38),
    ("Br", 79.904),
    ("I", 126.904),
];

/// The symbol of atomic number `z` (`""` when unknown or ≤ 0).
pub fn element_of_number(z: i64) -> &'static str {
    usize::try_from(z)
        .ok()
        .and_then(|z| ELEMENTS.get(z))
        .copied()
        .unwrap_or("")
}

/// The element whose standard mass is within 0.1 amu of `mass` (`""` if none; heavy
/// hydrogen of mass repartitioning is not recognised).
pub fn element_of_mass(mass: f64) -> &'static str {
    MASSES
        .iter()
        .find(|(_, m)| (m - mass).abs() < 0.1)
        .map_or("", |(e, _)| e)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn elements_by_number_and_mass() {
        assert_eq!(element_of_number(1), "H");
        assert_eq!(element_of_number(8), "O");
        assert_eq!(element_of_number(17), "Cl");
        assert_eq!(element_of_number(0), "");
        assert_eq!(element_of_number(-1), "");
        assert_eq!(element_of_number(500), "");
        assert_eq!(element_of_mass(12.01), "C");
        assert_eq!(element_of_mass(1.008), "H");
        assert_eq!(element_of_mass(3.024), "");
    }
}
