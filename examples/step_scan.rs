//! A step-size safety scan from library code, as `longstep scan steps` runs it: load a
//! system, choose the methods and the outer steps, scan, and read the table.
//!
//! `cargo run --release --example step_scan` (about a second: 39 short runs of the
//! three-spring system).

use longstep::settings::{RunSpec, Value};
use longstep::studies::{StepScanPlan, Unwatched, scan_steps};

fn main() -> longstep::Result<()> {
    // The system: a scene file of particles, force terms and the level of each term
    // (the three-spring system of GSS98: a stiff spring on the inner level).
    let mut plan = StepScanPlan::new("systems/three-spring.toml");
    // The methods, and the run settings every point shares: 40 inner steps per outer
    // step h, runs of 100 time units, h from 0.1 to 0.7.
    plan.methods = ["impulse", "short-average", "long-average"]
        .map(String::from)
        .to_vec();
    plan.run = RunSpec {
        h: "0.1:0.7:0.05".parse().ok(),
        inner_steps: Some(40),
        t_end: Some(Value::Number(100.0)),
        ..RunSpec::default()
    };
    plan.repeats = 0; // no timings
    plan.quiet = true;
    plan.out = "out/example-step-scan".into();

    // Scan: every point judged by the drift of the energy its method conserves.
    let scan = scan_steps(&plan, &Unwatched)?;

    // Read the table (also written to out/example-step-scan/scan.csv).
    let table = &scan.table;
    let [method, h, status] = ["method", "h", "status"].map(|c| table.column(c));
    let (method, h, status) = (method?, h?, status?);
    for row in &table.rows {
        println!("{:<14} h = {:<5} {}", row[method], row[h], row[status]);
    }
    for safe in &scan.safe {
        let up_to = safe.safe_up_to.map_or("none".into(), |h| h.to_string());
        println!("{:<14} safe up to h = {up_to}", safe.method);
    }
    Ok(())
}
