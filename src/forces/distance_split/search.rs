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

/// Cells per axis are capped (an open system whose atoms fly apart still gets a bounded
/// grid: larger cells, more candidates per cell, the same pairs).
const MAX_CELLS_PER_AXIS: usize = 64;

use super::model::MinimumImage;

/// Cells per axis, the grid's origin and the cells' sides.
#[derive(Default)]
struct Grid {
    counts: [usize; 3],
    origin: [f64; 3],
    side: [f64; 3],
}

pub(super) struct PairSearch {
    reach: f64,
    skin: f64,
    image: MinimumImage,
    /// Point positions at the last build.
    reference: Vec<[f64; 3]>,
    built: bool,
    /// Listed pairs `a < b`.
    pub pairs: Vec<[u32; 2]>,
    // Cell-list scratch.
    cell_of: Vec<u32>,
    cell_start: Vec<u32>,
    cell_points: Vec<u32>,
    cursor: Vec<u32>,
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
            cell_of: vec![0; points],
            cell_start: Vec::new(),
            cell_points: vec![0; points],
            cursor: Vec::new(),
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
        let grid = self.grid();
        let counts = grid.counts;
        let reach2 = self.reach * self.reach;
        self.pairs.clear();
        // A periodic axis with fewer than 3 cells would visit a cell twice: all pairs then.
        let all_pairs = counts.iter().product::<usize>() == 1
            || (0..3).any(|a| self.image.period[a] > 0.0 && counts[a] == 1);
        if all_pairs {
            for a in 0..n {
                for b in a + 1..n {
                    self.consider(a, b, reach2);
                }
            }
        } else {
            self.bin(&grid);
            self.scan_cells(counts, reach2);
        }
        let room = self.pairs.len() + self.pairs.len() / 4;
        self.pairs.reserve(room.saturating_sub(self.pairs.len()));
        self.built = true;
    }

    #[inline(always)]
    fn consider(&mut self, a: usize, b: usize, reach2: f64) {
        let (x, y) = (self.reference[a], self.reference[b]);
        let d = self.image.of(std::array::from_fn(|k| y[k] - x[k]));
        if d[0] * d[0] + d[1] * d[1] + d[2] * d[2] < reach2 {
            self.pairs.push([a as u32, b as u32]);
        }
    }

    /// The cell grid: per axis the count, origin and side. A periodic axis spans the box
    /// and needs at least 3 cells of side ≥ `reach` (else one cell: all pairs, minimum
    /// image); an open axis spans the points' extent.
    fn grid(&self) -> Grid {
        let mut grid = Grid::default();
        for axis in 0..3 {
            let period = self.image.period[axis];
            let (lo, hi) = if period > 0.0 {
                (0.0, period)
            } else {
                let along = self.reference.iter().map(|x| x[axis]);
                along.fold((f64::MAX, f64::MIN), |(lo, hi), x| (lo.min(x), hi.max(x)))
            };
            let extent = (hi - lo).max(0.0);
            let cells = (extent / self.reach).floor();
            let cells = if cells.is_finite() { cells as usize } else { 1 };
            let cells = cells.clamp(1, MAX_CELLS_PER_AXIS);
            grid.counts[axis] = if period > 0.0 && cells < 3 { 1 } else { cells };
            grid.origin[axis] = lo;
            grid.side[axis] = (extent / grid.counts[axis] as f64).max(f64::MIN_POSITIVE);
        }
        grid
    }

    /// Cell index along `axis` of coordinate `x`.
    fn cell_index(&self, grid: &Grid, axis: usize, x: f64) -> usize {
        let (period, inverse) = (self.image.period[axis], self.image.inverse[axis]);
        let c = if period > 0.0 {
            let wrapped = x - period * (x * inverse).floor();
            (wrapped / grid.side[axis]).floor()
        } else {
            ((x - grid.origin[axis]) / grid.side[axis]).floor()
        };
        (c.max(0.0) as usize).min(grid.counts[axis] - 1)
    }

    /// Counting sort of the points into cells (`cell_start`, `cell_points`).
    fn bin(&mut self, grid: &Grid) {
        let (n, counts) = (self.reference.len(), grid.counts);
        let total = counts.iter().product::<usize>();
        self.cell_start.clear();
        self.cell_start.resize(total + 1, 0);
        for k in 0..n {
            let x = self.reference[k];
            let c: [usize; 3] = std::array::from_fn(|a| self.cell_index(grid, a, x[a]));
            let cell = (c[0] * counts[1] + c[1]) * counts[2] + c[2];
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

    /// Every point against the points of its own and the 26 neighbouring cells (distinct:
    /// a periodic axis has ≥ 3 cells), keeping partners `b > a`: each pair once.
    fn scan_cells(&mut self, counts: [usize; 3], reach2: f64) {
        let n = self.reference.len();
        let periodic: [bool; 3] = std::array::from_fn(|a| self.image.period[a] > 0.0);
        let neighbour = |c: usize, offset: isize, axis: usize| -> Option<usize> {
            let m = counts[axis] as isize;
            let x = c as isize + offset;
            if periodic[axis] {
                Some(x.rem_euclid(m) as usize)
            } else if (0..m).contains(&x) {
                Some(x as usize)
            } else {
                None
            }
        };
        for a in 0..n {
            let cell = self.cell_of[a] as usize;
            let own = [
                cell / (counts[1] * counts[2]),
                (cell / counts[2]) % counts[1],
                cell % counts[2],
            ];
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
                        for t in range {
                            let b = self.cell_points[t] as usize;
                            if b > a {
                                self.consider(a, b, reach2);
                            }
                        }
                    }
                }
            }
        }
    }
}
