//! The short part's pair loops (formulas in the parent module's doc): by molecule, a
//! listed molecule pair inside `r_out` gets one switch value `S(R)` for all its atom pairs;
//! the pairs inside a molecule are each switched on their own distance (a split by atom
//! pair runs in the cluster-pair kernel instead). Gradients and Hessian-vector products go
//! into one chunk's buffer.

use super::{Model, ShortRange, Switch};

#[inline(always)]
fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `buffer[j] += h`, `buffer[i] −= h`.
#[inline(always)]
fn add_pair(buffer: &mut [f64], i: usize, j: usize, h: [f64; 3]) {
    for k in 0..3 {
        buffer[3 * j + k] += h[k];
        buffer[3 * i + k] -= h[k];
    }
}

#[inline(always)]
fn difference(v: &[f64], i: usize, j: usize) -> [f64; 3] {
    std::array::from_fn(|k| v[3 * j + k] - v[3 * i + k])
}

/// Molecule pairs: `Σ S(R) E_IJ`, and its gradient into `buffer` when `GRADIENT`.
#[inline(always)]
pub(super) fn molecule_pairs<const GRADIENT: bool>(
    short: &ShortRange,
    q: &[f64],
    pairs: &[[u32; 2]],
    buffer: &mut [f64],
) -> f64 {
    let model = &short.model;
    let r_out2 = short.switch.r_out() * short.switch.r_out();
    let mut energy = 0.0;
    for &[a, b] in pairs {
        let (a, b) = (a as usize, b as usize);
        let (ra, rb) = (
            short.molecules.reference[a] as usize,
            short.molecules.reference[b] as usize,
        );
        let d = model.displacement(q, ra, rb);
        let big_r2 = dot(&d, &d);
        if big_r2 >= r_out2 {
            continue;
        }
        let big_r = big_r2.sqrt();
        let (s, s1) = short.switch.value_slope(big_r);
        let mut pair_energy = 0.0;
        for &i in short.molecules.atoms(a) {
            for &j in short.molecules.atoms(b) {
                let (i, j) = (i as usize, j as usize);
                let dij = model.displacement(q, i, j);
                let r2 = dot(&dij, &dij);
                if r2 >= model.cutoff_squared {
                    continue;
                }
                let (v, f) = model.energy_force(i, j, r2);
                pair_energy += v;
                if GRADIENT {
                    // ∂V/∂x_j = V′ d/r = −f d, weighted by S.
                    let k = -s * f;
                    add_pair(buffer, i, j, dij.map(|x| k * x));
                }
            }
        }
        energy += s * pair_energy;
        if GRADIENT && s1 != 0.0 {
            let k = pair_energy * s1 / big_r;
            add_pair(buffer, ra, rb, d.map(|x| k * x));
        }
    }
    energy
}

/// Atom pairs, each switched on its own distance: `Σ S(r) V(r)`, and the gradient.
#[inline(always)]
pub(super) fn atom_pairs<const GRADIENT: bool>(
    short: &ShortRange,
    q: &[f64],
    pairs: &[[u32; 2]],
    buffer: &mut [f64],
) -> f64 {
    let model = &short.model;
    // r_out ≤ r_c: every pair inside r_out is inside the cutoff.
    let r_out2 = short.switch.r_out() * short.switch.r_out();
    let mut energy = 0.0;
    for &[i, j] in pairs {
        let (i, j) = (i as usize, j as usize);
        let d = model.displacement(q, i, j);
        let r2 = dot(&d, &d);
        if r2 >= r_out2 {
            continue;
        }
        let (v, f) = model.energy_force(i, j, r2);
        let r = r2.sqrt();
        let (s, s1) = short.switch.value_slope(r);
        energy += s * v;
        if GRADIENT {
            // W′/r = S′V/r + S V′/r = S′V/r − S f.
            let k = s1 * v / r - s * f;
            add_pair(buffer, i, j, d.map(|x| k * x));
        }
    }
    energy
}

/// `buffer += ∇²(Σ S(R) E_IJ) v` over molecule pairs (chain rule in the parent's doc).
#[inline(always)]
pub(super) fn molecule_pairs_hessian(
    short: &ShortRange,
    q: &[f64],
    v: &[f64],
    pairs: &[[u32; 2]],
    buffer: &mut [f64],
) {
    let model = &short.model;
    let r_out2 = short.switch.r_out() * short.switch.r_out();
    for &[a, b] in pairs {
        let (a, b) = (a as usize, b as usize);
        let (ra, rb) = (
            short.molecules.reference[a] as usize,
            short.molecules.reference[b] as usize,
        );
        let d = model.displacement(q, ra, rb);
        let big_r2 = dot(&d, &d);
        if big_r2 >= r_out2 {
            continue;
        }
        let big_r = big_r2.sqrt();
        let (s, s1, s2) = short.switch.derivatives(big_r);
        let n = d.map(|x| x / big_r);
        let dv_ref = difference(v, ra, rb);
        // ∇R·v
        let rv = dot(&n, &dv_ref);
        let mut pair_energy = 0.0;
        // ∇E·v
        let mut ev = 0.0;
        for &i in short.molecules.atoms(a) {
            for &j in short.molecules.atoms(b) {
                let (i, j) = (i as usize, j as usize);
                let dij = model.displacement(q, i, j);
                let r2 = dot(&dij, &dij);
                if r2 >= model.cutoff_squared {
                    continue;
                }
                let r = r2.sqrt();
                let (e, d1, d2) = model.derivatives(i, j, r);
                pair_energy += e;
                let dv = difference(v, i, j);
                let alpha = d1 / r;
                let along = (d2 - alpha) / r2 * dot(&dij, &dv);
                ev += alpha * dot(&dij, &dv);
                // S ∇²E v + S′(∇R·v)∇E, pair by pair (∇_j V = α d).
                let kick = s1 * rv * alpha;
                let h: [f64; 3] =
                    std::array::from_fn(|k| s * (alpha * dv[k] + along * dij[k]) + kick * dij[k]);
                add_pair(buffer, i, j, h);
            }
        }
        if s1 != 0.0 || s2 != 0.0 {
            // S′(∇E·v)∇R + E S″(∇R·v)∇R + E S′∇²R v on the reference atoms.
            let c = s1 * ev + pair_energy * s2 * rv;
            let t = pair_energy * s1 / big_r;
            let h: [f64; 3] = std::array::from_fn(|k| c * n[k] + t * (dv_ref[k] - n[k] * rv));
            add_pair(buffer, ra, rb, h);
        }
    }
}

/// `buffer += ∇²(Σ S(r) V(r)) v` over atom pairs: the radial Hessian of `W = S V`.
#[inline(always)]
pub(super) fn atom_pairs_hessian(
    short: &ShortRange,
    q: &[f64],
    v: &[f64],
    pairs: &[[u32; 2]],
    buffer: &mut [f64],
) {
    let model = &short.model;
    let r_out2 = short.switch.r_out() * short.switch.r_out();
    for &[i, j] in pairs {
        let (i, j) = (i as usize, j as usize);
        let d = model.displacement(q, i, j);
        let r2 = dot(&d, &d);
        if r2 >= r_out2 {
            continue;
        }
        let r = r2.sqrt();
        let (e, d1, d2) = model.derivatives(i, j, r);
        let (s, s1, s2) = short.switch.derivatives(r);
        let w1 = s1 * e + s * d1;
        let w2 = s2 * e + 2.0 * s1 * d1 + s * d2;
        let alpha = w1 / r;
        let dv = difference(v, i, j);
        let along = (w2 - alpha) / r2 * dot(&d, &dv);
        let h: [f64; 3] = std::array::from_fn(|k| alpha * dv[k] + along * d[k]);
        add_pair(buffer, i, j, h);
    }
}

/// The short part's energy as (Lennard-Jones, Coulomb), for reports: `pairs` switched `by`
/// molecule (a molecule-pair list) or not (an atom-pair list).
pub(super) fn energy_parts(
    short: &ShortRange,
    q: &[f64],
    pairs: &[[u32; 2]],
    by_molecule: bool,
) -> [f64; 2] {
    let model = &short.model;
    let r_out2 = short.switch.r_out() * short.switch.r_out();
    let mut parts = [0.0; 2];
    let mut add = |i: usize, j: usize, weight: Option<f64>| {
        let d = model.displacement(q, i, j);
        let r2 = dot(&d, &d);
        let limit = if weight.is_some() {
            model.cutoff_squared
        } else {
            r_out2
        };
        if r2 < limit {
            let s = weight.unwrap_or_else(|| short.switch.value_slope(r2.sqrt()).0);
            let (lj, coulomb) = model.energy_parts(i, j, r2);
            parts[0] += s * lj;
            parts[1] += s * coulomb;
        }
    };
    for &[a, b] in pairs {
        let (a, b) = (a as usize, b as usize);
        if !by_molecule {
            add(a, b, None);
            continue;
        }
        let (ra, rb) = (
            short.molecules.reference[a] as usize,
            short.molecules.reference[b] as usize,
        );
        let d = model.displacement(q, ra, rb);
        let big_r2 = dot(&d, &d);
        if big_r2 >= r_out2 {
            continue;
        }
        let s = short.switch.value_slope(big_r2.sqrt()).0;
        for &i in short.molecules.atoms(a) {
            for &j in short.molecules.atoms(b) {
                add(i as usize, j as usize, Some(s));
            }
        }
    }
    parts
}

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
            for v in [
                &mut self.partner_r,
                &mut self.partner_s,
                &mut self.partner_s1,
            ] {
                v.resize(n, 0.0);
            }
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
    scratch: &mut Scratch,
    buffer: &mut [f64],
) -> f64 {
    match short.molecules.uniform_size {
        3 => rows_of::<GRADIENT, 3>(short, packed, pairs, scratch, buffer),
        4 => rows_of::<GRADIENT, 4>(short, packed, pairs, scratch, buffer),
        _ => rows_of::<GRADIENT, 0>(short, packed, pairs, scratch, buffer),
    }
}

/// [`whole_molecule_rows`] for molecules of `M` atoms each (`M = 0`: any sizes).
#[inline(always)]
fn rows_of<const GRADIENT: bool, const M: usize>(
    short: &ShortRange,
    packed: &[[f64; 4]],
    pairs: &[[u32; 2]],
    scratch: &mut Scratch,
    buffer: &mut [f64],
) -> f64 {
    let mut energy = 0.0;
    for (a, group) in list_rows(pairs) {
        energy += whole_molecule_row::<GRADIENT, M>(short, packed, a, group, scratch, buffer);
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
    let reference_a = molecules.reference[a] as usize;
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
        if GRADIENT && sc.partner_s1[p] != 0.0 {
            let k = pair_energy * sc.partner_s1[p] / sc.partner_r[p];
            let reference_b = molecules.reference[sc.partner[p] as usize] as usize;
            add_pair(
                buffer,
                reference_a,
                reference_b,
                sc.partner_d[p].map(|x| k * x),
            );
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
    model.coulomb_block(qq, r2, inv_r, e_q, f_q);
    let (c12, c6, lj_shift) = (&sc.c12[..n], &sc.c6[..n], &sc.lj_shift[..n]);
    let (weight, energy, force) = (&sc.weight[..n], &mut sc.energy[..n], &mut sc.force[..n]);
    for t in 0..n {
        let inside = if r2[t] < rc2 { 1.0 } else { 0.0 };
        let (mut e, mut f) = (e_q[t], f_q[t]);
        if LJ {
            let inv_r2 = inv_r[t] * inv_r[t];
            let inv_r6 = inv_r2 * inv_r2 * inv_r2;
            e += inv_r6 * (c12[t] * inv_r6 - c6[t]) - lj_shift[t];
            f += inv_r2 * inv_r6 * (12.0 * c12[t] * inv_r6 - 6.0 * c6[t]);
        }
        energy[t] = inside * e;
        force[t] = inside * weight[t] * f;
    }
}
