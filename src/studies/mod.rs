//! Studies of methods: the step-size safety scan (`longstep scan steps`) as a library call.
//!
//! A [`StepScanPlan`] says what to scan — a scene, methods and outer steps (or a study file
//! of configurations), the run settings every point shares, the criterion — and
//! [`scan_steps`] runs it: builds every point once, slices a shard, runs each point's starts
//! in parallel, judges each ([`criterion`]: drift or sampling), finds each method's largest
//! safe step and times it, writes `scan.csv` and `timing.csv`, and returns a [`StepScan`].
//! The command line parses its flags into a plan, and prints and draws what comes back;
//! `examples/step_scan.rs` does the same from library code.
//!
//! Files: [`plan`] the plan and its checks against the scene; [`points`] the outer steps
//! and shards; [`scan`] running and judging one point, the safe steps and timings;
//! [`criterion`] the verdicts (drift, sampling); [`table`] the tables; [`steps`] the scan.

pub mod criterion;
pub mod plan;
pub mod points;
pub mod scan;
pub mod steps;
pub mod table;

pub use plan::{Criterion, StepScanPlan};
pub use steps::{SCAN_STEPS, StepScan, Unwatched, Watch, scan_steps};
