//! Analysis of runs and methods: energy monitors, normal modes and resonance prediction,
//! minimisation, and step-size safety scans.

pub mod async_stability;
pub mod exact;
pub mod growth;
pub mod minimize;
pub mod modes;
pub mod monitor;
pub mod scan;
pub mod stability;
pub mod stiffness;
pub mod work_precision;
