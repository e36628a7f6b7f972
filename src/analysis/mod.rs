//! Analysis of runs and methods: normal modes and resonance prediction, minimisation,
//! step-size safety scans, and the configurational analysis of runs (g(r), block
//! averages, configurational temperature, bond geometry).

pub mod async_stability;
pub mod block_average;
pub mod configurational;
pub mod dihedrals;
pub mod geometry;
pub mod growth;
pub mod lanczos;
pub mod minimize;
pub mod modes;
pub mod pooled;
pub mod pooling;
pub mod rdf;
pub mod run_analysis;
pub mod run_dir;
pub mod stability;
pub mod stiffness;
pub mod term_energies;
pub mod trajectory_input;
pub mod work_precision;
