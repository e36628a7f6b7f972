//! Block averages: means of correlated time series with honest error bars.
//!
//! A run's samples (energy rows, trajectory frames) are correlated over the system's
//! relaxation times, so the naive `σ/√N` understates the error of their mean. The run is cut
//! into `n` blocks of equal time; when each block is much longer than the correlation time
//! the block means are nearly independent and the standard error of the mean is
//! `√(Σ (B_i − B̄)² / (n (n − 1)))` over the block means `B_i`.
//!
//! Whether blocks are long enough is checked with the blocking transformation of
//! Flyvbjerg and Petersen (J. Chem. Phys. 91:461, 1989): the series is averaged in pairs
//! again and again; the error estimate `√(c₀/(m − 1))` (`c₀` the variance of the `m`
//! current values) rises with the block size until blocks are longer than the correlation
//! time and then stays on a plateau, within its own uncertainty `√(c₀/(m − 1))/√(2(m − 1))`.
//! [`blocks_long_enough`] asks whether a chosen error is on that plateau.
//!
//! A ratio of means (the configurational temperature `⟨|∇U|²⟩/⟨∇²U⟩`) takes its error from a
//! delete-one-block jackknife ([`ratio_of_means`]).

/// A mean and its standard error from `blocks` block means.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    pub mean: f64,
    pub error: f64,
    pub blocks: usize,
}

/// Mean and standard error of the mean from block means of equal weight (`n ≥ 2`; with
/// fewer the error is NaN).
pub fn from_block_means(means: &[f64]) -> Estimate {
    let n = means.len();
    let mean = means.iter().sum::<f64>() / n as f64;
    let error = if n >= 2 {
        let squares: f64 = means.iter().map(|b| (b - mean) * (b - mean)).sum();
        (squares / (n * (n - 1)) as f64).sqrt()
    } else {
        f64::NAN
    };
    Estimate {
        mean,
        error,
        blocks: n,
    }
}

/// `n` blocks of equal length over the times `[start, end]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Blocks {
    pub start: f64,
    pub end: f64,
    pub count: usize,
}

impl Blocks {
    pub fn length(&self) -> f64 {
        (self.end - self.start) / self.count as f64
    }

    /// The block of a sample at time `t`; `None` before `start` or after `end` (with a
    /// round-off tolerance, so samples at the ends count).
    pub fn index(&self, t: f64) -> Option<usize> {
        let tolerance = 1e-9 * (self.end - self.start).abs().max(f64::MIN_POSITIVE);
        if !(t >= self.start - tolerance && t <= self.end + tolerance) {
            return None;
        }
        let k = ((t - self.start) / self.length()).floor();
        Some((k.max(0.0) as usize).min(self.count - 1))
    }
}

/// Sums and counts per block for scalar samples (or, with `width > 1`, for vectors such
/// as a histogram per frame).
#[derive(Clone, Debug)]
pub struct BlockAccumulator {
    width: usize,
    sums: Vec<f64>,
    counts: Vec<usize>,
}

impl BlockAccumulator {
    pub fn new(blocks: usize, width: usize) -> Self {
        BlockAccumulator {
            width,
            sums: vec![0.0; blocks * width],
            counts: vec![0; blocks],
        }
    }

    pub fn add(&mut self, block: usize, value: f64) {
        self.sums[block * self.width] += value;
        self.counts[block] += 1;
    }

    pub fn add_vector(&mut self, block: usize, values: &[f64]) {
        debug_assert_eq!(values.len(), self.width);
        let row = &mut self.sums[block * self.width..(block + 1) * self.width];
        for (sum, value) in row.iter_mut().zip(values) {
            *sum += value;
        }
        self.counts[block] += 1;
    }

    pub fn counts(&self) -> &[usize] {
        &self.counts
    }

    /// The first block with no sample, if any.
    pub fn empty_block(&self) -> Option<usize> {
        self.counts.iter().position(|&c| c == 0)
    }

    /// Mean of block `block` (`width` values).
    pub fn block_mean(&self, block: usize) -> Vec<f64> {
        let count = self.counts[block].max(1) as f64;
        self.sums[block * self.width..(block + 1) * self.width]
            .iter()
            .map(|s| s / count)
            .collect()
    }

    /// Means of the scalar series per block.
    pub fn block_means(&self) -> Vec<f64> {
        (0..self.counts.len())
            .map(|b| self.sums[b * self.width] / self.counts[b].max(1) as f64)
            .collect()
    }

    /// Mean over every sample (not over blocks), `width` values.
    pub fn overall_mean(&self) -> Vec<f64> {
        let total = self.counts.iter().sum::<usize>().max(1) as f64;
        (0..self.width)
            .map(|k| {
                (0..self.counts.len())
                    .map(|b| self.sums[b * self.width + k])
                    .sum::<f64>()
                    / total
            })
            .collect()
    }

    /// The scalar estimate: mean over all samples, standard error from the block means.
    pub fn estimate(&self) -> Estimate {
        let mut estimate = from_block_means(&self.block_means());
        estimate.mean = self.overall_mean()[0];
        estimate
    }
}

/// One level of the Flyvbjerg–Petersen blocking transformation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlockingLevel {
    /// Samples per block at this level (1, 2, 4, …).
    pub block_size: usize,
    pub blocks: usize,
    /// `√(c₀/(m − 1))`: the standard error of the mean if these blocks were independent.
    pub error: f64,
    /// Its own standard deviation, `error/√(2(m − 1))`.
    pub error_of_error: f64,
}

/// Flyvbjerg–Petersen levels of `values`, down to two blocks.
pub fn flyvbjerg_petersen(values: &[f64]) -> Vec<BlockingLevel> {
    let mut levels = Vec::new();
    let mut current: Vec<f64> = values.to_vec();
    let mut block_size = 1;
    while current.len() >= 2 {
        let m = current.len();
        let mean = current.iter().sum::<f64>() / m as f64;
        let c0 = current.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / m as f64;
        let error = (c0 / (m - 1) as f64).sqrt();
        levels.push(BlockingLevel {
            block_size,
            blocks: m,
            error,
            error_of_error: error / (2.0 * (m - 1) as f64).sqrt(),
        });
        current = current
            .chunks_exact(2)
            .map(|p| 0.5 * (p[0] + p[1]))
            .collect();
        block_size *= 2;
    }
    levels
}

/// Fewest blocks a blocking level needs to be trusted in [`blocks_long_enough`]: with fewer,
/// its error estimate is uncertain by more than a quarter (`1/√(2·7)` ≈ 0.27).
pub const MIN_TRUSTED_BLOCKS: usize = 8;

/// Is `error`, a standard error from `blocks` block means, on the plateau of the blocking
/// levels? It is not when some level with at least [`MIN_TRUSTED_BLOCKS`] blocks estimates
/// a larger error by more than twice the combined uncertainty of the two estimates
/// (`√(δ_level² + δ²)`, `δ = error/√(2(blocks − 1))`): then the blocks behind `error` were
/// shorter than the correlation time and the error bar is too small. A one-sided 2σ test
/// fails by chance with probability ≈ 2.3 % per level on the plateau.
pub fn blocks_long_enough(levels: &[BlockingLevel], error: f64, blocks: usize) -> bool {
    let own = error / (2.0 * (blocks.max(2) - 1) as f64).sqrt();
    levels
        .iter()
        .filter(|level| level.blocks >= MIN_TRUSTED_BLOCKS)
        .all(|level| level.error - error <= 2.0 * level.error_of_error.hypot(own))
}

/// `Σ numerator / Σ denominator` over blocks, with a delete-one-block jackknife error:
/// `σ² = (n − 1)/n Σ_i (θ_(i) − θ̄)²`, `θ_(i)` the ratio without block `i`.
pub fn ratio_of_means(numerator: &[f64], denominator: &[f64]) -> Estimate {
    let n = numerator.len();
    let (sum_num, sum_den): (f64, f64) = (numerator.iter().sum(), denominator.iter().sum());
    let mean = sum_num / sum_den;
    if n < 2 {
        return Estimate {
            mean,
            error: f64::NAN,
            blocks: n,
        };
    }
    let leave_out: Vec<f64> = (0..n)
        .map(|i| (sum_num - numerator[i]) / (sum_den - denominator[i]))
        .collect();
    let average = leave_out.iter().sum::<f64>() / n as f64;
    let squares: f64 = leave_out
        .iter()
        .map(|t| (t - average) * (t - average))
        .sum();
    Estimate {
        mean,
        error: ((n - 1) as f64 / n as f64 * squares).sqrt(),
        blocks: n,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_cover_the_interval_and_clamp_the_end() {
        let blocks = Blocks {
            start: 10.0,
            end: 20.0,
            count: 4,
        };
        assert_eq!(blocks.index(9.0), None);
        assert_eq!(blocks.index(10.0), Some(0));
        assert_eq!(blocks.index(12.49), Some(0));
        assert_eq!(blocks.index(12.5), Some(1));
        assert_eq!(blocks.index(20.0), Some(3));
        assert_eq!(blocks.index(20.5), None);
    }

    #[test]
    fn independent_block_means_give_the_textbook_error() {
        // Block means 1, 2, 3, 4: mean 2.5, sample variance 5/3, error √(5/3/4).
        let e = from_block_means(&[1.0, 2.0, 3.0, 4.0]);
        assert_eq!(e.mean, 2.5);
        assert!((e.error - (5.0f64 / 12.0).sqrt()).abs() < 1e-15);
    }

    #[test]
    fn jackknife_of_a_constant_ratio_is_exact() {
        let num = [2.0, 4.0, 6.0];
        let den = [1.0, 2.0, 3.0];
        let e = ratio_of_means(&num, &den);
        assert_eq!(e.mean, 2.0);
        assert!(e.error.abs() < 1e-15);
    }
}
