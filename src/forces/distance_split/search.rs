//! The short part's own pair search: a Verlet list of point pairs closer than
//! `reach = r_out + skin` (points are the molecules' reference atoms, or the atoms), built
//! from a cell list and kept while no point has moved more than `skin / 2` since the build
//! (the minimum-image distance is a metric, so no pair can have come from beyond `reach`
//! to inside `r_out`). Distances are minimum-image in a periodic box; positions are never
//! wrapped (the integrators own them), only the cell indices are.
//!
//! The build is sequential and visits cells, points and neighbour cells in a fixed order,
//! so the list (and every sum over it) is the same at any thread count. Buffers keep 25 %
//! room after a build, so later builds allocate nothing once the list has reached its size.

use crate::forces::MinimumImage;
use crate::forces::cell_list::CellList;

pub(super) struct PairSearch {
    reach: f64,
    skin: f64,
    image: MinimumImage,
    /// Point positions at the last build.
    reference: Vec<[f64; 3]>,
    built: bool,
    /// Listed pairs `a < b`.
    pub pairs: Vec<[u32; 2]>,
    cells: CellList,
}

impl PairSearch {
    pub fn new(points: usize, reach: f64, skin: f64, lengths: Option<[f64; 3]>) -> Self {
        PairSearch {
            reach,
            skin,
            image: MinimumImage::new(lengths),
            reference: vec![[0.0; 3]; points],
            built: false,
            pairs: Vec::new(),
            cells: CellList::new(lengths),
        }
    }

    /// Build again at the next check, wherever the points are.
    pub fn invalidate(&mut self) {
        self.built = false;
    }

    /// The point positions at the last build (`None` before the first): the list is a
    /// function of them alone, so building at them again gives the same pairs in the same
    /// order.
    pub fn built_at(&self) -> Option<&[[f64; 3]]> {
        self.built.then_some(&self.reference[..])
    }

    /// Whether some point has moved more than `skin / 2` since the last build.
    pub fn needs_rebuild(&self, point: impl Fn(usize) -> [f64; 3]) -> bool {
        if !self.built {
            return true;
        }
        let limit = 0.25 * self.skin * self.skin;
        self.reference.iter().enumerate().any(|(k, r)| {
            let x = point(k);
            let d2: f64 = (0..3).map(|a| (x[a] - r[a]) * (x[a] - r[a])).sum();
            d2 > limit
        })
    }

    /// List every pair `a < b` of points closer than `reach`.
    pub fn build(&mut self, point: impl Fn(usize) -> [f64; 3]) {
        let n = self.reference.len();
        for k in 0..n {
            self.reference[k] = point(k);
        }
        self.cells.build(&self.reference, self.reach);
        let counts = self.cells.counts();
        let reach2 = self.reach * self.reach;
        self.pairs.clear();
        // A periodic axis with fewer than 3 cells has one: all pairs then.
        let all_pairs = counts.iter().product::<usize>() == 1
            || (0..3).any(|a| self.image.period[a] > 0.0 && counts[a] == 1);
        if all_pairs {
            for a in 0..n {
                for b in a + 1..n {
                    self.consider(a, b, reach2);
                }
            }
        } else {
            self.scan_cells(reach2);
        }
        let room = self.pairs.len() + self.pairs.len() / 4;
        self.pairs.reserve(room.saturating_sub(self.pairs.len()));
        self.built = true;
    }

    #[inline(always)]
    fn consider(&mut self, a: usize, b: usize, reach2: f64) {
        if within(&self.image, self.reference[a], self.reference[b], reach2) {
            self.pairs.push([a as u32, b as u32]);
        }
    }

    /// Every point against the points of its own and the 26 neighbouring cells (distinct:
    /// a periodic axis has ≥ 3 cells), keeping partners `b > a`: each pair once.
    fn scan_cells(&mut self, reach2: f64) {
        for a in 0..self.reference.len() {
            let (reference, image, pairs) = (&self.reference, &self.image, &mut self.pairs);
            let x = reference[a];
            self.cells.for_each_near(self.cells.cell_of(a), |b| {
                if b > a && within(image, x, reference[b], reach2) {
                    pairs.push([a as u32, b as u32]);
                }
            });
        }
    }
}

/// Whether points `x` and `y` are closer than `√reach2` (minimum image).
#[inline(always)]
fn within(image: &MinimumImage, x: [f64; 3], y: [f64; 3], reach2: f64) -> bool {
    let d = image.of(std::array::from_fn(|k| y[k] - x[k]));
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2] < reach2
}
