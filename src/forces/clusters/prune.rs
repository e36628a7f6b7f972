//! Dynamic pruning: the inner list keeps the outer list's cluster pairs that have a marked
//! atom pair within the inner reach at the current positions (module doc of [`super`]).
//! SIMD over the 16 atom pairs, in f32 lanes of the kernel's instruction set, against a
//! reach widened by a bound on the f32 round-off ([`reach2_f32`]): it keeps every pair the
//! same test in f64 keeps, and perhaps a few more with no pair within the reach, which the
//! kernel, testing the cutoff itself, computes as zero.

use super::{Cluster, Entry, PAD_POSITION, PairList};
use crate::forces::simd::{Isa, Real, Simd, row_lanes, simd_dispatch};

/// `to` = the pairs of `from` with a marked atom pair within `reach` (and perhaps a few
/// with none: see the module doc), `largest` the size bound of [`largest_coordinate`]
/// (one scan per build or prune, shared by the chunks). Cost: per cluster pair of `from`
/// 16 / WIDTH f32 register groups of `r² = Δx² + Δy² + Δz²` and a compare.
pub fn list(isa: Isa, from: &PairList, to: &mut PairList, work: Reach) {
    let Reach {
        positions,
        lanes,
        shifts,
        reach,
        largest,
    } = work;
    let work = Work {
        outer: from,
        positions,
        lanes,
        shifts,
        reach2: f64::from(reach2_f32(reach, largest)),
    };
    prune_on(isa, &work, to)
}

/// What every chunk's [`list`] shares: the positions (and the same rounded to f32 once,
/// [`to_f32`]), image shifts, the reach and the largest coordinate, shift included
/// ([`largest_coordinate`]).
#[derive(Clone, Copy)]
pub struct Reach<'a> {
    pub positions: &'a [Cluster<f64>],
    pub lanes: &'a [Cluster<f32>],
    pub shifts: &'a [[f64; 3]; 27],
    pub reach: f64,
    pub largest: f64,
}

impl<'a> Reach<'a> {
    /// The positions' size scanned once ([`largest_coordinate`]); `lanes` is
    /// [`to_f32`] of `positions`.
    pub fn new(
        positions: &'a [Cluster<f64>],
        lanes: &'a [Cluster<f32>],
        shifts: &'a [[f64; 3]; 27],
        reach: f64,
    ) -> Self {
        debug_assert_eq!(positions.len(), lanes.len());
        Reach {
            positions,
            lanes,
            shifts,
            reach,
            largest: largest_coordinate(positions, shifts),
        }
    }
}

/// `lanes` = the coordinates of `positions` rounded to f32 (`x as f32`, as the lanes of
/// [`prune`] would round each j-cluster at every pair it meets): once per build or
/// pruning instead of once per cluster pair ([`Cluster::to_f32`]; the charges come along).
pub fn to_f32(positions: &[Cluster<f64>], lanes: &mut Vec<Cluster<f32>>) {
    lanes.clear();
    lanes.extend(positions.iter().map(Cluster::to_f32));
}

/// The bound `x` of [`reach2_f32`]: the largest `|coordinate|` of `positions` (padding
/// apart) plus the largest `|shift|`. One pass over the positions.
pub fn largest_coordinate(positions: &[Cluster<f64>], shifts: &[[f64; 3]; 27]) -> f64 {
    let mut largest = 0.0f64;
    for cluster in positions {
        for &v in cluster.x.iter().chain(&cluster.y).chain(&cluster.z) {
            if v != PAD_POSITION {
                largest = largest.max(v.abs());
            }
        }
    }
    largest + shifts.iter().flatten().fold(0.0f64, |m, s| m.max(s.abs()))
}

/// The f32 threshold `T` such that `r²₃₂ < T` wherever the f64 test `r²₆₄ < R²` holds, for
/// pairs whose coordinates (shift included) are at most `x` in size, `R` = `reach`.
///
/// Both tests start from the same f64 coordinates `a = x_i + s` (rounded once in f64, by
/// [`row_lanes`]) and `b = x_j`; let `d = a − b` exactly (per coordinate), `u = 2⁻²⁴` (f32)
/// and `v = 2⁻⁵³` (f64), rounding to nearest.
/// * f64: `Δ = fl(a − b) = d (1 + ε)`, `r²₆₄` = three more roundings of a sum of
///   non-negative terms, so `r²₆₄ ≥ |d|² (1 − v)⁵` and keeping means
///   `|d| < R (1 − v)^{−5/2} < R (1 + 2⁻⁵⁰)`.
/// * f32: `|fl₃₂(a) − a| ≤ u x`, the same for `b`, so `c = fl₃₂(a) − fl₃₂(b)` is within
///   `2ux` of `d` and `|c| ≤ 2x (1 + u)`; `Δ₃₂ = fl₃₂(c)` is within `u |c|` of `c`: per
///   coordinate `|Δ₃₂ − d| ≤ 4ux + 2u²x < 5ux = e`, and `|Δ₃₂| ≤ |d| + √3 e` as vectors.
///   `r²₃₂ = fma(Δz, Δz, fma(Δy, Δy, Δx²))` is three roundings of non-negative terms:
///   `r²₃₂ ≤ |Δ₃₂|² (1 + u)³`.
///
/// Hence f64 keeps ⇒ `r²₃₂ < B = (R (1 + 2⁻⁵⁰) + √3 · 5ux)² (1 + u)³`. `B` is evaluated in
/// f64 (relative error below 2⁻⁵⁰) and times `1 + 2⁻²⁰` before rounding to f32 (which can
/// lower it by a factor `1 − u` at most), so `T ≥ B`. In Trp-cage's 42 Å box (`x` ≤ 84 Å,
/// positions wrapped and a shift) `√3 · 5ux` = 4.3e-5 Å, against the 1 Å inner buffer.
pub fn reach2_f32(reach: f64, x: f64) -> f32 {
    let u = f64::from(f32::EPSILON) / 2.0;
    let widened = reach * (1.0 + 2f64.powi(-50)) + 3f64.sqrt() * 5.0 * u * x;
    let bound = widened * widened * (1.0 + u).powi(3);
    (bound * (1.0 + 2f64.powi(-20))) as f32
}

struct Work<'a, R> {
    outer: &'a PairList,
    /// The i-clusters' rows are shifted in f64 and then rounded ([`row_lanes`]).
    positions: &'a [Cluster<f64>],
    /// The j-clusters in the lanes' precision: `R::of` of `positions`.
    lanes: &'a [Cluster<R>],
    shifts: &'a [[f64; 3]; 27],
    /// The squared reach the lanes compare with (exact in them: [`reach2_f32`] in f32).
    reach2: f64,
}

simd_dispatch! {
    /// [`prune`] on the instruction set `isa`.
    fn prune_on[][](work: &Work<f32>, inner: &mut PairList) = prune, lanes f32;
}

/// The prune in the lanes of `s` (f32 in a run; f64 too in the tests, as the reference).
#[inline(always)]
fn prune<S: Simd>(s: S, work: &Work<S::R>, inner: &mut PairList) {
    let reach2 = s.splat(S::R::of(work.reach2));
    let outer = work.outer;
    // `to` is at most as long as `from`: write every pair and advance only past the kept
    // ones (no branch on the test), then cut. Every slot below `outer`'s length is written
    // before it is read, so the old contents may stay (no clearing pass).
    inner.entries.clear();
    inner.j.resize(outer.j.len(), 0);
    inner.masks.resize(outer.masks.len(), 0);
    let mut kept = 0;
    for entry in &outer.entries {
        let shift = &work.shifts[entry.shift as usize];
        let i = &work.positions[entry.ci as usize];
        let mut rows = [[s.splat(S::R::default()); 3]; 4];
        for (g, row) in rows.iter_mut().enumerate() {
            *row = [
                row_lanes(s, &i.x, shift[0], g),
                row_lanes(s, &i.y, shift[1], g),
                row_lanes(s, &i.z, shift[2], g),
            ];
        }
        let start = kept;
        let range = entry.start as usize..entry.end as usize;
        for (&cj, &mask) in outer.j[range.clone()].iter().zip(&outer.masks[range]) {
            let j = &work.lanes[cj as usize];
            let (xj, yj, zj) = (s.load4(&j.x), s.load4(&j.y), s.load4(&j.z));
            let mut hits = 0u32;
            for (g, row) in rows.iter().enumerate().take(16 / S::WIDTH) {
                let dx = s.sub(row[0], xj);
                let dy = s.sub(row[1], yj);
                let dz = s.sub(row[2], zj);
                let r2 = s.fma(dz, dz, s.fma(dy, dy, s.mul(dx, dx)));
                hits |= s.bits(s.less(r2, reach2)) << (g * S::WIDTH);
            }
            inner.j[kept] = cj;
            inner.masks[kept] = mask;
            kept += usize::from(hits & mask as u32 != 0);
        }
        if kept > start {
            inner.entries.push(Entry {
                start: start as u32,
                end: kept as u32,
                ..*entry
            });
        }
    }
    inner.j.truncate(kept);
    inner.masks.truncate(kept);
}

#[cfg(test)]
mod tests {
    use super::{Reach, Work, list, prune, to_f32};
    use crate::forces::clusters::{ClusterList, PairList};
    use crate::forces::simd::{Isa, Portable};
    use std::collections::BTreeSet;

    /// Trp-cage in water (6920 atoms, 42 Å box): positions and box lengths of its xyz file.
    fn trpcage() -> (Vec<f64>, [f64; 3]) {
        let text = std::fs::read_to_string("systems/protein-amber/trpcage-300K.xyz").unwrap();
        let mut lines = text.lines();
        let n: usize = lines.next().unwrap().trim().parse().unwrap();
        let header = lines.next().unwrap();
        let lattice: Vec<f64> = header
            .split("Lattice=\"")
            .nth(1)
            .unwrap()
            .split('"')
            .next()
            .unwrap()
            .split_whitespace()
            .map(|v| v.parse().unwrap())
            .collect();
        let q: Vec<f64> = lines
            .take(n)
            .flat_map(|line| {
                line.split_whitespace()
                    .skip(1)
                    .take(3)
                    .map(|v| v.parse::<f64>().unwrap())
                    .collect::<Vec<_>>()
            })
            .collect();
        assert_eq!(q.len(), 3 * n);
        (q, [lattice[0], lattice[4], lattice[8]])
    }

    /// Every listed atom-pair block: (i-cluster, shift, j-cluster, mask).
    fn pairs(list: &PairList) -> BTreeSet<(u32, u32, u32, u16)> {
        let mut set = BTreeSet::new();
        for e in &list.entries {
            for k in e.start as usize..e.end as usize {
                set.insert((e.ci, e.shift, list.j[k], list.masks[k]));
            }
        }
        set
    }

    /// On Trp-cage's configuration, for reaches at the cutoff and with the inner buffers of
    /// a run, the f32 prune (every instruction set here) keeps every cluster pair the f64
    /// prune keeps; the few more it keeps have a marked pair within the reach plus 1e-3 Å
    /// (far above the bound's 4.3e-5 Å: they are near misses, not a broken test).
    #[test]
    fn the_f32_prune_keeps_every_pair_the_f64_prune_keeps() {
        let (q, lengths) = trpcage();
        let n = q.len() / 3;
        let mut clusters = ClusterList::new(
            9.0,
            2.0,
            Some(lengths),
            vec![0; n + 1],
            Vec::new(),
            vec![0.0; n],
        );
        clusters.update(&q);
        let shifts = &clusters.geometry.shifts;
        let positions = &clusters.positions;
        let mut lanes = Vec::new();
        to_f32(positions, &mut lanes);
        let (mut kept, mut extra) = (0, 0);
        for reach in [9.0, 9.5, 10.0, 10.5] {
            for chunk in &clusters.chunks {
                let work = Work {
                    outer: &chunk.outer,
                    positions,
                    lanes: positions,
                    shifts,
                    reach2: reach * reach,
                };
                let mut reference = PairList::default();
                prune(Portable::<f64>::new(), &work, &mut reference);
                let reference = pairs(&reference);
                let loose = Work {
                    reach2: (reach + 1e-3) * (reach + 1e-3),
                    ..work
                };
                let mut near = PairList::default();
                prune(Portable::<f64>::new(), &loose, &mut near);
                let near = pairs(&near);
                for isa in Isa::available() {
                    let mut to = PairList::default();
                    list(
                        isa,
                        &chunk.outer,
                        &mut to,
                        Reach::new(positions, &lanes, shifts, reach),
                    );
                    let to = pairs(&to);
                    assert!(
                        reference.is_subset(&to),
                        "{}: reach {reach}: a pair dropped",
                        isa.name()
                    );
                    assert!(
                        to.is_subset(&near),
                        "{}: reach {reach}: a far pair kept",
                        isa.name()
                    );
                    extra += to.len() - reference.len();
                }
                kept += reference.len();
            }
        }
        assert!(kept > 100_000, "too few pairs to test: {kept}");
        eprintln!("kept by f64: {kept}, more by f32 (all instruction sets): {extra}");
    }
}
