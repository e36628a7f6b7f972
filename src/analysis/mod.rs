//! Analysis of runs and methods: energy monitors, normal modes and resonance prediction,
//! minimisation, and step-size safety scans.

pub mod growth;
pub mod minimize;
pub mod modes;
pub mod monitor;
pub mod scan;
pub mod stability;
pub mod stiffness;
