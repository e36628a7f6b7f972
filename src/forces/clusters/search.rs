//! The search for cluster pairs within reach, in phases per i-cluster and image shift: the
//! stencil (grid columns whose x-y distance from the shifted bounding box is within
//! reach), the candidate filter (the column's clusters in the z range, the half rule,
//! bounding-box distance) and packing (the pair mask, the entry). The candidates then go
//! through the atom-pair test of [`super::prune`] (SIMD over the 16 pairs) at the reach.

use super::{CLUSTER, Chunk, Entry, Geometry, Grid, PAD, PairList, ZERO_SHIFT};

/// Columns with more clusters than this are cut to the z range by bisection first.
const TALL: usize = 16;
/// Candidates per branch-free pass.
const BLOCK: usize = 32;

/// Mask bits `4a + b` with `b > a`: the pairs of a cluster with itself.
const UPPER: u16 = 0b0000_1000_1100_1110;

pub struct Search<'a> {
    pub grid: &'a Grid,
    pub geometry: &'a Geometry,
    pub reach: f64,
    pub excluded_start: &'a [u32],
    pub excluded: &'a [u32],
}

impl Search<'_> {
    /// The candidates of a chunk (into `chunk.inner`, its outer list's room until pruned):
    /// cluster pairs whose bounding boxes are within reach.
    pub fn chunk(&self, chunk: &mut Chunk) {
        let mut excluded = std::mem::take(&mut chunk.excluded);
        excluded.clear();
        excluded.resize(self.grid.clusters(), 0);
        let mut candidates = std::mem::take(&mut chunk.inner);
        candidates.clear();
        for ci in chunk.clusters.clone() {
            self.mark_excluded(ci, &mut excluded, true);
            for shift in 0..27 {
                if self.geometry.shift_allowed(shift) {
                    self.stencil(ci, shift, &excluded, &mut candidates);
                }
            }
            self.mark_excluded(ci, &mut excluded, false);
        }
        chunk.excluded = excluded;
        chunk.inner = candidates;
    }

    /// Set (or clear) in `bits[c_j]` the mask bits of the excluded pairs between `ci` and
    /// each cluster `c_j` (zero elsewhere), so the mask of a candidate costs one load.
    fn mark_excluded(&self, ci: usize, bits: &mut [u16], set: bool) {
        for a in 0..CLUSTER {
            let atom = self.grid.slots[ci * CLUSTER + a];
            if atom == PAD {
                continue;
            }
            let range = self.excluded_start[atom as usize] as usize
                ..self.excluded_start[atom as usize + 1] as usize;
            for &partner in &self.excluded[range] {
                let slot = self.grid.slot_of[partner as usize] as usize;
                let bit = 1 << (4 * a + slot % CLUSTER);
                if set {
                    bits[slot / CLUSTER] |= bit;
                } else {
                    bits[slot / CLUSTER] = 0;
                }
            }
        }
    }

    /// Stencil: the columns within reach of `ci`'s bounding box moved by the shift (a disc
    /// of columns in x-y), each cut to the clusters the half rule keeps; one entry for the
    /// j-clusters found there.
    fn stencil(&self, ci: usize, shift: usize, excluded: &[u16], list: &mut PairList) {
        let grid = self.grid;
        let s = &self.geometry.shifts[shift];
        let b = &grid.bounds[ci];
        let reach = self.reach;
        let [z_low, z_high] = grid.z_extent;
        if b.low[2] + s[2] - reach > z_high || b.high[2] + s[2] + reach < z_low {
            return;
        }
        let Some(xs) = self.column_range(b.low[0] + s[0] - reach, b.high[0] + s[0] + reach, 0)
        else {
            return;
        };
        let kept = self.kept(ci, shift);
        let start = list.j.len();
        for cx in xs {
            let gap_x = self.gap(b, s, cx, 0);
            let reach_y = (reach * reach - gap_x * gap_x).sqrt();
            let low = b.low[1] + s[1] - reach_y;
            let Some(ys) = self.column_range(low, b.high[1] + s[1] + reach_y, 1) else {
                continue;
            };
            for cy in ys {
                let gap_y = self.gap(b, s, cy, 1);
                let d2 = gap_x * gap_x + gap_y * gap_y;
                if d2 >= reach * reach {
                    continue;
                }
                let column = cx * grid.columns[1] + cy;
                let clusters =
                    grid.column_start[column] as usize..grid.column_start[column + 1] as usize;
                for range in &kept {
                    let (from, to) = (range.start.max(clusters.start), range.end.min(clusters.end));
                    if from < to {
                        self.candidates(ci, shift, from..to, d2, excluded, list);
                    }
                }
            }
        }
        let end = list.j.len();
        if end > start {
            list.entries.push(Entry {
                ci: ci as u32,
                shift: shift as u32,
                start: start as u32,
                end: end as u32,
            });
        }
    }

    /// Columns along `axis` that overlap `[low, high]`, if any.
    fn column_range(
        &self,
        low: f64,
        high: f64,
        axis: usize,
    ) -> Option<std::ops::RangeInclusive<usize>> {
        let grid = self.grid;
        let low = (low - grid.origin[axis]) / grid.width[axis];
        let high = (high - grid.origin[axis]) / grid.width[axis];
        let count = grid.columns[axis];
        // NaN bounds (no atoms) fail both tests.
        if high.partial_cmp(&0.0).is_none_or(|o| o.is_lt())
            || low.partial_cmp(&(count as f64)).is_none_or(|o| o.is_ge())
        {
            return None;
        }
        Some(low.max(0.0) as usize..=(high as usize).min(count - 1))
    }

    /// Distance along `axis` between the shifted box and column `index`.
    fn gap(&self, b: &super::Bounds, s: &[f64; 3], index: usize, axis: usize) -> f64 {
        let low = self.grid.origin[axis] + index as f64 * self.grid.width[axis];
        let high = low + self.grid.width[axis];
        (low - (b.high[axis] + s[axis]))
            .max(b.low[axis] + s[axis] - high)
            .max(0.0)
    }

    /// The half rule of the module doc as (at most two) ranges of j-clusters: `c_j = c_i +
    /// d (mod N)` with `1 ≤ d` and `2d < N`, `2d = N` for `c_i < c_j`, and `d = 0` for the
    /// zero shift and those of index above it.
    fn kept(&self, ci: usize, shift: usize) -> [std::ops::Range<usize>; 2] {
        let n = self.grid.clusters();
        let first = ci + usize::from(shift < ZERO_SHIFT);
        let tie = n.is_multiple_of(2) && 2 * ci < n;
        let last = ci + (n - 1) / 2 + usize::from(tie);
        if last < n {
            [first..last + 1, 0..0]
        } else {
            [first.min(n)..n, 0..last + 1 - n]
        }
    }

    /// Candidate filter: the clusters `range` of one column (kept by the half rule) with
    /// bounding boxes within reach and a pair to compute. Tall columns are first cut to
    /// the z range by bisection (bounds along z rise with the index within a column);
    /// the rest is a branch-free pass over blocks of candidates.
    fn candidates(
        &self,
        ci: usize,
        shift: usize,
        range: std::ops::Range<usize>,
        d2_xy: f64,
        excluded: &[u16],
        list: &mut PairList,
    ) {
        let grid = self.grid;
        let s = &self.geometry.shifts[shift];
        let b = &grid.bounds[ci];
        let reach2 = self.reach * self.reach;
        let dz = (reach2 - d2_xy).sqrt();
        let (z_low, z_high) = (b.low[2] + s[2] - dz, b.high[2] + s[2] + dz);
        let bounds = &grid.bounds[range.clone()];
        let (first, last) = if range.len() > TALL {
            let first = bounds.partition_point(|other| other.high[2] < z_low);
            (
                first,
                bounds.partition_point(|other| other.low[2] <= z_high),
            )
        } else {
            let first = bounds
                .iter()
                .take_while(|other| other.high[2] < z_low)
                .count();
            let above = bounds
                .iter()
                .rev()
                .take_while(|other| other.low[2] > z_high)
                .count();
            (first, bounds.len() - above)
        };
        let range = range.start + first..range.start + last.max(first);
        let mut from = range.start;
        while from < range.end {
            let to = (from + BLOCK).min(range.end);
            let mut js = [0u32; BLOCK];
            let mut masks = [0u16; BLOCK];
            let mut kept = 0;
            for cj in from..to {
                let mask = self.mask(ci, cj, shift, excluded);
                js[kept] = cj as u32;
                masks[kept] = mask;
                kept += usize::from((b.distance2(s, &grid.bounds[cj]) < reach2) & (mask != 0));
            }
            list.j.extend_from_slice(&js[..kept]);
            list.masks.extend_from_slice(&masks[..kept]);
            from = to;
        }
    }

    /// Packing: the pairs to compute, without padding, excluded pairs, or `j ≤ i` within a
    /// cluster.
    fn mask(&self, ci: usize, cj: usize, shift: usize, excluded: &[u16]) -> u16 {
        // Filled rows spread to bit 4a each, times the filled columns (no carries).
        let rows = self.grid.filled[ci] as u16;
        let spread = (rows & 1) | (rows & 2) << 3 | (rows & 4) << 6 | (rows & 8) << 9;
        let mut mask = spread * self.grid.filled[cj] as u16;
        if ci == cj && shift == ZERO_SHIFT {
            mask &= UPPER;
        }
        mask & !excluded[cj]
    }
}
