//! A non-diagonal (banded) mass matrix, for scenes that ask for one — the consistent P1
//! finite-element mass matrix of the nonlinear string, MEMM18 3.3.
//!
//! The matrix couples particles, the same on every axis: `M = M_p ⊗ I_dim` with `M_p`
//! symmetric positive definite over particles, banded (`M_p[i][j] = 0` for
//! `|i − j| > bandwidth`). Its diagonal is the particles' masses; the scene lists the
//! off-diagonal entries. It is factorised once (banded Cholesky `M_p = L Lᵀ`), so
//!
//! * [`MassMatrix::solve`] (`M⁻¹ p`, the velocity of a free flight) costs
//!   `O(n_dofs · bandwidth)` and allocates nothing;
//! * [`MassMatrix::inverse_quadratic_form`] (`pᵀ M⁻¹ p`, twice the kinetic energy) streams
//!   the forward substitution through a fixed ring buffer, so the run loop's per-step
//!   kinetic-energy check allocates nothing either. That is why the bandwidth is capped at
//!   [`MAX_BANDWIDTH`]: order the particles along the mesh to stay inside it.
//!
//! Only methods that solve with `M` (the pseudo-energy schemes) accept a system with a
//! mass matrix; the others refuse it (see `Integrator::supports_mass_matrix`), and a scene
//! can lump it onto the diagonal instead.

use crate::error::{Error, Result};

/// Largest particle-index distance a mass-matrix entry may span.
pub const MAX_BANDWIDTH: usize = 8;

#[derive(Clone, Debug)]
pub struct MassMatrix {
    n: usize,
    dim: usize,
    bandwidth: usize,
    /// `M_p` by rows of its lower band: `entries[i * (b + 1) + k] = M_p[i][i − k]`.
    entries: Vec<f64>,
    /// The Cholesky factor `L` in the same layout.
    factor: Vec<f64>,
}

impl MassMatrix {
    /// The matrix with `diagonal` (the particles' masses) and the symmetric off-diagonal
    /// entries `(i, j, value)`, `i ≠ j`, on every one of `dim` axes. Fails when an entry
    /// spans more than [`MAX_BANDWIDTH`] particles or the matrix is not positive definite.
    pub fn new(dim: usize, diagonal: &[f64], off_diagonal: &[(usize, usize, f64)]) -> Result<Self> {
        let n = diagonal.len();
        let mut bandwidth = 0;
        for &(i, j, _) in off_diagonal {
            if i == j || i >= n || j >= n {
                return Err(Error::input(format!(
                    "mass matrix entry ({i}, {j}) is not an off-diagonal entry of a {n}-particle system"
                )));
            }
            bandwidth = bandwidth.max(i.abs_diff(j));
        }
        if bandwidth > MAX_BANDWIDTH {
            return Err(Error::input(format!(
                "mass matrix couples particles {bandwidth} indices apart; at most \
                 {MAX_BANDWIDTH} are supported (number the particles along the mesh)"
            )));
        }
        let width = bandwidth + 1;
        let mut entries = vec![0.0; n * width];
        for (i, &m) in diagonal.iter().enumerate() {
            entries[i * width] = m;
        }
        for &(i, j, value) in off_diagonal {
            let (row, col) = (i.max(j), i.min(j));
            entries[row * width + (row - col)] += value;
        }
        // Banded Cholesky: L[i][j] = (M[i][j] − Σ_{k<j} L[i][k] L[j][k]) / L[j][j].
        let mut factor = vec![0.0; n * width];
        for i in 0..n {
            for j in i.saturating_sub(bandwidth)..=i {
                let mut sum = entries[i * width + (i - j)];
                for k in i.saturating_sub(bandwidth)..j {
                    sum -= factor[i * width + (i - k)] * factor[j * width + (j - k)];
                }
                if i == j {
                    if !(sum > 0.0 && sum.is_finite()) {
                        return Err(Error::input(format!(
                            "the mass matrix is not positive definite (pivot {sum} at particle {i})"
                        )));
                    }
                    factor[i * width] = sum.sqrt();
                } else {
                    factor[i * width + (i - j)] = sum / factor[j * width];
                }
            }
        }
        Ok(MassMatrix {
            n,
            dim,
            bandwidth,
            entries,
            factor,
        })
    }

    pub fn bandwidth(&self) -> usize {
        self.bandwidth
    }

    /// `M_p[i][j]` (zero outside the band).
    pub fn entry(&self, i: usize, j: usize) -> f64 {
        let (row, col) = (i.max(j), i.min(j));
        if row - col > self.bandwidth {
            0.0
        } else {
            self.entries[row * (self.bandwidth + 1) + (row - col)]
        }
    }

    /// The lumped diagonal: each row's sum (what `lump = true` puts on the diagonal).
    pub fn row_sums(&self) -> Vec<f64> {
        (0..self.n)
            .map(|i| {
                let lo = i.saturating_sub(self.bandwidth);
                let hi = (i + self.bandwidth).min(self.n - 1);
                (lo..=hi).map(|j| self.entry(i, j)).sum()
            })
            .collect()
    }

    /// `out = M x` over all coordinates.
    pub fn apply(&self, x: &[f64], out: &mut [f64]) {
        let (n, d, b) = (self.n, self.dim, self.bandwidth);
        for i in 0..n {
            let lo = i.saturating_sub(b);
            let hi = (i + b).min(n - 1);
            for a in 0..d {
                let mut sum = 0.0;
                for j in lo..=hi {
                    sum += self.entry(i, j) * x[j * d + a];
                }
                out[i * d + a] = sum;
            }
        }
    }

    /// `out = M⁻¹ b` over all coordinates (forward then back substitution with `L`).
    pub fn solve(&self, b: &[f64], out: &mut [f64]) {
        let (n, d, w) = (self.n, self.dim, self.bandwidth + 1);
        let l = &self.factor;
        for a in 0..d {
            for i in 0..n {
                let mut sum = b[i * d + a];
                for k in i.saturating_sub(self.bandwidth)..i {
                    sum -= l[i * w + (i - k)] * out[k * d + a];
                }
                out[i * d + a] = sum / l[i * w];
            }
            for i in (0..n).rev() {
                let mut sum = out[i * d + a];
                for k in (i + 1)..(i + w).min(n) {
                    sum -= l[k * w + (k - i)] * out[k * d + a];
                }
                out[i * d + a] = sum / l[i * w];
            }
        }
    }

    /// `pᵀ M⁻¹ p = |L⁻¹ p|²`, without allocating: the forward substitution only needs the
    /// last `bandwidth` values, kept in a ring buffer.
    pub fn inverse_quadratic_form(&self, p: &[f64]) -> f64 {
        let (n, d, b, w) = (self.n, self.dim, self.bandwidth, self.bandwidth + 1);
        let l = &self.factor;
        let mut total = 0.0;
        let mut ring = [0.0; MAX_BANDWIDTH + 1];
        for a in 0..d {
            for i in 0..n {
                let mut sum = p[i * d + a];
                for k in i.saturating_sub(b)..i {
                    sum -= l[i * w + (i - k)] * ring[k % w];
                }
                let y = sum / l[i * w];
                ring[i % w] = y;
                total += y * y;
            }
        }
        total
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The P1 mass matrix of a string: Δx·tridiag(1/6, 2/3, 1/6), two axes.
    fn p1(n: usize, dx: f64) -> MassMatrix {
        let diagonal = vec![2.0 * dx / 3.0; n];
        let off: Vec<_> = (0..n - 1).map(|i| (i, i + 1, dx / 6.0)).collect();
        MassMatrix::new(2, &diagonal, &off).unwrap()
    }

    #[test]
    fn solve_inverts_apply_and_the_quadratic_form_matches() {
        let m = p1(9, 0.1);
        let x: Vec<f64> = (0..18).map(|k| ((k * 7 % 11) as f64 - 5.0) / 3.0).collect();
        let mut b = vec![0.0; 18];
        m.apply(&x, &mut b);
        let mut back = vec![0.0; 18];
        m.solve(&b, &mut back);
        // M has condition number ≤ 3 (eigenvalues in [Δx/3, Δx]): round-off is a few ulps.
        for (xi, yi) in x.iter().zip(&back) {
            assert!((xi - yi).abs() < 1e-14, "{xi} vs {yi}");
        }
        let direct: f64 = b.iter().zip(&x).map(|(bi, xi)| bi * xi).sum();
        let streamed = m.inverse_quadratic_form(&b);
        assert!((direct - streamed).abs() < 1e-13 * direct.abs());
    }

    #[test]
    fn wide_or_indefinite_matrices_are_refused() {
        let diagonal = vec![1.0; 20];
        let wide = MassMatrix::new(1, &diagonal, &[(0, 12, 0.1)]).unwrap_err();
        assert!(wide.to_string().contains("12 indices apart"));
        let indefinite = MassMatrix::new(1, &[1.0, 1.0], &[(0, 1, 2.0)]).unwrap_err();
        assert!(indefinite.to_string().contains("not positive definite"));
    }

    #[test]
    fn row_sums_lump_the_matrix() {
        let sums = p1(4, 0.3).row_sums();
        assert!((sums[0] - 0.3 * (2.0 / 3.0 + 1.0 / 6.0)).abs() < 1e-15);
        assert!((sums[1] - 0.3).abs() < 1e-15);
    }
}
