//! The ZD and ZDS integrators: the block solver behind the [`Integrator`] trait, one
//! node per step (see the module documentation of [`super`]).

use super::coefficients::StructuralCoefficients;
use super::physics::PhysicalEquations;
use super::solver::{BlockFailure, BlockSolver, Node};
use crate::error::{Error, Result};
use crate::integrators::integrator::{
    Integrator, StepFailure, restore_vector, state_from_json, state_to_json,
};
use crate::system::System;

/// Default relative tolerance of the fixed point: a few ulps above round-off.
pub const DEFAULT_TOLERANCE: f64 = 1e-14;
/// Default iteration cap of the fixed point.
pub const DEFAULT_MAX_ITERATIONS: usize = 100;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StructuralKind {
    /// Values and first derivatives.
    Zd,
    /// Values, first and second derivatives.
    Zds,
}

impl StructuralKind {
    /// Sixth order either way: ZD with R = 4, ZDS with R = 2.
    pub fn default_block(self) -> usize {
        match self {
            StructuralKind::Zd => 4,
            StructuralKind::Zds => 2,
        }
    }

    fn derivatives(self) -> usize {
        match self {
            StructuralKind::Zd => 1,
            StructuralKind::Zds => 2,
        }
    }

    /// The order of accuracy for block size `block`.
    pub fn order(self, block: usize) -> usize {
        match self {
            StructuralKind::Zd if block.is_multiple_of(2) => block + 2,
            StructuralKind::Zd => block + 1,
            StructuralKind::Zds => 2 * (block + 1),
        }
    }
}

pub struct Structural {
    kind: StructuralKind,
    h: f64,
    block: usize,
    tolerance: f64,
    max_iterations: usize,
    coefficients: StructuralCoefficients,
    solver: Option<BlockSolver>,
    physics: Option<PhysicalEquations>,
    /// The block's starting node (canonical momentum) and its derivatives.
    x: Vec<f64>,
    p: Vec<f64>,
    dx: Vec<f64>,
    dp: Vec<f64>,
    sx: Vec<f64>,
    sp: Vec<f64>,
    /// The next node of the current block to hand out; `block` when a new block is due.
    next_node: usize,
    last_iterations: u32,
    total_iterations: u64,
    blocks: u64,
    most_iterations: u32,
}

impl Structural {
    pub fn new(
        kind: StructuralKind,
        h: f64,
        block: usize,
        tolerance: f64,
        max_iterations: usize,
    ) -> Result<Self> {
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::setting("h", "step h must be positive and finite")
                .expected("a positive finite step")
                .got(h.to_string()));
        }
        if !(tolerance.is_finite() && tolerance > 0.0) {
            return Err(
                Error::setting("tol", "tolerance tol must be positive and finite")
                    .expected("a positive finite number")
                    .got(tolerance.to_string()),
            );
        }
        if max_iterations == 0 || max_iterations > u32::MAX as usize {
            return Err(Error::setting(
                "max_iter",
                format!("max_iter must be between 1 and {}", u32::MAX),
            )
            .expected(format!("1 to {}", u32::MAX))
            .got(max_iterations.to_string()));
        }
        let coefficients = StructuralCoefficients::new(block, kind.derivatives())?;
        Ok(Structural {
            kind,
            h,
            block,
            tolerance,
            max_iterations,
            coefficients,
            solver: None,
            physics: None,
            x: Vec::new(),
            p: Vec::new(),
            dx: Vec::new(),
            dp: Vec::new(),
            sx: Vec::new(),
            sp: Vec::new(),
            next_node: block,
            last_iterations: 0,
            total_iterations: 0,
            blocks: 0,
            most_iterations: 0,
        })
    }

    /// Fixed-point iterations over all blocks so far (initialisations not counted).
    pub fn total_iterations(&self) -> u64 {
        self.total_iterations
    }

    /// Blocks solved so far.
    pub fn blocks(&self) -> u64 {
        self.blocks
    }

    /// The most iterations any block needed.
    pub fn most_iterations(&self) -> u32 {
        self.most_iterations
    }

    pub fn coefficients(&self) -> &StructuralCoefficients {
        &self.coefficients
    }

    fn solve_block(&mut self, system: &mut System) -> Result<(), StepFailure> {
        let (Some(solver), Some(physics)) = (self.solver.as_mut(), self.physics.as_mut()) else {
            return Err(StepFailure(format!(
                "{} was stepped before setup",
                self.kind_name()
            )));
        };
        let start = Node {
            x: &self.x,
            p: &self.p,
            dx: &self.dx,
            dp: &self.dp,
            sx: &self.sx,
            sp: &self.sp,
        };
        match solver.solve(physics, &mut system.forces, &start) {
            Ok(iterations) => {
                self.last_iterations = iterations;
                self.total_iterations += iterations as u64;
                self.most_iterations = self.most_iterations.max(iterations);
                self.blocks += 1;
                Ok(())
            }
            Err(failure) => {
                let name = if self.kind == StructuralKind::Zd {
                    "structural-zd"
                } else {
                    "structural-zds"
                };
                Err(StepFailure(match failure {
                    BlockFailure::NotConverged { iterations, update } => format!(
                        "the fixed point of the block starting at t = {} did not converge \
                         in {iterations} iterations (last relative update {update:.3e}, \
                         tolerance {:e}); reduce --h or --block, or raise --max-iter",
                        system.state.t, self.tolerance
                    ),
                    BlockFailure::NonFinite { iterations } => format!(
                        "the fixed point of the block starting at t = {} diverged (a \
                         non-finite value after {iterations} iterations): {name} needs a \
                         smaller --h here",
                        system.state.t
                    ),
                }))
            }
        }
    }

    /// The block's starting node and its derivatives (`sx`, `sp` empty for ZD).
    fn start_node(&self) -> [Vec<f64>; 6] {
        [&self.x, &self.p, &self.dx, &self.dp, &self.sx, &self.sp].map(|v| v.to_vec())
    }

    /// The solved block while nodes of it remain to hand out (empty when a block is due).
    fn remaining_nodes(&self) -> [Vec<f64>; 6] {
        match &self.solver {
            Some(s) if self.next_node < self.block => {
                [&s.zx, &s.zp, &s.dx, &s.dp, &s.sx, &s.sp].map(|v| v.to_vec())
            }
            _ => Default::default(),
        }
    }

    fn kind_name(&self) -> &'static str {
        match self.kind {
            StructuralKind::Zd => "structural-zd",
            StructuralKind::Zds => "structural-zds",
        }
    }
}

impl Integrator for Structural {
    /// The block: its starting node and derivatives, the next node to hand out and, while
    /// some remain, the solved nodes and their derivatives (solving the block again in
    /// the continued run would evaluate forces over other pair lists than the first solve
    /// did); and the iteration counts (the `iterations` column is the last block's).
    fn save_state(&self) -> Result<serde_json::Value> {
        let (start, nodes) = (self.start_node(), self.remaining_nodes());
        let state = StructuralState {
            next_node: self.next_node,
            start,
            nodes,
            last_iterations: self.last_iterations,
            total_iterations: self.total_iterations,
            blocks: self.blocks,
            most_iterations: self.most_iterations,
        };
        state_to_json(self.name(), &state)
    }

    fn restore_state(&mut self, state: &serde_json::Value) -> Result<()> {
        let name = self.name();
        let state: StructuralState = state_from_json(name, state)?;
        if state.next_node > self.block {
            return Err(Error::input(format!(
                "the checkpoint's next node of {name} is {}, past its block of {}",
                state.next_node, self.block
            )));
        }
        let into = [
            &mut self.x,
            &mut self.p,
            &mut self.dx,
            &mut self.dp,
            &mut self.sx,
            &mut self.sp,
        ];
        restore_six(name, "block start", &state.start, into)?;
        if state.next_node < self.block {
            let Some(solver) = self.solver.as_mut() else {
                return Err(Error::input(format!("{name} restored before setup")));
            };
            let into = [
                &mut solver.zx,
                &mut solver.zp,
                &mut solver.dx,
                &mut solver.dp,
                &mut solver.sx,
                &mut solver.sp,
            ];
            restore_six(name, "block nodes", &state.nodes, into)?;
        }
        self.next_node = state.next_node;
        self.last_iterations = state.last_iterations;
        self.total_iterations = state.total_iterations;
        self.blocks = state.blocks;
        self.most_iterations = state.most_iterations;
        Ok(())
    }

    fn name(&self) -> &'static str {
        self.kind_name()
    }

    fn describe(&self) -> String {
        format!(
            "h = {}, R = {} (order {}), tol = {:e}, max_iter = {}",
            self.h,
            self.block,
            self.kind.order(self.block),
            self.tolerance,
            self.max_iterations
        )
    }

    fn outer_step(&self) -> f64 {
        self.h
    }

    fn setup(&mut self, system: &mut System) -> Result<()> {
        let n = system.n_dofs();
        let mut physics = PhysicalEquations::new(&system.inverse_mass, &system.forces);
        let second = self.kind == StructuralKind::Zds;
        let buffer = |on: bool| if on { vec![0.0; n] } else { Vec::new() };
        self.x = system.state.q.clone();
        self.p = vec![0.0; n];
        physics.to_canonical(&system.forces, &self.x, &system.state.p, &mut self.p);
        self.dx = vec![0.0; n];
        self.dp = vec![0.0; n];
        self.sx = buffer(second);
        self.sp = buffer(second);
        physics.first(
            &mut system.forces,
            &self.x,
            &self.p,
            &mut self.dx,
            &mut self.dp,
        );
        if second {
            physics.second(
                &mut system.forces,
                &self.x,
                &self.dx,
                &self.dp,
                &mut self.sx,
                &mut self.sp,
            );
        }
        self.solver = Some(BlockSolver::new(
            self.coefficients.clone(),
            self.h,
            n,
            self.tolerance,
            self.max_iterations as u32,
        ));
        self.physics = Some(physics);
        self.next_node = self.block;
        self.last_iterations = 0;
        self.total_iterations = 0;
        self.blocks = 0;
        self.most_iterations = 0;
        Ok(())
    }

    fn step(&mut self, system: &mut System) -> Result<(), StepFailure> {
        if self.next_node == self.block {
            self.solve_block(system)?;
            self.next_node = 0;
        }
        let (Some(solver), Some(physics)) = (self.solver.as_ref(), self.physics.as_mut()) else {
            return Err(StepFailure("stepped before setup".into()));
        };
        let n = self.x.len();
        let node = self.next_node * n..(self.next_node + 1) * n;
        system.state.q.copy_from_slice(&solver.zx[node.clone()]);
        physics.to_kinetic(
            &system.forces,
            &solver.zx[node.clone()],
            &solver.zp[node.clone()],
            &mut system.state.p,
        );
        system.state.t += self.h;
        self.next_node += 1;
        if self.next_node == self.block {
            // The block's last node starts the next block, with the derivatives the
            // converged iteration computed there.
            self.x.copy_from_slice(&solver.zx[node.clone()]);
            self.p.copy_from_slice(&solver.zp[node.clone()]);
            self.dx.copy_from_slice(&solver.dx[node.clone()]);
            self.dp.copy_from_slice(&solver.dp[node.clone()]);
            if self.kind == StructuralKind::Zds {
                self.sx.copy_from_slice(&solver.sx[node.clone()]);
                self.sp.copy_from_slice(&solver.sp[node]);
            }
        }
        Ok(())
    }

    fn extra_columns(&self) -> Vec<&'static str> {
        vec!["iterations"]
    }

    fn extra_values(&self, _system: &System, out: &mut Vec<f64>) {
        out.push(self.last_iterations as f64);
    }

    fn handles_magnetic(&self) -> bool {
        true
    }
}

/// What a checkpoint holds of ZD / ZDS ([`Structural`]'s `save_state`).
#[derive(serde::Serialize, serde::Deserialize)]
struct StructuralState {
    next_node: usize,
    /// `x, p, dx, dp, sx, sp` of the block's starting node.
    start: [Vec<f64>; 6],
    /// The solver's `zx, zp, dx, dp, sx, sp` over the block while nodes remain (else empty).
    nodes: [Vec<f64>; 6],
    last_iterations: u32,
    total_iterations: u64,
    blocks: u64,
    most_iterations: u32,
}

/// The six saved vectors of a block part (`x, p, dx, dp, sx, sp`) into `into`, each
/// refused by name when its length is not this system's.
fn restore_six(
    name: &str,
    part: &str,
    saved: &[Vec<f64>; 6],
    into: [&mut Vec<f64>; 6],
) -> Result<()> {
    const LABELS: [&str; 6] = ["x", "p", "dx", "dp", "sx", "sp"];
    for ((label, saved), into) in LABELS.iter().zip(saved).zip(into) {
        restore_vector(name, &format!("{part} {label}"), saved, into)?;
    }
    Ok(())
}
