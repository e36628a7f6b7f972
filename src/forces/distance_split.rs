//! The non-bonded term split by distance into a short-range part and a remainder, for
//! three or more r-RESPA levels (bonded innermost, short-range non-bonded in the middle, the
//! remainder outermost), as LAMMPS `run_style respa … inner/middle/outer` splits pair
//! forces. Non-bonded: both parts are placed by the scene.
//!
//! **The parts.** With `V_ij(r)` the pair energy of the non-bonded model
//! ([`super::nonbonded`]: Lennard-Jones and the Coulomb form, with its cutoff `r_c`, zero
//! beyond it) and a switch `S` that is 1 below `r_in` and 0 above `r_out`:
//!
//! * **by molecule**: `V_short = Σ_{I<J} S(R_IJ) Σ_{i∈I, j∈J} V_ij(r_ij) +
//!   Σ_I Σ_{i<j ∈ I, not excluded} S(r_ij) V_ij(r_ij)`, where `R_IJ` is the
//!   (minimum-image) distance between the reference atoms of molecules `I` and `J` (O–O for
//!   water) and molecules are the connected components of the bond graph. Every atom pair of
//!   two molecules gets the same weight, so a neutral molecule's short-range part is a whole
//!   dipole–dipole interaction, switched off together: the remainder is a small, smooth
//!   force. A pair inside one molecule has no second molecule: it is switched on its own
//!   distance, as by atom pair.
//! * **by atom pair**: `V_short = Σ_{i<j, not excluded} S(r_ij) V_ij(r_ij)`, LAMMPS's
//!   choice. Cheaper bookkeeping, but the O–H and H–H pairs of two waters at the same O–O
//!   distance are switched at different distances, so the remainder keeps large
//!   charge–charge pieces that cancel only when summed over the molecule.
//! * **the remainder**: `V_rest = V − V_short`, computed as the full term minus the short
//!   part: the two add up to the model to round-off, whatever `r_in`, `r_out`.
//!
//! **The switch** is the quintic smoothstep `S(R) = 1 − 10t³ + 15t⁴ − 6t⁵ = u³(10 − 15u + 6u²)`
//! (`u = 1 − t`, the form evaluated),
//! `t = (R − r_in)/(r_out − r_in)` on `[r_in, r_out]`: `S′ = −30t²(1 − t)²/w` and
//! `S″ = −60t(1 − t)(1 − 2t)/w²` (`w = r_out − r_in`) vanish at both ends, so both parts
//! have continuous forces and Hessians. (LAMMPS multiplies each pair's *force* by the cubic
//! `1 − t²(3 − 2t)`, which is C¹; switching the energy here keeps each part a potential
//! with an energy, for the level energies and the conserved-energy monitors.)
//!
//! **Conditions.** `0 < r_in < r_out ≤ r_c`: the short part must lie inside the cutoff
//! (beyond it there is nothing to switch), and `r_out < r_c < L/2` keeps `S(R_IJ)` smooth
//! where the minimum image of the reference atoms jumps (at `R = L/2`, where `S = 0`).
//!
//! **Chain rule.** By molecule, with `E_IJ = Σ V_ij` and `n̂ = (x_J − x_I)/R` between the
//! reference atoms: `∇(S E) = S ∇E + S′ E ∇R` (`∇R = ±n̂` on the reference atoms), and
//! `∇²(S E)·v = S ∇²E v + S′[(∇R·v)∇E + (∇E·v)∇R] + E S″ (∇R·v)∇R + E S′ ∇²R v`, with
//! `∇²R v = ±(I − n̂n̂ᵀ)(v_J − v_I)/R` on the reference atoms. By atom pair `W = S V` is
//! radial: `W′ = S′V + SV′`, `W″ = S″V + 2S′V′ + SV″`, and the radial Hessian of
//! [`super::nonbonded`] applies.
//!
//! **Cost.** By atom pair the short part is the cluster-pair kernel of
//! [`super::nonbonded`] with its list cut at `r_out` and the switch applied in the lanes
//! ([`Nonbonded::switched`]: the pair energy is computed for the force too, `S` and `S′`
//! by the quintic in add, multiply and fused multiply-add, the same bits on every
//! instruction set), in either precision; on the solvated Trp-cage (`r_out` = 6 Å, 9 Å
//! cutoff) one evaluation costs about half the full term's. By molecule in a box of one
//! kind of molecule of at most four atoms (water
//! models), each listed molecule pair inside `r_out` is one SIMD block of 4 × 4 atom pairs
//! with one switch value ([`lanes`]); other molecules take the row loop of [`kernels`],
//! which gathers each row's partner atoms (docs/thermostats.md has both costs); the pairs
//! inside a molecule take the same row loop pair by pair. By molecule the short part
//! has its own pair search ([`search`]): molecule pairs whose
//! reference atoms are closer than `r_out + skin`, rebuilt
//! when a point has moved half the skin. Its evaluation runs over fixed chunks of that list
//! (a number that depends only on the atom count), in parallel for large systems, each into
//! its own buffer, summed in chunk order: the same bits at any thread count. Nothing is
//! allocated once the list has reached its size. The short part keeps its last gradient with
//! a copy of the positions: r-RESPA evaluates the middle level and then the outer one at the
//! same positions, so the remainder `∇V − ∇V_short` costs one full non-bonded evaluation,
//! not two.

mod kernels;
mod lanes;
mod pairs;
mod search;

use std::sync::atomic::{AtomicU8, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

use rayon::prelude::*;

use super::clusters::Cluster;
use super::nonbonded::{
    CoulombPair, Electrostatics, LjPair, Nonbonded, NonbondedSpec, exclusion_lists,
};
use super::simd::Isa;
use super::{ForceTerm, Precision, TermClass};
use search::PairSearch;

/// Intramolecular non-excluded pairs held for the molecule switch, at most (a bound on
/// memory for scenes with very large molecules, which should switch by atom pair).
const MAX_INTRAMOLECULAR_PAIRS: usize = 20_000_000;

/// The C² quintic switch from 1 at `r_in` to 0 at `r_out` (module doc).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Switch {
    r_in: f64,
    r_out: f64,
    inverse_width: f64,
}

impl Switch {
    /// `0 < r_in < r_out`, both finite.
    pub fn new(r_in: f64, r_out: f64) -> Result<Self, String> {
        if !(r_in.is_finite() && r_out.is_finite()) {
            return Err(format!("r_in = {r_in} and r_out = {r_out} must be finite"));
        }
        if r_in <= 0.0 {
            return Err(format!("r_in = {r_in} must be positive"));
        }
        if r_in >= r_out {
            return Err(format!(
                "r_in = {r_in} must be smaller than r_out = {r_out} (the switch runs from 1 at \
                 r_in to 0 at r_out)"
            ));
        }
        Ok(Switch {
            r_in,
            r_out,
            inverse_width: 1.0 / (r_out - r_in),
        })
    }

    pub fn r_in(&self) -> f64 {
        self.r_in
    }

    pub fn r_out(&self) -> f64 {
        self.r_out
    }

    /// `1/(r_out − r_in)`.
    pub fn inverse_width(&self) -> f64 {
        self.inverse_width
    }

    /// `(S, S′)` at `r`.
    #[inline(always)]
    pub fn value_slope(&self, r: f64) -> (f64, f64) {
        // Clamped, not branched (t = 0 gives S = 1, S′ = 0 and t = 1 gives 0, 0 exactly), so
        // loops over it vectorise.
        let t = ((r - self.r_in) * self.inverse_width).clamp(0.0, 1.0);
        let u = 1.0 - t;
        // 1 − P(t) = P(1 − t) for the smoothstep P(t) = t³(10 − 15t + 6t²): each half
        // uses the form without cancellation at its end.
        let near = 1.0 - t * t * t * (10.0 - 15.0 * t + 6.0 * t * t);
        let far = u * u * u * (10.0 - 15.0 * u + 6.0 * u * u);
        let s = if t < 0.5 { near } else { far };
        // 0 − x, not −x: +0 at the ends, as before.
        (s, (0.0 - 30.0 * t * t * u * u) * self.inverse_width)
    }

    /// `(S, S′, S″)` at `r`.
    #[inline(always)]
    pub fn derivatives(&self, r: f64) -> (f64, f64, f64) {
        let (s, s1) = self.value_slope(r);
        if r <= self.r_in || r >= self.r_out {
            return (s, s1, 0.0);
        }
        let t = (r - self.r_in) * self.inverse_width;
        let w2 = self.inverse_width * self.inverse_width;
        (s, s1, -60.0 * t * (1.0 - t) * (1.0 - 2.0 * t) * w2)
    }
}

/// What the switch variable is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SwitchBy {
    /// The distance between the reference atoms of the two molecules.
    Molecule,
    /// The distance of the atom pair itself.
    AtomPair,
}

impl SwitchBy {
    pub fn name(&self) -> &'static str {
        match self {
            SwitchBy::Molecule => "molecule",
            SwitchBy::AtomPair => "atom",
        }
    }
}

/// The Coulomb form of the short-range part.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ShortCoulomb {
    /// The term's own form (shifted force, reaction field, PME's `erfc(αr)/r`).
    Model,
    /// Bare `1/r`, as LAMMPS's rRESPA inner and middle levels take it with `coul/long`: with
    /// PME the near-field Coulomb force is on the short level in full, and the remainder
    /// (real space − switched bare Coulomb) with the reciprocal sum is smooth when whole
    /// neutral molecules are switched together. With `erfc(αr)/r` in the short part the
    /// reciprocal sum's `erf(αr)/r` near field stays on the slow level.
    Bare,
}

/// How to split a non-bonded term.
#[derive(Clone, Debug)]
pub struct SplitSpec {
    pub r_in: f64,
    pub r_out: f64,
    pub by: SwitchBy,
    pub short_coulomb: ShortCoulomb,
    /// Molecule index per atom (by molecule; see [`molecules_from_bonds`]).
    pub molecule_of: Vec<u32>,
    /// The reference atom of each molecule (by molecule; see [`reference_atoms`]).
    pub reference_atoms: Vec<usize>,
}

/// Molecules as the connected components of the bond graph: an index per atom, numbered
/// in order of each molecule's first atom.
pub fn molecules_from_bonds(n: usize, bonds: &[[usize; 2]]) -> Vec<u32> {
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for &[a, b] in bonds {
        if a < n && b < n {
            let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
            if ra != rb {
                parent[ra.max(rb)] = ra.min(rb);
            }
        }
    }
    let mut index = vec![u32::MAX; n];
    let mut molecule_of = vec![0u32; n];
    let mut next = 0;
    for (i, molecule) in molecule_of.iter_mut().enumerate() {
        let r = root(&mut parent, i);
        if index[r] == u32::MAX {
            index[r] = next;
            next += 1;
        }
        *molecule = index[r];
    }
    molecule_of
}

/// The reference atom of each molecule: the first atom (in file order) for which
/// `eligible` holds, or with `eligible = None` the first of the heaviest atoms. Errors name
/// a molecule with no eligible atom.
pub fn reference_atoms(
    molecule_of: &[u32],
    masses: &[f64],
    eligible: Option<&dyn Fn(usize) -> bool>,
) -> Result<Vec<usize>, String> {
    let n_molecules = molecule_of
        .iter()
        .map(|&m| m as usize + 1)
        .max()
        .unwrap_or(0);
    let mut chosen: Vec<Option<usize>> = vec![None; n_molecules];
    for (i, &m) in molecule_of.iter().enumerate() {
        let slot = &mut chosen[m as usize];
        match eligible {
            Some(eligible) => {
                if slot.is_none() && eligible(i) {
                    *slot = Some(i);
                }
            }
            None => {
                if slot.is_none_or(|k| masses[i] > masses[k]) {
                    *slot = Some(i);
                }
            }
        }
    }
    chosen
        .into_iter()
        .enumerate()
        .map(|(m, atom)| {
            atom.ok_or_else(|| {
                let first = molecule_of
                    .iter()
                    .position(|&x| x as usize == m)
                    .unwrap_or(0);
                format!("molecule {m} (the one holding atom {first}) has no such atom")
            })
        })
        .collect()
}

/// The non-bonded model pair by pair, and the minimum image.
pub(crate) struct Model {
    pub cutoff_squared: f64,
    coulomb: CoulombPair,
    n_types: usize,
    types: Vec<u32>,
    lj: Vec<LjPair>,
    /// Whether a type has Lennard-Jones with any type.
    has_lj: Vec<bool>,
    /// `q_i √k_e`.
    scaled_charges: Vec<f64>,
    period: [f64; 3],
    inverse: [f64; 3],
}

impl Model {
    /// Minimum-image `x_j − x_i`.
    #[inline(always)]
    pub fn displacement(&self, q: &[f64], i: usize, j: usize) -> [f64; 3] {
        std::array::from_fn(|k| {
            let d = q[3 * j + k] - q[3 * i + k];
            d - self.period[k] * (d * self.inverse[k]).round()
        })
    }

    #[inline(always)]
    fn lj(&self, i: usize, j: usize) -> LjPair {
        self.lj[self.types[i] as usize * self.n_types + self.types[j] as usize]
    }

    /// `(V, −V′/r)` of pair `i, j` at `r² = s < r_c²`.
    #[inline(always)]
    pub fn energy_force(&self, i: usize, j: usize, s: f64) -> (f64, f64) {
        let qq = self.scaled_charges[i] * self.scaled_charges[j];
        self.typed_energy_force(self.lj(i, j), qq, s)
    }

    /// The Lennard-Jones coefficients of type `a` with every type, or `None` when they are
    /// all zero.
    #[inline(always)]
    pub fn lj_row(&self, a: u32) -> Option<&[LjPair]> {
        let row = &self.lj[a as usize * self.n_types..(a as usize + 1) * self.n_types];
        self.has_lj[a as usize].then_some(row)
    }

    /// `(V, −V′/r)` of a pair with coefficients `p` and `k_e q_i q_j = qq` at `r² = s`.
    #[inline(always)]
    pub fn typed_energy_force(&self, p: LjPair, qq: f64, s: f64) -> (f64, f64) {
        let inv_r2 = 1.0 / s;
        let (mut energy, mut force) = (0.0, 0.0);
        if p.c12 != 0.0 || p.c6 != 0.0 {
            let inv_r6 = inv_r2 * inv_r2 * inv_r2;
            energy = inv_r6 * (p.c12 * inv_r6 - p.c6) - p.shift;
            force = inv_r2 * inv_r6 * (12.0 * p.c12 * inv_r6 - 6.0 * p.c6);
        }
        if qq != 0.0 {
            let (e, f) = self.coulomb.energy_force(qq, s, inv_r2.sqrt());
            energy += e;
            force += f;
        }
        (energy, force)
    }

    /// `(V, −V′/r)` of the Coulomb form for a block of pairs.
    #[inline(always)]
    pub fn coulomb_block(
        &self,
        qq: &[f64],
        s: &[f64],
        inv_r: &[f64],
        energy: &mut [f64],
        force: &mut [f64],
    ) {
        self.coulomb.energy_force_block(qq, s, inv_r, energy, force);
    }

    /// The periodic lengths (0 along an open axis) and the shortest of them (∞ for none).
    pub fn shortest_period(&self) -> f64 {
        self.period
            .iter()
            .filter(|&&l| l > 0.0)
            .fold(f64::INFINITY, |a, &b| a.min(b))
    }

    /// Minimum image of a displacement `d`.
    #[inline(always)]
    pub fn image(&self, d: [f64; 3]) -> [f64; 3] {
        std::array::from_fn(|k| d[k] - self.period[k] * (d[k] * self.inverse[k]).round())
    }

    /// `q_i √k_e` (0 without electrostatics).
    #[inline(always)]
    pub fn scaled_charge(&self, i: usize) -> f64 {
        self.scaled_charges[i]
    }

    /// `(V_LJ, V_Coulomb)` of pair `i, j` at `r² = s < r_c²` (for reports).
    pub fn energy_parts(&self, i: usize, j: usize, s: f64) -> (f64, f64) {
        let p = self.lj(i, j);
        let inv_r6 = (1.0 / s).powi(3);
        let lj = inv_r6 * (p.c12 * inv_r6 - p.c6) - p.shift;
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
        let p = self.lj(i, j);
        let inv_r = 1.0 / r;
        let inv6 = inv_r.powi(6);
        let mut v = inv6 * (p.c12 * inv6 - p.c6) - p.shift;
        let mut d1 = inv_r * inv6 * (-12.0 * p.c12 * inv6 + 6.0 * p.c6);
        let mut d2 = inv_r * inv_r * inv6 * (156.0 * p.c12 * inv6 - 42.0 * p.c6);
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

/// Whole molecules for one chunk: packed atoms, clusters (one molecule kind) and scratch.
struct Whole<'a> {
    packed: &'a [[f64; 4]],
    clusters: &'a [Cluster<f64>],
    scratch: &'a mut kernels::Scratch,
}

/// What one evaluation computes.
#[derive(Clone, Copy)]
enum Mode<'a> {
    Energy,
    Gradient,
    HessianVector(&'a [f64]),
}

struct Workspace {
    search: PairSearch,
    /// By molecule: `[x, y, z, q√k_e]` per atom in molecule order, each atom at the image
    /// nearest its reference atom (molecules made whole).
    packed: Vec<[f64; 4]>,
    /// By molecule, one kind of molecule: each molecule as a cluster for [`lanes`].
    clusters: Vec<Cluster<f64>>,
    /// One scratch per chunk for the whole-molecule loop.
    scratch: Vec<kernels::Scratch>,
    /// One gradient (or Hessian-vector) buffer per chunk, `n × 3` each.
    buffers: Vec<Vec<f64>>,
    energies: Vec<f64>,
    /// Positions of the last gradient evaluation, its gradient and energy.
    cached_q: Vec<f64>,
    cached_gradient: Vec<f64>,
    cached_energy: Option<f64>,
}

/// The short-range part, shared by the two terms (the remainder subtracts it): by atom
/// pair the model's term in the cluster-pair kernel with every pair multiplied by the
/// switch ([`Nonbonded::switched`]), by molecule the molecule loops of [`ShortRange`].
pub enum ShortPart {
    AtomPairs(Box<Nonbonded>),
    Molecules(Box<ShortRange>),
}

/// The short-range part by molecule.
pub struct ShortRange {
    pub(crate) model: Model,
    pub(crate) switch: Switch,
    pub(crate) molecules: Molecules,
    /// Non-excluded pairs inside one molecule (by molecule), switched on their distance.
    intramolecular: Vec<[u32; 2]>,
    excluded_start: Vec<u32>,
    excluded_partners: Vec<u32>,
    chunks: usize,
    /// The instruction set the pair loops are compiled for (default the widest there is),
    /// as its index in [`INSTRUCTION_SETS`].
    isa: AtomicU8,
    /// By molecule in a box of one kind of small molecule: the SIMD block loop's constants.
    lanes: Option<lanes::Lanes>,
    listed_atom_pairs: AtomicUsize,
    workspace: Mutex<Workspace>,
}

/// The instruction sets by index, for [`ShortRange::set_isa`].
const INSTRUCTION_SETS: [Isa; 3] = [Isa::Portable, Isa::Avx2, Isa::Avx512];

/// Chunks of the short part's list: a function of the atom count only (determinism).
fn chunk_count(n_atoms: usize) -> usize {
    match n_atoms {
        0..2048 => 1,
        2048..8192 => 4,
        _ => 8,
    }
}

/// The short-range part on its level.
pub struct NonbondedShort {
    short: Arc<ShortPart>,
}

/// The full non-bonded term minus the short-range part, on a higher level.
pub struct NonbondedRemainder {
    full: Nonbonded,
    short: Arc<ShortPart>,
}

/// Split the non-bonded term of `spec` by `split` at positions `q`: the short-range part
/// and the remainder. Errors are messages for the scene to locate.
pub fn split_nonbonded(
    spec: NonbondedSpec,
    split: &SplitSpec,
    q: &[f64],
) -> Result<(NonbondedShort, NonbondedRemainder), String> {
    let switch = Switch::new(split.r_in, split.r_out)?;
    if split.r_out > spec.cutoff {
        return Err(format!(
            "r_out = {} is beyond the non-bonded cutoff {}: the short-range part must lie \
             inside the cutoff",
            split.r_out, spec.cutoff
        ));
    }
    let mut short_spec = spec.clone();
    if split.short_coulomb == ShortCoulomb::Bare && spec.electrostatics != Electrostatics::None {
        short_spec.electrostatics = Electrostatics::Plain;
    }
    let short = match split.by {
        SwitchBy::AtomPair => {
            ShortPart::AtomPairs(Box::new(Nonbonded::switched(short_spec, switch, q)?))
        }
        SwitchBy::Molecule => {
            ShortPart::Molecules(Box::new(ShortRange::new(&short_spec, switch, split, q)?))
        }
    };
    let full = Nonbonded::new(spec, q)?;
    let short = Arc::new(short);
    Ok((
        NonbondedShort {
            short: short.clone(),
        },
        NonbondedRemainder { full, short },
    ))
}

impl ShortRange {
    fn new(
        spec: &NonbondedSpec,
        switch: Switch,
        split: &SplitSpec,
        q: &[f64],
    ) -> Result<Self, String> {
        let n = spec.types.len();
        let model = Self::model(spec, q)?;
        let (excluded_start, excluded_partners) = exclusion_lists(n, &spec.excluded)?;
        let molecules = molecule_table(n, split, &spec.types)?;
        let points = molecules.reference.len();
        let chunks = chunk_count(n);
        let mut short = ShortRange {
            model,
            switch,
            molecules,
            intramolecular: Vec::new(),
            excluded_start,
            excluded_partners,
            chunks,
            isa: AtomicU8::new(0),
            lanes: None,
            listed_atom_pairs: AtomicUsize::new(0),
            workspace: Mutex::new(Self::workspace(spec, switch, points, chunks)),
        };
        short.set_isa(Isa::best());
        short.lanes = lanes::Lanes::of(&short.model, &short.molecules);
        short.intramolecular = short.intramolecular_pairs()?;
        {
            let mut workspace = short.lock();
            short.refresh(&mut workspace, q);
        }
        Ok(short)
    }

    /// The pair model of `spec` (types, Lennard-Jones table, charges scaled by `√k_e`,
    /// box), after checking the sizes agree with the positions `q`.
    fn model(spec: &NonbondedSpec, q: &[f64]) -> Result<Model, String> {
        let n = spec.types.len();
        if q.len() != 3 * n || spec.charges.len() != n {
            return Err("non-bonded split: sizes of positions, types and charges differ".into());
        }
        let n_types = (spec.lj.len() as f64).sqrt().round() as usize;
        if n_types * n_types != spec.lj.len() || spec.types.iter().any(|&t| t as usize >= n_types) {
            return Err("non-bonded split: the Lennard-Jones table does not fit the types".into());
        }
        let root_ke = spec.coulomb_constant.sqrt();
        let scaled_charges = if spec.electrostatics == Electrostatics::None {
            vec![0.0; n]
        } else {
            spec.charges.iter().map(|c| c * root_ke).collect()
        };
        let period = spec.box_lengths.unwrap_or([0.0; 3]);
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
            period,
            inverse: period.map(|l| if l > 0.0 { 1.0 / l } else { 0.0 }),
        })
    }

    /// The buffers, sized once here: the pair search over `points` (molecule reference
    /// atoms or atoms), one scratch and gradient buffer per chunk, the position cache.
    fn workspace(spec: &NonbondedSpec, switch: Switch, points: usize, chunks: usize) -> Workspace {
        let n = spec.types.len();
        Workspace {
            search: PairSearch::new(
                points,
                switch.r_out() + spec.skin,
                spec.skin,
                spec.box_lengths,
            ),
            packed: vec![[0.0; 4]; n],
            clusters: vec![Cluster::default(); points],
            scratch: (0..chunks).map(|_| kernels::Scratch::default()).collect(),
            buffers: vec![vec![0.0; 3 * n]; chunks],
            energies: vec![0.0; chunks],
            cached_q: vec![f64::NAN; 3 * n],
            cached_gradient: vec![0.0; 3 * n],
            cached_energy: None,
        }
    }

    /// The instruction set of the pair loops.
    pub fn isa(&self) -> Isa {
        INSTRUCTION_SETS[self.isa.load(Ordering::Relaxed) as usize]
    }

    /// Compile-time choice of the pair loops' instruction set (default: the widest
    /// available); every set gives the same bits. Panics if the processor lacks it.
    pub fn set_isa(&self, isa: Isa) {
        assert!(isa.is_available(), "{} is not available", isa.name());
        let index = INSTRUCTION_SETS.iter().position(|&i| i == isa).unwrap_or(0);
        self.isa.store(index as u8, Ordering::Relaxed);
        self.lock().cached_energy = None;
    }

    /// Which loop evaluates the molecule pairs: `"molecule blocks"` (SIMD, one kind of
    /// molecule of at most four atoms) or `"molecule rows"` (any molecules).
    pub fn pair_loop(&self) -> &'static str {
        match &self.lanes {
            Some(_) => "molecule blocks",
            None => "molecule rows",
        }
    }

    fn lock(&self) -> MutexGuard<'_, Workspace> {
        // A panic elsewhere while the lock was held leaves a list that is rebuilt anyway.
        self.workspace.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn is_excluded(&self, i: usize, j: usize) -> bool {
        self.excluded_partners[self.excluded_start[i] as usize..self.excluded_start[i + 1] as usize]
            .contains(&(j as u32))
    }

    fn intramolecular_pairs(&self) -> Result<Vec<[u32; 2]>, String> {
        let count: usize = (0..self.molecules.reference.len())
            .map(|m| {
                let k = self.molecules.atoms(m).len();
                k * k.saturating_sub(1) / 2
            })
            .sum();
        if count > MAX_INTRAMOLECULAR_PAIRS {
            return Err(format!(
                "by = \"molecule\" holds every pair inside a molecule ({count} here, at most \
                 {MAX_INTRAMOLECULAR_PAIRS}): switch large molecules by = \"atom\""
            ));
        }
        let mut pairs = Vec::new();
        for m in 0..self.molecules.reference.len() {
            let atoms = self.molecules.atoms(m);
            for (a, &i) in atoms.iter().enumerate() {
                for &j in &atoms[a + 1..] {
                    if !self.is_excluded(i as usize, j as usize) {
                        pairs.push([i, j]);
                    }
                }
            }
        }
        Ok(pairs)
    }

    /// The position of search point `k`, molecule `k`'s reference atom.
    #[inline(always)]
    fn point(&self, q: &[f64], k: usize) -> [f64; 3] {
        let i = self.molecules.reference[k] as usize;
        [q[3 * i], q[3 * i + 1], q[3 * i + 2]]
    }

    /// Rebuild the molecule pair list if a reference atom has moved half the skin.
    fn refresh(&self, workspace: &mut Workspace, q: &[f64]) {
        self.refresh_at(workspace, |k| self.point(q, k));
    }

    /// [`ShortRange::refresh`] with search point `k` at `point(k)`.
    fn refresh_at(&self, workspace: &mut Workspace, point: impl Fn(usize) -> [f64; 3]) {
        let search = &mut workspace.search;
        if !search.needs_rebuild(&point) {
            return;
        }
        search.build(point);
        let listed = search
            .pairs
            .iter()
            .map(|&[a, b]| {
                self.molecules.atoms(a as usize).len() * self.molecules.atoms(b as usize).len()
            })
            .sum::<usize>()
            + self.intramolecular.len();
        self.listed_atom_pairs.store(listed, Ordering::Relaxed);
        let (partners, atoms) = self.largest_row(&workspace.search.pairs);
        for scratch in &mut workspace.scratch {
            scratch.reserve(partners, atoms);
        }
    }

    /// The most partner molecules and partner atoms of one row molecule in `pairs`.
    fn largest_row(&self, pairs: &[[u32; 2]]) -> (usize, usize) {
        kernels::list_rows(pairs).fold((0, 0), |(partners, atoms), (_, group)| {
            let row_atoms = group
                .iter()
                .map(|&[_, b]| self.molecules.atoms(b as usize).len())
                .sum::<usize>();
            (partners.max(group.len()), atoms.max(row_atoms))
        })
    }

    /// One evaluation into the chunk buffers; returns the energy (0 for a Hessian-vector
    /// product). The buffers hold the gradient or product afterwards (not for `Energy`).
    fn run(&self, workspace: &mut Workspace, q: &[f64], mode: Mode) -> f64 {
        self.refresh(workspace, q);
        let whole = self.pack_molecules(q, &mut workspace.packed);
        if let (true, Some(lanes)) = (whole, &self.lanes) {
            lanes.pack(&workspace.packed, &mut workspace.clusters);
        }
        let Workspace {
            search,
            packed,
            clusters,
            scratch,
            buffers,
            energies,
            ..
        } = workspace;
        let pairs: &[[u32; 2]] = &search.pairs;
        let packed = whole.then_some(&packed[..]);
        let chunks = self.chunks;
        let work = |((c, buffer), scratch): ((usize, &mut Vec<f64>), &mut kernels::Scratch)| {
            let part = &pairs[c * pairs.len() / chunks..(c + 1) * pairs.len() / chunks];
            if !matches!(mode, Mode::Energy) {
                buffer.fill(0.0);
            }
            let whole = packed.map(|packed| Whole {
                packed,
                clusters,
                scratch,
            });
            self.evaluate(q, mode, part, SwitchBy::Molecule, whole, buffer)
        };
        if chunks > 1 {
            buffers
                .par_iter_mut()
                .enumerate()
                .zip(scratch.par_iter_mut())
                .zip(energies.par_iter_mut())
                .for_each(|(chunk, energy)| *energy = work(chunk));
        } else {
            for (chunk, energy) in buffers
                .iter_mut()
                .enumerate()
                .zip(scratch.iter_mut())
                .zip(energies.iter_mut())
            {
                *energy = work(chunk);
            }
        }
        // Pairs inside molecules after the chunks, into the first buffer (same order always).
        energies[0] += self.evaluate(
            q,
            mode,
            &self.intramolecular,
            SwitchBy::AtomPair,
            None,
            &mut buffers[0],
        );
        energies.iter().sum()
    }

    /// Fill `packed` (molecules made whole, charges) and say whether the whole-molecule
    /// pair loop gives the model's minimum-image pairs: it uses `d = D_IJ + u_j − u_i`
    /// (`D_IJ` the reference atoms' minimum image, `u` each atom's offset from its reference,
    /// at most `e`), which is the minimum image whenever `|d| < r_c < L/2`, and can only
    /// miss a pair inside the cutoff when `r_out + 2e > L − r_c` (a lattice vector is at
    /// least `L` long). Then the loop takes the minimum image pair by pair instead.
    fn pack_molecules(&self, q: &[f64], packed: &mut [[f64; 4]]) -> bool {
        let molecules = &self.molecules;
        let mut largest_offset2: f64 = 0.0;
        for m in 0..molecules.reference.len() {
            let r = molecules.reference[m] as usize;
            let x_ref = [q[3 * r], q[3 * r + 1], q[3 * r + 2]];
            let slots = molecules.start[m] as usize..molecules.start[m + 1] as usize;
            for (slot, &i) in packed[slots.clone()]
                .iter_mut()
                .zip(&molecules.atoms[slots])
            {
                let i = i as usize;
                let u = self
                    .model
                    .image(std::array::from_fn(|a| q[3 * i + a] - x_ref[a]));
                largest_offset2 = largest_offset2.max(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
                *slot = [
                    x_ref[0] + u[0],
                    x_ref[1] + u[1],
                    x_ref[2] + u[2],
                    self.model.scaled_charge(i),
                ];
            }
        }
        let reach = self.switch.r_out() + 2.0 * largest_offset2.sqrt();
        reach < self.model.shortest_period() - self.model.cutoff_squared.sqrt()
    }

    /// The pairs `part` of the list, switched `by` molecule or atom pair; `whole`: whole
    /// molecules (packed) and the chunk's scratch for the fast molecule loop. Compiled for
    /// the widest instruction set there is (the same operations in the same order, so the
    /// same bits; `round` becomes inline).
    fn evaluate(
        &self,
        q: &[f64],
        mode: Mode,
        part: &[[u32; 2]],
        by: SwitchBy,
        whole: Option<Whole>,
        buffer: &mut [f64],
    ) -> f64 {
        let isa = self.isa();
        isa.run(
            #[inline(always)]
            || self.evaluate_body(q, mode, part, by, whole, buffer),
        )
    }

    #[inline(always)]
    fn evaluate_body(
        &self,
        q: &[f64],
        mode: Mode,
        part: &[[u32; 2]],
        by: SwitchBy,
        whole: Option<Whole>,
        buffer: &mut [f64],
    ) -> f64 {
        match (mode, by, whole) {
            (Mode::HessianVector(v), _, _) => {
                self.loop_pairs(q, part, by, &mut pairs::HessianVector { v }, buffer);
                0.0
            }
            (_, SwitchBy::Molecule, Some(whole)) => self.whole_molecules(mode, part, whole, buffer),
            (Mode::Energy, _, _) => {
                let mut y = pairs::Energy::<false> { energy: 0.0 };
                self.loop_pairs(q, part, by, &mut y, buffer);
                y.energy
            }
            (Mode::Gradient, _, _) => {
                let mut y = pairs::Energy::<true> { energy: 0.0 };
                self.loop_pairs(q, part, by, &mut y, buffer);
                y.energy
            }
        }
    }

    /// The pair loop of [`pairs`] over `part`, a list of molecule pairs or of atom pairs.
    #[inline(always)]
    fn loop_pairs<Y: pairs::Yield>(
        &self,
        q: &[f64],
        part: &[[u32; 2]],
        by: SwitchBy,
        y: &mut Y,
        out: &mut [f64],
    ) {
        match by {
            SwitchBy::Molecule => pairs::molecule_pairs(self, q, part, y, out),
            SwitchBy::AtomPair => pairs::atom_pairs(self, q, part, y, out),
        }
    }

    /// Energy or gradient over whole molecules: the SIMD blocks for one molecule kind, else
    /// the row loop.
    #[inline(always)]
    fn whole_molecules(&self, mode: Mode, part: &[[u32; 2]], w: Whole, buffer: &mut [f64]) -> f64 {
        let isa = self.isa();
        let gradient = matches!(mode, Mode::Gradient);
        let Some(lanes) = &self.lanes else {
            return match gradient {
                true => {
                    kernels::whole_molecule_rows::<true>(self, w.packed, part, w.scratch, buffer)
                }
                false => {
                    kernels::whole_molecule_rows::<false>(self, w.packed, part, w.scratch, buffer)
                }
            };
        };
        let block = lanes::Block {
            lanes,
            model: &self.model,
            switch: self.switch,
            molecules: &self.molecules,
            clusters: w.clusters,
            packed: w.packed,
            pairs: part,
        };
        match gradient {
            true => lanes::evaluate::<true>(isa, &block, w.scratch, buffer),
            false => lanes::evaluate::<false>(isa, &block, w.scratch, buffer),
        }
    }

    fn energy(&self, q: &[f64]) -> f64 {
        let mut workspace = self.lock();
        if let Some(energy) = workspace.cached_energy
            && workspace.cached_q == q
        {
            return energy;
        }
        self.run(&mut workspace, q, Mode::Energy)
    }

    /// `gradient += sign ∇V_short(q)`, from the cache when `q` is the last gradient's.
    fn add_scaled_gradient(&self, q: &[f64], gradient: &mut [f64], sign: f64) {
        let mut guard = self.lock();
        let workspace = &mut *guard;
        if !(workspace.cached_energy.is_some() && workspace.cached_q == q) {
            let energy = self.run(workspace, q, Mode::Gradient);
            workspace.cached_gradient.fill(0.0);
            reduce(&workspace.buffers, &mut workspace.cached_gradient, 1.0);
            workspace.cached_q.copy_from_slice(q);
            workspace.cached_energy = Some(energy);
        }
        for (g, c) in gradient.iter_mut().zip(&workspace.cached_gradient) {
            *g += sign * c;
        }
    }

    /// `out += sign ∇²V_short(q) v`.
    fn add_scaled_hessian_vector(&self, q: &[f64], v: &[f64], out: &mut [f64], sign: f64) {
        let mut workspace = self.lock();
        self.run(&mut workspace, q, Mode::HessianVector(v));
        reduce(&workspace.buffers, out, sign);
    }

    /// The energy as (Lennard-Jones, Coulomb), for reports.
    fn energy_parts(&self, q: &[f64]) -> (f64, f64) {
        let mut workspace = self.lock();
        self.refresh(&mut workspace, q);
        let (mut listed, mut inside) = (pairs::Parts::default(), pairs::Parts::default());
        let pairs = &workspace.search.pairs;
        self.loop_pairs(q, pairs, SwitchBy::Molecule, &mut listed, &mut []);
        self.loop_pairs(
            q,
            &self.intramolecular,
            SwitchBy::AtomPair,
            &mut inside,
            &mut [],
        );
        let ([lj, coulomb], [lj_inside, coulomb_inside]) = (listed.parts, inside.parts);
        (lj + lj_inside, coulomb + coulomb_inside)
    }

    fn couplings(&self) -> Vec<Vec<usize>> {
        let workspace = self.lock();
        let mut couplings: Vec<Vec<usize>> = workspace
            .search
            .pairs
            .iter()
            .map(|&[a, b]| {
                let atoms = |m: u32| self.molecules.atoms(m as usize).iter().map(|&i| i as usize);
                atoms(a).chain(atoms(b)).collect()
            })
            .collect();
        couplings.extend(
            self.intramolecular
                .iter()
                .map(|&[a, b]| vec![a as usize, b as usize]),
        );
        couplings
    }

    /// How many times the molecule pair list has been built.
    pub fn list_builds(&self) -> u64 {
        self.lock().search.builds()
    }

    /// Atom pairs of the list (molecule pairs counted by their atom pairs).
    fn interaction_count(&self) -> usize {
        self.listed_atom_pairs.load(Ordering::Relaxed)
    }

    /// Forget the pair list and the cached gradient ([`ForceTerm::rebuild_lists`]).
    fn rebuild_lists(&self) {
        let mut workspace = self.lock();
        workspace.search.invalidate();
        workspace.cached_q.fill(f64::NAN);
        workspace.cached_energy = None;
    }

    /// The reference atoms' positions at the molecule list's last build (`None` before
    /// it): `{"molecule_list_built_at": [x, y, z, …]}`, three numbers per molecule.
    fn list_state(&self) -> Option<serde_json::Value> {
        let workspace = self.lock();
        let built_at = workspace.search.built_at()?;
        let flat: Vec<f64> = built_at.iter().flatten().copied().collect();
        Some(serde_json::json!({ LIST_KEY: flat }))
    }

    /// Build the molecule list at the positions of [`ShortRange::list_state`] (the build is
    /// a function of them alone), and forget the cached gradient.
    fn restore_lists(&self, state: &serde_json::Value) -> crate::error::Result<()> {
        let points = self.molecules.reference.len();
        let built_at = state_points(state, points).map_err(|e| {
            crate::error::Error::input(format!("the pair list of the nonbonded split: {e}"))
        })?;
        let mut workspace = self.lock();
        workspace.search.invalidate();
        self.refresh_at(&mut workspace, |k| built_at[k]);
        workspace.cached_q.fill(f64::NAN);
        workspace.cached_energy = None;
        Ok(())
    }
}

/// The key of the molecule list's state in a checkpoint.
const LIST_KEY: &str = "molecule_list_built_at";

/// The `points` positions of a [`ShortRange::list_state`]; an error names what is wrong.
fn state_points(state: &serde_json::Value, points: usize) -> Result<Vec<[f64; 3]>, String> {
    let values = state
        .get(LIST_KEY)
        .and_then(|v| v.as_array())
        .ok_or_else(|| format!("no array \"{LIST_KEY}\""))?;
    if values.len() != 3 * points {
        return Err(format!(
            "\"{LIST_KEY}\" has {} numbers, this split has {points} molecules ({} expected)",
            values.len(),
            3 * points
        ));
    }
    let number = |k: usize| {
        values[k]
            .as_f64()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("\"{LIST_KEY}\"[{k}] is not a finite number"))
    };
    (0..points)
        .map(|m| Ok([number(3 * m)?, number(3 * m + 1)?, number(3 * m + 2)?]))
        .collect()
}

/// The same call on either kind of short part (both have the method).
macro_rules! either {
    ($part:expr, $p:ident => $call:expr) => {
        match $part {
            ShortPart::AtomPairs($p) => $call,
            ShortPart::Molecules($p) => $call,
        }
    };
}

impl ShortPart {
    /// `"switched off between r_in = 6 and r_out = 7 by molecule (reference atoms' distance)"`.
    pub fn describe(&self) -> String {
        let (by, switch) = match self {
            ShortPart::AtomPairs(pairs) => ("by atom pair", pairs.switch()),
            ShortPart::Molecules(short) => (
                "by molecule (distance of the reference atoms)",
                Some(short.switch),
            ),
        };
        let (r_in, r_out) = switch.map_or((0.0, 0.0), |s| (s.r_in(), s.r_out()));
        format!("switched off between r_in = {r_in} and r_out = {r_out} {by}")
    }

    /// Which loop evaluates the short part: `"cluster pairs"` by atom pair, else
    /// [`ShortRange::pair_loop`].
    pub fn pair_loop(&self) -> &'static str {
        match self {
            ShortPart::AtomPairs(_) => "cluster pairs",
            ShortPart::Molecules(short) => short.pair_loop(),
        }
    }

    /// The instruction set of the pair loops (every set gives the same bits).
    pub fn set_isa(&self, isa: Isa) {
        either!(self, p => p.set_isa(isa))
    }

    /// How many times the pair list has been built.
    pub fn list_builds(&self) -> u64 {
        match self {
            ShortPart::AtomPairs(pairs) => pairs.list_counts().builds,
            ShortPart::Molecules(short) => short.list_builds(),
        }
    }

    fn energy(&self, q: &[f64]) -> f64 {
        either!(self, p => p.energy(q))
    }

    /// `gradient += sign ∇V_short(q)` (from the last evaluation at the same `q`).
    fn add_gradient(&self, q: &[f64], gradient: &mut [f64], sign: f64) {
        either!(self, p => p.add_scaled_gradient(q, gradient, sign))
    }

    fn add_hessian_vector(&self, q: &[f64], v: &[f64], out: &mut [f64], sign: f64) {
        either!(self, p => p.add_scaled_hessian_vector(q, v, out, sign))
    }

    /// The energy as (Lennard-Jones, Coulomb).
    fn energy_parts(&self, q: &[f64]) -> [f64; 2] {
        either!(self, p => p.energy_parts(q).into())
    }

    fn couplings(&self) -> Vec<Vec<usize>> {
        either!(self, p => p.couplings())
    }

    /// Atom pairs of the list.
    fn listed_pairs(&self) -> usize {
        either!(self, p => p.interaction_count())
    }

    /// Forget the pair list and the cached gradient ([`ForceTerm::rebuild_lists`]).
    fn rebuild_lists(&self) {
        either!(self, p => p.rebuild_lists())
    }

    /// The pair list's state for a checkpoint ([`ForceTerm::list_state`]): by atom pair
    /// the cluster engine's, by molecule the molecule list's.
    fn list_state(&self) -> Option<serde_json::Value> {
        either!(self, p => p.list_state())
    }

    fn restore_lists(&self, state: &serde_json::Value) -> crate::error::Result<()> {
        either!(self, p => p.restore_lists(state))
    }
}

/// `out += sign Σ_c buffers[c]`, chunk by chunk in order.
fn reduce(buffers: &[Vec<f64>], out: &mut [f64], sign: f64) {
    if buffers.len() == 1 {
        for (o, b) in out.iter_mut().zip(&buffers[0]) {
            *o += sign * b;
        }
        return;
    }
    for (k, o) in out.iter_mut().enumerate() {
        let mut sum = 0.0;
        for buffer in buffers {
            sum += buffer[k];
        }
        *o += sign * sum;
    }
}

/// Atoms per molecule (CSR) from `molecule_of`, checked against the reference atoms.
fn molecule_table(n: usize, split: &SplitSpec, types: &[u32]) -> Result<Molecules, String> {
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

impl NonbondedShort {
    /// The shared short-range part (its switch, description and list statistics).
    pub fn short_range(&self) -> &ShortPart {
        &self.short
    }
}

impl ForceTerm for NonbondedShort {
    fn kind(&self) -> &'static str {
        "nonbonded-short"
    }

    fn class(&self) -> TermClass {
        TermClass::Nonbonded
    }

    fn energy(&self, q: &[f64]) -> f64 {
        self.short.energy(q)
    }

    fn add_gradient(&self, q: &[f64], gradient: &mut [f64]) {
        self.short.add_gradient(q, gradient, 1.0);
    }

    fn add_hessian_vector(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        self.short.add_hessian_vector(q, v, out, 1.0);
    }

    fn couplings(&self) -> Vec<Vec<usize>> {
        self.short.couplings()
    }

    fn interaction_count(&self) -> usize {
        self.short.listed_pairs()
    }

    fn energy_components(&self, q: &[f64]) -> Vec<(&'static str, f64)> {
        let [lj, coulomb] = self.short.energy_parts(q);
        vec![("lennard-jones", lj), ("coulomb", coulomb)]
    }

    fn rebuild_lists(&self) {
        self.short.rebuild_lists();
    }

    fn list_state(&self) -> Option<serde_json::Value> {
        self.short.list_state()
    }

    fn restore_lists(&self, state: &serde_json::Value) -> crate::error::Result<()> {
        self.short.restore_lists(state)
    }

    /// By atom pair (the cluster-pair kernel) in either precision; the molecule loops
    /// stay in double.
    fn set_precision(&self, precision: Precision) -> bool {
        match &*self.short {
            ShortPart::AtomPairs(pairs) => pairs.set_precision(precision),
            ShortPart::Molecules(_) => false,
        }
    }
}

impl NonbondedRemainder {
    /// The full term the remainder is taken from.
    pub fn full(&self) -> &Nonbonded {
        &self.full
    }
}

impl ForceTerm for NonbondedRemainder {
    fn kind(&self) -> &'static str {
        "nonbonded-remainder"
    }

    fn class(&self) -> TermClass {
        TermClass::Nonbonded
    }

    fn energy(&self, q: &[f64]) -> f64 {
        self.full.energy(q) - self.short.energy(q)
    }

    fn rebuild_lists(&self) {
        self.full.rebuild_lists();
        self.short.rebuild_lists();
    }

    /// The full term's lists and the short part's (which [`NonbondedShort`] saves too):
    /// `{"full": …, "short": …}`, or `None` unless both have a state, so that a checkpoint
    /// rebuilds both or neither ([`ForceTerm::rebuild_lists`] does both).
    fn list_state(&self) -> Option<serde_json::Value> {
        let (full, short) = (self.full.list_state()?, self.short.list_state()?);
        Some(serde_json::json!({ "full": full, "short": short }))
    }

    fn restore_lists(&self, state: &serde_json::Value) -> crate::error::Result<()> {
        let part = |key: &str| {
            state.get(key).ok_or_else(|| {
                crate::error::Error::input(format!(
                    "the pair lists of the nonbonded remainder: no \"{key}\""
                ))
            })
        };
        self.full.restore_lists(part("full")?)?;
        self.short.restore_lists(part("short")?)
    }

    fn add_gradient(&self, q: &[f64], gradient: &mut [f64]) {
        self.full.add_gradient(q, gradient);
        self.short.add_gradient(q, gradient, -1.0);
    }

    fn add_hessian_vector(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        self.full.add_hessian_vector(q, v, out);
        self.short.add_hessian_vector(q, v, out, -1.0);
    }

    fn couplings(&self) -> Vec<Vec<usize>> {
        self.full.couplings()
    }

    /// The full term's pairs: the short part's gradient usually comes from its cache (the
    /// middle level was just evaluated at the same positions).
    fn interaction_count(&self) -> usize {
        self.full.interaction_count()
    }

    /// The full term's precision (the short part is the other term's).
    fn set_precision(&self, precision: Precision) -> bool {
        self.full.set_precision(precision)
    }

    fn energy_components(&self, q: &[f64]) -> Vec<(&'static str, f64)> {
        let full = self.full.energy_components(q);
        let [lj, coulomb] = self.short.energy_parts(q);
        let component = |name: &str| full.iter().find(|(n, _)| *n == name).map_or(0.0, |c| c.1);
        vec![
            ("lennard-jones", component("lennard-jones") - lj),
            ("coulomb", component("coulomb") - coulomb),
        ]
    }
}
