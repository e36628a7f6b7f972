//! Radial distribution functions `g_AB(r)` of element pairs in an orthorhombic periodic box.
//!
//! Distances are minimum-image, so `r_max` is at most half the shortest box edge (then
//! every pair within `r_max` is counted exactly once). One frame's histogram `n_k` of pair
//! distances in the shell `[r_k, r_k + Δr)` is normalised by the count an ideal gas at the
//! same pair density would give:
//!
//! `g(r_k) = n_k / (P/V · (4π/3)((r_k + Δr)³ − r_k³))`,
//!
//! with `V` the frame's box volume and `P` the number of pairs: `N_A N_B` for two
//! elements (each `(i ∈ A, j ∈ B)` once), `N_A(N_A − 1)/2` for one. When intramolecular
//! pairs are excluded, `P` counts only pairs in different molecules, so an ideal gas of
//! molecules still gives `g = 1`. Frames are averaged with equal weights.
//!
//! The first peak ([`first_peak`]) is the first bin, from small `r`, that is the largest of
//! its neighbourhood `±window` and at least half the global maximum (so a noisy rising flank
//! or a small shoulder is not taken); its position and height come from a least-squares
//! parabola through the bins within `±fit_half_width` of it, which removes most of the
//! upward bias of a maximum of noisy bins. Cost: `O(N_A + N_B)` per frame for a fixed
//! `r_max`: the second element's atoms in a cell list of cells no narrower than `r_max`
//! ([`crate::forces::cell_list`], the distance split's), each atom of the first against
//! the atoms of its 27 cells (rayon over the first element's atoms; counts are integers,
//! so the sum does not depend on the thread count or the order of the pairs).

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::forces::cell_list::CellList;
use crate::forces::minimum_image;

/// Most bins a g(r) may have (a bound on a user-given size).
pub const MAX_BINS: usize = 1_000_000;

/// Equal bins of width `bin_width` from 0 to `bins · bin_width`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RdfGrid {
    pub bin_width: f64,
    pub bins: usize,
}

impl RdfGrid {
    /// Bins of width `bin_width` up to `r_max` (the last bin may end a little short of
    /// `r_max`: bins are whole).
    pub fn new(r_max: f64, bin_width: f64) -> Result<Self, String> {
        if !(bin_width > 0.0 && bin_width.is_finite()) {
            return Err(format!("the bin width must be positive, got {bin_width}"));
        }
        if !(r_max > bin_width && r_max.is_finite()) {
            return Err(format!(
                "r_max ({r_max}) must be larger than the bin width ({bin_width})"
            ));
        }
        let bins = (r_max / bin_width * (1.0 + 1e-12)).floor();
        if bins > MAX_BINS as f64 {
            return Err(format!(
                "r_max / bin width = {bins} bins, more than {MAX_BINS}: use wider bins"
            ));
        }
        Ok(RdfGrid {
            bin_width,
            bins: bins as usize,
        })
    }

    pub fn r_max(&self) -> f64 {
        self.bins as f64 * self.bin_width
    }

    pub fn centre(&self, bin: usize) -> f64 {
        (bin as f64 + 0.5) * self.bin_width
    }

    /// `(4π/3)(r_{k+1}³ − r_k³)`.
    pub fn shell_volume(&self, bin: usize) -> f64 {
        let (r0, r1) = (
            bin as f64 * self.bin_width,
            (bin + 1) as f64 * self.bin_width,
        );
        4.0 / 3.0 * std::f64::consts::PI * (r1 * r1 * r1 - r0 * r0 * r0)
    }
}

/// The atoms of one element pair, and which molecule each atom is in when intramolecular
/// pairs are left out.
#[derive(Clone, Debug)]
pub struct PairSelection {
    /// `"O-O"`, `"O-H"`.
    pub name: String,
    first: Vec<usize>,
    second: Vec<usize>,
    same: bool,
    molecule_of: Option<Vec<usize>>,
    pairs: f64,
}

impl PairSelection {
    /// Atoms of elements `a` and `b` (`elements[i]` is atom `i`'s); `molecule_of` given,
    /// pairs within one molecule are excluded. Errors name a missing element.
    pub fn new(
        elements: &[String],
        a: &str,
        b: &str,
        molecule_of: Option<&[usize]>,
    ) -> Result<Self, String> {
        let of = |element: &str| -> Vec<usize> {
            (0..elements.len())
                .filter(|&i| elements[i] == element)
                .collect()
        };
        let (first, second) = (of(a), of(b));
        for (element, atoms) in [(a, &first), (b, &second)] {
            if atoms.is_empty() {
                let mut present: Vec<&str> = elements.iter().map(String::as_str).collect();
                present.sort_unstable();
                present.dedup();
                return Err(format!(
                    "no atom of element \"{element}\" (the atoms are {})",
                    present.join(", ")
                ));
            }
        }
        let same = a == b;
        let mut selection = PairSelection {
            name: format!("{a}-{b}"),
            first,
            second,
            same,
            molecule_of: molecule_of.map(<[usize]>::to_vec),
            pairs: 0.0,
        };
        selection.pairs = selection.count_pairs();
        if selection.pairs == 0.0 {
            return Err(format!(
                "{}: no pair of atoms is left (every pair is within one molecule)",
                selection.name
            ));
        }
        Ok(selection)
    }

    /// `P`: pairs counted by [`PairSelection::histogram`] over the whole box.
    fn count_pairs(&self) -> f64 {
        let (na, nb) = (self.first.len() as f64, self.second.len() as f64);
        let all = if self.same {
            na * (na - 1.0) / 2.0
        } else {
            na * nb
        };
        let Some(molecule) = &self.molecule_of else {
            return all;
        };
        // Intramolecular pairs: count partners per molecule.
        let mut in_second = std::collections::HashMap::<usize, f64>::new();
        for &j in &self.second {
            *in_second.entry(molecule[j]).or_default() += 1.0;
        }
        let intra: f64 = self
            .first
            .iter()
            .map(|&i| in_second.get(&molecule[i]).copied().unwrap_or(0.0))
            .sum();
        // For one element each atom meets itself once and every pair twice.
        let intra = if self.same { (intra - na) / 2.0 } else { intra };
        all - intra
    }

    pub fn pairs(&self) -> f64 {
        self.pairs
    }

    /// Add one frame's pair distances to `counts` (`grid.bins` entries). `q` is `n × 3`,
    /// `lengths` the box edges (minimum image on every axis). The second element's atoms
    /// go into a cell list, and each atom of the first meets only those in its own and
    /// the neighbouring cells: O(N) for a fixed `r_max`.
    pub fn histogram(&self, q: &[f64], lengths: [f64; 3], grid: &RdfGrid, counts: &mut [u64]) {
        let r_max2 = grid.r_max() * grid.r_max();
        let inverse_width = 1.0 / grid.bin_width;
        let position = |i: usize| [q[3 * i], q[3 * i + 1], q[3 * i + 2]];
        let points: Vec<[f64; 3]> = self.second.iter().map(|&j| position(j)).collect();
        let mut cells = CellList::new(Some(lengths));
        // Cells a relative 1e-9 wider than r_max: a pair just inside r_max whose cell
        // indices round (at ~1e-16) across a cell boundary is still in neighbouring cells.
        cells.build(&points, grid.r_max() * (1.0 + 1e-9));
        let partial = self
            .first
            .par_chunks(64)
            .enumerate()
            .fold(
                || vec![0u64; grid.bins],
                |mut local, (chunk_index, chunk)| {
                    for (offset, &i) in chunk.iter().enumerate() {
                        let ri = position(i);
                        // One element: `first` is `second`, each pair once (k after i).
                        let own = chunk_index * 64 + offset;
                        cells.for_each_near(cells.cell_at(ri), |k| {
                            let j = self.second[k];
                            let same_molecule =
                                self.molecule_of.as_ref().is_some_and(|m| m[i] == m[j]);
                            if (self.same && k <= own) || same_molecule {
                                return;
                            }
                            let rj = position(j);
                            let mut s = 0.0;
                            for a in 0..3 {
                                let d = minimum_image(ri[a] - rj[a], lengths[a]);
                                s += d * d;
                            }
                            if s < r_max2 {
                                let bin = (s.sqrt() * inverse_width) as usize;
                                if bin < local.len() {
                                    local[bin] += 1;
                                }
                            }
                        });
                    }
                    local
                },
            )
            .reduce(
                || vec![0u64; grid.bins],
                |mut a, b| {
                    for (x, y) in a.iter_mut().zip(&b) {
                        *x += y;
                    }
                    a
                },
            );
        for (c, p) in counts.iter_mut().zip(&partial) {
            *c += p;
        }
    }

    /// `g` of one frame from its histogram `counts` in a box of volume `volume`.
    pub fn normalise(&self, counts: &[u64], volume: f64, grid: &RdfGrid, g: &mut [f64]) {
        let density = self.pairs / volume;
        for (k, (g, &n)) in g.iter_mut().zip(counts).enumerate() {
            *g = n as f64 / (density * grid.shell_volume(k));
        }
    }
}

/// A g(r) peak: position and height from the fitted parabola, and the highest bin's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Peak {
    pub position: f64,
    pub height: f64,
    pub bin: usize,
    pub bin_height: f64,
    /// Whether the parabola fit was used (false: it was not concave or its vertex fell
    /// outside the fitted bins, and the peak is the bin's).
    pub fitted: bool,
}

/// The first peak of `g` (see the module doc); `None` when `g` is zero everywhere.
pub fn first_peak(grid: &RdfGrid, g: &[f64], window: f64, fit_half_width: f64) -> Option<Peak> {
    let highest = g.iter().copied().fold(0.0, f64::max);
    if highest <= 0.0 || !highest.is_finite() {
        return None;
    }
    let reach = ((window / grid.bin_width).round() as usize).max(1);
    let bin = (0..g.len()).find(|&k| {
        let (lo, hi) = (k.saturating_sub(reach), (k + reach).min(g.len() - 1));
        g[k] >= 0.5 * highest && g[lo..=hi].iter().all(|&x| x <= g[k])
    })?;
    let half = ((fit_half_width / grid.bin_width).round() as usize).max(1);
    let (lo, hi) = (bin.saturating_sub(half), (bin + half).min(g.len() - 1));
    let centre = grid.centre(bin);
    let bin_peak = Peak {
        position: centre,
        height: g[bin],
        bin,
        bin_height: g[bin],
        fitted: false,
    };
    if hi - lo < 2 {
        return Some(bin_peak);
    }
    // Normal equations of g ≈ c0 + c1 x + c2 x², x = r − r_bin.
    let mut normal = Matrix3::zeros();
    let mut rhs = Vector3::zeros();
    for (k, &value) in g.iter().enumerate().take(hi + 1).skip(lo) {
        let x = grid.centre(k) - centre;
        let basis = Vector3::new(1.0, x, x * x);
        normal += basis * basis.transpose();
        rhs += basis * value;
    }
    let Some(c) = normal.lu().solve(&rhs) else {
        return Some(bin_peak);
    };
    let vertex = -c[1] / (2.0 * c[2]);
    let in_range = vertex.abs() <= (bin - lo).min(hi - bin) as f64 * grid.bin_width;
    if c[2] < 0.0 && in_range {
        Some(Peak {
            position: centre + vertex,
            height: c[0] - c[1] * c[1] / (4.0 * c[2]),
            fitted: true,
            ..bin_peak
        })
    } else {
        Some(bin_peak)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::StdRng;
    use rand::{RngExt, SeedableRng};

    /// Every pair against every other, as the histogram was before it had a cell list.
    fn all_pairs(
        selection: &PairSelection,
        q: &[f64],
        lengths: [f64; 3],
        grid: &RdfGrid,
    ) -> Vec<u64> {
        let mut counts = vec![0u64; grid.bins];
        for (at, &i) in selection.first.iter().enumerate() {
            let start = if selection.same { at + 1 } else { 0 };
            for &j in &selection.second[start..] {
                if selection.molecule_of.as_ref().is_some_and(|m| m[i] == m[j]) {
                    continue;
                }
                let s: f64 = (0..3)
                    .map(|a| minimum_image(q[3 * i + a] - q[3 * j + a], lengths[a]).powi(2))
                    .sum();
                let bin = (s.sqrt() / grid.bin_width) as usize;
                if s < grid.r_max() * grid.r_max() && bin < grid.bins {
                    counts[bin] += 1;
                }
            }
        }
        counts
    }

    /// The cell list finds every pair within `r_max` once: the counts equal the all-pairs
    /// loop's exactly (integers), for one element and two, with molecules left out, in
    /// boxes of 1 to 14 cells per axis (one cell: every pair), `r_max` up to half the
    /// shortest edge, and positions outside the box (never wrapped).
    #[test]
    fn cell_list_counts_are_the_all_pairs_counts() {
        let mut rng = StdRng::seed_from_u64(42);
        let elements: Vec<String> = (0..600).map(|i| ["O", "H", "H"][i % 3].into()).collect();
        let molecule_of: Vec<usize> = (0..600).map(|i| i / 3).collect();
        for (lengths, r_max) in [
            ([12.0, 12.0, 12.0], 6.0),
            ([12.0, 9.0, 15.0], 4.5),
            ([20.0, 20.0, 20.0], 3.3),
            ([10.0, 10.0, 30.0], 2.0),
        ] {
            let q: Vec<f64> = (0..1800)
                .map(|k| rng.random::<f64>() * 3.0 * lengths[k % 3] - lengths[k % 3])
                .collect();
            let grid = RdfGrid::new(r_max, 0.05).unwrap();
            for (a, b, molecules) in [
                ("O", "O", None),
                ("O", "H", Some(&molecule_of[..])),
                ("H", "H", Some(&molecule_of[..])),
            ] {
                let selection = PairSelection::new(&elements, a, b, molecules).unwrap();
                let mut counts = vec![0u64; grid.bins];
                selection.histogram(&q, lengths, &grid, &mut counts);
                let expected = all_pairs(&selection, &q, lengths, &grid);
                assert!(
                    expected.iter().sum::<u64>() > 100,
                    "{a}-{b} in {lengths:?}: too few pairs to test"
                );
                assert_eq!(counts, expected, "{a}-{b} in {lengths:?}, r_max {r_max}");
            }
        }
    }

    #[test]
    fn parabola_fit_recovers_a_parabolic_peak_between_bins() {
        // g = 3 − 10 (r − 2.013)²: the fit is exact for a parabola, wherever its vertex.
        let grid = RdfGrid::new(4.0, 0.02).unwrap();
        let g: Vec<f64> = (0..grid.bins)
            .map(|k| {
                let x = grid.centre(k) - 2.013;
                (3.0 - 10.0 * x * x).max(0.0)
            })
            .collect();
        let peak = first_peak(&grid, &g, 0.25, 0.1).unwrap();
        assert!(peak.fitted);
        assert!((peak.position - 2.013).abs() < 1e-10, "{peak:?}");
        assert!((peak.height - 3.0).abs() < 1e-10, "{peak:?}");
    }

    #[test]
    fn a_low_shoulder_before_the_peak_is_not_the_first_peak() {
        let grid = RdfGrid::new(6.0, 0.05).unwrap();
        let bump = |r: f64, at: f64, height: f64| height * (-(r - at).powi(2) / 0.02).exp();
        let g: Vec<f64> = (0..grid.bins)
            .map(|k| {
                let r = grid.centre(k);
                bump(r, 1.0, 0.3) + bump(r, 2.8, 3.0) + bump(r, 4.5, 1.2)
            })
            .collect();
        let peak = first_peak(&grid, &g, 0.25, 0.1).unwrap();
        assert!((peak.position - 2.8).abs() < 0.01, "{peak:?}");
    }
}
