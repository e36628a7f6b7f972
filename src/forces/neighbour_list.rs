//! Verlet neighbour lists built from a cell list, for the cutoff pair terms.
//!
//! A list holds every pair closer than `cutoff + skin` at the positions it was built from;
//! it stays valid (holds every pair closer than `cutoff`) while no particle has moved more
//! than `skin / 2` since, because the distance on the periodic torus is a metric. Callers ask
//! [`NeighbourList::needs_rebuild`] before every use: an O(N) check of displacements.
//!
//! **Images.** Positions are never wrapped during a run (the integrators own them). At a
//! build each particle gets a fixed offset, a whole number of box lengths, that puts its
//! position into the box; the force loops subtract these offsets once per evaluation
//! ([`NeighbourList::wrap_positions`], O(N)). Between two wrapped positions the displacement
//! lies in `(−L, L)`, and each entry stores which image of its partner it means, one of 27
//! shift vectors (`−L, 0, +L` per axis), so the pair loop needs no `round()`. A pair may be
//! listed with two images when both lie within `cutoff + skin` (a box shorter than
//! `2(cutoff + skin)`, like the 216-water box: 18.6 Å against 2 × 10 Å); since
//! `cutoff < L/2`, at most one of them is inside the cutoff at any time, so each pair
//! interacts once. The skin is clipped so that `cutoff + skin < L`.
//!
//! **Chunks.** A half list: each pair once. Cell lists use a half shell (the own cell with
//! partners j > i and the neighbour cells at a lexicographically positive offset); all-pairs
//! lists store pair `i < j` in row `i`. The rows (particles) are split into a fixed number of
//! contiguous chunks that depends only on the particle count; each chunk keeps its own part of
//! the list and, in the force terms, its own gradient buffer, summed in chunk order. Results
//! are therefore bit-for-bit identical whatever the number of threads. In a `j > i` list row
//! `i` holds about `(n − i)/n` of its neighbours, so there the chunk boundaries are at
//! `n (1 − √(1 − c/C))`, which gives every chunk the same expected number of pairs.
//!
//! **Classes.** A builder callback sorts each pair into one of [`N_CLASSES`] classes (for
//! the non-bonded term: Lennard-Jones and charge, charge only, Lennard-Jones only) or drops it
//! (excluded pairs, pairs with nothing to compute), so the force loops have no branches on
//! pair kind.

use rayon::prelude::*;

/// A periodic list whose reach sphere holds more than this fraction of the box lists every
/// pair once, without images, and never rebuilds: the force loop takes the minimum image
/// itself. For the 216-water box (reach 10 Å in 18.6 Å) the sphere is 65 % of the box, and
/// evaluating the 1.55× more pairs costs less than rebuilding the list every few steps.
pub const ALL_PAIRS_FRACTION: f64 = 0.4;

/// Candidates per block of the list build's distance loop.
const BUILD_BLOCK: usize = 64;

/// Pair classes a list distinguishes.
pub const N_CLASSES: usize = 3;

/// Bits of an entry that hold the partner index; the rest hold the image shift (0..27).
const INDEX_BITS: u32 = 27;
const INDEX_MASK: u32 = (1 << INDEX_BITS) - 1;
/// The shift index of the zero shift (no image).
pub const NO_SHIFT: u32 = 13;

/// The partner index and image-shift index of a list entry.
#[inline(always)]
pub fn unpack(entry: u32) -> (usize, usize) {
    (
        (entry & INDEX_MASK) as usize,
        (entry >> INDEX_BITS) as usize,
    )
}

#[inline(always)]
fn pack(j: usize, shift: u32) -> u32 {
    j as u32 | (shift << INDEX_BITS)
}

/// One chunk of rows and its part of the list, per class in CSR form.
#[derive(Clone, Debug, Default)]
pub struct Chunk {
    pub rows: std::ops::Range<usize>,
    /// `starts[c][r]..starts[c][r + 1]` indexes `entries[c]` for row `rows.start + r`.
    pub starts: [Vec<u32>; N_CLASSES],
    pub entries: [Vec<u32>; N_CLASSES],
}

impl Chunk {
    pub fn pair_count(&self) -> usize {
        self.entries.iter().map(Vec::len).sum()
    }
}

#[derive(Clone, Debug)]
pub struct NeighbourList {
    cutoff: f64,
    skin: f64,
    /// Every pair listed once, no images, never rebuilt; users take the minimum image.
    pub all_pairs: bool,
    /// Box lengths (infinite along a non-periodic axis, or for no box at all).
    lengths: [f64; 3],
    periodic: bool,
    n: usize,
    /// Positions at the last build.
    reference: Vec<f64>,
    /// Per-particle whole-box offsets fixed at the last build (see the module doc).
    offsets: Vec<f64>,
    built: bool,
    /// Shift vectors by index `9(sx+1) + 3(sy+1) + (sz+1)`.
    pub shifts: [[f64; 3]; 27],
    pub chunks: Vec<Chunk>,
    builds: u64,
    // Cell-list scratch.
    cell_counts: [usize; 3],
    cell_start: Vec<u32>,
    cell_atoms: Vec<u32>,
    atom_cell: Vec<u32>,
    cell_next: Vec<u32>,
    wrapped: Vec<f64>,
    sorted: [Vec<f64>; 3],
}

/// Start row of chunk `c` of `chunks`: equal shares of the half list's `Σ (n − i)`.
fn balanced_boundary(c: usize, chunks: usize, n: usize) -> usize {
    if c >= chunks {
        return n;
    }
    let share = 1.0 - (1.0 - c as f64 / chunks as f64).sqrt();
    ((share * n as f64).round() as usize).min(n)
}

/// How many chunks for `n` particles: a function of `n` only, so a given system always
/// splits the same way whatever the thread count (see the module doc).
pub fn chunk_count(n: usize) -> usize {
    match n {
        0..256 => 1,
        256..2048 => 4,
        2048..8192 => 8,
        _ => 16,
    }
}

impl NeighbourList {
    /// A list for `n` particles in 3-D with a pair cutoff (`f64::INFINITY` for none) and a
    /// skin; `lengths` the periodic box, if any.
    pub fn new(n: usize, cutoff: f64, skin: f64, lengths: Option<[f64; 3]>) -> Self {
        let (lengths, periodic) = match lengths {
            Some(l) => (l, true),
            None => ([f64::INFINITY; 3], false),
        };
        let mut shifts = [[0.0; 3]; 27];
        for (index, shift) in shifts.iter_mut().enumerate() {
            let s = [index / 9, (index / 3) % 3, index % 3];
            for axis in 0..3 {
                shift[axis] = if periodic && lengths[axis].is_finite() {
                    (s[axis] as f64 - 1.0) * lengths[axis]
                } else {
                    0.0
                };
            }
        }
        let n_chunks = chunk_count(n);
        // Rows of the j > i lists (all pairs, no cutoff) hold (n − i)/n of the pairs; rows of
        // the half-shell cell lists about the same number each.
        let reach = cutoff + skin;
        let triangular = !reach.is_finite()
            || (periodic
                && lengths.iter().all(|l| l.is_finite())
                && 4.0 / 3.0 * std::f64::consts::PI * reach.powi(3)
                    > ALL_PAIRS_FRACTION * lengths[0] * lengths[1] * lengths[2]);
        let boundary = |c: usize| {
            if triangular {
                balanced_boundary(c, n_chunks, n)
            } else {
                c * n / n_chunks
            }
        };
        let chunks = (0..n_chunks)
            .map(|c| Chunk {
                rows: boundary(c)..boundary(c + 1),
                starts: Default::default(),
                entries: Default::default(),
            })
            .collect();
        // The images are −L, 0, +L only: the reach must stay below every periodic length.
        let mut skin = if cutoff.is_finite() { skin } else { 0.0 };
        if periodic {
            for &l in &lengths {
                if l.is_finite() && cutoff + skin >= l {
                    skin = (0.999 * l - cutoff).max(0.0);
                }
            }
        }
        let reach = cutoff + skin;
        let all_pairs = periodic
            && reach.is_finite()
            && lengths.iter().all(|l| l.is_finite())
            && 4.0 / 3.0 * std::f64::consts::PI * reach.powi(3)
                > ALL_PAIRS_FRACTION * lengths[0] * lengths[1] * lengths[2];
        NeighbourList {
            cutoff,
            skin,
            all_pairs,
            lengths,
            periodic,
            n,
            reference: vec![0.0; 3 * n],
            offsets: vec![0.0; 3 * n],
            built: false,
            shifts,
            chunks,
            builds: 0,
            cell_counts: [1; 3],
            cell_start: Vec::new(),
            cell_atoms: Vec::new(),
            atom_cell: Vec::new(),
            cell_next: Vec::new(),
            sorted: Default::default(),
            wrapped: vec![0.0; 3 * n],
        }
    }

    pub fn cutoff(&self) -> f64 {
        self.cutoff
    }

    /// The periodic box lengths (infinite along open axes).
    pub fn lengths(&self) -> [f64; 3] {
        self.lengths
    }

    pub fn skin(&self) -> f64 {
        self.skin
    }

    /// How many times the list was built.
    pub fn builds(&self) -> u64 {
        self.builds
    }

    pub fn pair_count(&self) -> usize {
        self.chunks.iter().map(Chunk::pair_count).sum()
    }

    /// Whether a particle has moved more than `skin / 2` from where the list was built
    /// (always true before the first build; never with no cutoff after it).
    pub fn needs_rebuild(&self, q: &[f64]) -> bool {
        if !self.built {
            return true;
        }
        if !self.cutoff.is_finite() || self.all_pairs {
            return false;
        }
        let limit = 0.25 * self.skin * self.skin;
        q.chunks_exact(3)
            .zip(self.reference.chunks_exact(3))
            .any(|(x, r)| {
                let d = [x[0] - r[0], x[1] - r[1], x[2] - r[2]];
                // `!(… <= …)` also catches NaN positions, which then rebuild (and fail loudly
                // in the energy) rather than use a stale list.
                (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).partial_cmp(&limit)
                    != Some(std::cmp::Ordering::Less)
            })
    }

    /// Rebuild from positions `q` (`n × 3`). `classify(i, j)` gives the class of the pair
    /// `i < j` or `None` to leave it out. Buffers grow only when a chunk holds more pairs than
    /// ever before.
    pub fn build<F>(&mut self, q: &[f64], classify: F)
    where
        F: Fn(usize, usize) -> Option<usize> + Sync,
    {
        debug_assert_eq!(q.len(), 3 * self.n);
        self.reference.copy_from_slice(q);
        for (k, (offset, &x)) in self.offsets.iter_mut().zip(q).enumerate() {
            let l = self.lengths[k % 3];
            *offset = if self.periodic && l.is_finite() && !self.all_pairs {
                l * (x / l).floor()
            } else {
                0.0
            };
        }
        let mut wrapped = std::mem::take(&mut self.wrapped);
        self.wrap_positions(q, &mut wrapped);
        let q: &[f64] = &wrapped;
        self.built = true;
        self.builds += 1;
        let reach = self.cutoff + self.skin;
        let reach2 = reach * reach;
        let n = self.n;

        // The cell grid: cells at least `reach` wide along periodic axes with three or more
        // of them; otherwise one cell along the axis (every pair is a candidate along it).
        let mut origin = [0.0; 3];
        let mut cell_width = [f64::INFINITY; 3];
        let mut counts = [1usize; 3];
        // Cells of width reach/2 with a ±2 stencil hold (5/2)³ ≈ 15.6 reach³ of candidates
        // against 27 reach³ for width reach and ±1: used when every periodic axis has room for
        // five such cells.
        let sub: usize = if self.periodic
            && self
                .lengths
                .iter()
                .all(|l| l.is_finite() && (2.0 * l / reach).floor() >= 5.0)
        {
            2
        } else {
            1
        };
        let cell_reach = reach / sub as f64;
        if reach.is_finite() && n > 0 {
            for axis in 0..3 {
                let (lo, span) = if self.periodic && self.lengths[axis].is_finite() {
                    (0.0, self.lengths[axis])
                } else {
                    let (lo, hi) = q
                        .iter()
                        .skip(axis)
                        .step_by(3)
                        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &x| {
                            (lo.min(x), hi.max(x))
                        });
                    (lo, (hi - lo).max(reach) * (1.0 + 1e-12))
                };
                let count = (span / cell_reach).floor() as usize;
                // Periodic axes need 2·sub + 1 cells for the stencil to hold distinct cells;
                // open axes can use any number.
                let usable = if self.periodic {
                    count > 2 * sub
                } else {
                    count >= 2
                };
                if usable && count < 1 << 10 {
                    counts[axis] = count;
                    cell_width[axis] = span / count as f64;
                    origin[axis] = lo;
                }
            }
        }
        self.cell_counts = counts;
        let n_cells = counts[0] * counts[1] * counts[2];
        let cell_of = |x: &[f64]| -> usize {
            let mut index = [0usize; 3];
            for axis in 0..3 {
                if counts[axis] > 1 {
                    let u = x[axis] - origin[axis];
                    index[axis] = ((u / cell_width[axis]) as usize).min(counts[axis] - 1);
                }
            }
            (index[0] * counts[1] + index[1]) * counts[2] + index[2]
        };
        self.atom_cell.clear();
        self.atom_cell
            .extend(q.chunks_exact(3).map(|x| cell_of(x) as u32));
        self.cell_start.clear();
        self.cell_start.resize(n_cells + 1, 0);
        for &c in &self.atom_cell {
            self.cell_start[c as usize + 1] += 1;
        }
        for c in 0..n_cells {
            self.cell_start[c + 1] += self.cell_start[c];
        }
        self.cell_atoms.resize(n, 0);
        self.cell_next.clear();
        self.cell_next
            .extend_from_slice(&self.cell_start[..n_cells]);
        for (i, &c) in self.atom_cell.iter().enumerate() {
            let slot = &mut self.cell_next[c as usize];
            self.cell_atoms[*slot as usize] = i as u32;
            *slot += 1;
        }

        let lengths = self.lengths;
        let periodic = self.periodic;
        let all_pairs = self.all_pairs;
        let cell_start = &self.cell_start;
        let cell_atoms = &self.cell_atoms;
        // Wrapped positions in cell order, one array per axis.
        for axis in 0..3 {
            self.sorted[axis].clear();
            self.sorted[axis].extend(self.cell_atoms.iter().map(|&i| q[3 * i as usize + axis]));
        }
        let sorted = &self.sorted;
        let atom_cell = &self.atom_cell;
        // Per axis: half the box (the minimum image is one comparison away) and whether a
        // second image can also lie within reach (a box shorter than twice the reach).
        let mut half = [f64::INFINITY; 3];
        let mut second_image = [false; 3];
        for axis in 0..3 {
            if periodic && lengths[axis].is_finite() {
                half[axis] = 0.5 * lengths[axis];
                second_image[axis] = reach > half[axis];
            }
        }
        let any_second = second_image.iter().any(|&b| b);
        // The box length along periodic axes, 0 along open ones (no image shift there).
        let box_step: [f64; 3] =
            std::array::from_fn(|a| if half[a].is_finite() { lengths[a] } else { 0.0 });

        let visit = |i: usize, chunk: &mut Chunk, row: usize| {
            let xi = [q[3 * i], q[3 * i + 1], q[3 * i + 2]];
            let ci = atom_cell[i] as usize;
            let c = [
                ci / (counts[1] * counts[2]),
                (ci / counts[2]) % counts[1],
                ci % counts[2],
            ];
            let reach_cells = sub as isize;
            let range = |axis: usize| -> std::ops::RangeInclusive<isize> {
                if counts[axis] == 1 {
                    0..=0
                } else if periodic {
                    -reach_cells..=reach_cells
                } else {
                    let lo = -(c[axis].min(sub) as isize);
                    let hi = (counts[axis] - 1 - c[axis]).min(sub) as isize;
                    lo..=hi
                }
            };
            // A half shell: the own cell (partners j > i) and the neighbour cells whose offset
            // (dx, dy, dz) is lexicographically positive; the other half sees this atom from
            // its own cell. Cells are distinct (counts > 2·sub along periodic axes).
            let z = range(2);
            let nz = counts[2] as isize;
            let own_start = cell_start[ci] as usize;
            let own_end = cell_start[ci + 1] as usize;
            for dx in range(0).filter(|&d| d >= 0) {
                for dy in range(1).filter(|&d| dx > 0 || d >= 0) {
                    let first = if dx == 0 && dy == 0 { 0 } else { *z.start() };
                    let (z_lo, z_hi) = (c[2] as isize + first, c[2] as isize + z.end());
                    // The z cells as at most two runs of consecutive cell indices.
                    let mut runs = [(0isize, -1isize); 2];
                    if z_lo >= 0 && z_hi < nz {
                        runs[0] = (z_lo, z_hi);
                    } else if z_lo < 0 {
                        runs[0] = (z_lo + nz, nz - 1);
                        runs[1] = (0, z_hi);
                    } else {
                        runs[0] = (z_lo, nz - 1);
                        runs[1] = (0, z_hi - nz);
                    }
                    let wrap = |v: usize, d: isize, count: usize| -> usize {
                        (v as isize + d).rem_euclid(count as isize) as usize
                    };
                    let base = (wrap(c[0], dx, counts[0]) * counts[1] + wrap(c[1], dy, counts[1]))
                        * counts[2];
                    for &(first_z, last_z) in &runs {
                        if last_z < first_z {
                            continue;
                        }
                        let start = cell_start[base + first_z as usize] as usize;
                        let end = cell_start[base + last_z as usize + 1] as usize;
                        // Distances of a block of candidates from the cell-sorted coordinates
                        // (contiguous, branch-free), then only the half-shell partners within
                        // reach, or with a second image possibly within reach, go on.
                        let mut from = start;
                        while from < end {
                            let to = (from + BUILD_BLOCK).min(end);
                            let mut keep = [0u16; BUILD_BLOCK];
                            let mut image = [[0.0f64; 3]; BUILD_BLOCK];
                            let mut codes = [0u32; BUILD_BLOCK];
                            let mut kept = 0;
                            for k in from..to {
                                let mut r2 = 0.0;
                                let mut alternative = false;
                                let mut e = [0.0; 3];
                                let mut code = 0;
                                for axis in 0..3 {
                                    let d = sorted[axis][k] - xi[axis];
                                    let up = (d < -half[axis]) as u32;
                                    let down = (d > half[axis]) as u32;
                                    e[axis] = d + (up as f64 - down as f64) * box_step[axis];
                                    code = 3 * code + 1 + up - down;
                                    r2 += e[axis] * e[axis];
                                    alternative |= second_image[axis]
                                        & (lengths[axis] - e[axis].abs() < reach);
                                }
                                keep[kept] = (k - from) as u16;
                                image[kept] = e;
                                codes[kept] = code;
                                let in_own = (k >= own_start) & (k < own_end);
                                let later = !in_own | (cell_atoms[k] as usize > i);
                                kept += (later & (r2 < reach2 || alternative)) as usize;
                            }
                            for (slot, &k) in keep[..kept].iter().enumerate() {
                                let j = cell_atoms[from + k as usize] as usize;
                                let (lo, hi) = if i < j { (i, j) } else { (j, i) };
                                // The minimum image (wrapped positions: d ∈ (−L, L)).
                                let e = image[slot];
                                let code = codes[slot];
                                let shift = [code / 9, (code / 3) % 3, code % 3];
                                let r2 = e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
                                let mut class = None;
                                if r2 < reach2 {
                                    class = classify(lo, hi);
                                    let Some(class) = class else {
                                        continue;
                                    };
                                    chunk.entries[class].push(pack(j, code));
                                }
                                if !any_second {
                                    continue;
                                }
                                // Other images within reach: per axis the image on the other side,
                                // |e′| = L − |e|, in every combination of such axes (a short box).
                                let mut alternatives = 0u32;
                                for axis in 0..3 {
                                    if second_image[axis] && lengths[axis] - e[axis].abs() < reach {
                                        alternatives |= 1 << axis;
                                    }
                                }
                                if alternatives == 0 {
                                    continue;
                                }
                                for mask in 1u32..8 {
                                    if mask & !alternatives != 0 {
                                        continue;
                                    }
                                    let mut f = e;
                                    let mut sh = shift;
                                    for axis in 0..3 {
                                        if mask & (1 << axis) != 0 {
                                            if e[axis] >= 0.0 {
                                                f[axis] -= lengths[axis];
                                                sh[axis] -= 1;
                                            } else {
                                                f[axis] += lengths[axis];
                                                sh[axis] += 1;
                                            }
                                        }
                                    }
                                    if f[0] * f[0] + f[1] * f[1] + f[2] * f[2] < reach2 {
                                        if class.is_none() {
                                            class = classify(lo, hi);
                                        }
                                        let Some(class) = class else {
                                            break;
                                        };
                                        chunk.entries[class]
                                            .push(pack(j, sh[0] * 9 + sh[1] * 3 + sh[2]));
                                    }
                                }
                            }
                            from = to;
                        }
                    }
                }
            }
            for class in 0..N_CLASSES {
                chunk.starts[class][row + 1] = chunk.entries[class].len() as u32;
            }
        };

        // With fewer than three cells along a periodic axis the stencil above would visit a
        // cell twice; the one-cell case visits it once, which is what `counts = 1` gives.
        let build_chunk = |chunk: &mut Chunk| {
            let rows = chunk.rows.clone();
            for class in 0..N_CLASSES {
                chunk.entries[class].clear();
                chunk.starts[class].clear();
                chunk.starts[class].resize(rows.len() + 1, 0);
            }
            if reach.is_finite() && !all_pairs {
                for (row, i) in rows.enumerate() {
                    visit(i, chunk, row);
                }
            } else {
                // No cutoff, or all pairs: every pair once, no images.
                for (row, i) in rows.enumerate() {
                    for j in i + 1..n {
                        if let Some(class) = classify(i, j) {
                            chunk.entries[class].push(pack(j, NO_SHIFT));
                        }
                    }
                    for class in 0..N_CLASSES {
                        chunk.starts[class][row + 1] = chunk.entries[class].len() as u32;
                    }
                }
            }
            // Room for density fluctuations, so later rebuilds rarely allocate in the run.
            for entries in &mut chunk.entries {
                let wanted = entries.len() + entries.len() / 4;
                if entries.capacity() < wanted {
                    entries.reserve(wanted - entries.len());
                }
            }
        };
        if n >= PARALLEL_MIN_PARTICLES {
            self.chunks.par_iter_mut().for_each(build_chunk);
        } else {
            self.chunks.iter_mut().for_each(build_chunk);
        }
        self.wrapped = wrapped;
    }

    /// `out = q − offsets`: the positions the list's image shifts refer to.
    pub fn wrap_positions(&self, q: &[f64], out: &mut [f64]) {
        for ((o, &x), &offset) in out.iter_mut().zip(q).zip(&self.offsets) {
            *o = x - offset;
        }
    }
}

/// Below this many particles list builds and force loops run on the calling thread: the
/// work per chunk (≈ 100 pairs per particle) no longer pays for waking other threads.
pub const PARALLEL_MIN_PARTICLES: usize = 256;
