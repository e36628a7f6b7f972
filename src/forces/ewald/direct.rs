//! The plain Ewald sum, term by term, as the reference for PME (tests and small boxes):
//! the real-space sum over every periodic image within a cutoff, the reciprocal sum over
//! every wave vector `|m_a| ≤ k_max,a / L_a` (EPBDLP95 eq. (2.49)), the self energy, the
//! excluded-pair correction and the neutralising background (formulas in [`super`]).
//! Energies and gradients in f64; `O(N² images + N k_max³)`: never used in a run.

use super::{background_energy, erf_over_r, self_energy};
use crate::forces::minimum_image;

/// A box of point charges and the parameters of its Ewald sum.
#[derive(Clone, Debug)]
pub struct DirectEwald {
    pub alpha: f64,
    pub lengths: [f64; 3],
    pub coulomb_constant: f64,
    pub charges: Vec<f64>,
    /// Pairs left out of the real-space sum and corrected for in reciprocal space.
    pub excluded: Vec<(usize, usize)>,
    /// Real-space cutoff (any length: every image within it counts).
    pub real_cutoff: f64,
    /// Largest wave-vector index per axis.
    pub k_max: [i64; 3],
}

/// The parts of the Ewald energy and the total gradient.
#[derive(Clone, Debug, Default)]
pub struct EwaldParts {
    pub real: f64,
    pub reciprocal: f64,
    pub self_energy: f64,
    pub exclusions: f64,
    pub background: f64,
    /// Gradient of the real-space sum.
    pub real_gradient: Vec<f64>,
    /// Gradient of the reciprocal sum and the exclusion correction.
    pub reciprocal_gradient: Vec<f64>,
}

impl EwaldParts {
    pub fn total(&self) -> f64 {
        self.real + self.reciprocal + self.self_energy + self.exclusions + self.background
    }
}

impl DirectEwald {
    fn is_excluded(&self, i: usize, j: usize) -> bool {
        self.excluded
            .iter()
            .any(|&(a, b)| (a, b) == (i, j) || (a, b) == (j, i))
    }

    /// Every part at positions `q` (`n × 3`).
    pub fn evaluate(&self, q: &[f64]) -> EwaldParts {
        let n = self.charges.len();
        let volume: f64 = self.lengths.iter().product();
        let mut parts = EwaldParts {
            self_energy: self_energy(self.alpha, self.coulomb_constant, &self.charges),
            background: background_energy(self.alpha, self.coulomb_constant, &self.charges, volume),
            real_gradient: vec![0.0; 3 * n],
            reciprocal_gradient: vec![0.0; 3 * n],
            ..EwaldParts::default()
        };
        self.real_space(q, &mut parts);
        self.reciprocal_space(q, &mut parts);
        self.exclusions(q, &mut parts);
        parts
    }

    /// `½ Σ_i Σ_j Σ_n' Q_ij erfc(α|r_ij + nL|)/|r_ij + nL|` within the cutoff, excluded
    /// pairs left out at their minimum image only (where the correction acts).
    fn real_space(&self, q: &[f64], parts: &mut EwaldParts) {
        let n = self.charges.len();
        let reach: [i64; 3] =
            std::array::from_fn(|a| (self.real_cutoff / self.lengths[a]).ceil() as i64 + 1);
        let alpha = self.alpha;
        for i in 0..n {
            for j in i..n {
                let qq = self.coulomb_constant * self.charges[i] * self.charges[j];
                // n = 0 is the minimum image.
                let base: [f64; 3] = std::array::from_fn(|a| {
                    let d = q[3 * j + a] - q[3 * i + a];
                    minimum_image(d, self.lengths[a])
                });
                for nx in -reach[0]..=reach[0] {
                    for ny in -reach[1]..=reach[1] {
                        for nz in -reach[2]..=reach[2] {
                            let central = nx == 0 && ny == 0 && nz == 0;
                            if central && (i == j || self.is_excluded(i, j)) {
                                continue;
                            }
                            let shift = [nx, ny, nz];
                            let d: [f64; 3] = std::array::from_fn(|a| {
                                base[a] + shift[a] as f64 * self.lengths[a]
                            });
                            let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                            if r >= self.real_cutoff {
                                continue;
                            }
                            let erfc = libm::erfc(alpha * r);
                            let gauss = std::f64::consts::FRAC_2_SQRT_PI
                                * alpha
                                * (-alpha * alpha * r * r).exp();
                            // A particle with its own images: each pair of images once.
                            let weight = if i == j { 0.5 } else { 1.0 };
                            parts.real += weight * qq * erfc / r;
                            let dv_over_r = -weight * qq * (erfc / r + gauss) / (r * r);
                            for (a, &da) in d.iter().enumerate() {
                                parts.real_gradient[3 * j + a] += dv_over_r * da;
                                parts.real_gradient[3 * i + a] -= dv_over_r * da;
                            }
                        }
                    }
                }
            }
        }
    }

    /// `(k_e/2πV) Σ_{m≠0} exp(−π²m²/α²)/m² |S(m)|²` and its gradient.
    fn reciprocal_space(&self, q: &[f64], parts: &mut EwaldParts) {
        let n = self.charges.len();
        let volume: f64 = self.lengths.iter().product();
        let pi = std::f64::consts::PI;
        let prefactor = self.coulomb_constant / (2.0 * pi * volume);
        let [kx, ky, kz] = self.k_max;
        let mut phase = vec![(0.0, 0.0); n];
        for mx in -kx..=kx {
            for my in -ky..=ky {
                for mz in -kz..=kz {
                    if mx == 0 && my == 0 && mz == 0 {
                        continue;
                    }
                    let m = [
                        mx as f64 / self.lengths[0],
                        my as f64 / self.lengths[1],
                        mz as f64 / self.lengths[2],
                    ];
                    let m2 = m[0] * m[0] + m[1] * m[1] + m[2] * m[2];
                    let f = prefactor * (-pi * pi * m2 / (self.alpha * self.alpha)).exp() / m2;
                    let (mut c, mut s) = (0.0, 0.0);
                    for (i, slot) in phase.iter_mut().enumerate() {
                        let arg = 2.0
                            * pi
                            * (m[0] * q[3 * i] + m[1] * q[3 * i + 1] + m[2] * q[3 * i + 2]);
                        let (si, ci) = arg.sin_cos();
                        *slot = (ci, si);
                        c += self.charges[i] * ci;
                        s += self.charges[i] * si;
                    }
                    parts.reciprocal += f * (c * c + s * s);
                    // ∂|S|²/∂r_i = 2 q_i 2π m (cos_i S_im − sin_i S_re).
                    for (i, &(ci, si)) in phase.iter().enumerate() {
                        let g = f * 4.0 * pi * self.charges[i] * (ci * s - si * c);
                        for (a, &ma) in m.iter().enumerate() {
                            parts.reciprocal_gradient[3 * i + a] += g * ma;
                        }
                    }
                }
            }
        }
    }

    /// `−Σ_excluded Q_ij erf(αr)/r` at the minimum image.
    fn exclusions(&self, q: &[f64], parts: &mut EwaldParts) {
        for &(i, j) in &self.excluded {
            let qq = self.coulomb_constant * self.charges[i] * self.charges[j];
            let d: [f64; 3] = std::array::from_fn(|a| {
                let d = q[3 * j + a] - q[3 * i + a];
                minimum_image(d, self.lengths[a])
            });
            let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let (f, f1, _) = erf_over_r(self.alpha, r);
            parts.exclusions -= qq * f;
            for (a, &da) in d.iter().enumerate() {
                parts.reciprocal_gradient[3 * j + a] -= qq * f1 / r * da;
                parts.reciprocal_gradient[3 * i + a] += qq * f1 / r * da;
            }
        }
    }
}
