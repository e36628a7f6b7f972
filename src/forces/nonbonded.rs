//! Non-bonded pair forces of a molecular force field: Lennard-Jones 12-6 and Coulomb with a
//! cutoff, over a Verlet neighbour list ([`super::neighbour_list`]). Non-bonded: slow by
//! default. 3-D only.
//!
//! For a pair at distance `r < r_c` (every pair when there is no cutoff), not excluded:
//!
//! * Lennard-Jones `V = 4ε((σ/r)¹² − (σ/r)⁶) − V_shift`, written `c₁₂/r¹² − c₆/r⁶` with
//!   `c₁₂ = 4εσ¹²`, `c₆ = 4εσ⁶`; `V_shift` is the same at `r_c` when the energy is shifted
//!   (the force is not), else 0. ε and σ of a pair come from the scene (Lorentz–Berthelot
//!   or given per type pair, see `io::forcefield`).
//! * Coulomb with `k_e q_i q_j = Q`:
//!   - damped shifted force (DSF, Fennell & Gezelter, J. Chem. Phys. 124, 234104 (2006),
//!     eq. (18); LAMMPS `coul/dsf`): `V = Q [erfc(αr)/r − erfc(αr_c)/r_c + (r − r_c)
//!     (erfc(αr_c)/r_c² + 2α/√π · exp(−α²r_c²)/r_c)]`; energy and force vanish at `r_c`.
//!     With α = 0 it is `Q (1/r − 2/r_c + r/r_c²)`, the model of the peer kit's water box.
//!     The constant DSF self energy `−(erfc(αr_c)/(2r_c) + α/√π) Σ k_e q_i²` is left out (it
//!     moves no atom; the kit leaves it out too).
//!   - reaction field (OpenMM `NonbondedForce.CutoffPeriodic`/`CutoffNonPeriodic`):
//!     `V = Q (1/r + k_rf r² − c_rf)`, `k_rf = (ε_rf − 1)/((2ε_rf + 1) r_c³)`,
//!     `c_rf = 1/r_c + k_rf r_c²`.
//!   - plain `V = Q/r`, only without a cutoff (a molecule in vacuum).
//!
//! Excluded pairs (1-2, 1-3 and scaled 1-4 pairs, which live in their own terms) are not in
//! the list at all: no energy, no shift term, no force.
//!
//! **Speed.** Pairs are sorted at list build into three classes (LJ and charge, charge
//! only, LJ only) with a branch-free loop each; the 216-water box has O–O pairs in the first
//! class and the 8/9 of pairs that involve a hydrogen in the second. The loops run over
//! fixed chunks of rows, in parallel (rayon) for large systems, each chunk into its own
//! gradient buffer; buffers are summed in chunk order, so results are bit-for-bit the same
//! for any thread count. Nothing is allocated after the list has grown to its size. A
//! gradient evaluation also computes the energy and keeps it with a copy of the positions, so
//! the energy monitor at the same positions costs a comparison, not a second pass.
//!
//! **Hessian-vector product.** For a radial `V(r)`, `∇²V = V″ r̂r̂ᵀ + (V′/r)(I − r̂r̂ᵀ)`, so
//! `(∇²V v)_j = a Δv + b (d·Δv) d` with `Δv = v_j − v_i`, `a = V′/r`, `b = (V″ − V′/r)/r²`.

use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;

use super::neighbour_list::{Chunk, N_CLASSES, NeighbourList, PARALLEL_MIN_PARTICLES, unpack};
use super::{ForceTerm, TermClass};

/// `2/√π`.
const TWO_OVER_SQRT_PI: f64 = std::f64::consts::FRAC_2_SQRT_PI;

/// The Coulomb form of the term.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Electrostatics {
    None,
    Plain,
    DampedShiftedForce { alpha: f64 },
    ReactionField { dielectric: f64 },
}

impl Electrostatics {
    pub fn describe(&self) -> String {
        match self {
            Electrostatics::None => "none".into(),
            Electrostatics::Plain => "plain 1/r (no cutoff)".into(),
            Electrostatics::DampedShiftedForce { alpha } => {
                format!("damped shifted force (DSF), alpha = {alpha} 1/length")
            }
            Electrostatics::ReactionField { dielectric } => {
                format!("reaction field, eps_rf = {dielectric}")
            }
        }
    }
}

/// Lennard-Jones coefficients of one type pair.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LjPair {
    pub c12: f64,
    pub c6: f64,
    /// The energy at the cutoff, subtracted when shifted (else 0).
    pub shift: f64,
}

impl LjPair {
    /// From ε, σ, for a cutoff (infinite for none) and whether the energy is shifted.
    pub fn new(epsilon: f64, sigma: f64, cutoff: f64, shift: bool) -> Self {
        let s6 = sigma.powi(6);
        let (c12, c6) = (4.0 * epsilon * s6 * s6, 4.0 * epsilon * s6);
        let shift = if shift && cutoff.is_finite() {
            let inv6 = cutoff.powi(-6);
            inv6 * (c12 * inv6 - c6)
        } else {
            0.0
        };
        LjPair { c12, c6, shift }
    }

    fn is_zero(&self) -> bool {
        self.c12 == 0.0 && self.c6 == 0.0
    }
}

/// The Coulomb kernel with its constants; `Q` is the charge product times `k_e`.
trait CoulombForm: Copy + Send + Sync {
    /// `(V, −V′/r)` at `r² = s` with `1/r = inv_r`.
    fn energy_force(&self, charge_product: f64, s: f64, inv_r: f64) -> (f64, f64);
    /// `(V, V′, V″)` at `r`.
    fn derivatives(&self, charge_product: f64, r: f64) -> (f64, f64, f64);
}

#[derive(Clone, Copy)]
struct Plain;

impl CoulombForm for Plain {
    #[inline(always)]
    fn energy_force(&self, qq: f64, _s: f64, inv_r: f64) -> (f64, f64) {
        let e = qq * inv_r;
        (e, e * inv_r * inv_r)
    }
    fn derivatives(&self, qq: f64, r: f64) -> (f64, f64, f64) {
        (qq / r, -qq / (r * r), 2.0 * qq / (r * r * r))
    }
}

/// DSF with α = 0 (shifted force): no erfc, no exp.
#[derive(Clone, Copy)]
struct ShiftedForce {
    two_over_rc: f64,
    inv_rc2: f64,
}

impl CoulombForm for ShiftedForce {
    #[inline(always)]
    fn energy_force(&self, qq: f64, s: f64, inv_r: f64) -> (f64, f64) {
        let r = s * inv_r;
        let e = qq * (inv_r - self.two_over_rc + r * self.inv_rc2);
        let f = qq * inv_r * (inv_r * inv_r - self.inv_rc2);
        (e, f)
    }
    fn derivatives(&self, qq: f64, r: f64) -> (f64, f64, f64) {
        (
            qq * (1.0 / r - self.two_over_rc + r * self.inv_rc2),
            qq * (-1.0 / (r * r) + self.inv_rc2),
            qq * 2.0 / (r * r * r),
        )
    }
}

/// DSF with α > 0.
#[derive(Clone, Copy)]
struct DampedShiftedForce {
    alpha: f64,
    rc: f64,
    /// `erfc(α r_c)/r_c`.
    e_shift: f64,
    /// `erfc(α r_c)/r_c² + 2α/√π exp(−α² r_c²)/r_c`.
    f_shift: f64,
}

impl DampedShiftedForce {
    fn new(alpha: f64, rc: f64) -> Self {
        let erfc_rc = libm::erfc(alpha * rc);
        DampedShiftedForce {
            alpha,
            rc,
            e_shift: erfc_rc / rc,
            f_shift: erfc_rc / (rc * rc)
                + TWO_OVER_SQRT_PI * alpha * (-alpha * alpha * rc * rc).exp() / rc,
        }
    }
}

impl CoulombForm for DampedShiftedForce {
    #[inline(always)]
    fn energy_force(&self, qq: f64, s: f64, inv_r: f64) -> (f64, f64) {
        let r = s * inv_r;
        let ar = self.alpha * r;
        let erfc = libm::erfc(ar);
        let gauss = TWO_OVER_SQRT_PI * self.alpha * (-ar * ar).exp();
        let e = qq * (erfc * inv_r - self.e_shift + (r - self.rc) * self.f_shift);
        // −V′ = Q (erfc/r² + (2α/√π) e^{−α²r²}/r − f_shift)
        let f = qq * inv_r * (erfc * inv_r * inv_r + gauss * inv_r - self.f_shift);
        (e, f)
    }
    fn derivatives(&self, qq: f64, r: f64) -> (f64, f64, f64) {
        let ar = self.alpha * r;
        let erfc = libm::erfc(ar);
        let gauss = TWO_OVER_SQRT_PI * self.alpha * (-ar * ar).exp();
        let v = qq * (erfc / r - self.e_shift + (r - self.rc) * self.f_shift);
        let d1 = qq * (-erfc / (r * r) - gauss / r + self.f_shift);
        let d2 = qq
            * (2.0 * erfc / (r * r * r) + gauss * (2.0 / (r * r) + 2.0 * self.alpha * self.alpha));
        (v, d1, d2)
    }
}

#[derive(Clone, Copy)]
struct ReactionField {
    k: f64,
    c: f64,
}

impl CoulombForm for ReactionField {
    #[inline(always)]
    fn energy_force(&self, qq: f64, s: f64, inv_r: f64) -> (f64, f64) {
        let e = qq * (inv_r + self.k * s - self.c);
        let f = qq * (inv_r * inv_r * inv_r - 2.0 * self.k);
        (e, f)
    }
    fn derivatives(&self, qq: f64, r: f64) -> (f64, f64, f64) {
        (
            qq * (1.0 / r + self.k * r * r - self.c),
            qq * (-1.0 / (r * r) + 2.0 * self.k * r),
            qq * (2.0 / (r * r * r) + 2.0 * self.k),
        )
    }
}

#[derive(Clone, Copy)]
enum Kernel {
    Plain(Plain),
    ShiftedForce(ShiftedForce),
    Damped(DampedShiftedForce),
    ReactionField(ReactionField),
}

/// The Coulomb form of a term, pair by pair: `V`, `V′`, `V″` of one pair with its cutoff
/// constants, the same formulas as the pair loop's.
///
/// Pub for `forces::distance_split`, which multiplies these pair energies by a switch and
/// must use exactly the model of this term (its parts add up to it). Whoever rewrites the
/// pair engine: keep this (and its formulas equal to the engine's) or tell that file.
#[derive(Clone, Copy)]
pub struct CoulombPair(Kernel);

impl CoulombPair {
    /// The form for `electrostatics` with `cutoff` (`f64::INFINITY` for none).
    pub fn new(electrostatics: Electrostatics, cutoff: f64) -> Result<Self, String> {
        let needs_cutoff = |name: &str| {
            if cutoff.is_finite() {
                Ok(())
            } else {
                Err(format!("{name} Coulomb needs a cutoff"))
            }
        };
        Ok(CoulombPair(match electrostatics {
            Electrostatics::None | Electrostatics::Plain => Kernel::Plain(Plain),
            Electrostatics::DampedShiftedForce { alpha } => {
                needs_cutoff("damped shifted force")?;
                if alpha == 0.0 {
                    Kernel::ShiftedForce(ShiftedForce {
                        two_over_rc: 2.0 / cutoff,
                        inv_rc2: 1.0 / (cutoff * cutoff),
                    })
                } else {
                    Kernel::Damped(DampedShiftedForce::new(alpha, cutoff))
                }
            }
            Electrostatics::ReactionField { dielectric } => {
                needs_cutoff("reaction-field")?;
                let k = (dielectric - 1.0) / ((2.0 * dielectric + 1.0) * cutoff.powi(3));
                Kernel::ReactionField(ReactionField {
                    k,
                    c: 1.0 / cutoff + k * cutoff * cutoff,
                })
            }
        }))
    }

    /// `(V, −V′/r)` of a pair with `k_e q_i q_j = charge_product` at `r² = s`, `1/r = inv_r`.
    #[inline(always)]
    pub fn energy_force(&self, charge_product: f64, s: f64, inv_r: f64) -> (f64, f64) {
        match self.0 {
            Kernel::Plain(c) => c.energy_force(charge_product, s, inv_r),
            Kernel::ShiftedForce(c) => c.energy_force(charge_product, s, inv_r),
            Kernel::Damped(c) => c.energy_force(charge_product, s, inv_r),
            Kernel::ReactionField(c) => c.energy_force(charge_product, s, inv_r),
        }
    }

    /// `(V, V′, V″)` of a pair at distance `r`.
    pub fn derivatives(&self, charge_product: f64, r: f64) -> (f64, f64, f64) {
        match self.0 {
            Kernel::Plain(c) => c.derivatives(charge_product, r),
            Kernel::ShiftedForce(c) => c.derivatives(charge_product, r),
            Kernel::Damped(c) => c.derivatives(charge_product, r),
            Kernel::ReactionField(c) => c.derivatives(charge_product, r),
        }
    }
}

/// Partners per block of the pair loop (see [`Nonbonded::block`]).
const BLOCK: usize = 64;

/// One block of partners of particle `i` and what locating them needs.
#[derive(Clone, Copy)]
struct Pairs<'a> {
    i: usize,
    block: &'a [u32],
    shifts: &'a [[f64; 3]; 27],
    /// Box lengths when the list is all-pairs (minimum image taken in the loop).
    image: Option<[f64; 3]>,
    x: &'a [f64],
}

/// Pair classes of the list.
const NO_CLASS: u8 = u8::MAX;
const LJ_AND_CHARGE: usize = 0;
const CHARGE_ONLY: usize = 1;
const LJ_ONLY: usize = 2;

/// What the neighbour list, chunk buffers and cached energy need; behind a mutex because
/// `ForceTerm` methods take `&self` (the list is rebuilt when particles have moved).
struct Workspace {
    list: NeighbourList,
    wrapped: Vec<f64>,
    /// `[x, y, z, q√k_e]` per particle (from `wrapped`): one 32-byte read per partner.
    packed: Vec<f64>,
    /// One gradient (or Hessian-vector) buffer per chunk, `n × 3` each.
    buffers: Vec<Vec<f64>>,
    /// (Lennard-Jones, Coulomb) energy of each chunk.
    energies: Vec<(f64, f64)>,
    /// Positions of the last gradient evaluation and the energies found there.
    cached_q: Vec<f64>,
    cached: Option<(f64, f64)>,
}

pub struct Nonbonded {
    n: usize,
    cutoff_squared: f64,
    electrostatics: Electrostatics,
    kernel: Kernel,
    n_types: usize,
    types: Vec<u32>,
    /// `n_types × n_types` coefficients.
    lj: Vec<LjPair>,
    /// `q_i √k_e`, so the product of two is `k_e q_i q_j`.
    scaled_charges: Vec<f64>,
    /// Excluded partners of each particle (CSR: `excluded_start[i]..excluded_start[i + 1]`).
    excluded_start: Vec<u32>,
    excluded_partners: Vec<u32>,
    /// Pair class by particle kind (type and whether charged): `n_kinds × n_kinds`.
    kind: Vec<u32>,
    n_kinds: usize,
    class_table: Vec<u8>,
    workspace: Mutex<Workspace>,
    listed_pairs: AtomicUsize,
}

/// What a non-bonded term is built from.
#[derive(Clone, Debug)]
pub struct NonbondedSpec {
    /// `f64::INFINITY` for no cutoff.
    pub cutoff: f64,
    pub skin: f64,
    pub electrostatics: Electrostatics,
    /// Coulomb constant `k_e` in the scene's units.
    pub coulomb_constant: f64,
    /// The periodic box, if any.
    pub box_lengths: Option<[f64; 3]>,
    /// Type index per particle.
    pub types: Vec<u32>,
    /// `n_types × n_types` Lennard-Jones coefficients (symmetric).
    pub lj: Vec<LjPair>,
    pub charges: Vec<f64>,
    /// Pairs left out of this term.
    pub excluded: Vec<(usize, usize)>,
}

impl Nonbonded {
    /// Build the term and its first neighbour list at positions `q`.
    pub fn new(spec: NonbondedSpec, q: &[f64]) -> Result<Self, String> {
        let n = spec.types.len();
        if q.len() != 3 * n || spec.charges.len() != n {
            return Err("non-bonded term: sizes of positions, types and charges differ".into());
        }
        let n_types = (spec.lj.len() as f64).sqrt().round() as usize;
        if n_types * n_types != spec.lj.len() || spec.types.iter().any(|&t| t as usize >= n_types) {
            return Err("non-bonded term: the Lennard-Jones table does not fit the types".into());
        }
        let cutoff = spec.cutoff;
        if let Some(lengths) = spec.box_lengths {
            let shortest = lengths.iter().cloned().fold(f64::INFINITY, f64::min);
            if !cutoff.is_finite() || 2.0 * cutoff >= shortest {
                return Err(format!(
                    "the non-bonded cutoff {cutoff} must be shorter than half the shortest box \
                     length ({shortest}) for the minimum-image convention"
                ));
            }
        }
        let kernel = match spec.electrostatics {
            Electrostatics::None | Electrostatics::Plain => {
                if spec.electrostatics == Electrostatics::Plain && cutoff.is_finite() {
                    return Err(
                        "plain Coulomb has no cutoff form: use coulomb = \"dsf\" or \
                         \"reaction-field\" with a cutoff, or no cutoff"
                            .into(),
                    );
                }
                Kernel::Plain(Plain)
            }
            Electrostatics::DampedShiftedForce { alpha } => {
                if !cutoff.is_finite() {
                    return Err("damped shifted force Coulomb needs a cutoff".into());
                }
                if alpha == 0.0 {
                    Kernel::ShiftedForce(ShiftedForce {
                        two_over_rc: 2.0 / cutoff,
                        inv_rc2: 1.0 / (cutoff * cutoff),
                    })
                } else {
                    Kernel::Damped(DampedShiftedForce::new(alpha, cutoff))
                }
            }
            Electrostatics::ReactionField { dielectric } => {
                if !cutoff.is_finite() {
                    return Err("reaction-field Coulomb needs a cutoff".into());
                }
                let k = (dielectric - 1.0) / ((2.0 * dielectric + 1.0) * cutoff.powi(3));
                Kernel::ReactionField(ReactionField {
                    k,
                    c: 1.0 / cutoff + k * cutoff * cutoff,
                })
            }
        };
        let root_ke = spec.coulomb_constant.sqrt();
        let scaled_charges: Vec<f64> = if spec.electrostatics == Electrostatics::None {
            vec![0.0; n]
        } else {
            spec.charges.iter().map(|q| q * root_ke).collect()
        };
        let mut excluded = vec![Vec::new(); n];
        for &(i, j) in &spec.excluded {
            if i >= n || j >= n {
                return Err(format!("excluded pair ({i}, {j}) names a missing particle"));
            }
            excluded[i].push(j as u32);
            excluded[j].push(i as u32);
        }
        for list in &mut excluded {
            list.sort_unstable();
            list.dedup();
        }
        let mut excluded_start = vec![0u32; n + 1];
        for (i, list) in excluded.iter().enumerate() {
            excluded_start[i + 1] = excluded_start[i] + list.len() as u32;
        }
        let excluded_partners: Vec<u32> = excluded.concat();
        let kind: Vec<u32> = (0..n)
            .map(|i| 2 * spec.types[i] + (scaled_charges[i] != 0.0) as u32)
            .collect();
        let n_kinds = 2 * n_types;
        let mut class_table = vec![NO_CLASS; n_kinds * n_kinds];
        for a in 0..n_kinds {
            for b in 0..n_kinds {
                let has_lj = !spec.lj[(a / 2) * n_types + b / 2].is_zero();
                let has_charge = a % 2 == 1 && b % 2 == 1;
                class_table[a * n_kinds + b] = match (has_lj, has_charge) {
                    (true, true) => LJ_AND_CHARGE as u8,
                    (false, true) => CHARGE_ONLY as u8,
                    (true, false) => LJ_ONLY as u8,
                    (false, false) => NO_CLASS,
                };
            }
        }
        let list = NeighbourList::new(n, cutoff, spec.skin, spec.box_lengths);
        let chunks = list.chunks.len();
        let term = Nonbonded {
            n,
            cutoff_squared: cutoff * cutoff,
            electrostatics: spec.electrostatics,
            kernel,
            n_types,
            types: spec.types,
            lj: spec.lj,
            scaled_charges,
            excluded_start,
            excluded_partners,
            kind,
            n_kinds,
            class_table,
            workspace: Mutex::new(Workspace {
                list,
                wrapped: vec![0.0; 3 * n],
                packed: vec![0.0; 4 * n],
                buffers: vec![vec![0.0; 3 * n]; chunks],
                energies: vec![(0.0, 0.0); chunks],
                cached_q: vec![f64::NAN; 3 * n],
                cached: None,
            }),
            listed_pairs: AtomicUsize::new(0),
        };
        {
            let mut workspace = term.lock();
            term.refresh_list(&mut workspace, q);
        }
        Ok(term)
    }

    pub fn electrostatics(&self) -> Electrostatics {
        self.electrostatics
    }

    /// Cutoff, skin and how many times the list has been built.
    pub fn list_statistics(&self) -> (f64, f64, u64) {
        let workspace = self.lock();
        (
            workspace.list.cutoff(),
            workspace.list.skin(),
            workspace.list.builds(),
        )
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Workspace> {
        // A panic elsewhere while the lock was held leaves a list that is rebuilt anyway.
        self.workspace.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The list class of the pair `i < j`, or `None` (excluded, or nothing to compute).
    #[inline(always)]
    fn classify(&self, i: usize, j: usize) -> Option<usize> {
        let class = self.class_table[self.kind[i] as usize * self.n_kinds + self.kind[j] as usize];
        if class == NO_CLASS {
            return None;
        }
        let excluded = &self.excluded_partners
            [self.excluded_start[i] as usize..self.excluded_start[i + 1] as usize];
        if excluded.contains(&(j as u32)) {
            return None;
        }
        Some(class as usize)
    }

    /// Rebuild the list if needed and set `wrapped` for `q`.
    fn refresh_list(&self, workspace: &mut Workspace, q: &[f64]) {
        if workspace.list.needs_rebuild(q) {
            workspace.list.build(q, |i, j| self.classify(i, j));
            self.listed_pairs
                .store(workspace.list.pair_count(), Ordering::Relaxed);
        }
        let Workspace {
            list,
            wrapped,
            packed,
            ..
        } = workspace;
        list.wrap_positions(q, wrapped);
        for ((p, x), &c) in packed
            .chunks_exact_mut(4)
            .zip(wrapped.chunks_exact(3))
            .zip(&self.scaled_charges)
        {
            p[..3].copy_from_slice(x);
            p[3] = c;
        }
    }

    /// Energies (LJ, Coulomb) and, with `gradient`, `gradient += ∇V`.
    fn evaluate(&self, q: &[f64], gradient: Option<&mut [f64]>) -> (f64, f64) {
        let mut guard = self.lock();
        let workspace = &mut *guard;
        if gradient.is_none()
            && let Some(cached) = workspace.cached
            && workspace.cached_q == q
        {
            return cached;
        }
        self.refresh_list(workspace, q);
        let with_gradient = gradient.is_some();
        let energies = match self.kernel {
            Kernel::Plain(c) => self.run_chunks(workspace, c, with_gradient),
            Kernel::ShiftedForce(c) => self.run_chunks(workspace, c, with_gradient),
            Kernel::Damped(c) => self.run_chunks(workspace, c, with_gradient),
            Kernel::ReactionField(c) => self.run_chunks(workspace, c, with_gradient),
        };
        if let Some(gradient) = gradient {
            reduce(&workspace.buffers, gradient, self.n);
            workspace.cached_q.copy_from_slice(q);
            workspace.cached = Some(energies);
        }
        energies
    }

    fn run_chunks<C: CoulombForm>(
        &self,
        workspace: &mut Workspace,
        coulomb: C,
        with_gradient: bool,
    ) -> (f64, f64) {
        let Workspace {
            list,
            wrapped,
            packed,
            buffers,
            energies,
            ..
        } = workspace;
        let shifts = &list.shifts;
        let _ = wrapped;
        let positions: &[f64] = packed;
        let image = list.all_pairs.then(|| list.lengths());
        let work = |(chunk, buffer): (&Chunk, &mut Vec<f64>)| -> (f64, f64) {
            if with_gradient {
                buffer.fill(0.0);
                self.chunk_kernel::<C, true>(chunk, shifts, image, positions, coulomb, buffer)
            } else {
                self.chunk_kernel::<C, false>(chunk, shifts, image, positions, coulomb, buffer)
            }
        };
        if self.n >= PARALLEL_MIN_PARTICLES && list.chunks.len() > 1 {
            list.chunks
                .par_iter()
                .zip(buffers.par_iter_mut())
                .zip(energies.par_iter_mut())
                .for_each(|(pair, energy)| *energy = work(pair));
        } else {
            for (pair, energy) in list
                .chunks
                .iter()
                .zip(buffers.iter_mut())
                .zip(energies.iter_mut())
            {
                *energy = work(pair);
            }
        }
        // Summed in chunk order: the same result for any thread count.
        energies
            .iter()
            .fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1))
    }

    /// The pairs of one chunk: energies, and the gradient into `buffer` when `GRADIENT`.
    /// Uses AVX2 when the processor has it (the same operations in the same order, so the
    /// same bits as the portable path).
    fn chunk_kernel<C: CoulombForm, const GRADIENT: bool>(
        &self,
        chunk: &Chunk,
        shifts: &[[f64; 3]; 27],
        image: Option<[f64; 3]>,
        x: &[f64],
        coulomb: C,
        buffer: &mut [f64],
    ) -> (f64, f64) {
        #[cfg(target_arch = "x86_64")]
        {
            if std::is_x86_feature_detected!("avx2") {
                // SAFETY: the processor supports AVX2, checked just above.
                return unsafe {
                    self.chunk_kernel_avx2::<C, GRADIENT>(chunk, shifts, image, x, coulomb, buffer)
                };
            }
        }
        self.chunk_kernel_body::<C, GRADIENT>(chunk, shifts, image, x, coulomb, buffer)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn chunk_kernel_avx2<C: CoulombForm, const GRADIENT: bool>(
        &self,
        chunk: &Chunk,
        shifts: &[[f64; 3]; 27],
        image: Option<[f64; 3]>,
        x: &[f64],
        coulomb: C,
        buffer: &mut [f64],
    ) -> (f64, f64) {
        self.chunk_kernel_body::<C, GRADIENT>(chunk, shifts, image, x, coulomb, buffer)
    }

    #[inline(always)]
    fn chunk_kernel_body<C: CoulombForm, const GRADIENT: bool>(
        &self,
        chunk: &Chunk,
        shifts: &[[f64; 3]; 27],
        image: Option<[f64; 3]>,
        x: &[f64],
        coulomb: C,
        buffer: &mut [f64],
    ) -> (f64, f64) {
        let mut energies = (0.0, 0.0);
        for (row, i) in chunk.rows.clone().enumerate() {
            let mut gi = [0.0; 3];
            for class in 0..N_CLASSES {
                let range =
                    chunk.starts[class][row] as usize..chunk.starts[class][row + 1] as usize;
                let entries = &chunk.entries[class][range];
                for block in entries.chunks(BLOCK) {
                    let pairs = Pairs {
                        i,
                        block,
                        shifts,
                        image,
                        x,
                    };
                    match (class, image.is_some()) {
                        (LJ_AND_CHARGE, false) => self.block::<C, GRADIENT, true, true, false>(
                            &pairs,
                            coulomb,
                            buffer,
                            &mut gi,
                            &mut energies,
                        ),
                        (CHARGE_ONLY, false) => self.block::<C, GRADIENT, false, true, false>(
                            &pairs,
                            coulomb,
                            buffer,
                            &mut gi,
                            &mut energies,
                        ),
                        (_, false) => self.block::<C, GRADIENT, true, false, false>(
                            &pairs,
                            coulomb,
                            buffer,
                            &mut gi,
                            &mut energies,
                        ),
                        (LJ_AND_CHARGE, true) => self.block::<C, GRADIENT, true, true, true>(
                            &pairs,
                            coulomb,
                            buffer,
                            &mut gi,
                            &mut energies,
                        ),
                        (CHARGE_ONLY, true) => self.block::<C, GRADIENT, false, true, true>(
                            &pairs,
                            coulomb,
                            buffer,
                            &mut gi,
                            &mut energies,
                        ),
                        (_, true) => self.block::<C, GRADIENT, true, false, true>(
                            &pairs,
                            coulomb,
                            buffer,
                            &mut gi,
                            &mut energies,
                        ),
                    }
                }
            }
            if GRADIENT {
                buffer[3 * i] += gi[0];
                buffer[3 * i + 1] += gi[1];
                buffer[3 * i + 2] += gi[2];
            }
        }
        energies
    }

    /// Up to `BLOCK` partners of particle `i`: gather their displacements and parameters,
    /// compute every pair in a loop free of indirect access and branches (the cutoff is a
    /// mask), so it vectorises, then sum the energies and scatter the forces in list order.
    /// `MIN_IMAGE`: an all-pairs list (no stored images): take the minimum image here.
    #[inline(always)]
    fn block<
        C: CoulombForm,
        const GRADIENT: bool,
        const LJ: bool,
        const CHARGE: bool,
        const MIN_IMAGE: bool,
    >(
        &self,
        pairs: &Pairs,
        coulomb: C,
        buffer: &mut [f64],
        gi: &mut [f64; 3],
        energies: &mut (f64, f64),
    ) {
        let Pairs {
            i,
            block,
            shifts,
            image,
            x,
        } = *pairs;
        let lengths = image.unwrap_or([1.0; 3]);
        let inverse = [1.0 / lengths[0], 1.0 / lengths[1], 1.0 / lengths[2]];
        let m = block.len();
        let xi = [x[4 * i], x[4 * i + 1], x[4 * i + 2]];
        let qi = self.scaled_charges[i];
        let nt = self.n_types;
        let lj_row = &self.lj[self.types[i] as usize * nt..(self.types[i] as usize + 1) * nt];
        let mut dx = [0.0; BLOCK];
        let mut dy = [0.0; BLOCK];
        let mut dz = [0.0; BLOCK];
        let mut qq = [0.0; BLOCK];
        let mut c12 = [0.0; BLOCK];
        let mut c6 = [0.0; BLOCK];
        let mut lj_shift = [0.0; BLOCK];
        for (k, &entry) in block.iter().enumerate() {
            let (j, s) = unpack(entry);
            let xj = &x[4 * j..4 * j + 4];
            if MIN_IMAGE {
                // All-pairs lists store no image (shift 0): the minimum image comes below.
                dx[k] = xj[0] - xi[0];
                dy[k] = xj[1] - xi[1];
                dz[k] = xj[2] - xi[2];
            } else {
                let shift = &shifts[s];
                dx[k] = xj[0] + shift[0] - xi[0];
                dy[k] = xj[1] + shift[1] - xi[1];
                dz[k] = xj[2] + shift[2] - xi[2];
            }
            if CHARGE {
                qq[k] = qi * xj[3];
            }
            if LJ {
                let p = lj_row[self.types[j] as usize];
                c12[k] = p.c12;
                c6[k] = p.c6;
                lj_shift[k] = p.shift;
            }
        }
        let rc2 = self.cutoff_squared;
        let mut f = [0.0; BLOCK];
        let mut e_lj = [0.0; BLOCK];
        let mut e_q = [0.0; BLOCK];
        if MIN_IMAGE {
            for k in 0..m {
                dx[k] -= lengths[0] * (dx[k] * inverse[0]).round();
                dy[k] -= lengths[1] * (dy[k] * inverse[1]).round();
                dz[k] -= lengths[2] * (dz[k] * inverse[2]).round();
            }
        }
        // Distances, then the pairs inside the cutoff packed to the front without branches:
        // the costly part (division, square root) runs on those only, as a dense loop.
        let mut r2 = [0.0; BLOCK];
        for k in 0..m {
            r2[k] = dx[k] * dx[k] + dy[k] * dy[k] + dz[k] * dz[k];
        }
        let mut index = [0u8; BLOCK];
        let mut count = 0;
        for (k, &distance) in r2[..m].iter().enumerate() {
            index[count] = k as u8;
            count += (distance < rc2) as usize;
        }
        let mut s = [0.0; BLOCK];
        for t in 0..count {
            let k = index[t] as usize;
            s[t] = r2[k];
            if LJ {
                c12[t] = c12[k];
                c6[t] = c6[k];
                lj_shift[t] = lj_shift[k];
            }
            if CHARGE {
                qq[t] = qq[k];
            }
        }
        for t in 0..count {
            let inv_r2 = 1.0 / s[t];
            let mut force = 0.0;
            if LJ {
                let inv_r6 = inv_r2 * inv_r2 * inv_r2;
                e_lj[t] = inv_r6 * (c12[t] * inv_r6 - c6[t]) - lj_shift[t];
                force += inv_r2 * inv_r6 * (12.0 * c12[t] * inv_r6 - 6.0 * c6[t]);
            }
            if CHARGE {
                let (e, fq) = coulomb.energy_force(qq[t], s[t], inv_r2.sqrt());
                e_q[t] = e;
                force += fq;
            }
            f[t] = force;
        }
        for t in 0..count {
            energies.0 += e_lj[t];
            energies.1 += e_q[t];
        }
        if GRADIENT {
            for t in 0..count {
                let k = index[t] as usize;
                let (j, _) = unpack(block[k]);
                // ∂V/∂r_j = V′ d/r = −f d.
                let g = [f[t] * dx[k], f[t] * dy[k], f[t] * dz[k]];
                gi[0] += g[0];
                gi[1] += g[1];
                gi[2] += g[2];
                buffer[3 * j] -= g[0];
                buffer[3 * j + 1] -= g[1];
                buffer[3 * j + 2] -= g[2];
            }
        }
    }

    /// `(V′, V″)` of the pair `i, j` at distance `r` (both zero beyond the cutoff).
    fn pair_derivatives(&self, class: usize, i: usize, j: usize, r: f64) -> (f64, f64) {
        let mut d1 = 0.0;
        let mut d2 = 0.0;
        if class != CHARGE_ONLY {
            let p = self.lj[self.types[i] as usize * self.n_types + self.types[j] as usize];
            let inv_r = 1.0 / r;
            let inv6 = inv_r.powi(6);
            d1 += inv_r * inv6 * (-12.0 * p.c12 * inv6 + 6.0 * p.c6);
            d2 += inv_r * inv_r * inv6 * (156.0 * p.c12 * inv6 - 42.0 * p.c6);
        }
        if class != LJ_ONLY {
            let qq = self.scaled_charges[i] * self.scaled_charges[j];
            let (_, a, b) = match self.kernel {
                Kernel::Plain(c) => c.derivatives(qq, r),
                Kernel::ShiftedForce(c) => c.derivatives(qq, r),
                Kernel::Damped(c) => c.derivatives(qq, r),
                Kernel::ReactionField(c) => c.derivatives(qq, r),
            };
            d1 += a;
            d2 += b;
        }
        (d1, d2)
    }
}

/// `gradient += Σ_c buffers[c]`, chunk by chunk in order (deterministic), split over
/// coordinates in parallel for large systems.
fn reduce(buffers: &[Vec<f64>], gradient: &mut [f64], n: usize) {
    let add = |(offset, out): (usize, &mut [f64])| {
        for buffer in buffers {
            for (o, b) in out.iter_mut().zip(&buffer[offset..]) {
                *o += b;
            }
        }
    };
    const BLOCK: usize = 3 * 1024;
    if n >= PARALLEL_MIN_PARTICLES * 8 {
        gradient
            .par_chunks_mut(BLOCK)
            .enumerate()
            .map(|(k, out)| (k * BLOCK, out))
            .for_each(add);
    } else {
        add((0, gradient));
    }
}

impl ForceTerm for Nonbonded {
    fn kind(&self) -> &'static str {
        "nonbonded"
    }

    fn class(&self) -> TermClass {
        TermClass::Nonbonded
    }

    fn energy(&self, q: &[f64]) -> f64 {
        let (lj, coulomb) = self.evaluate(q, None);
        lj + coulomb
    }

    fn add_gradient(&self, q: &[f64], gradient: &mut [f64]) {
        self.evaluate(q, Some(gradient));
    }

    fn add_hessian_vector(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        let mut guard = self.lock();
        let workspace = &mut *guard;
        self.refresh_list(workspace, q);
        let Workspace {
            list,
            wrapped,
            buffers,
            ..
        } = workspace;
        let x: &[f64] = wrapped;
        let rc2 = self.cutoff_squared;
        let image = list.all_pairs.then(|| list.lengths());
        let work = |(chunk, buffer): (&Chunk, &mut Vec<f64>)| {
            buffer.fill(0.0);
            for (row, i) in chunk.rows.clone().enumerate() {
                for class in 0..N_CLASSES {
                    let range =
                        chunk.starts[class][row] as usize..chunk.starts[class][row + 1] as usize;
                    for &entry in &chunk.entries[class][range] {
                        let (j, s) = unpack(entry);
                        let shift = &list.shifts[s];
                        let d: [f64; 3] = std::array::from_fn(|a| {
                            let d = x[3 * j + a] + shift[a] - x[3 * i + a];
                            match image {
                                Some(l) => d - l[a] * (d / l[a]).round(),
                                None => d,
                            }
                        });
                        let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                        if r2 >= rc2 {
                            continue;
                        }
                        let r = r2.sqrt();
                        let (d1, d2) = self.pair_derivatives(class, i, j, r);
                        let a = d1 / r;
                        let b = (d2 - a) / r2;
                        let dv: [f64; 3] = std::array::from_fn(|k| v[3 * j + k] - v[3 * i + k]);
                        let along = b * (d[0] * dv[0] + d[1] * dv[1] + d[2] * dv[2]);
                        for k in 0..3 {
                            let h = a * dv[k] + along * d[k];
                            buffer[3 * j + k] += h;
                            buffer[3 * i + k] -= h;
                        }
                    }
                }
            }
        };
        if self.n >= PARALLEL_MIN_PARTICLES && list.chunks.len() > 1 {
            list.chunks
                .par_iter()
                .zip(buffers.par_iter_mut())
                .for_each(work);
        } else {
            list.chunks.iter().zip(buffers.iter_mut()).for_each(work);
        }
        reduce(buffers, out, self.n);
    }

    fn couplings(&self) -> Vec<Vec<usize>> {
        let workspace = self.lock();
        let mut pairs = Vec::new();
        for chunk in &workspace.list.chunks {
            for (row, i) in chunk.rows.clone().enumerate() {
                for class in 0..N_CLASSES {
                    let range =
                        chunk.starts[class][row] as usize..chunk.starts[class][row + 1] as usize;
                    for &entry in &chunk.entries[class][range] {
                        let (j, _) = unpack(entry);
                        pairs.push([i.min(j), i.max(j)]);
                    }
                }
            }
        }
        pairs.sort_unstable();
        pairs.dedup();
        pairs.into_iter().map(|p| p.to_vec()).collect()
    }

    fn interaction_count(&self) -> usize {
        self.listed_pairs.load(Ordering::Relaxed)
    }

    fn energy_components(&self, q: &[f64]) -> Vec<(&'static str, f64)> {
        let (lj, coulomb) = self.evaluate(q, None);
        vec![("lennard-jones", lj), ("coulomb", coulomb)]
    }
}
