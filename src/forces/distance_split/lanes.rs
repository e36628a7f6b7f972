//! The short part by molecule for a box of one kind of small molecule (every molecule the
//! same atoms — at most four — with the same types and charges in the same order, the
//! reference atom in the same place: water models), SIMD over atom pairs as the
//! cluster-pair kernel ([`crate::forces::nonbonded`]) runs a cluster pair: a listed molecule
//! pair is one 4 × 4 block of atom pairs (rows the atoms of the row molecule, lanes the
//! partner's; the slots past the molecule's size are masked), and its switch `S(R_IJ)` is
//! one number for the whole block. With one molecule kind every block has the same
//! Lennard-Jones coefficients and charge products lane by lane, so a block reads only the
//! partner's twelve coordinates. The formulas are the parent module's; `1/r` is the
//! engine's Newton iteration, sums go in the engine's fixed lane order, so every instruction
//! set gives the same bits, and chunks make them independent of the thread count. Unlike
//! the row loop of [`super::kernels`] (partner atoms gathered into scratch arrays, a dozen
//! passes over them), a block stays in registers.

use super::kernels::{Scratch, keep_partners, list_rows};
use super::{Model, Molecules, Switch};
use crate::forces::clusters::{Cluster, PAD_POSITION};
use crate::forces::nonbonded::kernel::{
    Coulomb, Gradient4, add_pair_force, combine, finish_rows, gather, lennard_jones_energy,
    lennard_jones_force,
};
use crate::forces::nonbonded::{CoulombLanes, CoulombPair};
use crate::forces::simd::{Isa, Simd, row_lanes, simd_dispatch};

/// The lane constants of one molecule kind: per lane `4 × row + column` (row an atom of
/// the row molecule, column one of the partner's).
#[derive(Clone)]
pub(crate) struct Lanes {
    /// Atoms per molecule (≤ 4).
    size: usize,
    /// The reference atom's place in a molecule.
    reference: usize,
    /// Lanes of real atom pairs.
    mask: u16,
    c12: [f64; 16],
    c6: [f64; 16],
    lj_shift: [f64; 16],
    /// `k_e q_i q_j`.
    qq: [f64; 16],
    coulomb: CoulombPair,
}

impl Lanes {
    /// The constants when every molecule is the first one over again (`None` otherwise:
    /// the row loop of [`super::kernels`] takes any molecules).
    pub(crate) fn of(model: &Model, molecules: &Molecules) -> Option<Lanes> {
        let size = molecules.uniform_size;
        if size == 0 || size > 4 || molecules.reference.is_empty() {
            return None;
        }
        let first = &molecules.atoms[..size];
        let reference = molecules.reference_slot[0] as usize;
        let same_kind = (0..molecules.reference.len()).all(|m| {
            let atoms = &molecules.atoms[size * m..size * m + size];
            molecules.reference_slot[m] as usize == size * m + reference
                && molecules.types[size * m..size * m + size] == molecules.types[..size]
                && atoms.iter().zip(first).all(|(&a, &b)| {
                    model.scaled_charge(a as usize) == model.scaled_charge(b as usize)
                })
        });
        if !same_kind {
            return None;
        }
        let mut lanes = Lanes {
            size,
            reference,
            mask: 0,
            c12: [0.0; 16],
            c6: [0.0; 16],
            lj_shift: [0.0; 16],
            qq: [0.0; 16],
            coulomb: model.coulomb,
        };
        for (row, &i) in first.iter().enumerate() {
            for (column, &j) in first.iter().enumerate() {
                let (i, j) = (i as usize, j as usize);
                let lane = 4 * row + column;
                let p = model.lj(i, j);
                lanes.mask |= 1 << lane;
                (lanes.c12[lane], lanes.c6[lane], lanes.lj_shift[lane]) = (p.c12, p.c6, p.shift);
                lanes.qq[lane] = model.scaled_charge(i) * model.scaled_charge(j);
            }
        }
        Some(lanes)
    }

    /// Molecule `m` of `packed` (`[x, y, z, q√k_e]` in molecule order, molecules whole) as a
    /// cluster, the empty slots far away.
    pub(crate) fn pack(&self, packed: &[[f64; 4]], clusters: &mut [Cluster<f64>]) {
        for (m, cluster) in clusters.iter_mut().enumerate() {
            for k in 0..4 {
                let x = if k < self.size {
                    packed[self.size * m + k]
                } else {
                    [PAD_POSITION; 4]
                };
                // The charges are lane constants of the kind: `q` stays unused.
                (cluster.x[k], cluster.y[k], cluster.z[k]) = (x[0], x[1], x[2]);
            }
        }
    }
}

/// What one chunk's evaluation reads and where it writes.
pub(crate) struct Block<'a> {
    pub lanes: &'a Lanes,
    pub model: &'a Model,
    pub switch: Switch,
    pub molecules: &'a Molecules,
    pub clusters: &'a [Cluster<f64>],
    /// `[x, y, z, q√k_e]` per atom in molecule order (the reference atoms read here).
    pub packed: &'a [[f64; 4]],
    /// Molecule pairs, row by row ([`list_rows`]).
    pub pairs: &'a [[u32; 2]],
}

/// `Σ S(R) E_IJ` over the block's pairs, and its gradient into `buffer` when `GRADIENT`.
pub(crate) fn evaluate<const GRADIENT: bool>(
    isa: Isa,
    block: &Block,
    scratch: &mut Scratch,
    buffer: &mut [f64],
) -> f64 {
    struct Run<'a, 'b, const G: bool>(Isa, &'a Block<'a>, &'b mut Scratch, &'b mut [f64]);
    impl<const G: bool> CoulombLanes for Run<'_, '_, G> {
        type Out = f64;
        fn with<C: Coulomb>(self, coulomb: C) -> f64 {
            let Run(isa, block, scratch, buffer) = self;
            rows_on::<C, G>(isa, block, coulomb, scratch, buffer)
        }
    }
    block
        .lanes
        .coulomb
        .lanes(Run::<GRADIENT>(isa, block, scratch, buffer))
}

simd_dispatch! {
    /// [`rows`] on the instruction set `isa`.
    fn rows_on[C: Coulomb, const G: bool][C, G](
        block: &Block,
        coulomb: C,
        scratch: &mut Scratch,
        buffer: &mut [f64],
    ) -> f64 = rows::<_, C, G>, lanes f64;
}

/// The lane constants in registers, one per group of rows.
struct Registers<S: Simd> {
    zero: S::V,
    one: S::V,
    cutoff2: S::V,
    c12: [S::V; 4],
    c6: [S::V; 4],
    /// `12 c₁₂`, `6 c₆`.
    c12x12: [S::V; 4],
    c6x6: [S::V; 4],
    lj_shift: [S::V; 4],
    qq: [S::V; 4],
    /// Whether a group has a lane with Lennard-Jones (water: only rows with the O).
    has_lj: [bool; 4],
    /// Whether a group has a real atom pair (not with three atoms and four lanes a row).
    active: [bool; 4],
}

impl<S: Simd<R = f64>> Registers<S> {
    #[inline(always)]
    fn new(s: S, lanes: &Lanes, cutoff2: f64) -> Self {
        let group = |values: &[f64; 16]| -> [S::V; 4] {
            std::array::from_fn(|g| {
                let g = g.min(16 / S::WIDTH - 1);
                let mut a = [0.0; 16];
                a[..S::WIDTH].copy_from_slice(&values[g * S::WIDTH..(g + 1) * S::WIDTH]);
                s.load(&a)
            })
        };
        let times = |values: &[f64; 16], k: f64| values.map(|v| k * v);
        Registers {
            zero: s.splat(0.0),
            one: s.splat(1.0),
            cutoff2: s.splat(cutoff2),
            c12: group(&lanes.c12),
            c6: group(&lanes.c6),
            c12x12: group(&times(&lanes.c12, 12.0)),
            c6x6: group(&times(&lanes.c6, 6.0)),
            lj_shift: group(&lanes.lj_shift),
            qq: group(&lanes.qq),
            active: std::array::from_fn(|g| {
                let g = g.min(16 / S::WIDTH - 1);
                (lanes.mask as u32 >> (g * S::WIDTH)) & ((1u32 << S::WIDTH) - 1) != 0
            }),
            has_lj: std::array::from_fn(|g| {
                let g = g.min(16 / S::WIDTH - 1);
                (g * S::WIDTH..(g + 1) * S::WIDTH)
                    .any(|l| lanes.c12[l] != 0.0 || lanes.c6[l] != 0.0 || lanes.lj_shift[l] != 0.0)
            }),
        }
    }
}

/// Every row of the block.
#[inline(always)]
fn rows<S: Simd<R = f64>, C: Coulomb, const GRADIENT: bool>(
    s: S,
    block: &Block,
    coulomb: C,
    scratch: &mut Scratch,
    buffer: &mut [f64],
) -> f64 {
    let k = Registers::new(s, block.lanes, block.model.cutoff_squared);
    let mut energy = 0.0;
    for (a, group) in list_rows(block.pairs) {
        energy += row::<S, C, GRADIENT>(s, &k, coulomb, block, a, group, scratch, buffer);
    }
    energy
}

/// Row molecule `a` against its listed partners `group` inside `r_out`.
#[inline(always)]
#[allow(clippy::too_many_arguments, clippy::needless_range_loop)]
fn row<S: Simd<R = f64>, C: Coulomb, const GRADIENT: bool>(
    s: S,
    k: &Registers<S>,
    coulomb: C,
    block: &Block,
    a: usize,
    group: &[[u32; 2]],
    sc: &mut Scratch,
    buffer: &mut [f64],
) -> f64 {
    let lanes = block.lanes;
    let ci = &block.clusters[a];
    let reference = |m: usize| {
        let x = block.packed[lanes.size * m + lanes.reference];
        [x[0], x[1], x[2]]
    };
    let xa = reference(a);
    let partners = keep_partners(block.model, block.switch, xa, group, sc, reference);
    // Plain loops, not `array::from_fn`: its body is not compiled with the lanes'
    // instruction set, so the loads inside would be calls.
    let mut xi = [[k.zero; 4]; 3];
    for g in 0..4 {
        xi[0][g] = row_lanes(s, &ci.x, 0.0, g);
        xi[1][g] = row_lanes(s, &ci.y, 0.0, g);
        xi[2][g] = row_lanes(s, &ci.z, 0.0, g);
    }
    let mut gi = [[k.zero; 3]; 4];
    let mut energy = 0.0;
    for p in 0..partners {
        let b = sc.partner[p] as usize;
        let cj = &block.clusters[b];
        let d = sc.partner_d[p];
        let xb = reference(b);
        // The partner's atoms moved to the row molecule's image of it.
        let shift: [f64; 3] = std::array::from_fn(|c| d[c] - (xb[c] - xa[c]));
        let xj = [
            s.add(s.load4(&cj.x), s.splat(shift[0])),
            s.add(s.load4(&cj.y), s.splat(shift[1])),
            s.add(s.load4(&cj.z), s.splat(shift[2])),
        ];
        let weight = sc.partner_s[p];
        let (pair_energy, gj) =
            pair::<S, C, GRADIENT>(s, k, coulomb, lanes, &xi, xj, weight, &mut gi);
        energy += weight * pair_energy;
        if GRADIENT {
            let atoms = &block.molecules.atoms[lanes.size * b..lanes.size * b + lanes.size];
            add_slots(buffer, atoms, &gj);
            sc.add_switch_force(&block.molecules.reference, a, p, pair_energy, buffer);
        }
    }
    if GRADIENT && partners > 0 {
        let mut g = Gradient4::default();
        finish_rows(s, &gi, &mut g);
        let atoms = &block.molecules.atoms[lanes.size * a..lanes.size * a + lanes.size];
        add_slots(buffer, atoms, &g);
    }
    energy
}

/// `buffer[atom of slot k] += g[k]` for the molecule's slots.
#[inline(always)]
fn add_slots(buffer: &mut [f64], atoms: &[u32], g: &Gradient4) {
    for (k, &atom) in atoms.iter().enumerate() {
        let out = &mut buffer[3 * atom as usize..3 * atom as usize + 3];
        out[0] += g.x[k];
        out[1] += g.y[k];
        out[2] += g.z[k];
    }
}

/// One molecule pair: its energy `E_IJ` and, when `GRADIENT`, the partner's gradient
/// `S ∇_J E_IJ` (returned) and the row molecule's (added to `gi`, in registers).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn pair<S: Simd<R = f64>, C: Coulomb, const GRADIENT: bool>(
    s: S,
    k: &Registers<S>,
    coulomb: C,
    lanes: &Lanes,
    xi: &[[S::V; 4]; 3],
    xj: [S::V; 3],
    weight: f64,
    gi: &mut [[S::V; 3]; 4],
) -> (f64, Gradient4) {
    let lane_bits = if S::WIDTH >= 16 {
        0xFFFF
    } else {
        (1u32 << S::WIDTH) - 1
    };
    let weight = s.splat(weight);
    let mut fj = [[k.zero; 2]; 3];
    let mut ej = [k.zero; 2];
    for g in 0..16 / S::WIDTH {
        if !k.active[g] {
            continue;
        }
        let dx = s.sub(xi[0][g], xj[0]);
        let dy = s.sub(xi[1][g], xj[1]);
        let dz = s.sub(xi[2][g], xj[2]);
        let r2 = s.fma(dz, dz, s.fma(dy, dy, s.mul(dx, dx)));
        let bits = (lanes.mask as u32 >> (g * S::WIDTH)) & lane_bits;
        let m = s.and(s.mask(bits), s.less(r2, k.cutoff2));
        let r2 = s.select(m, r2, k.one);
        let rinv = s.rsqrt(r2);
        let rinv2 = s.mul(rinv, rinv);
        let (mut e, mut f) = coulomb.lanes::<S, true>(s, k.qq[g], r2, rinv, rinv2);
        if k.has_lj[g] {
            // Lanes without Lennard-Jones add exact zeros here: skipping it changes no bit.
            let (rinv8, rinv6, bracket) = lennard_jones_force(s, k.c12x12[g], k.c6x6[g], rinv2);
            e = s.add(
                lennard_jones_energy(s, k.c12[g], k.c6[g], k.lj_shift[g], rinv6),
                e,
            );
            f = s.fma(rinv8, bracket, f);
        }
        gather(s, &mut ej, g, s.select(m, e, k.zero));
        if GRADIENT {
            let f = s.mul(weight, s.select(m, f, k.zero));
            add_pair_force(s, f, [dx, dy, dz], g, &mut gi[g], &mut fj);
        }
    }
    let mut e = [0.0; 4];
    s.fold4(combine(s, &ej), &mut e);
    let mut gj = Gradient4::default();
    if GRADIENT {
        s.fold4(combine(s, &fj[0]), &mut gj.x);
        s.fold4(combine(s, &fj[1]), &mut gj.y);
        s.fold4(combine(s, &fj[2]), &mut gj.z);
    }
    ((e[0] + e[2]) + (e[1] + e[3]), gj)
}
