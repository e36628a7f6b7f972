//! Integrators: one file per method family, all behind [`Integrator`].
//!
//! An integrator owns its step sizes and scratch buffers (sized once in
//! [`Integrator::setup`], so a step allocates nothing), advances the [`System`] state by
//! one outer step, and leaves the force-evaluation counts in the system's
//! [`ForceSplit`](crate::split::ForceSplit). Steps are named everywhere as `h` (the outer
//! step, at which the slowest forces are sampled) and `inner_steps` / `dt` (the inner step
//! `dt = h / inner_steps`) — never a bare "timestep".

pub mod adaptive_verlet;
pub mod async_pseudo_energy;
pub mod constrained;
pub mod equilibrium_molly;
pub mod impulse;
pub mod innermost;
pub mod integrator;
pub mod lane_exp;
pub mod langevin;
pub mod mollified;
pub mod pseudo_energy;
pub mod quadrature;
pub mod registry;
pub mod sinr;
pub mod structural;
pub mod verlet;

pub use adaptive_verlet::AdaptiveVerlet;
pub use async_pseudo_energy::AsyncPseudoEnergy;
pub use impulse::Impulse;
pub use pseudo_energy::PseudoEnergy;
pub use structural::{Structural, StructuralKind};
pub use verlet::VelocityVerlet;

pub use innermost::{InnermostStep, VerletStep};
pub use integrator::{Integrator, StepFailure, drift, kick};
pub use registry::{METHODS, MethodInfo, build};
