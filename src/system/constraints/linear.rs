//! The constraints linearized: the transposed derivatives of a SHAKE/SETTLE position step
//! and of a RATTLE velocity projection, for reverse-mode differentiation through a
//! constrained Verlet trajectory (the constrained averaging of the mollified impulse
//! methods, `integrators::mollified`).
//!
//! **Notation.** Every scalar constraint is a pair `c = (i, j)` (a rigid water gives three:
//! O–H₁, O–H₂, H₁–H₂), `g_c(q) = ½(|r_c|² − d_c²)` with `r_c = qᵢ − qⱼ` (minimum image),
//! so the row `G_c(q)` of `G = ∂g/∂q` is `r_c` on `i` and `−r_c` on `j`. Two constraint
//! impulses `λ` (momentum changes `Δp = G(q)ᵀλ`) are recovered from the steps that made
//! them ([`Linearized::multipliers`]). Fixed `λ`, the derivative of `G(q)ᵀλ` is
//! `L_λ δq`, `L_λ = Σ_c λ_c (eᵢ − eⱼ)(eᵢ − eⱼ)ᵀ ⊗ I` (symmetric, independent of `q`); fixed
//! `x`, that of `G(q) x` is `D_x δq`, `(D_x δq)_c = δr_c·(xᵢ − xⱼ)`.
//!
//! **Position step** (And83 (2.4)–(2.6); SETTLE solves the same equations, its constraint
//! forces lying along the old bonds, [`super::settle`]): `q̂ = q + dt M⁻¹p̂`,
//! `q' = q̂ + dt M⁻¹G(q)ᵀλ`, `p' = p̂ + G(q)ᵀλ` with `g(q') = 0`. Linearized, with
//! `C = G(q′)M⁻¹G(q)ᵀ`, `u = δq̂ + dt M⁻¹L_λ δq` and `S = I − M⁻¹G(q)ᵀC⁻¹G(q′)`:
//! `δq′ = S u`, `δp′ = δp̂ + M(δq′ − δq̂)/dt`. Transposed ([`Linearized::shake_transpose`]),
//! from the adjoints `(q̄′, p̄′)`: `a = q̄′ + M p̄′/dt`, `c = G(q′)ᵀC⁻ᵀG(q)M⁻¹a`,
//! `q̂̄ = q̄′ − c`, then `p̄ = p̄′ + dt M⁻¹q̂̄` and `q̄ = q̂̄ + dt L_λ M⁻¹(a − c)`.
//!
//! **Velocity projection** (And83 (2.7)–(2.9)): `p⁺ = p + G(q)ᵀμ` with `G(q)M⁻¹p⁺ = 0`.
//! Linearized, with `B = G M⁻¹Gᵀ`, `Π = I − GᵀB⁻¹GM⁻¹` and `v⁺ = M⁻¹p⁺`:
//! `δp⁺ = Π(δp + L_μ δq) − GᵀB⁻¹D_{v⁺} δq`. Transposed
//! ([`Linearized::projection_transpose`]): `y = B⁻¹G p̄⁺`, `p̄ = p̄⁺ − M⁻¹Gᵀy`,
//! `q̄ += L_μ p̄ − D_{v⁺}ᵀ y`.
//!
//! With no constraint every correction vanishes and the transposed position step is the
//! transposed drift `p̄ = p̄′ + dt M⁻¹q̄′`, written as the unconstrained adjoint writes it
//! (the same bits).
//!
//! **Cost.** The constraints fall into clusters (connected by shared particles: a water,
//! a methyl group's three C–H); each solve factors one dense `m × m` matrix per cluster of
//! `m` constraints, `O(Σ m³)`: a few hundred flops per water or bond to hydrogen. With
//! `all-bonds` on a large molecule its one cluster makes this cubic in its bonds.
//! Nothing is allocated after [`Linearized::new`].

use super::{Constraints, PeriodicBox, separation};

/// The adjoints `(q̄, p̄)` a transposed step maps in place.
pub struct Adjoints<'a> {
    pub q: &'a mut [f64],
    pub p: &'a mut [f64],
}

/// The constraints as pairs grouped in clusters, with the scratch of their solves.
#[derive(Clone, Debug)]
pub struct Linearized {
    dim: usize,
    periodic_box: Option<PeriodicBox>,
    /// Every scalar constraint, ordered by cluster.
    pairs: Vec<(usize, usize)>,
    /// Cluster `k` holds the constraints `starts[k]..starts[k + 1]`.
    starts: Vec<usize>,
    /// The matrix of the largest cluster, row-major.
    matrix: Vec<f64>,
    /// A right-hand side, then the solution, per constraint.
    solution: Vec<f64>,
    /// `dim` numbers per constraint (the `L_λ M⁻¹ū` terms).
    along: Vec<f64>,
    /// A vector over all coordinates (the correction `c`).
    correction: Vec<f64>,
}

impl Linearized {
    /// The constraints of `constraints` among `n_dofs` coordinates.
    pub fn new(constraints: &Constraints, n_dofs: usize) -> Self {
        let mut all: Vec<(usize, usize)> = constraints.pairs.iter().map(|c| (c.i, c.j)).collect();
        for w in &constraints.waters {
            let [h1, h2] = w.hydrogens;
            all.extend([(w.oxygen, h1), (w.oxygen, h2), (h1, h2)]);
        }
        let (pairs, starts) = clusters(&all, n_dofs / constraints.dim.max(1));
        let largest = starts.windows(2).map(|w| w[1] - w[0]).max().unwrap_or(0);
        Linearized {
            dim: constraints.dim,
            periodic_box: constraints.periodic_box,
            matrix: vec![0.0; largest * largest],
            solution: vec![0.0; pairs.len()],
            along: vec![0.0; pairs.len() * constraints.dim],
            correction: vec![0.0; n_dofs],
            pairs,
            starts,
        }
    }

    /// The number of scalar constraints.
    pub fn len(&self) -> usize {
        self.pairs.len()
    }

    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// The clusters' sizes, for tests and notices.
    pub fn cluster_sizes(&self) -> impl Iterator<Item = usize> + '_ {
        self.starts.windows(2).map(|w| w[1] - w[0])
    }

    fn bond(&self, q: &[f64], c: usize) -> [f64; 3] {
        let (i, j) = self.pairs[c];
        separation(self.dim, self.periodic_box, q, i, j)
    }

    /// `out = λ` with `Δp = G(q)ᵀλ`: the impulses of a constraint step that changed the
    /// momenta by `delta_p` at positions `q` (`λ = B⁻¹G M⁻¹Δp`, exact when `Δp` lies in
    /// the range of `G(q)ᵀ`, as the steps' impulses do).
    pub fn multipliers(
        &mut self,
        q: &[f64],
        delta_p: &[f64],
        inverse_mass: &[f64],
        out: &mut [f64],
    ) {
        let dim = self.dim;
        for c in 0..self.pairs.len() {
            let (i, j) = self.pairs[c];
            let r = self.bond(q, c);
            self.solution[c] = (0..dim)
                .map(|a| {
                    r[a] * (inverse_mass[i * dim + a] * delta_p[i * dim + a]
                        - inverse_mass[j * dim + a] * delta_p[j * dim + a])
                })
                .sum();
        }
        self.solve(q, q, inverse_mass);
        out.copy_from_slice(&self.solution);
    }

    /// `out[c·dim..]`: the relative velocity `vᵢ − vⱼ` of every constraint (for `D_{v⁺}`).
    pub fn relative_velocities(&self, p: &[f64], inverse_mass: &[f64], out: &mut [f64]) {
        let dim = self.dim;
        for (c, &(i, j)) in self.pairs.iter().enumerate() {
            for a in 0..dim {
                out[c * dim + a] = inverse_mass[i * dim + a] * p[i * dim + a]
                    - inverse_mass[j * dim + a] * p[j * dim + a];
            }
        }
    }

    /// Solve `K y = self.solution` cluster by cluster, in place, where
    /// `K_cd = G_c(a) M⁻¹ G_d(b)ᵀ`: `B(q)` for `a = b = q`, `Cᵀ` for `a = q, b = q′`.
    fn solve(&mut self, a: &[f64], b: &[f64], inverse_mass: &[f64]) {
        let dim = self.dim;
        for k in 0..self.starts.len() - 1 {
            let (start, end) = (self.starts[k], self.starts[k + 1]);
            let m = end - start;
            for row in 0..m {
                let rc = self.bond(a, start + row);
                let (i, j) = self.pairs[start + row];
                for col in 0..m {
                    let (k2, l) = self.pairs[start + col];
                    let w = |x: usize| inverse_mass[x * dim];
                    let shared = (if i == k2 { w(i) } else { 0.0 })
                        - (if i == l { w(i) } else { 0.0 })
                        - (if j == k2 { w(j) } else { 0.0 })
                        + (if j == l { w(j) } else { 0.0 });
                    let entry = if shared == 0.0 {
                        0.0
                    } else {
                        let rd = self.bond(b, start + col);
                        shared * (0..dim).map(|x| rc[x] * rd[x]).sum::<f64>()
                    };
                    self.matrix[row * m + col] = entry;
                }
            }
            gauss(&mut self.matrix[..m * m], &mut self.solution[start..end], m);
        }
    }

    /// The transposed derivative of a position step from `q_old` to `q_new` with impulses
    /// `lambda` (see the module's doc): `(q̄′, p̄′) → (q̄, p̄)` in place.
    pub fn shake_transpose(
        &mut self,
        q_old: &[f64],
        q_new: &[f64],
        lambda: &[f64],
        inverse_mass: &[f64],
        dt: f64,
        bar: Adjoints<'_>,
    ) {
        let (dim, q_bar, p_bar) = (self.dim, bar.q, bar.p);
        // a = q̄′ + M p̄′/dt on the constrained particles; the right-hand side G(q)M⁻¹a.
        let a = |x: usize| q_bar[x] + p_bar[x] / (inverse_mass[x] * dt);
        for c in 0..self.pairs.len() {
            let (i, j) = self.pairs[c];
            let r = self.bond(q_old, c);
            self.solution[c] = (0..dim)
                .map(|k| {
                    r[k] * (inverse_mass[i * dim + k] * a(i * dim + k)
                        - inverse_mass[j * dim + k] * a(j * dim + k))
                })
                .sum();
        }
        self.solve(q_old, q_new, inverse_mass);
        // c = G(q′)ᵀ y.
        for &(i, j) in &self.pairs {
            self.correction[i * dim..(i + 1) * dim].fill(0.0);
            self.correction[j * dim..(j + 1) * dim].fill(0.0);
        }
        for c in 0..self.pairs.len() {
            let (i, j) = self.pairs[c];
            let r = self.bond(q_new, c);
            for (k, rk) in r.iter().enumerate().take(dim) {
                self.correction[i * dim + k] += self.solution[c] * rk;
                self.correction[j * dim + k] -= self.solution[c] * rk;
            }
        }
        // λ_c ((M⁻¹ū)ᵢ − (M⁻¹ū)ⱼ), ū = a − c, before q̄ and p̄ change.
        for (c, &(i, j)) in self.pairs.iter().enumerate() {
            for k in 0..dim {
                let (x, y) = (i * dim + k, j * dim + k);
                let ui = inverse_mass[x] * (a(x) - self.correction[x]);
                let uj = inverse_mass[y] * (a(y) - self.correction[y]);
                self.along[c * dim + k] = lambda[c] * (ui - uj);
            }
        }
        for &(i, j) in &self.pairs {
            for x in (i * dim..(i + 1) * dim).chain(j * dim..(j + 1) * dim) {
                q_bar[x] -= std::mem::take(&mut self.correction[x]);
            }
        }
        // The transposed drift, as the unconstrained adjoint writes it.
        for ((pa, qa), w) in p_bar.iter_mut().zip(q_bar.iter()).zip(inverse_mass) {
            *pa += dt * (w * qa);
        }
        for (c, &(i, j)) in self.pairs.iter().enumerate() {
            for k in 0..dim {
                q_bar[i * dim + k] += dt * self.along[c * dim + k];
                q_bar[j * dim + k] -= dt * self.along[c * dim + k];
            }
        }
    }

    /// The transposed derivative of a velocity projection at `q` with impulses `mu` and
    /// projected relative velocities `relative` (see the module's doc), in place.
    pub fn projection_transpose(
        &mut self,
        q: &[f64],
        mu: &[f64],
        relative: &[f64],
        inverse_mass: &[f64],
        bar: Adjoints<'_>,
    ) {
        let (dim, q_bar, p_bar) = (self.dim, bar.q, bar.p);
        for c in 0..self.pairs.len() {
            let (i, j) = self.pairs[c];
            let r = self.bond(q, c);
            self.solution[c] = (0..dim)
                .map(|k| r[k] * (p_bar[i * dim + k] - p_bar[j * dim + k]))
                .sum();
        }
        self.solve(q, q, inverse_mass);
        // p̄ = p̄⁺ − M⁻¹Gᵀy.
        for c in 0..self.pairs.len() {
            let (i, j) = self.pairs[c];
            let r = self.bond(q, c);
            let y = self.solution[c];
            for k in 0..dim {
                p_bar[i * dim + k] -= inverse_mass[i * dim + k] * y * r[k];
                p_bar[j * dim + k] += inverse_mass[j * dim + k] * y * r[k];
            }
        }
        // q̄ += L_μ p̄ − D_{v⁺}ᵀ y.
        for (c, &(i, j)) in self.pairs.iter().enumerate() {
            for k in 0..dim {
                let term = mu[c] * (p_bar[i * dim + k] - p_bar[j * dim + k])
                    - self.solution[c] * relative[c * dim + k];
                q_bar[i * dim + k] += term;
                q_bar[j * dim + k] -= term;
            }
        }
    }
}

/// The constraints `all` ordered by cluster (connected through shared particles, among
/// `n` particles), and the clusters' starts (one past the end last). Clusters come in the
/// order of their first constraint, the constraints of each in their given order.
fn clusters(all: &[(usize, usize)], n: usize) -> (Vec<(usize, usize)>, Vec<usize>) {
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut x: usize) -> usize {
        while parent[x] != x {
            parent[x] = parent[parent[x]];
            x = parent[x];
        }
        x
    }
    for &(i, j) in all {
        let (a, b) = (root(&mut parent, i), root(&mut parent, j));
        if a != b {
            parent[a.max(b)] = a.min(b);
        }
    }
    let mut order: Vec<(usize, usize)> = Vec::with_capacity(all.len());
    let mut cluster_of_root: Vec<Option<usize>> = vec![None; n];
    let mut members: Vec<Vec<(usize, usize)>> = Vec::new();
    for &(i, j) in all {
        let r = root(&mut parent, i);
        let k = *cluster_of_root[r].get_or_insert_with(|| {
            members.push(Vec::new());
            members.len() - 1
        });
        members[k].push((i, j));
    }
    let mut starts = vec![0];
    for cluster in members {
        order.extend(cluster);
        starts.push(order.len());
    }
    (order, starts)
}

/// Solve `A x = b` in place (`A` is `m × m`, row-major; `b` becomes `x`) by Gaussian
/// elimination with partial pivoting. A singular `A` (a degenerate constraint geometry,
/// which the step itself would have refused) gives non-finite numbers.
fn gauss(a: &mut [f64], b: &mut [f64], m: usize) {
    for col in 0..m {
        let pivot = (col..m)
            .max_by(|&x, &y| a[x * m + col].abs().total_cmp(&a[y * m + col].abs()))
            .unwrap_or(col);
        if pivot != col {
            for k in 0..m {
                a.swap(col * m + k, pivot * m + k);
            }
            b.swap(col, pivot);
        }
        let d = a[col * m + col];
        for row in col + 1..m {
            let f = a[row * m + col] / d;
            if f != 0.0 {
                for k in col..m {
                    a[row * m + k] -= f * a[col * m + k];
                }
                b[row] -= f * b[col];
            }
        }
    }
    for row in (0..m).rev() {
        let mut s = b[row];
        for k in row + 1..m {
            s -= a[row * m + k] * b[k];
        }
        b[row] = s / a[row * m + row];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauss_solves_a_pivoting_system() {
        // [[0, 2], [3, 1]] x = [4, 5] → x = [1, 2]; the zero pivot needs the row swap.
        let mut a = [0.0, 2.0, 3.0, 1.0];
        let mut b = [4.0, 5.0];
        gauss(&mut a, &mut b, 2);
        assert_eq!(b, [1.0, 2.0]);
    }

    #[test]
    fn clusters_join_constraints_that_share_particles() {
        let (order, starts) = clusters(&[(0, 1), (4, 5), (1, 2), (3, 4)], 6);
        assert_eq!(order, [(0, 1), (1, 2), (4, 5), (3, 4)]);
        assert_eq!(starts, [0, 2, 4]);
    }
}
