//! longstep: multiple-time-step molecular dynamics.
//!
//! Layout, in the order a run uses it: [`io::scene`] reads a scene into a
//! [`system::System`] whose [`forces`] terms the [`split`] puts on levels; an
//! [`integrators::Integrator`] advances it; [`run`] records energies and stops on a
//! blow-up; [`analysis`] holds observables and the analyses of methods; [`studies`] runs
//! the step-size scan; [`cli`] is the command line.
//!
//! Imports point down the layers: `error`, `units`, `expr`, `plot` < `settings` <
//! `forces` < `split` < `system` < `integrators` < `io` < `run` < `analysis` < `studies` <
//! `cli` (checked by `tests/layout.rs`).

pub mod analysis;
pub mod cli;
pub mod error;
pub mod expr;
pub mod forces;
pub mod integrators;
pub mod io;
pub mod plot;
pub mod run;
pub mod settings;
pub mod split;
pub mod studies;
pub mod system;
pub mod units;

pub use error::{Error, Result};
