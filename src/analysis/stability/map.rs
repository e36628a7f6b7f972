//! Stability maps: the spectral radius and instability type over a (Γ1, Γ2) grid.
//!
//! Points are numbered row by row, Γ1 slow and Γ2 fast: point `k` is
//! `(Γ1[k / n2], Γ2[k % n2])`, and the CSV rows follow that order. A shard `k/n` is the
//! contiguous block of points `[⌊(k−1)N/n⌋, ⌊kN/n⌋)`, so the shards' rows concatenated in
//! shard order are exactly the rows of the whole map.
//!
//! Evaluation goes block by block (in parallel within a block, with rayon), so a caller can
//! write and flush rows and advance a progress bar as blocks finish, in point order.

use std::collections::BTreeMap;
use std::ops::Range;

use rayon::prelude::*;

use super::analytic::LinearProblem;
use super::integrator::IntegratorProbe;
use super::{InstabilityType, StabilityPoint};
use crate::error::{Error, Result};
use crate::expr;

/// An evenly spaced closed interval of `count` values from `start` to `end`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Axis {
    pub start: f64,
    pub end: f64,
    pub count: usize,
}

impl Axis {
    pub fn new(start: f64, end: f64, count: usize, what: &str) -> Result<Self> {
        if !(start.is_finite() && end.is_finite()) {
            return Err(Error::flag(
                what,
                format!("{what}: the range {start}:{end} is not finite"),
            )
            .expected("a finite range START:END")
            .got_named(format!("{start}:{end}")));
        }
        if count == 0 {
            return Err(
                Error::flag(what, format!("{what}: at least one point is needed"))
                    .expected("at least one point"),
            );
        }
        if count > 1 && end <= start {
            return Err(Error::flag(
                what,
                format!(
                    "{what}: the range {start}:{end} is empty; give START:END with START < END"
                ),
            )
            .expected("START:END with START < END")
            .got_named(format!("{start}:{end}")));
        }
        Ok(Axis { start, end, count })
    }

    /// Parse `START:END` (numbers or expressions such as `4*pi`).
    pub fn parse(text: &str, count: usize, what: &str) -> Result<Self> {
        let Some((start, end)) = text.split_once(':') else {
            return Err(Error::flag(
                what,
                format!("{what}: expected a range START:END such as 0:6.5 or 0:4*pi"),
            )
            .expected("a range START:END")
            .got(format!("\"{}\"", text)));
        };
        let no_parameters = BTreeMap::new();
        let value = |part: &str| -> Result<f64> {
            expr::evaluate(part.trim(), &no_parameters).map_err(|e| {
                Error::flag(what, format!("{what}: {e}")).expected("a number or an expression")
            })
        };
        Axis::new(value(start)?, value(end)?, count, what)
    }

    /// The i-th value; the last one is `end` exactly.
    pub fn value(&self, i: usize) -> f64 {
        if self.count == 1 {
            return self.start;
        }
        if i + 1 == self.count {
            return self.end;
        }
        self.start + (self.end - self.start) * (i as f64) / ((self.count - 1) as f64)
    }

    /// Half the spacing (the half-width of a cell drawn around a value).
    pub fn half_step(&self) -> f64 {
        if self.count > 1 {
            0.5 * (self.end - self.start) / ((self.count - 1) as f64)
        } else {
            0.5
        }
    }
}

/// The (Γ1, Γ2) grid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid {
    pub gamma1: Axis,
    pub gamma2: Axis,
}

impl Grid {
    pub fn len(&self) -> usize {
        self.gamma1.count * self.gamma2.count
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// (Γ1, Γ2) of point `k`.
    pub fn point(&self, k: usize) -> (f64, f64) {
        let n2 = self.gamma2.count;
        (self.gamma1.value(k / n2), self.gamma2.value(k % n2))
    }
}

/// `--shard k/n`: the k-th of n contiguous slices (k from 1 to n).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl Shard {
    pub fn parse(text: &str) -> Result<Self> {
        let parsed = text.split_once('/').and_then(|(k, n)| {
            Some((
                k.trim().parse::<usize>().ok()?,
                n.trim().parse::<usize>().ok()?,
            ))
        });
        match parsed {
            Some((index, count)) if count >= 1 && (1..=count).contains(&index) => {
                Ok(Shard { index, count })
            }
            _ => Err(Error::flag(
                "--shard",
                "--shard: expected k/n with 1 <= k <= n (for example 2/8)",
            )
            .expected("k/n with 1 <= k <= n")
            .got(format!("\"{}\"", text))),
        }
    }

    /// The whole range as one shard.
    pub fn whole() -> Self {
        Shard { index: 1, count: 1 }
    }

    /// The points of this shard among `total`.
    pub fn range(&self, total: usize) -> Range<usize> {
        let bound = |k: usize| ((k as u128 * total as u128) / self.count as u128) as usize;
        bound(self.index - 1)..bound(self.index)
    }
}

/// What computes a point.
pub enum Evaluator {
    /// GSS98 Lemma 4 (exact reduced flow and averages).
    Analytic(LinearProblem),
    /// One outer step of an integrator from the registry.
    Integrator(Box<IntegratorProbe>),
}

impl Evaluator {
    pub fn point(&self, gamma1: f64, gamma2: f64) -> Result<StabilityPoint> {
        match self {
            Evaluator::Analytic(problem) => Ok(problem.point(gamma1, gamma2)),
            Evaluator::Integrator(probe) => probe.point(gamma1, gamma2),
        }
    }

    /// Points per block: enough work per block to keep the threads busy, small enough
    /// for a smooth progress bar and regular flushes.
    fn block_size(&self) -> usize {
        match self {
            Evaluator::Analytic(_) => 1 << 16,
            Evaluator::Integrator(_) => 64,
        }
    }
}

/// Evaluate the points `range` of `grid` in blocks; `sink(first, values)` receives each
/// block in order as it finishes.
pub fn evaluate<F>(
    evaluator: &Evaluator,
    grid: &Grid,
    range: Range<usize>,
    mut sink: F,
) -> Result<()>
where
    F: FnMut(usize, &[StabilityPoint]) -> Result<()>,
{
    let block = evaluator.block_size();
    let mut first = range.start;
    while first < range.end {
        let last = (first + block).min(range.end);
        let values = (first..last)
            .into_par_iter()
            .with_min_len(16)
            .map(|k| {
                let (gamma1, gamma2) = grid.point(k);
                evaluator.point(gamma1, gamma2)
            })
            .collect::<Result<Vec<_>>>()?;
        sink(first, &values)?;
        first = last;
    }
    Ok(())
}

/// Every point of the grid, in order.
pub fn evaluate_all(evaluator: &Evaluator, grid: &Grid) -> Result<Vec<StabilityPoint>> {
    let mut all = Vec::with_capacity(grid.len());
    evaluate(evaluator, grid, 0..grid.len(), |_, values| {
        all.extend_from_slice(values);
        Ok(())
    })?;
    Ok(all)
}

/// How many points of each type: `[stable, type 1, type 2, type 3, overflow]`.
pub fn census(points: &[StabilityPoint]) -> [usize; 5] {
    let mut counts = [0; 5];
    for point in points {
        let slot = match point.kind {
            InstabilityType::Stable => 0,
            InstabilityType::Type1 => 1,
            InstabilityType::Type2 => 2,
            InstabilityType::Type3 => 3,
            InstabilityType::Overflow => 4,
        };
        counts[slot] += 1;
    }
    counts
}
