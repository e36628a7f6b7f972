//! Analysis of runs and methods: energy monitors now; stability maps and normal modes
//! join them.

pub mod monitor;
pub mod stability;
