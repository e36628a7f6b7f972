//! Dynamic pruning: the inner list keeps the outer list's cluster pairs that have a marked
//! atom pair within the inner reach at the current positions (module doc of [`super`]).
//! SIMD over the 16 atom pairs, in the instruction set of the kernel.

use super::{Cluster, Entry, PairList};
use crate::forces::simd::{Isa, Simd, row_lanes, simd_dispatch};

/// `to` = the pairs of `from` with a marked atom pair within `reach`.
pub fn list(
    isa: Isa,
    from: &PairList,
    to: &mut PairList,
    positions: &[Cluster<f64>],
    shifts: &[[f64; 3]; 27],
    reach: f64,
) {
    let work = Work {
        outer: from,
        positions,
        shifts,
        reach,
    };
    prune_on(isa, &work, to)
}

struct Work<'a> {
    outer: &'a PairList,
    positions: &'a [Cluster<f64>],
    shifts: &'a [[f64; 3]; 27],
    reach: f64,
}

simd_dispatch! {
    /// [`prune`] on the instruction set `isa`.
    fn prune_on[][](work: &Work, inner: &mut PairList) = prune, lanes f64;
}

#[inline(always)]
fn prune<S: Simd<R = f64>>(s: S, work: &Work, inner: &mut PairList) {
    let reach2 = s.splat(work.reach * work.reach);
    let outer = work.outer;
    // `to` is at most as long as `from`: write every pair and advance only past the kept
    // ones (no branch on the test), then cut.
    inner.entries.clear();
    inner.j.clear();
    inner.j.resize(outer.j.len(), 0);
    inner.masks.clear();
    inner.masks.resize(outer.masks.len(), 0);
    let mut kept = 0;
    for entry in &outer.entries {
        let shift = &work.shifts[entry.shift as usize];
        let i = &work.positions[entry.ci as usize];
        let mut rows = [[s.splat(0.0); 3]; 4];
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
            let j = &work.positions[cj as usize];
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
