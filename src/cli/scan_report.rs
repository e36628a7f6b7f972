//! The safe-step table of a step-size scan on the terminal, for `scan steps` and for the
//! merged shards of `merge`.

use crate::io::summary::format_time;
use crate::studies::Criterion;
use crate::studies::StepScan;
use crate::studies::scan::{SafeStep, Timing};
use crate::studies::table::per_day;
use crate::units::Units;

/// The end of a scan: its safe-step table, then how many runs (`12 runs`) took how long,
/// and where the results are.
pub(super) fn print_scan_end(scan: &StepScan) {
    print_safe_steps(
        &scan.safe,
        &|s| scan.steps_of(s),
        &scan.timings,
        scan.units,
        (scan.criterion, scan.shard.as_deref()),
    );
    let wall: f64 = scan.results.iter().map(|r| r.wall_seconds).sum();
    eprintln!(
        "{}, {wall:.1} s of run time; results in {}",
        scan.runs,
        scan.path.display()
    );
}

fn per_day_unit(units: Units) -> &'static str {
    match units {
        Units::Real => "ns/day",
        Units::None => "time units/day",
    }
}

/// The summary table: one line per method (per configuration of a study), with the
/// scanned steps of each (`steps`) for its islands.
pub(super) fn print_safe_steps(
    safe: &[SafeStep],
    steps: &dyn Fn(&SafeStep) -> Vec<f64>,
    timings: &[Timing],
    units: Units,
    (criterion, shard): (Criterion, Option<&str>),
) {
    // A shard's slice is not the answer: the largest safe step needs every point.
    if let Some(shard) = shard {
        println!(
            "shard {shard}: its points are in scan.csv; `longstep merge` the shards' outputs \
             for the safe-step table"
        );
        return;
    }
    let mut threads: Vec<usize> = timings.iter().map(|t| t.threads).collect();
    threads.sort_unstable();
    threads.dedup();
    let unit = per_day_unit(units);
    let heads: Vec<String> = threads
        .iter()
        .map(|n| format!("{unit} ({n} thr)"))
        .collect();
    let again = match criterion {
        Criterion::Drift => "stable again at",
        Criterion::Sampling => "passes again at",
    };
    let safe_head = match criterion {
        Criterion::Drift => "safe up to",
        Criterion::Sampling => "passes up to",
    };
    let label = |s: &SafeStep| s.config.clone().unwrap_or_else(|| s.method.clone());
    let width = safe
        .iter()
        .map(|s| label(s).chars().count())
        .fold(18, usize::max);
    let first = match safe.iter().any(|s| s.config.is_some()) {
        true => "configuration",
        false => "method",
    };
    let mut head = format!("{first:<width$} {:>12}  {:<24}", safe_head, "first failure");
    for h in &heads {
        head += &format!(" {h:>20}");
    }
    println!("{head}  {again}");
    for s in safe {
        let mut line = format!(
            "{:<width$} {:>12}  {:<24}",
            label(s),
            s.safe_up_to
                .map_or("none".to_string(), |h| format_time(h, units)),
            s.first_failure.map_or("-".to_string(), |(h, v)| format!(
                "{} at {}",
                v.name(),
                format_time(h, units)
            )),
        );
        for &n in &threads {
            let cell = timings
                .iter()
                .find(|t| t.method == s.method && t.config == s.config && t.threads == n)
                .map_or("-".to_string(), |t| {
                    crate::io::summary::significant(per_day(t.t_end, t.median_seconds, units), 4)
                });
            line += &format!(" {cell:>20}");
        }
        println!("{line}  {}", islands(&s.stable_beyond, &steps(s), units));
    }
}

/// Stable steps beyond the first failure as intervals of consecutive scanned steps,
/// e.g. "0.23–0.255, 0.27–0.305" (`7 fs, 9 fs–10 fs` in a real scene).
fn islands(stable: &[f64], scanned: &[f64], units: Units) -> String {
    let mut sorted: Vec<f64> = scanned.to_vec();
    sorted.sort_by(f64::total_cmp);
    let mut runs: Vec<(f64, f64)> = Vec::new();
    let mut previous: Option<usize> = None;
    for &h in stable {
        let position = sorted.iter().position(|&x| x == h);
        match (position, previous, runs.last_mut()) {
            (Some(i), Some(j), Some(run)) if i == j + 1 => run.1 = h,
            _ => runs.push((h, h)),
        }
        previous = position;
    }
    if runs.is_empty() {
        return "-".into();
    }
    runs.iter()
        .map(|(a, b)| {
            if a == b {
                format_time(*a, units)
            } else {
                format!("{}–{}", format_time(*a, units), format_time(*b, units))
            }
        })
        .collect::<Vec<_>>()
        .join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn islands_carry_the_time_unit_in_a_real_scene() {
        let scanned = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
        assert_eq!(
            islands(&[3.0, 4.0, 6.0], &scanned, Units::Real),
            "3 fs–4 fs, 6 fs"
        );
        assert_eq!(islands(&[3.0, 4.0, 6.0], &scanned, Units::None), "3–4, 6");
        assert_eq!(islands(&[], &scanned, Units::Real), "-");
    }
}
