//! Analysis of runs and methods: energy monitors now; stability maps and normal modes
//! join them.

pub mod async_stability;
pub mod exact;
pub mod monitor;
