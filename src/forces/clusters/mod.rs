//! Cluster-pair lists for the non-bonded term: GROMACS's nbnxm scheme (Páll & Hess, Comput.
//! Phys. Commun. 184, 2641 (2013)) with an exact buffer.
//!
//! **Clusters.** At a build, atoms are binned into columns of an x-y grid, sorted along z
//! and cut into clusters of four ([`grid`]). The order ignores Lennard-Jones: clusters of
//! atoms without it (GROMACS's nbnxm flags those) would have to be taller, and cost more
//! pairs than the kernel's skipped lanes save (module doc of forces/nonbonded/kernel.rs).
//! The list holds pairs of clusters (4 × 4 atom pairs) whose bounding boxes come closer
//! than the list reach `r_c + b_outer`, and of those only the ones with an atom pair within
//! reach ([`search`]); a 16-bit mask per cluster pair marks the atom pairs to compute (no
//! padding, no excluded pair, `j > i` within a cluster). The kernel then runs SIMD over the
//! 16 pairs of a cluster pair with no branch on a pair, computing only the register groups
//! that have a pair within the cutoff.
//!
//! **Rare rebuilds, dynamic pruning.** An atom pair's distance changes by at most the sum of
//! the two atoms' displacements, so a list built with buffer `b` holds every pair within
//! `r_c` while the two largest displacements since the build sum to less than `b`: that is
//! the rebuild test, exact (no pair is ever missed) and O(N). Between rebuilds the outer
//! list (buffer `b_outer`) is pruned to an inner list (buffer `b_inner < b_outer`) at the
//! current positions ([`prune`]), and the kernel runs over the inner list; the inner list
//! is pruned again when the displacements since the last pruning reach `b_inner`. A large
//! outer buffer makes builds rare, a small inner one keeps the kernel's pairs few.
//!
//! **Images.** Positions are never wrapped during a run (the integrators own them): at a
//! build each atom gets a fixed offset, a whole number of box lengths, that puts it into the
//! box, and evaluations subtract it. A list entry is an i-cluster with one of the 27 image
//! shifts (`−L, 0, +L` per periodic axis) and its j-clusters; a cluster pair may be listed
//! under two shifts in a box shorter than twice the reach, and since `r_c < L/2` at most one
//! image of an atom pair is within the cutoff. Excluded pairs are masked under every shift
//! (their other images lie beyond `L − r_excl > r_c`).
//!
//! **Each pair once, work balanced.** Of the two orders of a cluster pair the list keeps
//! `(c_i, c_j)` with `0 < (c_j − c_i) mod N < N/2` (a cyclic half: every cluster sees about
//! half of its neighbours, also across the periodic boundary), `c_i < c_j` for the tie, and
//! for `c_i = c_j` the zero shift (with `j > i`) and the shifts of index ≥ 13. The
//! i-clusters are split into a fixed number of chunks that depends only on the atom count;
//! each chunk has its own list and, in the force term, its own gradient buffer over the
//! window of clusters it touches, summed in chunk order: the same bits for any number of
//! threads.

mod grid;
mod prune;
mod search;

use rayon::prelude::*;

use super::simd::Isa;

pub use grid::Grid;

/// Atoms per cluster.
pub const CLUSTER: usize = 4;
/// An empty slot of a cluster.
pub const PAD: u32 = u32::MAX;
/// Where padding slots sit: far from everything, and finite in f32.
pub const PAD_POSITION: f64 = 1e9;
/// The index of the zero shift among the 27.
pub const ZERO_SHIFT: usize = 13;

/// Below this many atoms builds and pruning run on the calling thread.
pub const PARALLEL_MIN_ATOMS: usize = 256;

/// From this many atoms on, the per-atom passes run in parallel too: the displacement test,
/// the positions into clusters, and the reduction and its scatter to atoms (below, they are
/// a few microseconds).
pub const PARALLEL_PASSES_MIN_ATOMS: usize = 8 * PARALLEL_MIN_ATOMS;

/// Atoms per task of the displacement test.
const ATOM_BLOCK: usize = 1024;

/// Clusters per task of the positions into clusters.
const CLUSTER_BLOCK: usize = 256;

/// `top` keeps the two largest squared displacements seen, `top[0] ≥ top[1]` (a NaN counts
/// as infinite).
fn keep_two_largest(top: &mut [f64; 2], d2: f64) {
    if d2.is_nan() || d2 > top[1] {
        top[1] = if d2.is_nan() { f64::INFINITY } else { d2 };
        if top[1] > top[0] {
            top.swap(0, 1);
        }
    }
}

/// Positions and charges of a cluster's four atoms.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(32))]
pub struct Cluster<R> {
    pub x: [R; 4],
    pub y: [R; 4],
    pub z: [R; 4],
    pub q: [R; 4],
}

impl Cluster<f64> {
    /// The cluster rounded to f32 (`v as f32`, charges included): the lanes of the
    /// mixed-precision kernel and of the pruning.
    pub fn to_f32(&self) -> Cluster<f32> {
        let round = |a: [f64; 4]| a.map(|v| v as f32);
        Cluster {
            x: round(self.x),
            y: round(self.y),
            z: round(self.z),
            q: round(self.q),
        }
    }
}

/// Capacity for `total` elements in `v` (nothing happens when it has it already).
pub fn reserve_total<T>(v: &mut Vec<T>, total: usize) {
    if v.capacity() < total {
        v.reserve_exact(total - v.len());
    }
}

/// An axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    pub low: [f64; 3],
    pub high: [f64; 3],
}

impl Bounds {
    pub const EMPTY: Bounds = Bounds {
        low: [f64::INFINITY; 3],
        high: [f64::NEG_INFINITY; 3],
    };

    pub fn include(&mut self, p: &[f64]) {
        for (axis, &x) in p.iter().enumerate().take(3) {
            self.low[axis] = self.low[axis].min(x);
            self.high[axis] = self.high[axis].max(x);
        }
    }

    /// Squared distance between `self` moved by `shift` and `other` (0 if they overlap).
    #[inline]
    pub fn distance2(&self, shift: &[f64; 3], other: &Bounds) -> f64 {
        // Plain comparisons (not f64::max, whose NaN rules cost instructions): bounds are
        // finite.
        let larger = |a: f64, b: f64| if a > b { a } else { b };
        let mut d2 = 0.0;
        for (axis, &s) in shift.iter().enumerate() {
            let above = other.low[axis] - (self.high[axis] + s);
            let below = self.low[axis] + s - other.high[axis];
            let gap = larger(larger(above, below), 0.0);
            d2 += gap * gap;
        }
        d2
    }
}

/// The box and its image shifts.
#[derive(Clone, Copy, Debug)]
pub struct Geometry {
    /// Box lengths (infinite along open axes).
    pub lengths: [f64; 3],
    pub periodic: [bool; 3],
    /// Shift vectors by index `9(sx+1) + 3(sy+1) + (sz+1)`.
    pub shifts: [[f64; 3]; 27],
}

impl Geometry {
    pub fn new(lengths: Option<[f64; 3]>) -> Self {
        let lengths = lengths.unwrap_or([f64::INFINITY; 3]);
        let periodic = lengths.map(f64::is_finite);
        let shifts = std::array::from_fn(|index| {
            let s = [index / 9, (index / 3) % 3, index % 3];
            std::array::from_fn(|axis| {
                if periodic[axis] {
                    (s[axis] as f64 - 1.0) * lengths[axis]
                } else {
                    0.0
                }
            })
        });
        Geometry {
            lengths,
            periodic,
            shifts,
        }
    }

    /// Whether the shift of this index moves only along periodic axes.
    pub fn shift_allowed(&self, index: usize) -> bool {
        let s = [index / 9, (index / 3) % 3, index % 3];
        (0..3).all(|axis| self.periodic[axis] || s[axis] == 1)
    }
}

/// An i-cluster under one image shift and its j-clusters `start..end` of the list.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Entry {
    pub ci: u32,
    pub shift: u32,
    pub start: u32,
    pub end: u32,
}

/// Entries, j-clusters and their 16-bit pair masks (bit `4a + b`: i-atom `a`, j-atom `b`).
#[derive(Clone, Debug, Default)]
pub struct PairList {
    pub entries: Vec<Entry>,
    pub j: Vec<u32>,
    pub masks: Vec<u16>,
}

impl PairList {
    fn clear(&mut self) {
        self.entries.clear();
        self.j.clear();
        self.masks.clear();
    }

    /// Atom pairs marked in the masks.
    pub fn atom_pairs(&self) -> usize {
        self.masks.iter().map(|m| m.count_ones() as usize).sum()
    }
}

/// A fixed share of the i-clusters and their lists.
#[derive(Clone, Debug, Default)]
pub struct Chunk {
    pub clusters: std::ops::Range<usize>,
    pub outer: PairList,
    pub inner: PairList,
    /// The clusters this chunk touches: `window.0` and the `window.1 − 1` after it, cyclic.
    pub window: (usize, usize),
    /// Search scratch: mask bits of the current i-cluster's excluded pairs, by j-cluster.
    excluded: Vec<u16>,
    /// Atom pairs marked in `inner` (counted where it is pruned, in parallel).
    inner_pairs: usize,
}

impl Chunk {
    /// The window of the clusters the outer list touches (of `n`), and room for later
    /// builds so that they rarely allocate during a run.
    fn set_window(&mut self, n: usize) {
        let first = self.clusters.start;
        // `(c_j − first) mod n` for `c_j, first < n`, without a division per pair.
        let far = self
            .outer
            .j
            .iter()
            .map(|&cj| {
                let offset = cj as usize + n - first;
                if offset >= n { offset - n } else { offset }
            })
            .max()
            .map_or(0, |offset| offset + 1);
        self.window = (first, far.max(self.clusters.len()));
        let list = &mut self.outer;
        list.j.reserve(list.j.len() / 4);
        list.masks.reserve(list.masks.len() / 4);
        list.entries.reserve(list.entries.len() / 4);
    }
}

/// How many chunks for `n` atoms: a function of `n` only (module doc).
pub fn chunk_count(n: usize) -> usize {
    match n {
        0..256 => 1,
        256..2048 => 4,
        2048..8192 => 8,
        _ => 16,
    }
}

/// What an update did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refresh {
    Built,
    Pruned,
    Kept,
}

/// The list with its grid, buffers and the positions of the current evaluation.
#[derive(Clone, Debug)]
pub struct ClusterList {
    n: usize,
    cutoff: f64,
    outer_buffer: f64,
    inner_buffer: f64,
    pub geometry: Geometry,
    pub grid: Grid,
    /// Excluded partners per atom (CSR).
    excluded_start: Vec<u32>,
    excluded: Vec<u32>,
    charges: Vec<f64>,
    /// Per-atom whole-box offsets fixed at the last build.
    offsets: Vec<f64>,
    at_build: Vec<f64>,
    at_prune: Vec<f64>,
    /// Wrapped positions of the last update in cluster order, and charges.
    pub positions: Vec<Cluster<f64>>,
    /// The coordinates of `positions` in f32 at the last build or pruning (their lanes).
    lanes: Vec<Cluster<f32>>,
    pub chunks: Vec<Chunk>,
    built: bool,
    builds: u64,
    prunes: u64,
    wrapped: Vec<f64>,
    /// The instruction set of pruning.
    pub isa: Isa,
}

/// Rebuild or prune when the displacement sum reaches the buffer less this fraction of the
/// reach (room for the round-off of the distances compared at the build).
const ROUNDING_MARGIN: f64 = 1e-9;

impl ClusterList {
    /// A list for `n` atoms with a cutoff (infinite for none), an outer buffer (the scene's
    /// skin), the periodic box if any, excluded pairs per atom (CSR) and charges.
    pub fn new(
        cutoff: f64,
        skin: f64,
        lengths: Option<[f64; 3]>,
        excluded_start: Vec<u32>,
        excluded: Vec<u32>,
        charges: Vec<f64>,
    ) -> Self {
        let n = charges.len();
        let geometry = Geometry::new(lengths);
        let mut list = ClusterList {
            n,
            cutoff,
            outer_buffer: 0.0,
            inner_buffer: 0.0,
            geometry,
            grid: Grid::default(),
            excluded_start,
            excluded,
            charges,
            offsets: vec![0.0; 3 * n],
            at_build: vec![0.0; 3 * n],
            at_prune: vec![0.0; 3 * n],
            positions: Vec::new(),
            lanes: Vec::new(),
            chunks: vec![Chunk::default(); chunk_count(n)],
            built: false,
            builds: 0,
            prunes: 0,
            wrapped: vec![0.0; 3 * n],
            isa: Isa::best(),
        };
        list.set_buffers(skin, skin / 2.0);
        list
    }

    /// Outer and inner buffers (the inner at most the outer; the outer kept below the box
    /// so that the shifts −L, 0, +L reach every image within reach). Forces a rebuild.
    pub fn set_buffers(&mut self, outer: f64, inner: f64) {
        let mut outer = if self.cutoff.is_finite() {
            outer.max(0.0)
        } else {
            0.0
        };
        for axis in 0..3 {
            if self.geometry.periodic[axis] {
                let length = self.geometry.lengths[axis];
                outer = outer.min((0.999 * length - self.cutoff).max(0.0));
            }
        }
        self.outer_buffer = outer;
        self.inner_buffer = inner.clamp(0.0, outer);
        self.built = false;
    }

    pub fn cutoff(&self) -> f64 {
        self.cutoff
    }

    /// (outer, inner) buffers.
    pub fn buffers(&self) -> (f64, f64) {
        (self.outer_buffer, self.inner_buffer)
    }

    pub fn builds(&self) -> u64 {
        self.builds
    }

    pub fn prunes(&self) -> u64 {
        self.prunes
    }

    pub fn clusters(&self) -> usize {
        self.grid.clusters()
    }

    /// Whether the pair `i, j` is excluded.
    pub fn is_excluded(&self, i: usize, j: usize) -> bool {
        let range = self.excluded_start[i] as usize..self.excluded_start[i + 1] as usize;
        self.excluded[range].binary_search(&(j as u32)).is_ok()
    }

    /// The most clusters a build in the current grid can make ([`Grid::max_clusters`]).
    pub fn max_clusters(&self) -> usize {
        self.grid.max_clusters(self.n)
    }

    /// Atom pairs the kernel computes (masked pairs of the inner list).
    pub fn inner_pairs(&self) -> usize {
        self.chunks.iter().map(|c| c.inner_pairs).sum()
    }

    /// Atom pairs of the outer list.
    pub fn outer_pairs(&self) -> usize {
        self.chunks.iter().map(|c| c.outer.atom_pairs()).sum()
    }

    /// Make the list valid for positions `q` (`n × 3`) and fill [`ClusterList::positions`].
    pub fn update(&mut self, q: &[f64]) -> Refresh {
        debug_assert_eq!(q.len(), 3 * self.n);
        let (since_build, since_prune) = self.displacements(q);
        let reach = self.cutoff + self.outer_buffer;
        let margin = ROUNDING_MARGIN * if reach.is_finite() { reach } else { 1.0 };
        // A NaN displacement compares as not smaller: the list is rebuilt.
        let within = |d: f64, buffer: f64| d < buffer - margin;
        let refresh = if !self.built || !within(since_build, self.outer_buffer) {
            self.build(q);
            Refresh::Built
        } else if !within(since_prune, self.inner_buffer) {
            Refresh::Pruned
        } else {
            Refresh::Kept
        };
        if refresh != Refresh::Built {
            self.fill_positions(q);
        }
        if refresh != Refresh::Kept {
            self.at_prune.copy_from_slice(q);
            self.prunes += 1;
            self.prune();
        }
        refresh
    }

    /// The positions the lists were last built and last pruned at (`None` before the first
    /// build): all a checkpoint needs to make them again. A build is a function of its
    /// positions alone (offsets, the grid's z sort with ties by index, the search and its
    /// atom-pair test read nothing of the previous list), and a pruning a function of the
    /// outer list and its own positions.
    pub fn built_at(&self) -> Option<(&[f64], &[f64])> {
        self.built.then_some((&self.at_build, &self.at_prune))
    }

    /// Make the lists [`ClusterList::built_at`] gave in another run: build at `at_build`,
    /// then prune at `at_prune`, as [`ClusterList::update`] did there. The next update
    /// then keeps, prunes or rebuilds exactly where that run's did. An error says which
    /// array is wrong.
    pub fn restore(&mut self, at_build: &[f64], at_prune: &[f64]) -> Result<(), String> {
        for (name, q) in [("built_at", at_build), ("pruned_at", at_prune)] {
            if q.len() != 3 * self.n {
                return Err(format!(
                    "{name} has {} coordinates, this term has {} atoms ({} expected)",
                    q.len(),
                    self.n,
                    3 * self.n
                ));
            }
            if let Some(k) = q.iter().position(|x| !x.is_finite()) {
                return Err(format!("{name}[{k}] is not a finite number"));
            }
        }
        self.build(at_build);
        self.fill_positions(at_prune);
        self.at_prune.copy_from_slice(at_prune);
        self.prunes += 1;
        self.prune();
        Ok(())
    }

    /// The two largest displacements summed, since the build and since the pruning
    /// (infinite for a NaN position, which then rebuilds and fails loudly in the energy).
    /// Zero without a cutoff: every pair is listed and stays so.
    fn displacements(&self, q: &[f64]) -> (f64, f64) {
        if !self.built || !self.cutoff.is_finite() {
            return (if self.built { 0.0 } else { f64::INFINITY }, 0.0);
        }
        // The two largest values do not depend on the order they are met in: blocks of
        // atoms in parallel, merged, give the serial loop's result.
        let block = |(q, (at_build, at_prune)): (&[f64], (&[f64], &[f64]))| {
            let (mut build, mut prune) = ([0.0f64; 2], [0.0f64; 2]);
            for ((x, b), p) in q
                .chunks_exact(3)
                .zip(at_build.chunks_exact(3))
                .zip(at_prune.chunks_exact(3))
            {
                let d2 = |r: &[f64]| {
                    let d = [x[0] - r[0], x[1] - r[1], x[2] - r[2]];
                    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
                };
                keep_two_largest(&mut build, d2(b));
                keep_two_largest(&mut prune, d2(p));
            }
            (build, prune)
        };
        let merge = |(mut b, mut p): ([f64; 2], [f64; 2]), (b2, p2): ([f64; 2], [f64; 2])| {
            b2.into_iter().for_each(|d2| keep_two_largest(&mut b, d2));
            p2.into_iter().for_each(|d2| keep_two_largest(&mut p, d2));
            (b, p)
        };
        let len = 3 * ATOM_BLOCK;
        let (build, prune) = if self.n >= PARALLEL_PASSES_MIN_ATOMS {
            q.par_chunks(len)
                .zip(
                    self.at_build
                        .par_chunks(len)
                        .zip(self.at_prune.par_chunks(len)),
                )
                .map(block)
                .reduce(|| ([0.0; 2], [0.0; 2]), merge)
        } else {
            block((q, (&self.at_build, &self.at_prune)))
        };
        (
            build[0].sqrt() + build[1].sqrt(),
            prune[0].sqrt() + prune[1].sqrt(),
        )
    }

    /// Offsets, grid and the outer lists at positions `q`.
    fn build(&mut self, q: &[f64]) {
        self.at_build.copy_from_slice(q);
        for (k, (offset, &x)) in self.offsets.iter_mut().zip(q).enumerate() {
            let length = self.geometry.lengths[k % 3];
            *offset = if self.geometry.periodic[k % 3] {
                length * (x / length).floor()
            } else {
                0.0
            };
        }
        for ((w, &x), &offset) in self.wrapped.iter_mut().zip(q).zip(&self.offsets) {
            *w = x - offset;
        }
        self.grid.build(&self.wrapped, &self.geometry);
        let most = self.max_clusters();
        reserve_total(&mut self.positions, most);
        reserve_total(&mut self.lanes, most);
        for chunk in &mut self.chunks {
            reserve_total(&mut chunk.excluded, most);
        }
        self.fill_positions(q);
        let clusters = self.grid.clusters();
        let n_chunks = self.chunks.len();
        for (c, chunk) in self.chunks.iter_mut().enumerate() {
            chunk.clusters = c * clusters / n_chunks..(c + 1) * clusters / n_chunks;
        }
        let reach = self.cutoff + self.outer_buffer;
        let search = search::Search {
            grid: &self.grid,
            geometry: &self.geometry,
            reach,
            excluded_start: &self.excluded_start,
            excluded: &self.excluded,
        };
        let isa = self.isa;
        prune::to_f32(&self.positions, &mut self.lanes);
        let work = prune::Reach::new(&self.positions, &self.lanes, &self.geometry.shifts, reach);
        let run = |chunk: &mut Chunk| {
            search.chunk(chunk);
            prune::list(isa, &chunk.inner, &mut chunk.outer, work);
            chunk.set_window(clusters);
        };
        if self.n >= PARALLEL_MIN_ATOMS {
            self.chunks.par_iter_mut().for_each(run);
        } else {
            self.chunks.iter_mut().for_each(run);
        }
        self.built = true;
        self.builds += 1;
    }

    /// The inner lists from the outer ones at the current positions.
    fn prune(&mut self) {
        let isa = self.isa;
        let reach = self.cutoff + self.inner_buffer;
        prune::to_f32(&self.positions, &mut self.lanes);
        let work = prune::Reach::new(&self.positions, &self.lanes, &self.geometry.shifts, reach);
        let run = |chunk: &mut Chunk| {
            prune::list(isa, &chunk.outer, &mut chunk.inner, work);
            chunk.inner_pairs = chunk.inner.atom_pairs();
        };
        if self.n >= PARALLEL_MIN_ATOMS {
            self.chunks.par_iter_mut().for_each(run);
        } else {
            self.chunks.iter_mut().for_each(run);
        }
    }

    /// Wrapped positions and charges in cluster order.
    fn fill_positions(&mut self, q: &[f64]) {
        let clusters = self.grid.clusters();
        self.positions.resize(clusters, Cluster::default());
        let (slots, offsets, charges) = (&self.grid.slots, &self.offsets, &self.charges);
        let fill = |(block, positions): (usize, &mut [Cluster<f64>])| {
            for (i, cluster) in positions.iter_mut().enumerate() {
                let c = block * CLUSTER_BLOCK + i;
                for k in 0..CLUSTER {
                    let atom = slots[c * CLUSTER + k];
                    if atom == PAD {
                        cluster.x[k] = PAD_POSITION;
                        cluster.y[k] = PAD_POSITION;
                        cluster.z[k] = PAD_POSITION;
                        cluster.q[k] = 0.0;
                    } else {
                        let a = atom as usize;
                        cluster.x[k] = q[3 * a] - offsets[3 * a];
                        cluster.y[k] = q[3 * a + 1] - offsets[3 * a + 1];
                        cluster.z[k] = q[3 * a + 2] - offsets[3 * a + 2];
                        cluster.q[k] = charges[a];
                    }
                }
            }
        };
        let positions = &mut self.positions[..];
        if self.n >= PARALLEL_PASSES_MIN_ATOMS {
            positions
                .par_chunks_mut(CLUSTER_BLOCK)
                .enumerate()
                .for_each(fill);
        } else {
            positions
                .chunks_mut(CLUSTER_BLOCK)
                .enumerate()
                .for_each(fill);
        }
    }

    /// `f(i, j, x_j − x_i)` for every marked atom pair of the inner (or `outer`) lists at
    /// the positions of the last update (pairs beyond the cutoff included).
    pub fn for_each_pair(&self, outer: bool, mut f: impl FnMut(usize, usize, [f64; 3])) {
        let slots = &self.grid.slots;
        for chunk in &self.chunks {
            let pairs = if outer { &chunk.outer } else { &chunk.inner };
            for entry in &pairs.entries {
                let s = self.geometry.shifts[entry.shift as usize];
                let ci = entry.ci as usize;
                let pi = &self.positions[ci];
                let range = entry.start as usize..entry.end as usize;
                for (&cj, &mask) in pairs.j[range.clone()].iter().zip(&pairs.masks[range]) {
                    let cj = cj as usize;
                    let pj = &self.positions[cj];
                    for bit in (0..16).filter(|b| mask >> b & 1 == 1) {
                        let (a, b) = (bit / 4, bit % 4);
                        let d = [
                            pj.x[b] - (pi.x[a] + s[0]),
                            pj.y[b] - (pi.y[a] + s[1]),
                            pj.z[b] - (pi.z[a] + s[2]),
                        ];
                        let (i, j) = (slots[ci * CLUSTER + a], slots[cj * CLUSTER + b]);
                        f(i as usize, j as usize, d);
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::keep_two_largest;
    use rand::rngs::StdRng;
    use rand::{RngExt, SeedableRng};

    /// The parallel displacement test merges per-block results: the two largest values
    /// must not depend on how the values are cut into blocks or merged.
    #[test]
    fn the_two_largest_do_not_depend_on_the_blocks() {
        let mut rng = StdRng::seed_from_u64(5);
        let mut values: Vec<f64> = (0..1000).map(|_| rng.random::<f64>()).collect();
        values[517] = values[3]; // a tie
        let mut serial = [0.0; 2];
        values
            .iter()
            .for_each(|&v| keep_two_largest(&mut serial, v));
        for block in [1, 7, 64, 999] {
            let mut merged = [0.0; 2];
            for part in values.chunks(block).rev() {
                let mut top = [0.0; 2];
                part.iter().for_each(|&v| keep_two_largest(&mut top, v));
                top.into_iter()
                    .for_each(|v| keep_two_largest(&mut merged, v));
            }
            assert_eq!(merged, serial, "blocks of {block}");
        }
        let mut with_nan = serial;
        keep_two_largest(&mut with_nan, f64::NAN);
        assert_eq!(with_nan[0], f64::INFINITY);
    }
}
