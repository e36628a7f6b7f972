//! The short part's pair loops (formulas in the parent module's doc): by molecule, a
//! listed molecule pair inside `r_out` gets one switch value `S(R)` for all its atom pairs;
//! by atom pair, each pair is switched on its own distance. Gradients and Hessian-vector
//! products go into one chunk's buffer.

use super::ShortRange;

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

/// Molecule pairs over whole molecules (`packed`: `[x, y, z, q√k_e]` in molecule order,
/// each atom at the image nearest its reference): one image shift per molecule pair, the
/// forces on the first molecule's atoms summed locally.
#[inline(always)]
pub(super) fn whole_molecule_pairs<const GRADIENT: bool>(
    short: &ShortRange,
    packed: &[[f64; 4]],
    pairs: &[[u32; 2]],
    buffer: &mut [f64],
) -> f64 {
    let model = &short.model;
    let molecules = &short.molecules;
    let r_out2 = short.switch.r_out() * short.switch.r_out();
    let rc2 = model.cutoff_squared;
    let mut energy = 0.0;
    for &[a, b] in pairs {
        let (a, b) = (a as usize, b as usize);
        let (ka, kb) = (
            molecules.reference_slot[a] as usize,
            molecules.reference_slot[b] as usize,
        );
        let raw: [f64; 3] = std::array::from_fn(|k| packed[kb][k] - packed[ka][k]);
        let d = model.image(raw);
        let big_r2 = dot(&d, &d);
        if big_r2 >= r_out2 {
            continue;
        }
        let shift: [f64; 3] = std::array::from_fn(|k| d[k] - raw[k]);
        let big_r = big_r2.sqrt();
        let (s, s1) = short.switch.value_slope(big_r);
        let atoms_b = molecules.start[b] as usize..molecules.start[b + 1] as usize;
        let mut pair_energy = 0.0;
        for k in molecules.start[a] as usize..molecules.start[a + 1] as usize {
            let xi = packed[k];
            let type_i = molecules.types[k];
            let mut gi = [0.0; 3];
            for l in atoms_b.clone() {
                let xj = packed[l];
                let dij: [f64; 3] = std::array::from_fn(|c| (xj[c] + shift[c]) - xi[c]);
                let r2 = dot(&dij, &dij);
                if r2 >= rc2 {
                    continue;
                }
                let p = model.lj_types(type_i, molecules.types[l]);
                let (v, f) = model.typed_energy_force(p, xi[3] * xj[3], r2);
                pair_energy += v;
                if GRADIENT {
                    // ∂V/∂x_j = V′ d/r = −f d, weighted by S.
                    let g = dij.map(|x| -s * f * x);
                    let j = molecules.atoms[l] as usize;
                    for c in 0..3 {
                        buffer[3 * j + c] += g[c];
                        gi[c] -= g[c];
                    }
                }
            }
            if GRADIENT {
                let i = molecules.atoms[k] as usize;
                for c in 0..3 {
                    buffer[3 * i + c] += gi[c];
                }
            }
        }
        energy += s * pair_energy;
        if GRADIENT && s1 != 0.0 {
            let k = pair_energy * s1 / big_r;
            let (ra, rb) = (
                molecules.reference[a] as usize,
                molecules.reference[b] as usize,
            );
            add_pair(buffer, ra, rb, d.map(|x| k * x));
        }
    }
    energy
}
