//! A cell list: points sorted into a grid of cells no narrower than a reach, so that every
//! pair of points closer than the reach (minimum image along the periodic axes) lies in
//! the same or neighbouring cells. The distance split's pair search
//! (`forces/distance_split/search.rs`) builds its Verlet list from it, and the radial
//! distribution functions (`analysis/rdf.rs`) count their pairs with it.
//!
//! A periodic axis spans the box and has at least 3 cells of side ≥ reach, or one cell;
//! an open axis spans the points' extent. Points are never moved, only their cell indices
//! are wrapped. Sorting is a counting sort (O(N + cells), points in index order within each
//! cell); visiting the neighbours of a point is O(points in 27 cells). Buffers are kept
//! between builds, so a rebuild allocates nothing once they have reached their size.

use super::MinimumImage;

/// Cells per axis are capped (an open system whose atoms fly apart still gets a bounded
/// grid: larger cells, more candidates per cell, the same pairs).
const MAX_CELLS_PER_AXIS: usize = 64;

/// The points binned into a grid of cells.
pub struct CellList {
    image: MinimumImage,
    /// Cells per axis, the grid's origin and the cells' sides.
    counts: [usize; 3],
    origin: [f64; 3],
    side: [f64; 3],
    cell_of: Vec<u32>,
    cell_start: Vec<u32>,
    cell_points: Vec<u32>,
    cursor: Vec<u32>,
}

impl CellList {
    /// An empty list for a box with edges `lengths` (`None`: open along every axis).
    pub fn new(lengths: Option<[f64; 3]>) -> Self {
        CellList {
            image: MinimumImage::new(lengths),
            counts: [1; 3],
            origin: [0.0; 3],
            side: [f64::MIN_POSITIVE; 3],
            cell_of: Vec::new(),
            cell_start: Vec::new(),
            cell_points: Vec::new(),
            cursor: Vec::new(),
        }
    }

    /// Cells per axis of the last [`CellList::build`].
    pub fn counts(&self) -> [usize; 3] {
        self.counts
    }

    /// Sort `points` into cells of side ≥ `reach` (module doc).
    pub fn build(&mut self, points: &[[f64; 3]], reach: f64) {
        self.grid(points, reach);
        let (n, counts) = (points.len(), self.counts);
        let total = counts.iter().product::<usize>();
        self.cell_of.resize(n, 0);
        self.cell_points.resize(n, 0);
        self.cell_start.clear();
        self.cell_start.resize(total + 1, 0);
        for (k, x) in points.iter().enumerate() {
            let cell = self.cell_at(*x);
            self.cell_of[k] = cell as u32;
            self.cell_start[cell + 1] += 1;
        }
        for c in 0..total {
            self.cell_start[c + 1] += self.cell_start[c];
        }
        // Points in index order within each cell.
        self.cursor.clear();
        self.cursor.extend_from_slice(&self.cell_start[..total]);
        for k in 0..n {
            let cell = self.cell_of[k] as usize;
            self.cell_points[self.cursor[cell] as usize] = k as u32;
            self.cursor[cell] += 1;
        }
    }

    /// Per axis the count, origin and side of the cells (module doc).
    fn grid(&mut self, points: &[[f64; 3]], reach: f64) {
        for axis in 0..3 {
            let period = self.image.period[axis];
            let (lo, hi) = if period > 0.0 {
                (0.0, period)
            } else {
                let along = points.iter().map(|x| x[axis]);
                along.fold((f64::MAX, f64::MIN), |(lo, hi), x| (lo.min(x), hi.max(x)))
            };
            let extent = (hi - lo).max(0.0);
            let cells = (extent / reach).floor();
            let cells = if cells.is_finite() { cells as usize } else { 1 };
            let cells = cells.clamp(1, MAX_CELLS_PER_AXIS);
            self.counts[axis] = if period > 0.0 && cells < 3 { 1 } else { cells };
            self.origin[axis] = lo;
            self.side[axis] = (extent / self.counts[axis] as f64).max(f64::MIN_POSITIVE);
        }
    }

    /// The cell of a position (wrapped into the box along the periodic axes).
    pub fn cell_at(&self, x: [f64; 3]) -> usize {
        let c: [usize; 3] = std::array::from_fn(|axis| {
            let c = if self.image.period[axis] > 0.0 {
                (self.image.wrapped(axis, x[axis]) / self.side[axis]).floor()
            } else {
                ((x[axis] - self.origin[axis]) / self.side[axis]).floor()
            };
            (c.max(0.0) as usize).min(self.counts[axis] - 1)
        });
        (c[0] * self.counts[1] + c[1]) * self.counts[2] + c[2]
    }

    /// The cell of point `k` of the last build.
    pub fn cell_of(&self, k: usize) -> usize {
        self.cell_of[k] as usize
    }

    /// `visit(b)` for every point `b` of `cell` and its neighbours (27 cells, each once:
    /// along a periodic axis of one cell, that cell once),
    /// cells in the order `dx, dy, dz ∈ {−1, 0, 1}`, points in index order within each.
    #[inline]
    pub fn for_each_near(&self, cell: usize, mut visit: impl FnMut(usize)) {
        let counts = self.counts;
        let own = [
            cell / (counts[1] * counts[2]),
            (cell / counts[2]) % counts[1],
            cell % counts[2],
        ];
        let periodic: [bool; 3] = std::array::from_fn(|a| self.image.period[a] > 0.0);
        let neighbour = |c: usize, offset: isize, axis: usize| -> Option<usize> {
            let m = counts[axis] as isize;
            let x = c as isize + offset;
            if periodic[axis] {
                // One cell (never 2, see `grid`): −1 and +1 name the own cell again.
                (m >= 3 || offset == 0).then_some(x.rem_euclid(m) as usize)
            } else if (0..m).contains(&x) {
                Some(x as usize)
            } else {
                None
            }
        };
        for dx in -1..=1 {
            let Some(x) = neighbour(own[0], dx, 0) else {
                continue;
            };
            for dy in -1..=1 {
                let Some(y) = neighbour(own[1], dy, 1) else {
                    continue;
                };
                for dz in -1..=1 {
                    let Some(z) = neighbour(own[2], dz, 2) else {
                        continue;
                    };
                    let other = (x * counts[1] + y) * counts[2] + z;
                    let range =
                        self.cell_start[other] as usize..self.cell_start[other + 1] as usize;
                    for &b in &self.cell_points[range] {
                        visit(b as usize);
                    }
                }
            }
        }
    }
}
