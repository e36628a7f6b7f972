//! The symmetric KKT matrix of one molecule's projection, stored by rows in a skyline
//! (each row from its first non-zero column to the diagonal) and factored in place as
//! `L D Lᵀ` without pivoting.
//!
//! Why no pivoting is safe here: the unknowns are ordered atom by atom along a breadth-first
//! walk of the molecule, and each constraint row comes right after the last of its atoms.
//! Every leading block is then `[[K₁, G₁ᵀ], [G₁, 0]]` with `K₁` a principal block of `K`
//! and `G₁` whole rows of independent constraints (chosen so by the rank check), hence
//! non-singular whenever `K` is positive definite — always for `K = M`, and for
//! `K = M + H_μ` near the rest manifold. The number of negative pivots is the number of
//! negative eigenvalues (Sylvester's law of inertia): Newton uses it to tell a minimum
//! (exactly one per constraint) from a saddle. Fill-in stays inside the skyline, so a chain ordered along its backbone costs
//! O(n b²) for bandwidth b, and a water molecule is a dense 11×11 or 12×12 block.

/// A symmetric matrix in skyline storage and, after [`Skyline::factor`], its `L D Lᵀ`.
#[derive(Clone, Debug)]
pub struct Skyline {
    /// First stored column of each row.
    first: Vec<usize>,
    /// Offset of each row's first stored entry in `values`.
    start: Vec<usize>,
    /// Row i holds columns `first[i] ..= i`; after factoring, `L` below the diagonal and
    /// `D` on it.
    values: Vec<f64>,
    /// `1 / D` after factoring (a multiply instead of a divide per entry).
    inverse_pivots: Vec<f64>,
}

impl Skyline {
    /// An all-zero matrix whose row `i` may be non-zero from column `first[i]` on.
    pub fn new(first: Vec<usize>) -> Self {
        let mut start = Vec::with_capacity(first.len());
        let mut offset = 0;
        for (i, &f) in first.iter().enumerate() {
            assert!(f <= i, "skyline row {i} starts after its diagonal");
            start.push(offset);
            offset += i - f + 1;
        }
        Skyline {
            inverse_pivots: vec![0.0; first.len()],
            first,
            start,
            values: vec![0.0; offset],
        }
    }

    pub fn size(&self) -> usize {
        self.first.len()
    }

    /// Stored entries.
    #[cfg(test)]
    pub fn stored(&self) -> usize {
        self.values.len()
    }

    pub fn clear(&mut self) {
        self.values.fill(0.0);
    }

    /// `A[row][col] += value` and, by symmetry, `A[col][row]`; `col ≤ row`.
    #[inline]
    pub fn add(&mut self, row: usize, col: usize, value: f64) {
        debug_assert!(col <= row && col >= self.first[row]);
        self.values[self.start[row] + col - self.first[row]] += value;
    }

    /// Factor in place; returns the number of negative pivots (by Sylvester's law of
    /// inertia, the number of negative eigenvalues). On failure (a zero or non-finite
    /// pivot) returns its row.
    pub fn factor(&mut self) -> Result<usize, usize> {
        let mut negative = 0;
        for i in 0..self.size() {
            let (fi, si) = (self.first[i], self.start[i]);
            let (done, rest) = self.values.split_at_mut(si);
            let row = &mut rest[..=i - fi];
            // Row i holds W = L D while its entries are computed: W_ij = A_ij − Σ_k W_ik L_jk.
            for j in fi..i {
                let (fj, sj) = (self.first[j], self.start[j]);
                let from = fi.max(fj);
                let other = &done[sj + from - fj..sj + j - fj];
                let (head, tail) = row.split_at_mut(j - fi);
                let dot: f64 = head[from - fi..]
                    .iter()
                    .zip(other)
                    .map(|(w, l)| w * l)
                    .sum();
                tail[0] -= dot;
            }
            // L_ij = W_ij / D_j and D_i = A_ii − Σ_j W_ij L_ij.
            let (off_diagonal, diagonal) = row.split_at_mut(i - fi);
            let mut pivot = diagonal[0];
            for (w, inverse) in off_diagonal.iter_mut().zip(&self.inverse_pivots[fi..i]) {
                let l = *w * inverse;
                pivot -= *w * l;
                *w = l;
            }
            if pivot == 0.0 || !pivot.is_finite() {
                return Err(i);
            }
            negative += usize::from(pivot < 0.0);
            diagonal[0] = pivot;
            self.inverse_pivots[i] = 1.0 / pivot;
        }
        Ok(negative)
    }

    /// Solve `A x = b` in place with the factors.
    pub fn solve(&self, b: &mut [f64]) {
        let n = self.size();
        for i in 0..n {
            let (fi, si) = (self.first[i], self.start[i]);
            let row = &self.values[si..si + i - fi];
            let sum: f64 = row.iter().zip(&b[fi..i]).map(|(l, x)| l * x).sum();
            b[i] -= sum;
        }
        for (x, inverse) in b.iter_mut().zip(&self.inverse_pivots) {
            *x *= inverse;
        }
        for i in (0..n).rev() {
            let (fi, si) = (self.first[i], self.start[i]);
            let x = b[i];
            let row = &self.values[si..si + i - fi];
            for (bk, l) in b[fi..i].iter_mut().zip(row) {
                *bk -= l * x;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_saddle_point_system_like_a_dense_solver() {
        // [[K, gᵀ], [g, 0]] with K = diag(2, 3) + coupling, one constraint row last.
        let a = nalgebra::DMatrix::from_row_slice(
            3,
            3,
            &[2.0, -0.5, 1.0, -0.5, 3.0, -1.0, 1.0, -1.0, 0.0],
        );
        let mut skyline = Skyline::new(vec![0, 0, 0]);
        for i in 0..3 {
            for j in 0..=i {
                skyline.add(i, j, a[(i, j)]);
            }
        }
        // One constraint row: one negative eigenvalue.
        assert_eq!(skyline.factor(), Ok(1));
        let mut x = vec![1.0, -2.0, 0.5];
        let b = nalgebra::DVector::from_vec(x.clone());
        skyline.solve(&mut x);
        let dense = a.lu().solve(&b).unwrap();
        for i in 0..3 {
            assert!((x[i] - dense[i]).abs() < 1e-14, "{x:?} vs {dense}");
        }
    }

    #[test]
    fn banded_rows_keep_their_band() {
        // A tridiagonal SPD matrix: row i starts at column i − 1.
        let n: usize = 6;
        let first: Vec<usize> = (0..n).map(|i| i.saturating_sub(1)).collect();
        let mut skyline = Skyline::new(first);
        assert_eq!(skyline.stored(), 2 * n - 1);
        for i in 0..n {
            skyline.add(i, i, 4.0);
            if i > 0 {
                skyline.add(i, i - 1, -1.0);
            }
        }
        skyline.factor().unwrap();
        let mut x = vec![1.0; n];
        skyline.solve(&mut x);
        // Residual of the original tridiagonal system.
        for i in 0..n {
            let mut r = 4.0 * x[i] - 1.0;
            if i > 0 {
                r -= x[i - 1];
            }
            if i + 1 < n {
                r -= x[i + 1];
            }
            assert!(r.abs() < 1e-14);
        }
    }
}

#[cfg(test)]
mod random_tests {
    use super::*;

    #[test]
    fn random_envelopes_solve_like_a_dense_solver() {
        let mut seed = 12345u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..50 {
            let n: usize = 30;
            let first: Vec<usize> = (0..n)
                .map(|i| i.saturating_sub((next() * 8.0) as usize))
                .collect();
            let mut dense = nalgebra::DMatrix::zeros(n, n);
            let mut skyline = Skyline::new(first.clone());
            for i in 0..n {
                for j in first[i]..i {
                    let v = next() - 0.5;
                    dense[(i, j)] = v;
                    dense[(j, i)] = v;
                    skyline.add(i, j, v);
                }
                let d = 10.0 * (next() + 0.5) * if i % 3 == 2 { -1.0 } else { 1.0 };
                dense[(i, i)] = d;
                skyline.add(i, i, d);
            }
            skyline.factor().unwrap();
            let b: Vec<f64> = (0..n).map(|_| next()).collect();
            let mut x = b.clone();
            skyline.solve(&mut x);
            let reference = dense.lu().solve(&nalgebra::DVector::from_vec(b)).unwrap();
            for i in 0..n {
                assert!(
                    (x[i] - reference[i]).abs() < 1e-10,
                    "{i}: {} vs {}",
                    x[i],
                    reference[i]
                );
            }
        }
    }
}
