//! The KKT solve of a small molecule through the Schur complement of `K`.
//!
//! With squared-distance constraints, `K = M + H_μ` couples only like coordinates: its
//! `dim × dim` blocks are multiples of the identity, `K = K̂ ⊗ I` with `K̂` an `n × n` matrix
//! over the molecule's `n` atoms (the masses on the diagonal, `±2μ_c` from each
//! constraint). So `K⁻¹ = K̂⁻¹ ⊗ I`, and the Schur complement `S = G K⁻¹ Gᵀ` has entries
//! `S_cd = 4 (d_c·d_d) (K̂⁻¹_{a_c a_d} − K̂⁻¹_{a_c b_d} − K̂⁻¹_{b_c a_d} + K̂⁻¹_{b_c b_d})`,
//! `d_c = A_a − A_b` (terms of an anchor left out). Then
//! `[[K, Gᵀ], [G, 0]] [x; y] = [r₁; r₂]` is `y = S⁻¹ (G z − r₂)`, `x = z − Y y` with
//! `z = K⁻¹ r₁` and `Y = K⁻¹ Gᵀ`: for a water molecule 3×3 matrices instead of an 11×11 or
//! 12×12 factorization. `K̂⁻¹`, `S⁻¹` and `Y` are formed at factor time, so a solve is a
//! few small matrix-vector products. The inertia of the KKT matrix is
//! `dim · inertia(K̂) + inertia(−S)` (Haynsworth), so its negative eigenvalues are `dim`
//! times those of `K̂` plus the positive ones of `S`.

/// The second end of a constraint held to a fixed anchor.
pub const ANCHOR: usize = usize::MAX;

pub type Vector = [f64; 3];

#[inline]
pub fn dot(x: &Vector, y: &Vector) -> f64 {
    x[0] * y[0] + x[1] * y[1] + x[2] * y[2]
}

/// Factors and buffers for one molecule (sized at setup).
#[derive(Clone, Debug)]
pub struct Schur {
    atoms: usize,
    constraints: usize,
    /// `K̂⁻¹`, row-major `atoms × atoms`.
    k_inverse: Vec<f64>,
    /// `S⁻¹`, row-major `constraints × constraints`.
    s_inverse: Vec<f64>,
    /// `Y = K⁻¹ Gᵀ`: for each constraint, its column as one 3-vector per atom.
    y: Vec<Vector>,
    /// Scratch: a factored matrix, `K⁻¹ r₁`, `G z − r₂`.
    factor: Vec<f64>,
    z: Vec<Vector>,
    t: Vec<f64>,
}

impl Schur {
    pub fn new(atoms: usize, constraints: usize) -> Self {
        let (n, m) = (atoms, constraints);
        Schur {
            atoms: n,
            constraints: m,
            k_inverse: vec![0.0; n * n],
            s_inverse: vec![0.0; m * m],
            y: vec![[0.0; 3]; m * n],
            factor: vec![0.0; n.max(m) * n.max(m)],
            z: vec![[0.0; 3]; n],
            t: vec![0.0; m],
        }
    }

    /// The estimated multiply-adds of one factorization and solve.
    pub fn cost(atoms: usize, constraints: usize) -> usize {
        let (n, m) = (atoms, constraints);
        n * n * n + m * m * m + 4 * m * m + 6 * m * n
    }

    /// Factor at the masses, `mu` (`None`: without curvature) and the arms `d_c = arm(c)`.
    /// Returns the KKT matrix's number of negative eigenvalues; on a zero pivot, the atom
    /// (`Ok`) or constraint (`Err`) where it occurred.
    pub fn factor(
        &mut self,
        ends: &[[usize; 2]],
        mass: &[f64],
        mu: Option<&[f64]>,
        arm: impl Fn(usize) -> Vector,
        dim: usize,
    ) -> Result<usize, Result<usize, usize>> {
        let (n, m) = (self.atoms, self.constraints);
        // K̂.
        let k = &mut self.factor[..n * n];
        k.fill(0.0);
        for (u, &mass) in mass.iter().enumerate() {
            k[u * n + u] = mass;
        }
        if let Some(mu) = mu {
            for (&[a, b], &mu) in ends.iter().zip(mu) {
                k[a * n + a] += 2.0 * mu;
                if b != ANCHOR {
                    k[b * n + b] += 2.0 * mu;
                    k[a.max(b) * n + a.min(b)] -= 2.0 * mu;
                }
            }
        }
        let k_negative = invert(k, n, &mut self.k_inverse).map_err(Ok)?;
        // Y = K⁻¹ Gᵀ: column c is 2 d_c (K̂⁻¹_{u a} − K̂⁻¹_{u b}) at atom u.
        for (c, &[a, b]) in ends.iter().enumerate() {
            let d = arm(c);
            for u in 0..n {
                let far = if b == ANCHOR {
                    0.0
                } else {
                    self.k_inverse[u * n + b]
                };
                let w = 2.0 * (self.k_inverse[u * n + a] - far);
                self.y[c * n + u] = [w * d[0], w * d[1], w * d[2]];
            }
        }
        // S = G Y: S_cd = 2 d_c · (Y_d[a_c] − Y_d[b_c]).
        let s = &mut self.factor[..m * m];
        for (c, &[a, b]) in ends.iter().enumerate() {
            let d = arm(c);
            for e in 0..=c {
                let near = self.y[e * n + a];
                let far = if b == ANCHOR {
                    [0.0; 3]
                } else {
                    self.y[e * n + b]
                };
                let diff = [near[0] - far[0], near[1] - far[1], near[2] - far[2]];
                s[c * m + e] = 2.0 * dot(&d, &diff);
            }
        }
        let s_negative = invert(s, m, &mut self.s_inverse).map_err(Err)?;
        Ok(dim * k_negative + (m - s_negative))
    }

    /// Solve in place: `atom_rhs` (r₁, one 3-vector per atom) becomes `x`,
    /// `constraint_rhs` (r₂) becomes `y`.
    pub fn solve(&mut self, atom_rhs: &mut [Vector], constraint_rhs: &mut [f64]) {
        let (n, m) = (self.atoms, self.constraints);
        for (u, z) in self.z.iter_mut().enumerate() {
            let row = &self.k_inverse[u * n..(u + 1) * n];
            let mut sum = [0.0; 3];
            for (k, r) in row.iter().zip(atom_rhs.iter()) {
                sum = [sum[0] + k * r[0], sum[1] + k * r[1], sum[2] + k * r[2]];
            }
            *z = sum;
        }
        // G z − r₂, with G_c z = 2 d_c·(z_a − z_b) = (Gᵀ e_c)·z; Y's column c is K⁻¹ Gᵀ e_c,
        // and K⁻¹ is symmetric, so G_c z = Y_cᵀ r₁.
        for (c, t) in self.t.iter_mut().enumerate() {
            let column = &self.y[c * n..(c + 1) * n];
            let gz: f64 = column
                .iter()
                .zip(atom_rhs.iter())
                .map(|(y, r)| dot(y, r))
                .sum();
            *t = gz - constraint_rhs[c];
        }
        for (c, y) in constraint_rhs.iter_mut().enumerate().take(m) {
            let row = &self.s_inverse[c * m..(c + 1) * m];
            *y = row.iter().zip(&self.t).map(|(s, t)| s * t).sum();
        }
        for (u, x) in atom_rhs.iter_mut().enumerate() {
            let mut value = self.z[u];
            for (c, &weight) in constraint_rhs.iter().enumerate() {
                let y = self.y[c * n + u];
                value = [
                    value[0] - y[0] * weight,
                    value[1] - y[1] * weight,
                    value[2] - y[2] * weight,
                ];
            }
            *x = value;
        }
    }
}

/// The inverse of a symmetric `n × n` matrix (row-major, lower triangle read; overwritten
/// by its `L D Lᵀ`, no pivoting) into `inverse`. Returns the number of negative pivots, or
/// the row of a zero one.
fn invert(a: &mut [f64], n: usize, inverse: &mut [f64]) -> Result<usize, usize> {
    match n {
        2 => return invert_2(a, inverse),
        3 => return invert_3(a, inverse),
        _ => {}
    }
    let mut negative = 0;
    for i in 0..n {
        for j in 0..i {
            let mut w = a[i * n + j];
            for k in 0..j {
                w -= a[i * n + k] * a[j * n + k];
            }
            a[i * n + j] = w;
        }
        let mut pivot = a[i * n + i];
        for j in 0..i {
            let w = a[i * n + j];
            let l = w / a[j * n + j];
            pivot -= w * l;
            a[i * n + j] = l;
        }
        if pivot == 0.0 || !pivot.is_finite() {
            return Err(i);
        }
        negative += usize::from(pivot < 0.0);
        a[i * n + i] = pivot;
    }
    for column in 0..n {
        let x = &mut inverse[column * n..(column + 1) * n];
        x.fill(0.0);
        x[column] = 1.0;
        for i in 0..n {
            let mut sum = x[i];
            for k in 0..i {
                sum -= a[i * n + k] * x[k];
            }
            x[i] = sum;
        }
        for i in 0..n {
            x[i] /= a[i * n + i];
        }
        for i in (0..n).rev() {
            let xi = x[i];
            for k in 0..i {
                x[k] -= a[i * n + k] * xi;
            }
        }
    }
    Ok(negative)
}

/// [`invert`] for 2 × 2: the pivots of `L D Lᵀ` for the inertia, the adjugate for the inverse.
fn invert_2(a: &[f64], inverse: &mut [f64]) -> Result<usize, usize> {
    let (a11, a21, a22) = (a[0], a[2], a[3]);
    let d1 = a11;
    if d1 == 0.0 || !d1.is_finite() {
        return Err(0);
    }
    let d2 = a22 - a21 * a21 / d1;
    if d2 == 0.0 || !d2.is_finite() {
        return Err(1);
    }
    let det = d1 * d2;
    inverse.copy_from_slice(&[a22 / det, -a21 / det, -a21 / det, a11 / det]);
    Ok(usize::from(d1 < 0.0) + usize::from(d2 < 0.0))
}

/// [`invert`] for 3 × 3 (a water molecule's `K̂` and `S`): pivots and cofactors.
fn invert_3(a: &[f64], inverse: &mut [f64]) -> Result<usize, usize> {
    let (a11, a21, a22, a31, a32, a33) = (a[0], a[3], a[4], a[6], a[7], a[8]);
    let d1 = a11;
    if d1 == 0.0 || !d1.is_finite() {
        return Err(0);
    }
    let (l21, l31) = (a21 / d1, a31 / d1);
    let d2 = a22 - a21 * l21;
    if d2 == 0.0 || !d2.is_finite() {
        return Err(1);
    }
    let l32 = (a32 - a31 * l21) / d2;
    let d3 = a33 - a31 * l31 - l32 * l32 * d2;
    if d3 == 0.0 || !d3.is_finite() {
        return Err(2);
    }
    let c11 = a22 * a33 - a32 * a32;
    let c21 = a31 * a32 - a21 * a33;
    let c31 = a21 * a32 - a22 * a31;
    let c22 = a11 * a33 - a31 * a31;
    let c32 = a21 * a31 - a11 * a32;
    let c33 = a11 * a22 - a21 * a21;
    let scale = 1.0 / (d1 * d2 * d3);
    inverse.copy_from_slice(&[
        c11 * scale,
        c21 * scale,
        c31 * scale,
        c21 * scale,
        c22 * scale,
        c32 * scale,
        c31 * scale,
        c32 * scale,
        c33 * scale,
    ]);
    Ok(usize::from(d1 < 0.0) + usize::from(d2 < 0.0) + usize::from(d3 < 0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_inverses_match_the_general_one() {
        // Symmetric, one negative eigenvalue in the 3×3 (a KKT-like sign pattern).
        for (n, a) in [
            (2, vec![2.0, 0.0, -0.7, 1.5]),
            (3, vec![4.0, 0.0, 0.0, 1.0, 3.0, 0.0, -0.5, 0.8, -2.0]),
        ] {
            let (mut small, mut general) = (vec![0.0; n * n], vec![0.0; n * n]);
            let small_negative = invert(&mut a.clone(), n, &mut small).unwrap();
            // The general path, by embedding in a block-diagonal (n + 2) matrix.
            let big = n + 2;
            let mut b = vec![0.0; big * big];
            for i in 0..n {
                for j in 0..n {
                    b[i * big + j] = a[i.max(j) * n + i.min(j)];
                }
            }
            b[n * big + n] = 1.0;
            b[(n + 1) * big + n + 1] = 1.0;
            let mut full = vec![0.0; big * big];
            let general_negative = invert(&mut b, big, &mut full).unwrap();
            for i in 0..n {
                for j in 0..n {
                    general[i * n + j] = full[i * big + j];
                }
            }
            assert_eq!(small_negative, general_negative);
            for (x, y) in small.iter().zip(&general) {
                assert!((x - y).abs() < 1e-14, "{small:?} vs {general:?}");
            }
        }
    }
}
