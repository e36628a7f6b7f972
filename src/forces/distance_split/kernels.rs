//! The short part's row loop over whole molecules (energy and gradient; formulas in the
//! parent module's doc): each row molecule against its listed partners inside `r_out`,
//! one switch value `S(R)` per partner for all its atom pairs. Any molecules; a box of one
//! kind of small molecule takes the SIMD blocks of [`super::lanes`] instead, and
//! Hessian-vector products the pair loop of [`super::pairs`].

use super::pairs::{add_pair, dot};
use super::{Model, ShortRange, Switch};
use crate::forces::nonbonded::LjPair;

/// Scratch of one chunk for [`whole_molecule_rows`]: the partner molecules of one row
/// molecule inside `r_out`, and their atoms laid out for a branch-free loop.
#[derive(Default)]
pub(super) struct Scratch {
    partner_count: usize,
    /// Per partner molecule: the reference displacement, `R`, `S`, `S′`, its energy sum.
    pub(super) partner: Vec<u32>,
    pub(super) partner_d: Vec<[f64; 3]>,
    pub(super) partner_r: Vec<f64>,
    pub(super) partner_s: Vec<f64>,
    pub(super) partner_s1: Vec<f64>,
    /// Where each partner's atoms start among the partner atoms (one more entry: the end).
    partner_start: Vec<u32>,
    /// Per partner atom: position (shifted to the row molecule's image), scaled charge,
    /// type, global index, switch weight.
    x: [Vec<f64>; 3],
    charge: Vec<f64>,
    kind: Vec<u32>,
    atom: Vec<u32>,
    weight: Vec<f64>,
    /// Per pair of the current row atom: LJ coefficients, displacement, energy, weighted
    /// force factor.
    c12: Vec<f64>,
    c6: Vec<f64>,
    lj_shift: Vec<f64>,
    d: [Vec<f64>; 3],
    r2: Vec<f64>,
    inv_r: Vec<f64>,
    qq: Vec<f64>,
    coulomb_energy: Vec<f64>,
    coulomb_force: Vec<f64>,
    energy: Vec<f64>,
    force: Vec<f64>,
    /// Per partner atom, summed over the row molecule's atoms: pair energy and gradient.
    energy_sum: Vec<f64>,
    gradient_sum: [Vec<f64>; 3],
}

impl Scratch {
    /// Room for `partners` molecules and `atoms` atoms per row (25 % more, so later list
    /// builds rarely grow it).
    pub(super) fn reserve(&mut self, partners: usize, atoms: usize) {
        let grow = |n: usize| n + n / 4;
        if self.partner.len() < partners {
            let n = grow(partners);
            self.partner.resize(n, 0);
            self.partner_start.resize(n + 1, 0);
            self.partner_d.resize(n, [0.0; 3]);
            self.partner_r.resize(n, 0.0);
            self.partner_s.resize(n, 0.0);
            self.partner_s1.resize(n, 0.0);
        }
        if self.charge.len() < atoms {
            let n = grow(atoms);
            for v in [&mut self.kind, &mut self.atom] {
                v.resize(n, 0);
            }
            for v in self
                .x
                .iter_mut()
                .chain(&mut self.d)
                .chain(&mut self.gradient_sum)
            {
                v.resize(n, 0.0);
            }
            for v in [
                &mut self.charge,
                &mut self.weight,
                &mut self.c12,
                &mut self.c6,
                &mut self.lj_shift,
                &mut self.r2,
                &mut self.inv_r,
                &mut self.qq,
                &mut self.coulomb_energy,
                &mut self.coulomb_force,
                &mut self.energy,
                &mut self.force,
                &mut self.energy_sum,
            ] {
                v.resize(n, 0.0);
            }
        }
    }

    /// The switch's force `E_IJ S′ ∇R` (module doc's chain rule) between row molecule `a`
    /// and its kept partner `p`, with pair energy `e`, on their reference atoms.
    #[inline(always)]
    pub(super) fn add_switch_force(
        &self,
        reference: &[u32],
        a: usize,
        p: usize,
        e: f64,
        out: &mut [f64],
    ) {
        if self.partner_s1[p] != 0.0 {
            let k = e * self.partner_s1[p] / self.partner_r[p];
            let (ra, rb) = (reference[a], reference[self.partner[p] as usize]);
            add_pair(
                out,
                ra as usize,
                rb as usize,
                self.partner_d[p].map(|x| k * x),
            );
        }
    }
}

/// Molecule pairs over whole molecules (`packed`: `[x, y, z, q√k_e]` in molecule order,
/// each atom at the image nearest its reference), row by row: each run of list entries
/// with the same first molecule is one row ([`whole_molecule_row`]). Molecules that all
/// have 3 or 4 atoms (water models) take a copy of the loops with that size fixed at
/// compile time, so the per-partner copies and sums unroll: the same operations in the
/// same order, so the same bits.
#[inline(always)]
pub(super) fn whole_molecule_rows<const GRADIENT: bool>(
    short: &ShortRange,
    packed: &[[f64; 4]],
    pairs: &[[u32; 2]],
    sc: &mut Scratch,
    out: &mut [f64],
) -> f64 {
    let mut energy = 0.0;
    for (a, group) in list_rows(pairs) {
        energy += match short.molecules.uniform_size {
            3 => whole_molecule_row::<GRADIENT, 3>(short, packed, a, group, sc, out),
            4 => whole_molecule_row::<GRADIENT, 4>(short, packed, a, group, sc, out),
            _ => whole_molecule_row::<GRADIENT, 0>(short, packed, a, group, sc, out),
        };
    }
    energy
}

/// The rows of a molecule-pair list: each run of entries with the same first molecule, as
/// that molecule and its entries (the list is built row by row).
#[inline(always)]
pub(super) fn list_rows(pairs: &[[u32; 2]]) -> impl Iterator<Item = (usize, &[[u32; 2]])> {
    pairs
        .chunk_by(|x, y| x[0] == y[0])
        .map(|group| (group[0][0] as usize, group))
}

/// The slots of molecule (or gathered partner) `m`: `M m ..` when every molecule has `M`
/// atoms (a constant the loops over them unroll on), else from its table of starts.
#[inline(always)]
fn slots<const M: usize>(start: &[u32], m: usize) -> std::ops::Range<usize> {
    if M > 0 {
        M * m..M * m + M
    } else {
        start[m] as usize..start[m + 1] as usize
    }
}

/// One row molecule `a` against its listed partners: gather the partners inside `r_out`
/// and their atoms; for each atom of `a` one branch-free pass over all partner atoms (the
/// cutoff is a 0/1 factor, so it vectorises) that adds each pair's energy and gradient to
/// the partner atom's sums; then the sums per partner molecule, the scatter of the partner
/// atoms' forces (once per row molecule), and the switch's force on the reference atoms.
#[inline(always)]
fn whole_molecule_row<const GRADIENT: bool, const M: usize>(
    short: &ShortRange,
    packed: &[[f64; 4]],
    a: usize,
    group: &[[u32; 2]],
    sc: &mut Scratch,
    buffer: &mut [f64],
) -> f64 {
    let n = gather_partners::<M>(short, packed, a, group, sc);
    if sc.partner_count == 0 {
        return 0.0;
    }
    sc.energy_sum[..n].fill(0.0);
    for g in &mut sc.gradient_sum {
        g[..n].fill(0.0);
    }
    row_atom_passes::<GRADIENT, M>(short, packed, a, n, sc, buffer);
    partner_sums::<GRADIENT, M>(short, a, sc, buffer)
}

/// For each atom of row molecule `a`, its pairs with the `n` gathered partner atoms into
/// the partner atoms' sums, and its own gradient into `buffer`.
#[inline(always)]
fn row_atom_passes<const GRADIENT: bool, const M: usize>(
    short: &ShortRange,
    packed: &[[f64; 4]],
    a: usize,
    n: usize,
    sc: &mut Scratch,
    buffer: &mut [f64],
) {
    let model = &short.model;
    let molecules = &short.molecules;
    let atoms_a = slots::<M>(&molecules.start, a);
    let row_atoms = packed[atoms_a.clone()]
        .iter()
        .zip(&molecules.types[atoms_a.clone()])
        .zip(&molecules.atoms[atoms_a]);
    for ((&xk, &type_k), &atom_k) in row_atoms {
        // Atoms of a type without Lennard-Jones (water's H) skip its gather and arithmetic.
        match model.lj_row(type_k) {
            Some(row) => {
                let kind = &sc.kind[..n];
                let (c12, c6) = (&mut sc.c12[..n], &mut sc.c6[..n]);
                let lj_shift = &mut sc.lj_shift[..n];
                for t in 0..n {
                    let p = row[kind[t] as usize];
                    (c12[t], c6[t], lj_shift[t]) = (p.c12, p.c6, p.shift);
                }
                pair_block::<true>(model, xk, n, sc);
            }
            None => pair_block::<false>(model, xk, n, sc),
        }
        let gi = accumulate::<GRADIENT>(sc, n);
        if GRADIENT {
            let i = atom_k as usize;
            let out = &mut buffer[3 * i..3 * i + 3];
            for c in 0..3 {
                out[c] += gi[c];
            }
        }
    }
}

/// Per gathered partner of row molecule `a`: its pair energy `E_IJ` (returned summed as
/// `Σ S E_IJ`), the scatter of its atoms' gradient sums, and the switch's force
/// `E_IJ S′ ∇R` on the two reference atoms.
#[inline(always)]
fn partner_sums<const GRADIENT: bool, const M: usize>(
    short: &ShortRange,
    a: usize,
    sc: &Scratch,
    buffer: &mut [f64],
) -> f64 {
    let molecules = &short.molecules;
    let mut energy = 0.0;
    for p in 0..sc.partner_count {
        let slots = slots::<M>(&sc.partner_start, p);
        let pair_energy: f64 = sc.energy_sum[slots.clone()].iter().sum();
        if GRADIENT {
            let [gx, gy, gz] = &sc.gradient_sum;
            let sums = gx[slots.clone()]
                .iter()
                .zip(&gy[slots.clone()])
                .zip(&gz[slots.clone()]);
            for (&j, ((x, y), z)) in sc.atom[slots].iter().zip(sums) {
                let out = &mut buffer[3 * j as usize..3 * j as usize + 3];
                out[0] += x;
                out[1] += y;
                out[2] += z;
            }
        }
        energy += sc.partner_s[p] * pair_energy;
        if GRADIENT {
            sc.add_switch_force(&molecules.reference, a, p, pair_energy, buffer);
        }
    }
    energy
}

/// The pairs of one row atom into the partner atoms' sums (vectorised: no reduction across
/// partners); returns the row atom's gradient `−Σ_t g_t` (summed in order).
#[inline(always)]
fn accumulate<const GRADIENT: bool>(sc: &mut Scratch, n: usize) -> [f64; 3] {
    let (energy, energy_sum) = (&sc.energy[..n], &mut sc.energy_sum[..n]);
    for t in 0..n {
        energy_sum[t] += energy[t];
    }
    let mut gi = [0.0; 3];
    if !GRADIENT {
        return gi;
    }
    let force = &sc.force[..n];
    for (c, g) in gi.iter_mut().enumerate() {
        // ∂V/∂x_j = V′ d/r = −f d, weighted by S (in `force`); stored in `d` for the sum.
        let (d, sum) = (&mut sc.d[c][..n], &mut sc.gradient_sum[c][..n]);
        for t in 0..n {
            d[t] *= -force[t];
            sum[t] += d[t];
        }
        *g = -sum_in_lanes(d);
    }
    gi
}

/// `Σ x` in eight interleaved partial sums, combined in a fixed tree: one vector add per
/// eight terms where a left-to-right sum waits out an add's latency per term (that chain
/// was a quarter of the row's time). The order depends only on `x.len()`, never on threads
/// or the instruction set.
#[inline(always)]
fn sum_in_lanes(x: &[f64]) -> f64 {
    let mut lanes = [0.0; 8];
    let chunks = x.chunks_exact(8);
    let rest = chunks.remainder();
    for chunk in chunks {
        for (lane, v) in lanes.iter_mut().zip(chunk) {
            *lane += v;
        }
    }
    for (lane, v) in lanes.iter_mut().zip(rest) {
        *lane += v;
    }
    let [a0, a1, a2, a3, a4, a5, a6, a7] = lanes;
    ((a0 + a4) + (a2 + a6)) + ((a1 + a5) + (a3 + a7))
}

/// The partners of row molecule `a` inside `r_out` into `sc` (count in `partner_count`)
/// and their atoms, shifted to `a`'s image; returns the number of partner atoms.
#[inline(always)]
fn gather_partners<const M: usize>(
    short: &ShortRange,
    packed: &[[f64; 4]],
    a: usize,
    group: &[[u32; 2]],
    sc: &mut Scratch,
) -> usize {
    let molecules = &short.molecules;
    let reference = |m: usize| {
        let x = packed[molecules.reference_slot[m] as usize];
        [x[0], x[1], x[2]]
    };
    let xa = reference(a);
    let partners = keep_partners(&short.model, short.switch, xa, group, sc, reference);
    let mut atoms = 0;
    for p in 0..partners {
        let b = sc.partner[p] as usize;
        let d = sc.partner_d[p];
        let xb = reference(b);
        // The shift from each atom's stored image to the row molecule's.
        let shift: [f64; 3] = std::array::from_fn(|c| d[c] - (xb[c] - xa[c]));
        sc.partner_start[p] = atoms as u32;
        // The partner's atoms are contiguous in molecule order: copy them as blocks.
        let source = slots::<M>(&molecules.start, b);
        let slots = atoms..atoms + source.len();
        let from = &packed[source.clone()];
        for c in 0..3 {
            for (x, xj) in sc.x[c][slots.clone()].iter_mut().zip(from) {
                *x = xj[c] + shift[c];
            }
        }
        for (q, xj) in sc.charge[slots.clone()].iter_mut().zip(from) {
            *q = xj[3];
        }
        sc.kind[slots.clone()].copy_from_slice(&molecules.types[source.clone()]);
        sc.atom[slots.clone()].copy_from_slice(&molecules.atoms[source]);
        sc.weight[slots.clone()].fill(sc.partner_s[p]);
        atoms = slots.end;
    }
    sc.partner_count = partners;
    sc.partner_start[partners] = atoms as u32;
    atoms
}

/// The listed partners `group` of a row molecule whose reference atom is at `xa` that lie
/// inside `r_out`, into `sc`: molecule, reference displacement (minimum image), `R`, `S`,
/// `S′`; returns their count. `reference(b)` is molecule `b`'s reference position.
#[inline(always)]
pub(super) fn keep_partners(
    model: &Model,
    switch: Switch,
    xa: [f64; 3],
    group: &[[u32; 2]],
    sc: &mut Scratch,
    reference: impl Fn(usize) -> [f64; 3],
) -> usize {
    let r_out2 = switch.r_out() * switch.r_out();
    // Two passes without data-dependent branches (about half the listed molecules lie
    // outside r_out, a coin toss for a branch predictor): every listed partner's image
    // displacement is written and the count moves on only for those inside r_out; then the
    // switch of the kept ones.
    let mut partners = 0;
    for &[_, b] in group {
        let xb = reference(b as usize);
        let d = model.image([xb[0] - xa[0], xb[1] - xa[1], xb[2] - xa[2]]);
        let big_r2 = dot(&d, &d);
        sc.partner[partners] = b;
        sc.partner_d[partners] = d;
        sc.partner_r[partners] = big_r2; // R², made R in the next pass
        partners += usize::from(big_r2 < r_out2);
    }
    for p in 0..partners {
        let big_r = sc.partner_r[p].sqrt();
        (sc.partner_s[p], sc.partner_s1[p]) = switch.value_slope(big_r);
        sc.partner_r[p] = big_r;
    }
    partners
}

/// The pairs of one row atom at `xi` (`[x, y, z, q√k_e]`) with the `n` gathered partner
/// atoms: energies and weighted force factors into `sc.energy`, `sc.force`, displacements
/// into `sc.d`. Branch-free passes (the cutoff is a 0/1 factor), so they vectorise.
#[inline(always)]
fn pair_block<const LJ: bool>(model: &Model, xi: [f64; 4], n: usize, sc: &mut Scratch) {
    let rc2 = model.cutoff_squared;
    // Every slice cut to `n`, so the loops carry no bounds checks and vectorise.
    let [dx, dy, dz] = &mut sc.d;
    let (dx, dy, dz) = (&mut dx[..n], &mut dy[..n], &mut dz[..n]);
    let (x, y, z) = (&sc.x[0][..n], &sc.x[1][..n], &sc.x[2][..n]);
    let (r2, inv_r, qq) = (&mut sc.r2[..n], &mut sc.inv_r[..n], &mut sc.qq[..n]);
    let charge = &sc.charge[..n];
    for t in 0..n {
        dx[t] = x[t] - xi[0];
        dy[t] = y[t] - xi[1];
        dz[t] = z[t] - xi[2];
        r2[t] = dx[t] * dx[t] + dy[t] * dy[t] + dz[t] * dz[t];
        inv_r[t] = 1.0 / r2[t].sqrt();
        qq[t] = xi[3] * charge[t];
    }
    let (e_q, f_q) = (&mut sc.coulomb_energy[..n], &mut sc.coulomb_force[..n]);
    model.coulomb.energy_force_block(qq, r2, inv_r, e_q, f_q);
    let (c12, c6, lj_shift) = (&sc.c12[..n], &sc.c6[..n], &sc.lj_shift[..n]);
    let (weight, energy, force) = (&sc.weight[..n], &mut sc.energy[..n], &mut sc.force[..n]);
    for t in 0..n {
        let inside = if r2[t] < rc2 { 1.0 } else { 0.0 };
        let (mut e, mut f) = (e_q[t], f_q[t]);
        if LJ {
            let (c12, c6, shift) = (c12[t], c6[t], lj_shift[t]);
            let (lj_e, lj_f) = LjPair { c12, c6, shift }.energy_force(inv_r[t] * inv_r[t]);
            e += lj_e;
            f += lj_f;
        }
        energy[t] = inside * e;
        force[t] = inside * weight[t] * f;
    }
}
