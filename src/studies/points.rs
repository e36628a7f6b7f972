//! The points of a step-size scan: the outer steps as the user writes them, and the slice of
//! the points one shard of a job array runs.

use crate::error::{Error, Result};
use crate::settings::Value;
use crate::units::Units;

/// `LO:HI:STEP` (inclusive, with a tolerance for the last point) or `A,B,C`; in a scene with
/// real units the values may carry time units (`1fs:10fs:0.25fs`).
pub fn parse_steps(text: &str, units: Units) -> Result<Vec<f64>> {
    let value = |s: &str| -> Result<f64> {
        let v: Value = s
            .parse()
            .map_err(|_| Error::flag("--h", "bad number").got(format!("\"{s}\"")))?;
        let x = v.evaluate_time(&Default::default(), "--h", units.time_units())?;
        if x <= 0.0 {
            return Err(Error::flag("--h", "--h: steps must be positive")
                .expected("positive steps")
                .got(x.to_string()));
        }
        Ok(x)
    };
    if text.contains(':') {
        let parts: Vec<&str> = text.split(':').collect();
        let [lo, hi, step] = parts.as_slice() else {
            return Err(Error::flag("--h", "--h expects LO:HI:STEP")
                .expected("LO:HI:STEP")
                .got(format!("\"{text}\"")));
        };
        let (lo, hi, step) = (value(lo)?, value(hi)?, value(step)?);
        if hi < lo {
            return Err(Error::flag(
                "--h",
                format!(
                    "--h {text}: the range is reversed (LO:HI:STEP runs from LO up to HI); did \
                 you mean {}:{}:{}?",
                    parts[1], parts[0], parts[2]
                ),
            ));
        }
        let count = ((hi - lo) / step + 1e-9).floor() as usize + 1;
        if count > 100_000 {
            return Err(Error::flag(
                "--h",
                format!("--h gives {count} steps; that is too many"),
            ));
        }
        // Round to 12 significant digits so 0.2 + 0.1·9 reads 1.1, not 1.1000000000000001.
        let round = |x: f64| format!("{x:.11e}").parse::<f64>().unwrap_or(x);
        Ok((0..count).map(|i| round(lo + i as f64 * step)).collect())
    } else {
        text.split(',').map(value).collect()
    }
}

/// Keep only the points of the `--shard k/n` slice (none given: all): those whose index is
/// `k − 1` modulo `n`.
pub fn keep_shard<T>(points: &mut Vec<(usize, T, f64)>, shard: Option<&str>) -> Result<()> {
    if let Some(shard) = shard {
        let (k, n) = parse_shard(shard)?;
        points.retain(|(index, _, _)| index % n == k);
    }
    Ok(())
}

/// `k/n` → (k − 1, n), checked.
pub fn parse_shard(text: &str) -> Result<(usize, usize)> {
    let bad = || {
        Error::flag("--shard", "--shard expects K/N with 1 ≤ K ≤ N")
            .expected("K/N with 1 ≤ K ≤ N")
            .got(format!("\"{text}\""))
    };
    let (k, n) = text.split_once('/').ok_or_else(bad)?;
    let (k, n): (usize, usize) = (
        k.trim().parse().map_err(|_| bad())?,
        n.trim().parse().map_err(|_| bad())?,
    );
    if k == 0 || n == 0 || k > n {
        return Err(bad());
    }
    Ok((k - 1, n))
}
