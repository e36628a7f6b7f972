//! The highest normal modes of one force level under constraints, by Lanczos iterations on
//! Hessian-vector products: no dense Hessian, so a solvated protein's fast level (20 000
//! coordinates) costs `k` products and `k` stored vectors.
//!
//! **The operator.** With `M` the (diagonal) mass matrix, `H = ∇²V_level(q)` and the
//! distance constraints `g_c(q) = |q_j − q_i| − d_c = 0` (SHAKE/RATTLE bonds, and each rigid
//! water's three distances), let `G` be the constraint Jacobian (row `c`: `+û_c` at `j`,
//! `−û_c` at `i`, `û_c` the unit bond vector, minimum image) and `N = G M^{-1/2}` its rows
//! in mass-weighted coordinates `x = M^{1/2} q`. The projector onto the directions the
//! constraints leave free is
//!
//! ```text
//!   P = I − Nᵀ (N Nᵀ)⁻¹ N,
//! ```
//!
//! and the linearised constrained motion `M δq̈ = −K δq − Gᵀ δλ`, `G δq = 0`, has the
//! frequencies ω² of the eigenvalues of
//!
//! ```text
//!   A = P M^{-1/2} K M^{-1/2} P,    K = H + Σ_c λ_c ∇²g_c,
//!   λ = −(G M⁻¹ Gᵀ)⁻¹ G M⁻¹ ∇V_level,     ∇²g_c δq = ± (I − û_c û_cᵀ)(δq_j − δq_i) / r_c,
//! ```
//!
//! `λ` being the constraint forces that keep the level's force from accelerating along the
//! constraints (Lagrange's equations `M q̈ = −∇V − Gᵀλ` at rest). The curvature term matters
//! away from a minimum: a stretched bond held rigid pulls with `V′` and its Hessian has
//! `V′/r` across the bond, which `λ ∇²g` cancels exactly, so a rigid rotation has ω = 0.
//! Neglected: the velocity terms of λ (`m v⊥²/r`, about `k_B T / r²` ≈ 0.6 kcal/mol/Å² at
//! 300 K against the ~40 kcal/mol/Å²·amu of a libration) — the modes are those of the
//! level's forces at rest at `q`. The constrained directions are eigenvectors of `A` with
//! eigenvalue 0, so no mode found here has a component along a constraint gradient. `N Nᵀ`
//! is block-diagonal over clusters of constraints sharing atoms (a water; a heavy atom with
//! its hydrogens); each block is inverted once (nalgebra, dense: a handful of rows).
//!
//! **Lanczos** (Golub & Van Loan, *Matrix Computations*, section 10.1) with full
//! reorthogonalisation (Gram–Schmidt twice against every stored vector), from a seeded
//! random start projected by `P`: after `k` steps the tridiagonal `T_k = V_kᵀ A V_k` has Ritz
//! values `θ` whose largest converge first; each has a residual `‖A y − θ y‖ = β_k |s_k|`
//! (`s_k` the last entry of its eigenvector of `T_k`), and some eigenvalue of `A` lies within
//! that residual of `θ` (Parlett, *The Symmetric Eigenvalue Problem*, Theorem 4.5.1).
//!
//! **Cost.** `k` Hessian-vector products of the level plus `O(k² n)` for the
//! reorthogonalisation and `O(k n)` memory (200 vectors of 20 000 coordinates: 32 MB).

use nalgebra::{DMatrix, SymmetricEigen};
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, StandardNormal};

use crate::error::{Error, Result};
use crate::forces::components::Components;
use crate::split::ForceSplit;
use crate::system::System;

/// One constrained distance, as the projection sees it at the operator's positions.
#[derive(Clone, Debug)]
struct Row {
    i: usize,
    j: usize,
    /// Unit vector from `i` to `j` (minimum image).
    unit: [f64; 3],
    /// Current length `r_c`.
    length: f64,
    /// Lagrange multiplier of the level's force at rest.
    lambda: f64,
}

/// A cluster of constraints sharing atoms, with the inverse of its block of `N Nᵀ`.
#[derive(Clone, Debug)]
struct Block {
    rows: Vec<usize>,
    /// `(N Nᵀ)⁻¹` of the block, row-major.
    inverse: Vec<f64>,
}

/// The operator `A = P M^{-1/2} K M^{-1/2} P` of one force level (module documentation).
pub struct ConstrainedHessian {
    level: usize,
    dim: usize,
    q: Vec<f64>,
    /// `m^{-1/2}` per coordinate.
    sqrt_inverse_mass: Vec<f64>,
    rows: Vec<Row>,
    blocks: Vec<Block>,
    scaled: Vec<f64>,
    product: Vec<f64>,
    row_values: Vec<f64>,
    multipliers: Vec<f64>,
}

impl ConstrainedHessian {
    /// The operator of `level` at the system's positions, with the system's constraints
    /// (none: `A = M^{-1/2} H M^{-1/2}`). Costs one gradient of the level (for λ).
    pub fn new(system: &mut System, level: usize) -> Result<Self> {
        if system.mass_matrix.is_some() {
            return Err(Error::input(
                "the Lanczos modes need a diagonal mass matrix; this scene gives a full one",
            ));
        }
        if level >= system.forces.n_levels() {
            return Err(Error::input(format!(
                "no force level {level}: the split has {}",
                system.forces.n_levels()
            )));
        }
        let dim = system.dim;
        let q = system.state.q.clone();
        let rows = constraint_rows(system, dim)?;
        let sqrt_inverse_mass: Vec<f64> = system.inverse_mass.iter().map(|w| w.sqrt()).collect();
        let blocks = constraint_blocks(&rows, &system.inverse_mass, dim, system.n_particles())?;
        let largest = blocks.iter().map(|b| b.rows.len()).max().unwrap_or(0);
        let n = q.len();
        let mut operator = ConstrainedHessian {
            level,
            dim,
            q,
            sqrt_inverse_mass,
            rows,
            blocks,
            scaled: vec![0.0; n],
            product: vec![0.0; n],
            row_values: vec![0.0; largest],
            multipliers: vec![0.0; largest],
        };
        operator.set_multipliers(&mut system.forces);
        Ok(operator)
    }

    /// Number of coordinates.
    pub fn len(&self) -> usize {
        self.q.len()
    }

    pub fn is_empty(&self) -> bool {
        self.q.is_empty()
    }

    /// Number of constrained distances projected out.
    pub fn constraint_count(&self) -> usize {
        self.rows.len()
    }

    /// `N_c v` for every constraint row: `û_c · (v_j/√m_j − v_i/√m_i)`, in `out[c]`.
    pub fn constraint_components(&self, v: &[f64], out: &mut [f64]) {
        for (row, o) in self.rows.iter().zip(out.iter_mut()) {
            *o = self.row_dot(row, v);
        }
    }

    fn row_dot(&self, row: &Row, v: &[f64]) -> f64 {
        let (d, s) = (self.dim, &self.sqrt_inverse_mass);
        (0..d)
            .map(|k| {
                row.unit[k]
                    * (s[row.j * d + k] * v[row.j * d + k] - s[row.i * d + k] * v[row.i * d + k])
            })
            .sum()
    }

    /// λ = −(N Nᵀ)⁻¹ N M^{-1/2} ∇V_level, block by block.
    fn set_multipliers(&mut self, forces: &mut ForceSplit) {
        let mut gradient = vec![0.0; self.q.len()];
        forces.add_gradient(self.level, &self.q, &mut gradient);
        // N M^{-1/2} g = û·(g_j/m_j − g_i/m_i): scale by m^{-1/2} once, then row_dot.
        for (g, s) in gradient.iter_mut().zip(&self.sqrt_inverse_mass) {
            *g *= s;
        }
        for b in 0..self.blocks.len() {
            let size = self.blocks[b].rows.len();
            for (a, &r) in self.blocks[b].rows.iter().enumerate() {
                self.row_values[a] = self.row_dot(&self.rows[r], &gradient);
            }
            for a in 0..size {
                let lambda: f64 = (0..size)
                    .map(|c| self.blocks[b].inverse[a * size + c] * self.row_values[c])
                    .sum();
                let r = self.blocks[b].rows[a];
                self.rows[r].lambda = -lambda;
            }
        }
    }

    /// `v ← P v`.
    pub fn project(&mut self, v: &mut [f64]) {
        let (d, s) = (self.dim, &self.sqrt_inverse_mass);
        for block in &self.blocks {
            let size = block.rows.len();
            for (a, &r) in block.rows.iter().enumerate() {
                self.row_values[a] = self.rows[r].unit[..d]
                    .iter()
                    .enumerate()
                    .map(|(k, u)| {
                        let (i, j) = (self.rows[r].i * d + k, self.rows[r].j * d + k);
                        u * (s[j] * v[j] - s[i] * v[i])
                    })
                    .sum();
            }
            for a in 0..size {
                self.multipliers[a] = (0..size)
                    .map(|c| block.inverse[a * size + c] * self.row_values[c])
                    .sum();
            }
            for (a, &r) in block.rows.iter().enumerate() {
                let row = &self.rows[r];
                for k in 0..d {
                    let (i, j) = (row.i * d + k, row.j * d + k);
                    v[j] -= self.multipliers[a] * row.unit[k] * s[j];
                    v[i] += self.multipliers[a] * row.unit[k] * s[i];
                }
            }
        }
    }

    /// `out = A x`: one Hessian-vector product of the level. Allocates nothing.
    pub fn apply(&mut self, forces: &mut ForceSplit, x: &[f64], out: &mut [f64]) {
        out.copy_from_slice(x);
        self.project(out);
        for ((z, o), s) in self
            .scaled
            .iter_mut()
            .zip(out.iter())
            .zip(&self.sqrt_inverse_mass)
        {
            *z = o * s;
        }
        forces.hessian_vector(self.level, &self.q, &self.scaled, &mut self.product);
        let d = self.dim;
        for row in &self.rows {
            let du: [f64; 3] = std::array::from_fn(|k| {
                if k < d {
                    self.scaled[row.j * d + k] - self.scaled[row.i * d + k]
                } else {
                    0.0
                }
            });
            let along: f64 = (0..d).map(|k| row.unit[k] * du[k]).sum();
            let scale = row.lambda / row.length;
            for (k, (&du_k, &unit_k)) in du.iter().zip(&row.unit).take(d).enumerate() {
                let t = scale * (du_k - along * unit_k);
                self.product[row.j * d + k] += t;
                self.product[row.i * d + k] -= t;
            }
        }
        for ((o, p), s) in out
            .iter_mut()
            .zip(&self.product)
            .zip(&self.sqrt_inverse_mass)
        {
            *o = p * s;
        }
        self.project(out);
    }

    /// The dense matrix of `A`, column by column (`n` products): for tests and small
    /// molecules only.
    pub fn dense(&mut self, forces: &mut ForceSplit) -> DMatrix<f64> {
        let n = self.len();
        let mut matrix = DMatrix::zeros(n, n);
        let (mut unit, mut column) = (vec![0.0; n], vec![0.0; n]);
        for c in 0..n {
            unit.fill(0.0);
            unit[c] = 1.0;
            self.apply(forces, &unit, &mut column);
            for r in 0..n {
                matrix[(r, c)] = column[r];
            }
        }
        (&matrix + matrix.transpose()) * 0.5
    }
}

/// Every constrained distance of the system: its SHAKE/RATTLE pairs, and each rigid
/// water's O–H₁, O–H₂, H₁–H₂.
fn constraint_rows(system: &System, dim: usize) -> Result<Vec<Row>> {
    let Some(constraints) = &system.constraints else {
        return Ok(Vec::new());
    };
    let mut pairs: Vec<(usize, usize)> = constraints.pairs().iter().map(|c| (c.i, c.j)).collect();
    for w in constraints.waters() {
        let [h1, h2] = w.hydrogens;
        pairs.extend([(w.oxygen, h1), (w.oxygen, h2), (h1, h2)]);
    }
    if !pairs.is_empty() && dim > 3 {
        return Err(Error::input("constraints in more than three dimensions"));
    }
    let q = &system.state.q;
    pairs
        .into_iter()
        .map(|(i, j)| {
            let mut unit = [0.0; 3];
            for (k, u) in unit.iter_mut().enumerate().take(dim) {
                let raw = q[j * dim + k] - q[i * dim + k];
                *u = match &system.periodic_box {
                    Some(b) => b.wrap(k, raw),
                    None => raw,
                };
            }
            let length = unit.iter().map(|u| u * u).sum::<f64>().sqrt();
            if length <= 0.0 || !length.is_finite() {
                return Err(Error::input(format!(
                    "constrained atoms {i} and {j} sit on each other"
                )));
            }
            unit.iter_mut().for_each(|u| *u /= length);
            Ok(Row {
                i,
                j,
                unit,
                length,
                lambda: 0.0,
            })
        })
        .collect()
}

/// Clusters of rows sharing atoms, each with `(N Nᵀ)⁻¹`: entry `(a, b)` is
/// `Σ_atoms s_a s_b (û_a·û_b)/m` over the atoms both rows hold (`s = +1` at `j`, `−1` at `i`).
fn constraint_blocks(
    rows: &[Row],
    inverse_mass: &[f64],
    dim: usize,
    n_particles: usize,
) -> Result<Vec<Block>> {
    let mut atoms = Components::new(n_particles);
    for row in rows {
        atoms.join(row.i, row.j);
    }
    let mut by_root: std::collections::BTreeMap<usize, Vec<usize>> = Default::default();
    for (r, row) in rows.iter().enumerate() {
        by_root.entry(atoms.root(row.i)).or_default().push(r);
    }
    let side = |row: &Row, atom: usize| {
        if row.j == atom {
            1.0
        } else if row.i == atom {
            -1.0
        } else {
            0.0
        }
    };
    by_root
        .into_values()
        .map(|members| {
            let size = members.len();
            let gram = DMatrix::from_fn(size, size, |a, b| {
                let (ra, rb) = (&rows[members[a]], &rows[members[b]]);
                let cos: f64 = (0..3).map(|k| ra.unit[k] * rb.unit[k]).sum();
                [ra.i, ra.j]
                    .iter()
                    .map(|&atom| side(ra, atom) * side(rb, atom) * inverse_mass[atom * dim])
                    .sum::<f64>()
                    * cos
            });
            let inverse = gram.try_inverse().ok_or_else(|| {
                Error::input(format!(
                    "the constraints on atoms {}–{} are not independent",
                    rows[members[0]].i, rows[members[0]].j
                ))
            })?;
            Ok(Block {
                rows: members,
                inverse: inverse.transpose().as_slice().to_vec(),
            })
        })
        .collect()
}

/// What [`lanczos_highest`] iterates for.
#[derive(Clone, Copy, Debug)]
pub struct LanczosOptions {
    /// At most this many iterations (Hessian-vector products).
    pub iterations: usize,
    /// How many of the largest Ritz values must converge before stopping early.
    pub wanted: usize,
    /// Converged: residual ≤ `tolerance × θ_max`.
    pub tolerance: f64,
    pub seed: u64,
}

impl Default for LanczosOptions {
    fn default() -> Self {
        LanczosOptions {
            iterations: 150,
            wanted: 8,
            tolerance: 1e-6,
            seed: 1,
        }
    }
}

/// One Ritz pair: an approximate eigenvalue ω² of `A` and its mass-weighted vector.
#[derive(Clone, Debug)]
pub struct RitzPair {
    pub value: f64,
    /// `‖A y − θ y‖`: an eigenvalue of `A` lies within it of `value`.
    pub residual: f64,
    /// Unit vector in mass-weighted coordinates (`x = M^{1/2} q`).
    pub vector: Vec<f64>,
}

/// The result of [`lanczos_highest`].
#[derive(Clone, Debug)]
pub struct LanczosResult {
    /// The `wanted` largest Ritz pairs, largest first.
    pub pairs: Vec<RitzPair>,
    pub iterations: usize,
}

/// The largest eigenvalues of `operator` (module documentation: Lanczos with full
/// reorthogonalisation). Stops when the `wanted` largest have converged, at
/// `options.iterations`, or when the Krylov space is invariant (β = 0: every Ritz value
/// exact).
pub fn lanczos_highest(
    operator: &mut ConstrainedHessian,
    forces: &mut ForceSplit,
    options: &LanczosOptions,
) -> LanczosResult {
    lanczos_highest_with(operator, forces, options, &mut |_, _| {})
}

/// [`lanczos_highest`], calling `progress(done, most)` after each iteration (`most`: the
/// iterations allowed; convergence may stop it sooner).
pub fn lanczos_highest_with(
    operator: &mut ConstrainedHessian,
    forces: &mut ForceSplit,
    options: &LanczosOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> LanczosResult {
    let n = operator.len();
    let mut rng = StdRng::seed_from_u64(options.seed);
    let mut start: Vec<f64> = (0..n).map(|_| StandardNormal.sample(&mut rng)).collect();
    operator.project(&mut start);
    let norm = dot(&start, &start).sqrt();
    start.iter_mut().for_each(|v| *v /= norm);
    let mut basis = vec![start];
    let (mut alpha, mut beta) = (Vec::new(), Vec::new());
    let mut w = vec![0.0; n];
    loop {
        let j = basis.len() - 1;
        operator.apply(forces, &basis[j], &mut w);
        alpha.push(dot(&basis[j], &w));
        for _ in 0..2 {
            for b in &basis {
                let c = dot(b, &w);
                w.iter_mut().zip(b).for_each(|(x, y)| *x -= c * y);
            }
        }
        let b = dot(&w, &w).sqrt();
        beta.push(b);
        progress(basis.len(), options.iterations.min(n));
        let scale = alpha.iter().map(|a| a.abs()).fold(0.0, f64::max);
        let done = basis.len() >= options.iterations.min(n) || b <= 1e-13 * scale;
        if done || (basis.len() % 10 == 0 && converged(&alpha, &beta, options)) {
            break;
        }
        basis.push(w.iter().map(|x| x / b).collect());
    }
    let ritz = ritz_pairs(&alpha, &beta, options.wanted);
    let pairs = ritz
        .into_iter()
        .map(|(value, residual, s)| {
            let mut vector = vec![0.0; n];
            for (v, c) in basis.iter().zip(s.iter()) {
                vector.iter_mut().zip(v).for_each(|(x, y)| *x += c * y);
            }
            RitzPair {
                value,
                residual,
                vector,
            }
        })
        .collect();
    LanczosResult {
        pairs,
        iterations: alpha.len(),
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Whether the `wanted` largest Ritz values of `T` have residual ≤ tolerance × θ_max.
fn converged(alpha: &[f64], beta: &[f64], options: &LanczosOptions) -> bool {
    let pairs = ritz_pairs(alpha, beta, options.wanted);
    let top = pairs.first().map_or(0.0, |p| p.0.abs());
    pairs.len() == options.wanted.min(alpha.len())
        && pairs.iter().all(|p| p.1 <= options.tolerance * top)
}

/// The `wanted` largest eigenpairs of the tridiagonal `T` (diagonal `alpha`, off-diagonal
/// `beta[..k−1]`), each with its residual `β_k |s_k|` and its eigenvector `s`.
fn ritz_pairs(alpha: &[f64], beta: &[f64], wanted: usize) -> Vec<(f64, f64, Vec<f64>)> {
    let k = alpha.len();
    let t = DMatrix::from_fn(k, k, |r, c| match r.abs_diff(c) {
        0 => alpha[r],
        1 => beta[r.min(c)],
        _ => 0.0,
    });
    let eigen = SymmetricEigen::new(t);
    let mut order: Vec<usize> = (0..k).collect();
    order.sort_by(|&a, &b| eigen.eigenvalues[b].total_cmp(&eigen.eigenvalues[a]));
    order
        .into_iter()
        .take(wanted)
        .map(|i| {
            let s: Vec<f64> = eigen.eigenvectors.column(i).iter().copied().collect();
            (eigen.eigenvalues[i], (beta[k - 1] * s[k - 1]).abs(), s)
        })
        .collect()
}
