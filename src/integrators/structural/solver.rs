//! The fixed-point block solver of CFM25 sections 2.3, 3.2 and 4.2.
//!
//! Given the state `(Zx_n, Zp_n)` and its derivatives `(D, S)` at the start of a block,
//! it finds the `R` nodes `n+1 … n+R` that satisfy the physical equations and the
//! structural equations (CFM25 (18)–(21)):
//!
//! * **initialisation**: a Taylor predictor node by node,
//!   `Z_{n+r} = Z_{n+r−1} + Δt D_{n+r−1} (+ Δt²/2 S_{n+r−1})`, then the physical
//!   equations at each predicted node;
//! * **iteration**: `bZ ← −(b_z⊗Z_n + b_d⊗D_n + b_s⊗S_n + B_d×bD + B_s×bS)` for `x` and
//!   `p` alike, then the physical equations at every node;
//! * **stopping**: when the update of the whole block is below `tol` relative to the
//!   block's size, for positions and momenta separately:
//!   `max|ΔZx| ≤ tol·max|Zx|` and `max|ΔZp| ≤ tol·max|Zp|`. CFM25 4.2 tests only
//!   `Zx_{n+R}` against an absolute tolerance (1e-30 in quadruple precision); relative
//!   norms over the block keep the test meaningful for momenta of any scale (the solar
//!   system's are 1e-8 of its positions). When `tol` is below what double precision can
//!   resolve, the iteration stalls at round-off, which a slowly contracting fixed point
//!   (contraction ρ near 1) amplifies by about `1/(1 − ρ)`. Two rules accept such a
//!   stall as convergence: an update no larger than `ROUNDOFF_FACTOR · ε` that no
//!   longer shrinks by half, or an update that has not reached a new minimum for
//!   `STALL_ITERATIONS` iterations after the minimum fell below `STALL_LEVEL` (far above
//!   ε, far below any error a structural scheme is run for). After `max_iter`
//!   iterations without either the block fails.
//!
//! One iteration costs `R` evaluations of `PE[1]` (`R` gradient evaluations of every force
//! level) and, for ZDS, `R` of `PE[2]` (`R` Hessian-vector products); the initialisation
//! costs the same. A block of `R` steps with `k` iterations thus costs `R(k + 1)`
//! gradient evaluations (and as many Hessian-vector products for ZDS): `k + 1` per step.

use super::coefficients::StructuralCoefficients;
use super::physics::PhysicalEquations;
use crate::split::ForceSplit;

/// Updates within this many ε (relative) that stop shrinking are round-off.
pub const ROUNDOFF_FACTOR: f64 = 1e3;
/// A smallest relative update below this that does not improve for
/// [`STALL_ITERATIONS`] iterations is round-off amplified by a slow contraction.
pub const STALL_LEVEL: f64 = 1e-10;
pub const STALL_ITERATIONS: u32 = 4;

/// The state at one node: position, momentum (canonical) and their derivatives.
pub struct Node<'a> {
    pub x: &'a [f64],
    pub p: &'a [f64],
    pub dx: &'a [f64],
    pub dp: &'a [f64],
    /// Second derivatives (ZDS only; empty for ZD).
    pub sx: &'a [f64],
    pub sp: &'a [f64],
}

/// Why a block failed.
#[derive(Clone, Debug, PartialEq)]
pub enum BlockFailure {
    /// No convergence within the iteration cap: the last relative update.
    NotConverged { iterations: u32, update: f64 },
    /// A non-finite value appeared (the iteration diverged).
    NonFinite { iterations: u32 },
}

pub struct BlockSolver {
    pub coefficients: StructuralCoefficients,
    /// The step `Δt`.
    pub h: f64,
    n: usize,
    tolerance: f64,
    max_iterations: u32,
    /// `B_d Δt`, `B_s Δt²`, `b_d Δt`, `b_s Δt²`.
    matrix_d: Vec<f64>,
    matrix_s: Vec<f64>,
    start_d: Vec<f64>,
    start_s: Vec<f64>,
    /// The block, node `r` (1-based `n + r`) at `[(r − 1)n, rn)`.
    pub zx: Vec<f64>,
    pub zp: Vec<f64>,
    pub dx: Vec<f64>,
    pub dp: Vec<f64>,
    pub sx: Vec<f64>,
    pub sp: Vec<f64>,
    next_x: Vec<f64>,
    next_p: Vec<f64>,
}

impl BlockSolver {
    pub fn new(
        coefficients: StructuralCoefficients,
        h: f64,
        n: usize,
        tolerance: f64,
        max_iterations: u32,
    ) -> Self {
        let r = coefficients.block;
        let second = coefficients.derivatives == 2;
        let scaled = |v: &[f64], factor: f64| v.iter().map(|c| c * factor).collect::<Vec<_>>();
        let block_buffer = || vec![0.0; r * n];
        let second_buffer = || if second { vec![0.0; r * n] } else { Vec::new() };
        BlockSolver {
            matrix_d: scaled(&coefficients.matrix_d, h),
            matrix_s: scaled(&coefficients.matrix_s, h * h),
            start_d: scaled(&coefficients.start_d, h),
            start_s: scaled(&coefficients.start_s, h * h),
            coefficients,
            h,
            n,
            tolerance,
            max_iterations,
            zx: block_buffer(),
            zp: block_buffer(),
            dx: block_buffer(),
            dp: block_buffer(),
            sx: second_buffer(),
            sp: second_buffer(),
            next_x: block_buffer(),
            next_p: block_buffer(),
        }
    }

    pub fn block(&self) -> usize {
        self.coefficients.block
    }

    fn second(&self) -> bool {
        self.coefficients.derivatives == 2
    }

    /// The physical equations at node `r` (0-based within the block).
    fn physical(&mut self, physics: &mut PhysicalEquations, forces: &mut ForceSplit, r: usize) {
        let range = r * self.n..(r + 1) * self.n;
        physics.first(
            forces,
            &self.zx[range.clone()],
            &self.zp[range.clone()],
            &mut self.dx[range.clone()],
            &mut self.dp[range.clone()],
        );
        if self.second() {
            physics.second(
                forces,
                &self.zx[range.clone()],
                &self.dx[range.clone()],
                &self.dp[range.clone()],
                &mut self.sx[range.clone()],
                &mut self.sp[range],
            );
        }
    }

    /// Solve the block that follows `start`. Returns the number of fixed-point
    /// iterations (the initialisation not counted).
    pub fn solve(
        &mut self,
        physics: &mut PhysicalEquations,
        forces: &mut ForceSplit,
        start: &Node<'_>,
    ) -> Result<u32, BlockFailure> {
        self.initialise(physics, forces, start);
        let mut history = UpdateHistory::new();
        for iteration in 1..=self.max_iterations {
            let update = self.structural_update(start);
            if !update.is_finite() {
                return Err(BlockFailure::NonFinite {
                    iterations: iteration,
                });
            }
            for r in 0..self.block() {
                self.physical(physics, forces, r);
            }
            if history.stop(update, self.tolerance) {
                return Ok(iteration);
            }
            if iteration == self.max_iterations {
                return Err(BlockFailure::NotConverged {
                    iterations: iteration,
                    update,
                });
            }
        }
        unreachable!("max_iterations is at least 1")
    }

    /// Initialisation: the Taylor predictor node after node, each followed by the
    /// physical equations (its derivatives feed the next node's prediction).
    fn initialise(
        &mut self,
        physics: &mut PhysicalEquations,
        forces: &mut ForceSplit,
        start: &Node<'_>,
    ) {
        let (n, h) = (self.n, self.h);
        let second = self.second();
        for r in 0..self.block() {
            let (before, this) = (r.checked_sub(1), r * n);
            for i in 0..n {
                let (x, p, dx, dp) = match before {
                    None => (start.x[i], start.p[i], start.dx[i], start.dp[i]),
                    Some(b) => {
                        let j = b * n + i;
                        (self.zx[j], self.zp[j], self.dx[j], self.dp[j])
                    }
                };
                let (mut nx, mut np) = (x + h * dx, p + h * dp);
                if second {
                    let (sx, sp) = match before {
                        None => (start.sx[i], start.sp[i]),
                        Some(b) => (self.sx[b * n + i], self.sp[b * n + i]),
                    };
                    nx += 0.5 * h * h * sx;
                    np += 0.5 * h * h * sp;
                }
                self.zx[this + i] = nx;
                self.zp[this + i] = np;
            }
            self.physical(physics, forces, r);
        }
    }

    /// One fixed-point step of the structural equations: the new block from the
    /// derivatives, swapped in as the current one. Returns the relative update
    /// (the larger of positions' and momenta's; NaN if a value is not finite).
    fn structural_update(&mut self, start: &Node<'_>) -> f64 {
        for m in 0..self.block() {
            self.structural_row(start, m);
        }
        let update =
            relative_update(&self.next_x, &self.zx).max(relative_update(&self.next_p, &self.zp));
        std::mem::swap(&mut self.zx, &mut self.next_x);
        std::mem::swap(&mut self.zp, &mut self.next_p);
        update
    }

    /// Row `m` of the structural equations into `next_x`, `next_p`:
    /// `−(b_z Z_n + b_d D_n + b_s S_n + Σ_r B_d[m,r] D_r + B_s[m,r] S_r)`.
    fn structural_row(&mut self, start: &Node<'_>, m: usize) {
        let (n, block) = (self.n, self.block());
        let second = self.second();
        let row = m * n..(m + 1) * n;
        let (z, d) = (self.coefficients.start_z[m], self.start_d[m]);
        for i in 0..n {
            self.next_x[m * n + i] = -(z * start.x[i] + d * start.dx[i]);
            self.next_p[m * n + i] = -(z * start.p[i] + d * start.dp[i]);
        }
        if second {
            let s = self.start_s[m];
            for i in 0..n {
                self.next_x[m * n + i] -= s * start.sx[i];
                self.next_p[m * n + i] -= s * start.sp[i];
            }
        }
        for r in 0..block {
            let c = self.matrix_d[m * block + r];
            let (next_x, next_p) = (&mut self.next_x[row.clone()], &mut self.next_p[row.clone()]);
            let node = r * n..(r + 1) * n;
            for ((nx, np), (dx, dp)) in next_x
                .iter_mut()
                .zip(next_p.iter_mut())
                .zip(self.dx[node.clone()].iter().zip(&self.dp[node.clone()]))
            {
                *nx -= c * dx;
                *np -= c * dp;
            }
            if second {
                let c = self.matrix_s[m * block + r];
                for ((nx, np), (sx, sp)) in next_x
                    .iter_mut()
                    .zip(next_p.iter_mut())
                    .zip(self.sx[node.clone()].iter().zip(&self.sp[node]))
                {
                    *nx -= c * sx;
                    *np -= c * sp;
                }
            }
        }
    }
}

/// `max|next − current| / max|next|` (0 when nothing changed); NaN as soon as `next`
/// holds a non-finite value, since `f64::max` would skip a NaN.
fn relative_update(next: &[f64], current: &[f64]) -> f64 {
    let mut change = 0.0f64;
    let mut size = 0.0f64;
    for (a, b) in next.iter().zip(current) {
        if !a.is_finite() {
            return f64::NAN;
        }
        change = change.max((a - b).abs());
        size = size.max(a.abs());
    }
    if change == 0.0 { 0.0 } else { change / size }
}

/// The sizes of the updates so far, to accept convergence or a round-off stall.
struct UpdateHistory {
    previous: f64,
    smallest: f64,
    since_smallest: u32,
}

impl UpdateHistory {
    fn new() -> Self {
        Self {
            previous: f64::INFINITY,
            smallest: f64::INFINITY,
            since_smallest: 0,
        }
    }

    /// Records `update`; true when it is within `tolerance` or the iteration has
    /// stalled at round-off (the two rules of the module doc).
    fn stop(&mut self, update: f64, tolerance: f64) -> bool {
        let converged = update <= tolerance;
        if update < self.smallest {
            self.smallest = update;
            self.since_smallest = 0;
        } else {
            self.since_smallest += 1;
        }
        let at_roundoff = (update <= ROUNDOFF_FACTOR * f64::EPSILON
            && update > 0.5 * self.previous)
            || (self.smallest <= STALL_LEVEL && self.since_smallest >= STALL_ITERATIONS);
        self.previous = update;
        converged || at_roundoff
    }
}
