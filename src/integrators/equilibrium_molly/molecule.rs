//! One molecule's projection: its state, Newton, and the Jacobian product, with the KKT
//! solve done by whichever of [`Skyline`] and [`Schur`] is cheaper for its shape.
//!
//! Positions are kept as 3-vectors per atom whatever the scene's dimension (the unused
//! components stay zero, which changes no distance), so the inner loops are short and
//! fixed-length.

use super::MollyJacobian;
use super::kkt::Skyline;
use super::schur::{ANCHOR, Schur, Vector, dot};
use super::selection::{self, MoleculePlan};
use crate::system::PeriodicBox;

/// Why one molecule's projection failed.
#[derive(Clone, Copy, Debug)]
pub enum Failure {
    NotConverged {
        residual: f64,
        iterations: usize,
    },
    Singular {
        row: usize,
        iterations: usize,
    },
    /// Converged to a stationary point of the distance that is not a minimum.
    Saddle {
        iterations: usize,
    },
}

/// A factorization of the KKT matrix `[[K, Gᵀ], [G, 0]]`.
enum Solver {
    /// The whole matrix, `L D Lᵀ` in skyline storage (long chains: banded), with its
    /// right-hand side in KKT numbering.
    Skyline(Skyline, Vec<f64>),
    /// Through `K = K̂ ⊗ I` and the Schur complement (small molecules: water).
    Schur(Box<Schur>),
}

impl Solver {
    /// The cheaper solver for `plan`, by the multiply-adds of one factorization and solve.
    fn for_plan(plan: &MoleculePlan) -> Self {
        let skyline_cost: usize = (0..plan.kkt_size())
            .map(|i| {
                let length = i - plan.first[i];
                length * length / 2 + 2 * length
            })
            .sum();
        let (n, m) = (plan.atoms.len(), plan.constraints.len());
        if Schur::cost(n, m) <= skyline_cost {
            Solver::Schur(Box::new(Schur::new(n, m)))
        } else {
            Solver::Skyline(Skyline::new(plan.first.clone()), vec![0.0; plan.kkt_size()])
        }
    }
}

/// The state of one molecule's projection.
struct State {
    plan: MoleculePlan,
    /// Each constraint's atoms (the second is [`ANCHOR`] for an anchor).
    ends: Vec<[usize; 2]>,
    length2: Vec<f64>,
    /// Mass of each (local) atom.
    mass: Vec<f64>,
    /// `q` unwrapped along the breadth-first tree, the root at the origin.
    local: Vec<Vector>,
    /// `A` in the same frame.
    projected: Vec<Vector>,
    /// Anchor positions of anchored constraints in the same frame.
    anchors: Vec<Vector>,
    mu: Vec<f64>,
    /// `−F₁` and `−F₂` at the current iterate, then the Newton step; the right-hand side
    /// and solution of the Jacobian solve.
    atom_rhs: Vec<Vector>,
    constraint_rhs: Vec<f64>,
    dim: usize,
}

/// One molecule: its state, the KKT factorization of the last Newton iterate and, for the
/// projection Jacobian, the one without curvature at the solution.
pub struct MoleculeSolver {
    state: State,
    kkt: Solver,
    projection: Option<Solver>,
}

impl MoleculeSolver {
    pub fn new(plan: MoleculePlan, masses: &[f64], dim: usize, jacobian: MollyJacobian) -> Self {
        let (n, m) = (plan.atoms.len(), plan.constraints.len());
        let kkt = Solver::for_plan(&plan);
        let projection = (jacobian == MollyJacobian::Projection).then(|| Solver::for_plan(&plan));
        MoleculeSolver {
            state: State {
                ends: plan
                    .constraints
                    .iter()
                    .map(|c| [c.a, c.b.unwrap_or(ANCHOR)])
                    .collect(),
                length2: plan.constraints.iter().map(|c| c.length2).collect(),
                mass: plan.atoms.iter().map(|&i| masses[i]).collect(),
                local: vec![[0.0; 3]; n],
                projected: vec![[0.0; 3]; n],
                anchors: vec![[0.0; 3]; m],
                mu: vec![0.0; m],
                atom_rhs: vec![[0.0; 3]; n],
                constraint_rhs: vec![0.0; m],
                plan,
                dim,
            },
            kkt,
            projection,
        }
    }

    pub fn plan(&self) -> &MoleculePlan {
        &self.state.plan
    }

    /// Unwrap `q`, run Newton from `A = q`, `μ = 0`, and keep the factorization the
    /// Jacobian product needs. Returns the iterations and how many were fallback steps.
    pub fn project(
        &mut self,
        q: &[f64],
        periodic_box: Option<&PeriodicBox>,
        tolerance: f64,
        max_iterations: usize,
    ) -> Result<(usize, usize), Failure> {
        let state = &mut self.state;
        state.unwrap(q, periodic_box);
        state.projected.copy_from_slice(&state.local);
        state.mu.fill(0.0);
        let (iterations, fallbacks) = state.newton(&mut self.kkt, tolerance, max_iterations)?;
        if let Some(projection) = &mut self.projection {
            state
                .factor(projection, false)
                .map_err(|row| Failure::Singular { row, iterations })?;
        }
        Ok((iterations, fallbacks))
    }

    /// `A = q + (A_local − q_local)` for this molecule's atoms.
    pub fn write_back(&self, q: &[f64], out: &mut [f64]) {
        let s = &self.state;
        let dim = s.dim;
        for ((&atom, a), x) in s.plan.atoms.iter().zip(&s.projected).zip(&s.local) {
            for axis in 0..dim {
                let i = atom * dim + axis;
                out[i] = q[i] + (a[axis] - x[axis]);
            }
        }
    }

    /// `out = A_qᵀ v` on this molecule's atoms: `M x` with `[[K, Gᵀ], [G, 0]] [x; y] = [v; 0]`.
    pub fn transpose_product(&mut self, v: &[f64], out: &mut [f64]) {
        let s = &mut self.state;
        let dim = s.dim;
        for (&atom, r) in s.plan.atoms.iter().zip(&mut s.atom_rhs) {
            *r = [0.0; 3];
            r[..dim].copy_from_slice(&v[atom * dim..atom * dim + dim]);
        }
        s.constraint_rhs.fill(0.0);
        let solver = self.projection.as_mut().unwrap_or(&mut self.kkt);
        s.solve(solver);
        for ((&atom, r), m) in s.plan.atoms.iter().zip(&s.atom_rhs).zip(&s.mass) {
            for axis in 0..dim {
                out[atom * dim + axis] = m * r[axis];
            }
        }
    }
}

impl State {
    /// `local = q` unwrapped by minimum image along the tree, the root at the origin.
    fn unwrap(&mut self, q: &[f64], periodic_box: Option<&PeriodicBox>) {
        let dim = self.dim;
        let atoms = &self.plan.atoms;
        self.local[0] = [0.0; 3];
        for k in 1..atoms.len() {
            let p = self.plan.parent[k];
            let mut x = self.local[p];
            for (axis, x) in x.iter_mut().enumerate().take(dim) {
                let d = q[atoms[k] * dim + axis] - q[atoms[p] * dim + axis];
                *x += selection::wrap(periodic_box, axis, d);
            }
            self.local[k] = x;
        }
        for (c, &[a, b]) in self.ends.iter().enumerate() {
            if b == ANCHOR {
                let anchor = self.plan.constraints[c].anchor;
                let mut x = self.local[a];
                for (axis, x) in x.iter_mut().enumerate().take(dim) {
                    let d = anchor[axis] - q[atoms[a] * dim + axis];
                    *x += selection::wrap(periodic_box, axis, d);
                }
                self.anchors[c] = x;
            }
        }
    }

    /// `d_c = A_a − A_b` (or `A_a −` the anchor) of constraint `c`.
    #[inline]
    fn arm(&self, c: usize) -> Vector {
        let [a, b] = self.ends[c];
        let far = if b == ANCHOR {
            self.anchors[c]
        } else {
            self.projected[b]
        };
        let near = self.projected[a];
        [near[0] - far[0], near[1] - far[1], near[2] - far[2]]
    }

    /// `−(F₁, F₂)` into the right-hand sides at the current iterate; returns the largest
    /// relative residual, `|g_c|/d_c²` or `|F₁|/(m ℓ)`.
    fn residual(&mut self) -> f64 {
        for ((r, (a, x)), m) in self
            .atom_rhs
            .iter_mut()
            .zip(self.projected.iter().zip(&self.local))
            .zip(&self.mass)
        {
            *r = [-m * (a[0] - x[0]), -m * (a[1] - x[1]), -m * (a[2] - x[2])];
        }
        let mut worst: f64 = 0.0;
        for c in 0..self.ends.len() {
            let [a, b] = self.ends[c];
            let d = self.arm(c);
            let twice_mu = 2.0 * self.mu[c];
            let f = [twice_mu * d[0], twice_mu * d[1], twice_mu * d[2]];
            let ra = &mut self.atom_rhs[a];
            *ra = [ra[0] - f[0], ra[1] - f[1], ra[2] - f[2]];
            if b != ANCHOR {
                let rb = &mut self.atom_rhs[b];
                *rb = [rb[0] + f[0], rb[1] + f[1], rb[2] + f[2]];
            }
            let g = dot(&d, &d) - self.length2[c];
            self.constraint_rhs[c] = -g;
            worst = worst.max(g.abs() / self.length2[c]);
        }
        let length = self.plan.length_scale;
        for (r, m) in self.atom_rhs.iter().zip(&self.mass) {
            let largest = r[0].abs().max(r[1].abs()).max(r[2].abs());
            worst = worst.max(largest / (m * length));
        }
        if worst.is_nan() { f64::INFINITY } else { worst }
    }

    /// Factor `[[M + H_μ, Gᵀ], [G, 0]]` at the current iterate (`curvature = false`:
    /// without `H_μ`) into `solver`; returns its number of negative eigenvalues.
    fn factor(&self, solver: &mut Solver, curvature: bool) -> Result<usize, usize> {
        let mu = curvature.then_some(&self.mu[..]);
        match solver {
            Solver::Skyline(skyline, _) => {
                self.assemble(skyline, mu);
                skyline.factor()
            }
            Solver::Schur(schur) => schur
                .factor(&self.ends, &self.mass, mu, |c| self.arm(c), self.dim)
                .map_err(|failure| match failure {
                    Ok(atom) => self.plan.atom_row[atom],
                    Err(c) => self.plan.constraints[c].row,
                }),
        }
    }

    fn assemble(&self, kkt: &mut Skyline, mu: Option<&[f64]>) {
        let dim = self.dim;
        let plan = &self.plan;
        kkt.clear();
        for (k, &m) in self.mass.iter().enumerate() {
            for axis in 0..dim {
                let row = plan.atom_row[k] + axis;
                kkt.add(row, row, m);
            }
        }
        for (c, constraint) in plan.constraints.iter().enumerate() {
            let h = mu.map_or(0.0, |mu| 2.0 * mu[c]);
            let d = self.arm(c);
            for (axis, &d) in d.iter().enumerate().take(dim) {
                let ra = plan.atom_row[constraint.a] + axis;
                kkt.add(constraint.row, ra, 2.0 * d);
                kkt.add(ra, ra, h);
                if let Some(b) = constraint.b {
                    let rb = plan.atom_row[b] + axis;
                    kkt.add(constraint.row, rb, -2.0 * d);
                    kkt.add(rb, rb, h);
                    kkt.add(ra.max(rb), ra.min(rb), -h);
                }
            }
        }
    }

    /// Solve with `solver`'s factors, the right-hand sides in place.
    fn solve(&mut self, solver: &mut Solver) {
        match solver {
            Solver::Skyline(skyline, rhs) => {
                let (plan, dim) = (&self.plan, self.dim);
                for (k, r) in self.atom_rhs.iter().enumerate() {
                    rhs[plan.atom_row[k]..plan.atom_row[k] + dim].copy_from_slice(&r[..dim]);
                }
                for (constraint, r) in plan.constraints.iter().zip(&self.constraint_rhs) {
                    rhs[constraint.row] = *r;
                }
                skyline.solve(rhs);
                for (k, r) in self.atom_rhs.iter_mut().enumerate() {
                    r[..dim].copy_from_slice(&rhs[plan.atom_row[k]..plan.atom_row[k] + dim]);
                }
                for (constraint, r) in plan.constraints.iter().zip(&mut self.constraint_rhs) {
                    *r = rhs[constraint.row];
                }
            }
            Solver::Schur(schur) => schur.solve(&mut self.atom_rhs, &mut self.constraint_rhs),
        }
    }

    /// Newton iterations, inertia-corrected: a step is the full Newton step when the KKT
    /// matrix has the inertia of a minimum (as many negative eigenvalues as constraints,
    /// i.e. `K` positive definite on the tangent space), and otherwise the step with
    /// `K = M` (no curvature; a projection step that is always well defined). Near the
    /// solution every step is a full Newton step, so convergence is quadratic; far from
    /// it — a chain at its rest angles — the fallback keeps the iteration from wandering
    /// off to a maximum of the distance.
    fn newton(
        &mut self,
        kkt: &mut Solver,
        tolerance: f64,
        max_iterations: usize,
    ) -> Result<(usize, usize), Failure> {
        let constraints = self.ends.len();
        let mut residual = self.residual();
        let mut fallbacks = 0;
        for iteration in 0..=max_iterations {
            let factored = self.factor(kkt, true);
            let minimum = factored == Ok(constraints);
            if residual <= tolerance {
                return match factored {
                    Ok(_) if minimum => Ok((iteration, fallbacks)),
                    Ok(_) => Err(Failure::Saddle {
                        iterations: iteration,
                    }),
                    Err(row) => Err(Failure::Singular {
                        row,
                        iterations: iteration,
                    }),
                };
            }
            if iteration == max_iterations || !residual.is_finite() {
                return Err(Failure::NotConverged {
                    residual,
                    iterations: iteration,
                });
            }
            if !minimum {
                fallbacks += 1;
                self.factor(kkt, false).map_err(|row| Failure::Singular {
                    row,
                    iterations: iteration,
                })?;
            }
            self.solve(kkt);
            for (a, r) in self.projected.iter_mut().zip(&self.atom_rhs) {
                *a = [a[0] + r[0], a[1] + r[1], a[2] + r[2]];
            }
            for (mu, r) in self.mu.iter_mut().zip(&self.constraint_rhs) {
                *mu += r;
            }
            residual = self.residual();
        }
        unreachable!("the loop returns at its last iteration")
    }
}
