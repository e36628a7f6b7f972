//! The non-bonded model of the short part pair by pair (Lennard-Jones and the Coulomb form
//! of [`crate::forces::nonbonded`], the minimum image) and the molecules' atom table.

use super::SplitSpec;
use crate::forces::MinimumImage;
use crate::forces::nonbonded::{CoulombPair, Electrostatics, LjPair, NonbondedSpec};

/// The non-bonded model pair by pair, and the minimum image.
pub(crate) struct Model {
    pub cutoff_squared: f64,
    pub(super) coulomb: CoulombPair,
    n_types: usize,
    types: Vec<u32>,
    lj: Vec<LjPair>,
    /// Whether a type has Lennard-Jones with any type.
    has_lj: Vec<bool>,
    /// `q_i √k_e`.
    scaled_charges: Vec<f64>,
    pub periodic: MinimumImage,
}

impl Model {
    /// The pair model of `spec` (types, Lennard-Jones table, charges scaled by `√k_e`,
    /// box), after checking the sizes agree with the positions `q`.
    pub(super) fn new(spec: &NonbondedSpec, q: &[f64]) -> Result<Model, String> {
        let n = spec.types.len();
        let n_types = spec.type_count(q, "non-bonded split")?;
        let root_ke = spec.coulomb_constant.sqrt();
        let scaled_charges = if spec.electrostatics == Electrostatics::None {
            vec![0.0; n]
        } else {
            spec.charges.iter().map(|c| c * root_ke).collect()
        };
        Ok(Model {
            cutoff_squared: spec.cutoff * spec.cutoff,
            coulomb: CoulombPair::new(spec.electrostatics, spec.cutoff)?,
            n_types,
            types: spec.types.clone(),
            lj: spec.lj.clone(),
            has_lj: (0..n_types)
                .map(|a| {
                    spec.lj[a * n_types..(a + 1) * n_types]
                        .iter()
                        .any(|p| p.c12 != 0.0 || p.c6 != 0.0 || p.shift != 0.0)
                })
                .collect(),
            scaled_charges,
            periodic: MinimumImage::new(spec.box_lengths),
        })
    }

    /// Minimum-image `x_j − x_i`.
    #[inline(always)]
    pub fn displacement(&self, q: &[f64], i: usize, j: usize) -> [f64; 3] {
        self.image(std::array::from_fn(|k| q[3 * j + k] - q[3 * i + k]))
    }

    #[inline(always)]
    pub(super) fn lj(&self, i: usize, j: usize) -> LjPair {
        self.lj[self.types[i] as usize * self.n_types + self.types[j] as usize]
    }

    /// `(V, −V′/r)` of pair `i, j` at `r² = s < r_c²`.
    #[inline(always)]
    pub fn energy_force(&self, i: usize, j: usize, s: f64) -> (f64, f64) {
        let (p, qq) = (
            self.lj(i, j),
            self.scaled_charges[i] * self.scaled_charges[j],
        );
        let inv_r2 = 1.0 / s;
        let (mut energy, mut force) = (0.0, 0.0);
        if p.c12 != 0.0 || p.c6 != 0.0 {
            (energy, force) = p.energy_force(inv_r2);
        }
        if qq != 0.0 {
            let (e, f) = self.coulomb.energy_force(qq, s, inv_r2.sqrt());
            energy += e;
            force += f;
        }
        (energy, force)
    }

    /// The Lennard-Jones coefficients of type `a` with every type, or `None` when they are
    /// all zero.
    #[inline(always)]
    pub fn lj_row(&self, a: u32) -> Option<&[LjPair]> {
        let row = &self.lj[a as usize * self.n_types..(a as usize + 1) * self.n_types];
        self.has_lj[a as usize].then_some(row)
    }

    /// The shortest periodic length (∞ for none).
    pub fn shortest_period(&self) -> f64 {
        let periods = self.periodic.period.into_iter().filter(|&l| l > 0.0);
        periods.fold(f64::INFINITY, f64::min)
    }

    /// Minimum image of a displacement `d`.
    #[inline(always)]
    pub fn image(&self, d: [f64; 3]) -> [f64; 3] {
        self.periodic.of(d)
    }

    /// `q_i √k_e` (0 without electrostatics).
    #[inline(always)]
    pub fn scaled_charge(&self, i: usize) -> f64 {
        self.scaled_charges[i]
    }

    /// `(V_LJ, V_Coulomb)` of pair `i, j` at `r² = s < r_c²` (for reports).
    pub fn energy_parts(&self, i: usize, j: usize, s: f64) -> (f64, f64) {
        let p = self.lj(i, j);
        let lj = p.energy_force(1.0 / s).0;
        let qq = self.scaled_charges[i] * self.scaled_charges[j];
        let coulomb = if qq != 0.0 {
            self.coulomb.energy_force(qq, s, 1.0 / s.sqrt()).0
        } else {
            0.0
        };
        (lj, coulomb)
    }

    /// `(V, V′, V″)` of pair `i, j` at `r < r_c`.
    pub fn derivatives(&self, i: usize, j: usize, r: f64) -> (f64, f64, f64) {
        let (mut v, mut d1, mut d2) = self.lj(i, j).derivatives(r);
        let qq = self.scaled_charges[i] * self.scaled_charges[j];
        if qq != 0.0 {
            let (e, a, b) = self.coulomb.derivatives(qq, r);
            v += e;
            d1 += a;
            d2 += b;
        }
        (v, d1, d2)
    }
}

/// Atoms of each molecule (CSR) and their reference atoms.
pub(crate) struct Molecules {
    pub start: Vec<u32>,
    /// Atoms in molecule order (global indices).
    pub atoms: Vec<u32>,
    pub reference: Vec<u32>,
    /// Position of each reference atom in `atoms`.
    pub reference_slot: Vec<u32>,
    /// Type of each atom of `atoms`.
    pub types: Vec<u32>,
    /// The atom count of every molecule when they all have the same, else 0.
    pub uniform_size: usize,
}

impl Molecules {
    #[inline(always)]
    pub fn atoms(&self, m: usize) -> &[u32] {
        &self.atoms[self.start[m] as usize..self.start[m + 1] as usize]
    }
}

/// Atoms per molecule (CSR) from `molecule_of`, checked against the reference atoms.
pub(super) fn molecule_table(
    n: usize,
    split: &SplitSpec,
    types: &[u32],
) -> Result<Molecules, String> {
    if split.molecule_of.len() != n {
        return Err(format!(
            "non-bonded split: {} molecule indices for {n} atoms",
            split.molecule_of.len()
        ));
    }
    let n_molecules = split.reference_atoms.len();
    let mut start = vec![0u32; n_molecules + 1];
    for &m in &split.molecule_of {
        if m as usize >= n_molecules {
            return Err(format!(
                "non-bonded split: molecule {m} has no reference atom"
            ));
        }
        start[m as usize + 1] += 1;
    }
    for m in 0..n_molecules {
        start[m + 1] += start[m];
    }
    let mut fill = start.clone();
    let mut atoms = vec![0u32; n];
    for (i, &m) in split.molecule_of.iter().enumerate() {
        atoms[fill[m as usize] as usize] = i as u32;
        fill[m as usize] += 1;
    }
    for (m, &r) in split.reference_atoms.iter().enumerate() {
        if r >= n || split.molecule_of[r] as usize != m {
            return Err(format!(
                "non-bonded split: reference atom {r} is not in molecule {m}"
            ));
        }
    }
    let mut slot_of = vec![0u32; n];
    for (k, &a) in atoms.iter().enumerate() {
        slot_of[a as usize] = k as u32;
    }
    let reference_slot = split.reference_atoms.iter().map(|&r| slot_of[r]).collect();
    let first = start.get(1).copied().unwrap_or(0);
    let uniform = start.windows(2).all(|w| w[1] - w[0] == first);
    Ok(Molecules {
        uniform_size: if uniform { first as usize } else { 0 },
        start,
        reference: split.reference_atoms.iter().map(|&r| r as u32).collect(),
        reference_slot,
        types: atoms.iter().map(|&a| types[a as usize]).collect(),
        atoms,
    })
}
