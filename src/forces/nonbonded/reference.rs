//! The term's reference sums, for tests and diagnostics: every atom pair by brute force
//! (minimum image, no list), and the pairs within the cutoff that the list's kernel sees.
//! O(N²): never called in a run.

use super::{CoulombForm, Kernel, Nonbonded};
use crate::forces::minimum_image;

/// Energy, gradient and the number of pairs within the cutoff of a brute-force sum.
#[derive(Clone, Debug)]
pub struct BruteForce {
    pub energy: f64,
    pub gradient: Vec<f64>,
    pub pairs: usize,
}

impl Nonbonded {
    /// Every pair not excluded at its minimum image, within the cutoff, straight from the
    /// scalar formulas of the term (f64): what the list and the kernel must reproduce.
    pub fn brute_force(&self, q: &[f64]) -> BruteForce {
        let n = self.n;
        let guard = self.lock();
        let list = &guard.list;
        let lengths = list.geometry.lengths;
        let cutoff2 = self.cutoff * self.cutoff;
        let mut out = BruteForce {
            energy: 0.0,
            gradient: vec![0.0; q.len()],
            pairs: 0,
        };
        for i in 0..n {
            for j in i + 1..n {
                if list.is_excluded(i, j) {
                    continue;
                }
                let d: [f64; 3] = std::array::from_fn(|a| {
                    let d = q[3 * j + a] - q[3 * i + a];
                    if lengths[a].is_finite() {
                        minimum_image(d, lengths[a])
                    } else {
                        d
                    }
                });
                let s = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                if s >= cutoff2 {
                    continue;
                }
                let (e, f) = self.pair_energy_force(i, j, s);
                out.energy += e;
                out.pairs += 1;
                for (a, &da) in d.iter().enumerate() {
                    out.gradient[3 * j + a] -= f * da;
                    out.gradient[3 * i + a] += f * da;
                }
            }
        }
        out
    }

    /// Pairs of the list within the cutoff at the positions of the last evaluation: equal
    /// to [`BruteForce::pairs`] there when the list misses no pair.
    pub fn listed_pairs_within_cutoff(&self) -> usize {
        let cutoff2 = self.cutoff * self.cutoff;
        let mut count = 0;
        self.lock().list.for_each_pair(false, |_, _, d| {
            count += usize::from(d[0] * d[0] + d[1] * d[1] + d[2] * d[2] < cutoff2);
        });
        count
    }

    /// `(V, −V′/r)` of the pair `i, j` at `r² = s`.
    fn pair_energy_force(&self, i: usize, j: usize, s: f64) -> (f64, f64) {
        let p = self.lj[self.types[i] as usize * self.n_types + self.types[j] as usize];
        let inv_r = 1.0 / s.sqrt();
        let (mut e, mut f) = p.energy_force(inv_r * inv_r);
        let qq = self.scaled_charges[i] * self.scaled_charges[j];
        if qq != 0.0 {
            let (ec, fc) = match self.kernel {
                Kernel::Plain(c) => c.energy_force(qq, s, inv_r),
                Kernel::ShiftedForce(c) => c.energy_force(qq, s, inv_r),
                Kernel::Damped(c) => c.energy_force(qq, s, inv_r),
                Kernel::ReactionField(c) => c.energy_force(qq, s, inv_r),
                Kernel::Ewald(c) => c.energy_force(qq, s, inv_r),
            };
            e += ec;
            f += fc;
        }
        match self.switch {
            None => (e, f),
            // −(S V)′/r = S (−V′/r) − S′ V/r.
            Some(switch) => {
                let (sw, slope) = switch.value_slope(s.sqrt());
                (sw * e, sw * f - slope * e * inv_r)
            }
        }
    }
}
