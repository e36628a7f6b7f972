//! The excluded pairs' Ewald correction `E_excl = −Σ Q_ij erf(αr)/r` (the reciprocal sum
//! holds every pair, excluded ones too; [`super`]), which stays with the mesh term.
//!
//! **Gradient in SIMD lanes.** Per pair `d = r_j − r_i` (minimum image) and `r² = d·d` are
//! formed one pair at a time; then, [`BATCH`] pairs at a time in the kernel's lanes
//! ([`crate::forces::simd`]), `r = √r²`, `erfc(αr)` and `e^{−α²r²}` from [`erfc_exp`] (its
//! error bound is in the cluster kernel's module doc), `erf = 1 − erfc` and, with
//! `V = −Q erf(αr)/r`, the coefficient `c = V′/r = Q (erf/r² − (2α/√π) e^{−α²r²}/r)/r`:
//! `∂V/∂r_j = c d`, so atom `j` gains `c d` and atom `i` loses it. Only IEEE square
//! root, add, multiply, divide and fused multiply-add in the lanes: the same bits on every
//! instruction set, and each pair's result is its own (at any thread count the additions
//! to the gradient are made in pair order on the calling thread).
//!
//! For `αr ≪ 1` both terms of `c` approach `(2α/√π)/r²` and cancel to `(4α³/3√π) r⁰`: the
//! relative error of `c` is about `1.6e-15 · 3/(2α²r²)` (~2e-14 for an O–H pair at
//! α = 0.35 Å⁻¹), far below the mesh's own 1e-5. The energy and the Hessian-vector
//! product take libm's `erf` and `exp`, as before.
//!
//! **Cost.** `O(N_excl)` per gradient: one erfc/exp per pair, in lanes.

use super::erf_over_r;
use crate::forces::minimum_image_baseline;
use crate::forces::scratch::{Scratch, parallel};
use crate::forces::simd::{Isa, Simd, erfc_exp, simd_dispatch};

/// Pairs per batch: one AVX-512 register of doubles, two of AVX2 or the portable path.
const BATCH: usize = 8;

/// The charged excluded pairs of a box and their correction.
pub(super) struct Exclusions {
    alpha: f64,
    lengths: [f64; 3],
    /// `(i, j, Q_ij)`, `i < j`, in the order of the term's sorted exclusion list, uncharged
    /// pairs left out.
    pairs: Vec<(u32, u32, f64)>,
    /// Per pair, its change in a parallel gradient or Hessian-vector product.
    scratch: Scratch<[f64; 3]>,
    isa: Isa,
}

impl Exclusions {
    /// The correction for the sorted `excluded` pairs with charges `charges` and
    /// `k_e = coulomb_constant`.
    pub(super) fn new(
        alpha: f64,
        lengths: [f64; 3],
        coulomb_constant: f64,
        charges: &[f64],
        excluded: &[(u32, u32)],
    ) -> Self {
        let pairs: Vec<(u32, u32, f64)> = excluded
            .iter()
            .map(|&(i, j)| {
                let qq = coulomb_constant * charges[i as usize] * charges[j as usize];
                (i, j, qq)
            })
            .filter(|&(_, _, qq)| qq != 0.0)
            .collect();
        Exclusions {
            alpha,
            lengths,
            scratch: Scratch::with_len(pairs.len()),
            pairs,
            isa: Isa::best(),
        }
    }

    /// Minimum-image `r_j − r_i` of pair `k`.
    fn difference(&self, q: &[f64], k: usize) -> [f64; 3] {
        let (i, j, _) = self.pairs[k];
        let (i, j) = (i as usize, j as usize);
        std::array::from_fn(|a| {
            let d = q[3 * j + a] - q[3 * i + a];
            let l = self.lengths[a];
            minimum_image_baseline(d, l)
        })
    }

    /// `E_excl = −Σ Q_ij erf(αr)/r`.
    pub(super) fn energy(&self, q: &[f64]) -> f64 {
        let mut energy = 0.0;
        for k in 0..self.pairs.len() {
            let d = self.difference(q, k);
            let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            energy -= self.pairs[k].2 * erf_over_r(self.alpha, r).0;
        }
        energy
    }

    /// `out += ∇E_excl`: batches of [`BATCH`] pairs in lanes (the module doc), for many
    /// pairs in parallel tasks whose changes are then added in pair order.
    pub(super) fn add_gradient(&self, q: &[f64], out: &mut [f64]) {
        let n = self.pairs.len();
        if parallel(n) {
            let compute = |first: usize, changes: &mut [[f64; 3]]| {
                for (b, batch) in changes.chunks_mut(BATCH).enumerate() {
                    self.gradient_batch(q, first + b * BATCH, batch);
                }
            };
            self.scratch
                .two_phase_chunks(n, compute, |k, change| self.apply(k, change, out));
        } else {
            let mut changes = [[0.0; 3]; BATCH];
            for first in (0..n).step_by(BATCH) {
                let batch = &mut changes[..BATCH.min(n - first)];
                self.gradient_batch(q, first, batch);
                for (b, change) in batch.iter().enumerate() {
                    self.apply(first + b, change, out);
                }
            }
        }
    }

    /// `out += ∇²E_excl v`, pair by pair with libm (for many pairs in two phases).
    pub(super) fn add_hessian_vector(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        let n = self.pairs.len();
        if parallel(n) {
            let compute = |k: usize| self.hessian_change(q, v, k);
            self.scratch
                .two_phase(n, compute, |k, change| self.apply(k, change, out));
        } else {
            for k in 0..n {
                self.apply(k, &self.hessian_change(q, v, k), out);
            }
        }
    }

    /// Pair `k`'s change to its atom `j` (minus it to `i`).
    fn apply(&self, k: usize, change: &[f64; 3], out: &mut [f64]) {
        let (i, j, _) = self.pairs[k];
        let (i, j) = (i as usize, j as usize);
        for a in 0..3 {
            out[3 * j + a] += change[a];
            out[3 * i + a] -= change[a];
        }
    }

    /// The gradient changes to atom `j` of pairs `first …` into `changes` (at most
    /// [`BATCH`]).
    fn gradient_batch(&self, q: &[f64], first: usize, changes: &mut [[f64; 3]]) {
        let mut d = [[0.0; 3]; BATCH];
        // Padding lanes: r² = 1 and Q = 0 (finite, and unused).
        let mut r2 = [1.0; BATCH];
        let mut qq = [0.0; BATCH];
        for b in 0..changes.len() {
            d[b] = self.difference(q, first + b);
            r2[b] = d[b][0] * d[b][0] + d[b][1] * d[b][1] + d[b][2] * d[b][2];
            qq[b] = self.pairs[first + b].2;
        }
        let mut c = [0.0; BATCH];
        coefficients_on(self.isa, self.alpha, &r2, &qq, &mut c);
        for (b, change) in changes.iter_mut().enumerate() {
            *change = std::array::from_fn(|a| c[b] * d[b][a]);
        }
    }

    /// Pair `k`'s Hessian-vector change to atom `j`: `(V′/r) Δv + ((V″ − V′/r)/r²)(d·Δv) d`.
    fn hessian_change(&self, q: &[f64], v: &[f64], k: usize) -> [f64; 3] {
        let (i, j, qq) = self.pairs[k];
        let (i, j) = (i as usize, j as usize);
        let d = self.difference(q, k);
        let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let (_, f1, f2) = erf_over_r(self.alpha, r);
        // V(r) = −Q f(r).
        let (v1, v2) = (-qq * f1, -qq * f2);
        let dv: [f64; 3] = std::array::from_fn(|a| v[3 * j + a] - v[3 * i + a]);
        let along = d[0] * dv[0] + d[1] * dv[1] + d[2] * dv[2];
        let (a1, b1) = (v1 / r, (v2 - v1 / r) / (r * r));
        std::array::from_fn(|a| a1 * dv[a] + b1 * along * d[a])
    }
}

simd_dispatch! {
    /// [`coefficients`] on the instruction set `isa`.
    fn coefficients_on[][](
        alpha: f64,
        r2: &[f64; BATCH],
        qq: &[f64; BATCH],
        out: &mut [f64; BATCH],
    ) = coefficients, lanes f64;
}

/// `out = V′(r)/r = Q (erf(αr)/r² − (2α/√π) e^{−α²r²}/r)/r` of each pair, from `r²` and
/// `Q`, in `S`'s lanes.
#[inline(always)]
fn coefficients<S: Simd<R = f64>>(
    s: S,
    alpha: f64,
    r2: &[f64; BATCH],
    qq: &[f64; BATCH],
    out: &mut [f64; BATCH],
) {
    let gauss_scale = s.splat(std::f64::consts::FRAC_2_SQRT_PI * alpha);
    let (one, alpha) = (s.splat(1.0), s.splat(alpha));
    let mut lanes = [0.0; 16];
    for start in (0..BATCH).step_by(S::WIDTH) {
        let mut load = |values: &[f64; BATCH]| {
            lanes[..S::WIDTH].copy_from_slice(&values[start..start + S::WIDTH]);
            s.load(&lanes)
        };
        let (r2, qq) = (load(r2), load(qq));
        let r = s.sqrt(r2);
        let (erfc, gauss) = erfc_exp(s, s.mul(alpha, r));
        let erf = s.sub(one, erfc);
        let slope = s.sub(s.div(erf, r2), s.div(s.mul(gauss_scale, gauss), r));
        s.store(s.div(s.mul(qq, slope), r), &mut lanes);
        out[start..start + S::WIDTH].copy_from_slice(&lanes[..S::WIDTH]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The lanes' coefficient against libm's `erf` and `exp` over the distances of excluded
    /// pairs (0.5–3 Å) at GROMACS's α, on every instruction set with the same bits.
    #[test]
    fn lanes_match_libm_and_every_instruction_set() {
        let alpha = 0.347;
        let r2: [f64; BATCH] = std::array::from_fn(|b| (0.5 + 0.35 * b as f64).powi(2));
        let qq: [f64; BATCH] = std::array::from_fn(|b| 332.0 * (0.1 + 0.2 * b as f64));
        let mut reference = None;
        for isa in Isa::available() {
            let mut c = [0.0; BATCH];
            coefficients_on(isa, alpha, &r2, &qq, &mut c);
            for b in 0..BATCH {
                let r = r2[b].sqrt();
                let (_, f1, _) = erf_over_r(alpha, r);
                let expected = -qq[b] * f1 / r;
                // erfc's relative error 3e-15 (its bound), amplified by the cancellation
                // 3/(2α²r²) (module doc), ≤ 25 at r = 0.5 Å: 1e-13 relative.
                let tolerance = 1e-13 * expected.abs();
                assert!(
                    (c[b] - expected).abs() <= tolerance,
                    "{isa:?} r = {r}: {} against {expected}",
                    c[b]
                );
            }
            match reference {
                None => reference = Some(c),
                Some(first) => assert_eq!(
                    first.map(f64::to_bits),
                    c.map(f64::to_bits),
                    "{isa:?} differs from the portable path"
                ),
            }
        }
    }
}
