//! Binning: atoms into columns of an x-y grid, sorted along z in each column and cut into
//! clusters of four (the last cluster of a column padded), with a bounding box per cluster.
//! The column width makes a cluster about as tall as it is wide at the system's mean
//! density, `(4/ρ)^{1/3}` (GROMACS's nbnxm grid, Páll & Hess, Comput. Phys. Commun. 184,
//! 2641 (2013)).

use super::{Bounds, CLUSTER, Geometry, PAD};

/// At most this many columns along an axis (bounds memory for sparse open systems).
const MAX_COLUMNS: usize = 1024;

#[derive(Clone, Debug, Default)]
pub struct Grid {
    pub origin: [f64; 2],
    pub width: [f64; 2],
    pub columns: [usize; 2],
    /// Clusters of column `cx · ny + cy`: `column_start[c]..column_start[c + 1]`.
    pub column_start: Vec<u32>,
    /// The atom in each slot (four per cluster), [`PAD`] for padding.
    pub slots: Vec<u32>,
    /// The slot of each atom.
    pub slot_of: Vec<u32>,
    /// Bit `k` set where slot `k` of a cluster holds an atom.
    pub filled: Vec<u8>,
    /// Bounding box of each cluster's atoms at the build.
    pub bounds: Vec<Bounds>,
    /// The atoms' extent along z (the box along a periodic z).
    pub z_extent: [f64; 2],
    column_of: Vec<u32>,
    order: Vec<u32>,
}

impl Grid {
    pub fn clusters(&self) -> usize {
        self.bounds.len()
    }

    /// The most clusters `n` atoms can fill in this grid's columns: a column of `a` atoms
    /// makes `⌈a/4⌉ ≤ (a + 3)/4` clusters, and at most `min(columns, n)` columns hold atoms.
    pub fn max_clusters(&self, n: usize) -> usize {
        let columns = (self.columns[0] * self.columns[1]).min(n);
        (n + (CLUSTER - 1) * columns).div_ceil(CLUSTER)
    }

    /// Bin the wrapped positions `x` (`n × 3`).
    pub fn build(&mut self, x: &[f64], geometry: &Geometry) {
        self.layout(x, geometry);
        // Room for any later build in the same columns: the cluster count moves with the
        // atoms, and a run's rebuilds must not allocate.
        let most = self.max_clusters(x.len() / 3);
        super::reserve_total(&mut self.slots, most * CLUSTER);
        super::reserve_total(&mut self.filled, most);
        super::reserve_total(&mut self.bounds, most);
        self.bin(x);
        self.cut();
        self.bound(x);
    }

    /// Origin, width and count of the columns along x and y.
    fn layout(&mut self, x: &[f64], geometry: &Geometry) {
        let n = x.len() / 3;
        let mut span = [1.0f64; 3];
        let mut low = [0.0f64; 3];
        for axis in 0..3 {
            if geometry.periodic[axis] {
                span[axis] = geometry.lengths[axis];
            } else if n > 0 {
                let (lo, hi) = x
                    .iter()
                    .skip(axis)
                    .step_by(3)
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                        (lo.min(v), hi.max(v))
                    });
                low[axis] = lo;
                // A little wider than the atoms, so the highest falls inside the last column.
                span[axis] = ((hi - lo) * (1.0 + 1e-9)).max(1e-6);
            }
        }
        self.z_extent = [low[2], low[2] + span[2]];
        let density = n as f64 / (span[0] * span[1] * span[2]).max(1e-300);
        let target = (CLUSTER as f64 / density).cbrt();
        for axis in 0..2 {
            let count = (span[axis] / target).floor();
            let count = if count.is_finite() {
                (count as usize).clamp(1, MAX_COLUMNS)
            } else {
                1
            };
            self.columns[axis] = count;
            self.width[axis] = span[axis] / count as f64;
            self.origin[axis] = low[axis];
        }
    }

    /// Column of every atom, then the atoms in column order, each column sorted along z
    /// (ties by index, so the order depends on the positions only).
    fn bin(&mut self, x: &[f64]) {
        let n = x.len() / 3;
        let [nx, ny] = self.columns;
        let index = |v: f64, axis: usize| -> usize {
            let u = ((v - self.origin[axis]) / self.width[axis]).floor();
            if u >= 0.0 {
                (u as usize).min(self.columns[axis] - 1)
            } else {
                0
            }
        };
        self.column_of.clear();
        self.column_of.extend(
            x.chunks_exact(3)
                .map(|p| (index(p[0], 0) * ny + index(p[1], 1)) as u32),
        );
        // Counting sort: column_start temporarily holds atom offsets per column.
        self.column_start.clear();
        self.column_start.resize(nx * ny + 1, 0);
        for &c in &self.column_of {
            self.column_start[c as usize + 1] += 1;
        }
        for c in 0..nx * ny {
            self.column_start[c + 1] += self.column_start[c];
        }
        self.order.clear();
        self.order.resize(n, 0);
        self.slot_of.clear();
        self.slot_of
            .extend_from_slice(&self.column_start[..nx * ny]);
        for (i, &c) in self.column_of.iter().enumerate() {
            let next = &mut self.slot_of[c as usize];
            self.order[*next as usize] = i as u32;
            *next += 1;
        }
        for c in 0..nx * ny {
            let range = self.column_start[c] as usize..self.column_start[c + 1] as usize;
            self.order[range].sort_unstable_by(|&a, &b| {
                x[3 * a as usize + 2]
                    .total_cmp(&x[3 * b as usize + 2])
                    .then(a.cmp(&b))
            });
        }
    }

    /// Each column's atoms in fours: slots, the atom→slot map and the column→cluster ranges.
    fn cut(&mut self) {
        let columns = self.columns[0] * self.columns[1];
        let n = self.order.len();
        let mut clusters = 0;
        for c in 0..columns {
            let atoms = (self.column_start[c + 1] - self.column_start[c]) as usize;
            clusters += atoms.div_ceil(CLUSTER);
        }
        self.slots.clear();
        self.slots.resize(clusters * CLUSTER, PAD);
        self.slot_of.clear();
        self.slot_of.resize(n, 0);
        let mut cluster = 0;
        let mut atom_start = 0;
        for c in 0..columns {
            let atom_end = self.column_start[c + 1] as usize;
            self.column_start[c] = cluster as u32;
            for (k, &atom) in self.order[atom_start..atom_end].iter().enumerate() {
                let slot = cluster * CLUSTER + k;
                self.slots[slot] = atom;
                self.slot_of[atom as usize] = slot as u32;
            }
            cluster += (atom_end - atom_start).div_ceil(CLUSTER);
            atom_start = atom_end;
        }
        self.column_start[columns] = cluster as u32;
        self.filled.clear();
        self.filled
            .extend(self.slots.chunks_exact(CLUSTER).map(|slots| {
                (0..CLUSTER).fold(0u8, |bits, k| bits | (u8::from(slots[k] != PAD) << k))
            }));
    }

    fn bound(&mut self, x: &[f64]) {
        let clusters = self.slots.len() / CLUSTER;
        self.bounds.clear();
        self.bounds.extend((0..clusters).map(|c| {
            let mut b = Bounds::EMPTY;
            for &atom in &self.slots[c * CLUSTER..(c + 1) * CLUSTER] {
                if atom != PAD {
                    b.include(&x[3 * atom as usize..3 * atom as usize + 3]);
                }
            }
            b
        }));
    }
}
