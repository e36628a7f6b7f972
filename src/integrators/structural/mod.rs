//! Structural schemes ZD and ZDS (CFM25 sections 2–4): implicit, very high order block
//! methods that separate the *physical equations* (the Hamiltonian's derivatives at a
//! node, [`physics`]) from the *structural equations* (linear relations between the
//! values and derivatives at the `R + 1` nodes of a block, exact for polynomials,
//! [`coefficients`]), solved together by a fixed point ([`solver`]).
//!
//! * **ZD** (`structural-zd`, CFM25 2.1, 3.2.1, (18)–(19)): values and first derivatives,
//!   structural equations exact to degree `R + 1`. It is collocation at the `R + 1`
//!   equally spaced nodes of the block, so its order is that of the closed Newton–Cotes
//!   rule: `R + 2` for even `R` (CFM25's "order R + 2", with R = 2, 4, 6, 8) and `R + 1`
//!   for odd `R` (measured: `tests/structural.rs`).
//! * **ZDS** (`structural-zds`, CFM25 2.2, 3.2.2, (20)–(21)): values, first and second
//!   derivatives, exact to degree `2R + 2`: order `2(R + 1)`. The second derivatives use
//!   the force terms' Hessian-vector products.
//!
//! `--h` is the step `Δt` between nodes; `--block R`; the fixed point stops at the
//! relative update `--tol` (default [`DEFAULT_TOLERANCE`]) or fails after `--max-iter`
//! iterations (default [`DEFAULT_MAX_ITERATIONS`]) with a
//! [`StepFailure`](crate::integrators::StepFailure) naming the time.
//! Each `step` advances one node; a block is solved when its first node is needed.
//! Cost per step: `k + 1` gradient evaluations of every level for a block solved in `k`
//! iterations (the `+1` is the predictor), and for ZDS as many Hessian-vector products
//! ([`solver`]); `energy.csv` gets the iteration count of each block (`iterations`).
//!
//! Separable and non-separable Hamiltonians: the physical equations take
//! `H = Σ|p − eA(x)|²/2m + V(x)`, so a scene with a magnetic term (CFM25 5.7) runs with
//! the same code; the state keeps the kinetic momentum and the scheme works in the
//! canonical one ([`physics`]).

pub mod coefficients;
pub mod double_double;
pub mod physics;
pub mod schemes;
pub mod solver;

pub use schemes::{DEFAULT_MAX_ITERATIONS, DEFAULT_TOLERANCE, Structural, StructuralKind};
