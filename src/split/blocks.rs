//! One level cut into blocks of particles that none of its interactions crosses, so that
//! each block's gradient of the level can be computed on its own — for the fast level of a
//! box of small molecules, a whole inner loop of r-RESPA per block on its own thread.
//!
//! A block's gradient is the level's terms, in level order, each over its interactions in
//! the block in their order: every particle receives the additions of the full gradient
//! in the same order, so the blocks give the same bits as [`ForceSplit::gradient`].

use std::ops::Range;

use super::ForceSplit;
use crate::forces::ForceTerm;

/// The blocks of one level.
#[derive(Clone, Debug)]
pub struct Blocks {
    level: usize,
    /// Particles of each block (consecutive, together `0..n`).
    pub particles: Vec<Range<usize>>,
    /// Per block, per term of the level (in level order), its interactions in the block.
    interactions: Vec<Vec<Range<usize>>>,
}

impl Blocks {
    pub fn len(&self) -> usize {
        self.particles.len()
    }

    pub fn is_empty(&self) -> bool {
        self.particles.is_empty()
    }
}

/// Boundaries `b` (`0 < b < n`) that no interaction crosses (no interaction has
/// particles on both sides).
fn free_boundaries(spans: &[(usize, usize)], n: usize) -> Vec<bool> {
    let mut crossings = vec![0i64; n + 1];
    for &(low, high) in spans {
        crossings[low + 1] += 1;
        crossings[high + 1] -= 1;
    }
    let mut open = 0;
    crossings
        .iter()
        .map(|c| {
            open += c;
            open == 0
        })
        .collect()
}

/// About `target` blocks of equal size, each boundary moved up to the next free one.
fn cut(free: &[bool], n: usize, target: usize) -> Vec<Range<usize>> {
    let mut blocks = Vec::new();
    let mut start = 0;
    for k in 1..target {
        let mut b = (k * n / target).max(start + 1);
        while b < n && !free[b] {
            b += 1;
        }
        if b >= n {
            break;
        }
        blocks.push(start..b);
        start = b;
    }
    blocks.push(start..n);
    blocks
}

/// Each interaction's block (by its first particle) in order, as one range per block, if
/// the blocks come in order.
fn ranges(spans: &[(usize, usize)], blocks: &[Range<usize>]) -> Option<Vec<Range<usize>>> {
    let mut out = Vec::with_capacity(blocks.len());
    let mut k = 0;
    for block in blocks {
        let start = k;
        while k < spans.len() && block.contains(&spans[k].0) {
            k += 1;
        }
        out.push(start..k);
    }
    (k == spans.len()).then_some(out)
}

impl ForceSplit {
    /// `level` cut into about `target` blocks of `n` particles, if every term on it can
    /// compute a block's gradient, every interaction couples at least one particle, and
    /// each term lists its interactions block by block.
    pub fn blocks(&self, level: usize, n: usize, target: usize) -> Option<Blocks> {
        let terms: Vec<&dyn ForceTerm> = self.levels[level]
            .iter()
            .map(|&t| self.terms[t].term.as_ref())
            .collect();
        let mut spans_per_term = Vec::with_capacity(terms.len());
        for term in &terms {
            if !term.add_block_gradient(&[], &mut [], 0, 0..0) {
                return None;
            }
            let spans: Option<Vec<(usize, usize)>> = term
                .couplings()
                .iter()
                .map(|p| Some((*p.iter().min()?, *p.iter().max()?)))
                .collect();
            spans_per_term.push(spans?);
        }
        let all: Vec<(usize, usize)> = spans_per_term.iter().flatten().copied().collect();
        if all.iter().any(|&(_, high)| high >= n) {
            return None;
        }
        let particles = cut(&free_boundaries(&all, n), n, target);
        let per_term: Vec<Vec<Range<usize>>> = spans_per_term
            .iter()
            .map(|spans| ranges(spans, &particles))
            .collect::<Option<_>>()?;
        let interactions = (0..particles.len())
            .map(|b| per_term.iter().map(|r| r[b].clone()).collect())
            .collect();
        Some(Blocks {
            level,
            particles,
            interactions,
        })
    }

    /// `gradient = ∇V_level` of block `b`, `q` and `gradient` the block's slices (not
    /// counted: [`ForceSplit::count_block_gradients`] counts whole evaluations).
    pub fn block_gradient(&self, blocks: &Blocks, b: usize, q: &[f64], gradient: &mut [f64]) {
        gradient.fill(0.0);
        let first = blocks.particles[b].start;
        for (&t, range) in self.levels[blocks.level]
            .iter()
            .zip(&blocks.interactions[b])
        {
            self.terms[t]
                .term
                .add_block_gradient(q, gradient, first, range.clone());
        }
    }

    /// Count `times` evaluations of the blocks' level, as [`ForceSplit::gradient`] would.
    pub fn count_block_gradients(&mut self, blocks: &Blocks, times: u64) {
        for &t in &self.levels[blocks.level] {
            self.counts.interactions += times * self.terms[t].term.interaction_count() as u64;
        }
        self.counts.gradient[blocks.level] += times;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn boundaries_inside_an_interaction_are_not_free() {
        // Molecules {0, 1, 2}, {3, 4}, {5}: free boundaries at 3 and 5.
        let free = free_boundaries(&[(0, 1), (0, 2), (3, 4)], 6);
        assert_eq!(free[1..6], [false, false, true, false, true]);
        assert_eq!(cut(&free, 6, 3), vec![0..3, 3..5, 5..6]);
        assert_eq!(cut(&free, 6, 6), vec![0..3, 3..5, 5..6]);
        assert_eq!(cut(&free, 6, 1), vec![0..6]);
    }

    #[test]
    fn interactions_out_of_block_order_give_no_ranges() {
        let blocks = [0..3, 3..6];
        assert_eq!(
            ranges(&[(0, 1), (3, 4), (4, 5)], &blocks),
            Some(vec![0..1, 1..3])
        );
        assert_eq!(ranges(&[(3, 4), (0, 1)], &blocks), None);
    }
}
