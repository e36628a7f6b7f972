//! The structural equations' coefficients (CFM25 sections 2.1–2.2): the kernel of the
//! polynomial-exactness matrix.
//!
//! A structural equation of block size `R` with derivative order `S` (1 for ZD, 2 for
//! ZDS) is `Σ_{r=0}^{R} Σ_{s=0}^{S} a_{r,s} Δt^s Z^{(s)}_{n+r} = 0`; CFM25 asks it to be
//! exact for every polynomial of degree below `K`, with `K = R + 2` (ZD, CFM25 (4)) or
//! `K = 2R + 3` (ZDS, CFM25 (6)). The `K` exactness conditions on the `(S+1)(R+1)`
//! coefficients leave a kernel of dimension `R`: the `R` structural equations. ZDS has no
//! `a_{r,0}` beyond `Z`, `D`, `S`; only the `Z`-coefficients at `r ≥ 1` are eliminated.
//!
//! **Basis of the kernel.** CFM25 picks an orthogonal basis; any basis gives the same
//! scheme, because the block form (9) `bZ + B_d bD + B_s bS + b_z Z_n + b_d D_n +
//! b_s S_n = 0` uses `B = A_z⁻¹A`, and a change of basis multiplies every `A` on the left
//! by the same invertible matrix. So the basis here is the one with `A_z = I`: equation
//! `m` has `a_{m,0} = 1` and `a_{r,0} = 0` for the other `r ≥ 1`, and its remaining
//! `K` unknowns (`a_{0,0}` and the derivative coefficients) solve a square `K × K`
//! system. This gives `B_d`, `B_s`, `b_z`, `b_d`, `b_s` directly.
//!
//! **Conditioning.** With monomial rows `t^k` at the nodes `t = 0, 1, …, R` (CFM25's
//! matrix `M`) the system is a confluent Vandermonde matrix whose condition number grows
//! fast: about 5e3 (ZD, R = 4), 6e9 (ZD, R = 8), 3e8 (ZDS, R = 4), 3e14 (ZDS, R = 6). In
//! f64 that costs about as many digits (relative error against the double-double result:
//! 5e-10 for ZDS R = 4, 3e-8 for ZD R = 8, `tests/structural.rs`; 8e-4 for ZDS R = 6
//! against exact fractions), more than the schemes' errors at the finest steps of
//! CFM25's tables. Two remedies, both used:
//! the rows are Chebyshev polynomials `T_k(2t/R − 1)` instead (they span the same
//! polynomials, so the kernel is the same; condition numbers fall to 1e2 (ZD R = 8) and
//! 2e3 (ZDS R = 4)), and the elimination runs in double-double arithmetic (~32 digits),
//! so the coefficients come out correctly rounded to f64 for every block size allowed
//! (`R ≤ MAX_BLOCK`). The tests check them against the exact Lagrange/Hermite integrals
//! and measure the f64-monomial loss.

use super::double_double::DoubleDouble;
use crate::error::{Error, Result};

/// The largest block size accepted. The double-double solve stays exact far beyond it;
/// the limit is practical: `‖B_d‖` grows with `R` (the fixed point needs `h·‖B‖·L < 1`),
/// and CFM25 stops at R = 8 (ZD) and R = 4 (ZDS).
pub const MAX_BLOCK: usize = 16;

/// Rows of the exactness matrix: monomials `t^k` as in CFM25, or Chebyshev polynomials
/// `T_k(2t/R − 1)` (same kernel, far better conditioned).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RowBasis {
    Monomial,
    Chebyshev,
}

/// Arithmetic of the elimination.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Precision {
    Double,
    DoubleDouble,
}

/// The structural equations in block form (CFM25 (9), (14)–(17), (18)–(21)) for a unit
/// step: `Z_{n+m} + Σ_r (B_d[m][r] Δt D_{n+r} + B_s[m][r] Δt² S_{n+r}) + b_z[m] Z_n +
/// b_d[m] Δt D_n + b_s[m] Δt² S_n = 0` for `m = 1..R` (rows and columns 0-based).
#[derive(Clone, Debug, PartialEq)]
pub struct StructuralCoefficients {
    pub block: usize,
    /// 1 (ZD) or 2 (ZDS).
    pub derivatives: usize,
    /// `B_d`, `R × R` row-major.
    pub matrix_d: Vec<f64>,
    /// `B_s`, `R × R` row-major; empty for ZD.
    pub matrix_s: Vec<f64>,
    /// `b_z` (always −1: the equations are consistent).
    pub start_z: Vec<f64>,
    /// `b_d`.
    pub start_d: Vec<f64>,
    /// `b_s`; empty for ZD.
    pub start_s: Vec<f64>,
}

/// What the elimination needs of a number type.
trait Real:
    Copy
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
    + std::ops::Div<Output = Self>
{
    fn from_f64(x: f64) -> Self;
    fn to_f64(self) -> f64;
    fn magnitude(self) -> f64;
}

impl Real for f64 {
    fn from_f64(x: f64) -> Self {
        x
    }
    fn to_f64(self) -> f64 {
        self
    }
    fn magnitude(self) -> f64 {
        self.abs()
    }
}

impl Real for DoubleDouble {
    fn from_f64(x: f64) -> Self {
        DoubleDouble::from_f64(x)
    }
    fn to_f64(self) -> f64 {
        DoubleDouble::to_f64(self)
    }
    fn magnitude(self) -> f64 {
        DoubleDouble::magnitude(self)
    }
}

/// `d^s/dt^s` of row polynomial `k` at node `t = r` (unit step), for `s ≤ 2`.
fn row_value<T: Real>(basis: RowBasis, block: usize, k: usize, s: usize, r: usize) -> T {
    match basis {
        RowBasis::Monomial => {
            if k < s {
                return T::from_f64(0.0);
            }
            let falling = (0..s).map(|j| (k - j) as f64).product::<f64>();
            // r^(k−s) exactly: integers below 2^53 for every block size allowed … except
            // the largest powers, which the product of doubles keeps to a few ulps.
            let mut power = T::from_f64(falling);
            let base = T::from_f64(r as f64);
            for _ in 0..(k - s) {
                power = power * base;
            }
            power
        }
        RowBasis::Chebyshev => {
            // τ = 2t/R − 1; T_{k+1} = 2τT_k − T_{k−1}, differentiated in τ term by term;
            // d/dt = (2/R) d/dτ.
            let scale = T::from_f64(2.0) / T::from_f64(block as f64);
            let tau = scale * T::from_f64(r as f64) - T::from_f64(1.0);
            let two = T::from_f64(2.0);
            let zero = T::from_f64(0.0);
            // (value, first, second derivative in τ) of T_{j−1} and T_j.
            let mut previous = [T::from_f64(1.0), zero, zero];
            let mut current = [tau, T::from_f64(1.0), zero];
            let pick = |v: [T; 3]| v[s];
            let in_tau = if k == 0 {
                pick(previous)
            } else {
                for _ in 1..k {
                    let next = [
                        two * tau * current[0] - previous[0],
                        two * current[0] + two * tau * current[1] - previous[1],
                        two * two * current[1] + two * tau * current[2] - previous[2],
                    ];
                    previous = current;
                    current = next;
                }
                pick(current)
            };
            let mut factor = T::from_f64(1.0);
            for _ in 0..s {
                factor = factor * scale;
            }
            in_tau * factor
        }
    }
}

/// Solve `A X = B` (`A` `n × n`, `B` `n × m`, both row-major) by Gaussian elimination
/// with partial pivoting; `None` when a pivot vanishes.
fn solve<T: Real>(mut a: Vec<T>, mut b: Vec<T>, n: usize, m: usize) -> Option<Vec<T>> {
    for col in 0..n {
        let pivot = (col..n).max_by(|&i, &j| {
            a[i * n + col]
                .magnitude()
                .total_cmp(&a[j * n + col].magnitude())
        })?;
        if a[pivot * n + col].magnitude() == 0.0 {
            return None;
        }
        if pivot != col {
            for k in 0..n {
                a.swap(col * n + k, pivot * n + k);
            }
            for k in 0..m {
                b.swap(col * m + k, pivot * m + k);
            }
        }
        let diagonal = a[col * n + col];
        for row in col + 1..n {
            let factor = a[row * n + col] / diagonal;
            for k in col..n {
                a[row * n + k] = a[row * n + k] - factor * a[col * n + k];
            }
            for k in 0..m {
                b[row * m + k] = b[row * m + k] - factor * b[col * m + k];
            }
        }
    }
    for col in (0..n).rev() {
        for k in 0..m {
            let mut sum = b[col * m + k];
            for j in col + 1..n {
                sum = sum - a[col * n + j] * b[j * m + k];
            }
            b[col * m + k] = sum / a[col * n + col];
        }
    }
    Some(b)
}

impl StructuralCoefficients {
    /// The coefficients of ZD (`derivatives = 1`) or ZDS (`derivatives = 2`) with block
    /// size `block`, computed as longstep does: Chebyshev rows, double-double.
    pub fn new(block: usize, derivatives: usize) -> Result<Self> {
        Self::computed(
            block,
            derivatives,
            RowBasis::Chebyshev,
            Precision::DoubleDouble,
        )
    }

    /// The same with a chosen row basis and arithmetic (to measure the conditioning).
    pub fn computed(
        block: usize,
        derivatives: usize,
        basis: RowBasis,
        precision: Precision,
    ) -> Result<Self> {
        if !(1..=MAX_BLOCK).contains(&block) {
            return Err(Error::setting(
                "block",
                format!("block size R must be between 1 and {MAX_BLOCK}"),
            )
            .expected(format!("1 to {MAX_BLOCK}"))
            .got(block.to_string()));
        }
        if !(1..=2).contains(&derivatives) {
            return Err(Error::input(format!(
                "structural schemes use first (ZD) or second (ZDS) derivatives, not {derivatives}"
            ))
            .expected("1 or 2 derivatives"));
        }
        match precision {
            Precision::Double => Self::compute::<f64>(block, derivatives, basis),
            Precision::DoubleDouble => Self::compute::<DoubleDouble>(block, derivatives, basis),
        }
    }

    fn compute<T: Real>(block: usize, derivatives: usize, basis: RowBasis) -> Result<Self> {
        let size = 1 + derivatives * (block + 1);
        // Unknown columns: a_{0,0}, then a_{r,s} for s = 1..S, r = 0..R.
        let columns: Vec<(usize, usize)> = std::iter::once((0, 0))
            .chain((1..=derivatives).flat_map(|s| (0..=block).map(move |r| (s, r))))
            .collect();
        let mut matrix = Vec::with_capacity(size * size);
        for k in 0..size {
            for &(s, r) in &columns {
                matrix.push(row_value::<T>(basis, block, k, s, r));
            }
        }
        // Right-hand sides: equation m has a_{m,0} = 1 moved to the right.
        let mut rhs = vec![T::from_f64(0.0); size * block];
        for k in 0..size {
            for m in 1..=block {
                rhs[k * block + (m - 1)] = T::from_f64(0.0) - row_value::<T>(basis, block, k, 0, m);
            }
        }
        let solution = solve(matrix, rhs, size, block).ok_or_else(|| {
            Error::input(format!(
                "the structural exactness system for R = {block} is singular"
            ))
        })?;
        let at = |column: usize, m: usize| solution[column * block + m].to_f64();
        let column_of = |s: usize, r: usize| 1 + (s - 1) * (block + 1) + r;
        let matrix_of = |s: usize| -> Vec<f64> {
            (0..block)
                .flat_map(|m| (1..=block).map(move |r| (m, r)))
                .map(|(m, r)| at(column_of(s, r), m))
                .collect()
        };
        let start_of =
            |s: usize| -> Vec<f64> { (0..block).map(|m| at(column_of(s, 0), m)).collect() };
        Ok(StructuralCoefficients {
            block,
            derivatives,
            matrix_d: matrix_of(1),
            matrix_s: if derivatives == 2 {
                matrix_of(2)
            } else {
                Vec::new()
            },
            start_z: (0..block).map(|m| at(0, m)).collect(),
            start_d: start_of(1),
            start_s: if derivatives == 2 {
                start_of(2)
            } else {
                Vec::new()
            },
        })
    }

    /// The largest residual of the block equations on the monomials `t^k`, `k < K`, at the
    /// nodes `0..R`, each relative to the sum of the magnitudes of its terms, evaluated in
    /// double-double: how exactly these (f64) coefficients reproduce polynomials.
    pub fn exactness_residual(&self) -> f64 {
        let block = self.block;
        let size = 1 + self.derivatives * (block + 1);
        let value = |k: usize, s: usize, r: usize| -> DoubleDouble {
            row_value::<DoubleDouble>(RowBasis::Monomial, block, k, s, r)
        };
        let dd = DoubleDouble::from_f64;
        let mut worst = 0.0f64;
        for k in 0..size {
            for m in 0..block {
                let mut terms = vec![value(k, 0, m + 1), dd(self.start_z[m]) * value(k, 0, 0)];
                terms.push(dd(self.start_d[m]) * value(k, 1, 0));
                for r in 1..=block {
                    terms.push(dd(self.matrix_d[m * block + r - 1]) * value(k, 1, r));
                }
                if self.derivatives == 2 {
                    terms.push(dd(self.start_s[m]) * value(k, 2, 0));
                    for r in 1..=block {
                        terms.push(dd(self.matrix_s[m * block + r - 1]) * value(k, 2, r));
                    }
                }
                let sum = terms
                    .iter()
                    .fold(DoubleDouble::ZERO, |acc, &t| acc + t)
                    .abs()
                    .to_f64();
                let scale: f64 = terms.iter().map(|t| t.abs().to_f64()).sum();
                if scale > 0.0 {
                    worst = worst.max(sum / scale);
                }
            }
        }
        worst
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// R = 1: ZD is the trapezoidal rule `Z₁ − Z₀ − (Δt/2)(D₀ + D₁) = 0`, ZDS the
    /// two-derivative rule `… + (Δt²/12)(S₁ − S₀) = 0` (CFM25 section 2, SE[1]/12).
    #[test]
    fn block_one_gives_the_trapezoidal_and_hermite_rules() {
        let zd = StructuralCoefficients::new(1, 1).unwrap();
        assert_eq!(zd.start_z, vec![-1.0]);
        assert_eq!(zd.start_d, vec![-0.5]);
        assert_eq!(zd.matrix_d, vec![-0.5]);
        let zds = StructuralCoefficients::new(1, 2).unwrap();
        let close = |a: f64, b: f64| (a - b).abs() <= f64::EPSILON * b.abs();
        assert!(close(zds.start_d[0], -0.5) && close(zds.matrix_d[0], -0.5));
        assert!(close(zds.start_s[0], -1.0 / 12.0) && close(zds.matrix_s[0], 1.0 / 12.0));
    }
}
