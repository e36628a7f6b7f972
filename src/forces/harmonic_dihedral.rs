//! Harmonic dihedrals `V = (k/2)(ξ − ξ₀)²` in the dihedral angle ξ of `i–j–k–l`, the
//! difference `ξ − ξ₀` taken in (−π, π] (GROMACS's improper dihedral function 2, GROMACS
//! manual "Improper dihedrals: harmonic type"; OpenMM's `GromacsTopFile` builds the same as
//! a `CustomTorsionForce`). ξ and `∂ξ/∂r` are those of [`super::torsion`] (IUPAC sign,
//! Blondel & Karplus 1996); `∂V/∂r = k (ξ − ξ₀) ∂ξ/∂r`. The Hessian-vector product runs
//! the same code on dual numbers. Bonded: fast by default; cost linear in the dihedrals,
//! 3-D only.

use std::f64::consts::PI;

use super::dual::{Dual, Scalar};
use super::scratch::{PARALLEL_MIN_DIHEDRALS, Scratch};
use super::torsion::{
    DihedralGradient, difference, dihedral_gradient, dihedral_term_methods, scatter,
};
use super::{ForceTerm, PeriodicBox, TermClass};

/// One harmonic dihedral.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HarmonicDihedral {
    pub atoms: [usize; 4],
    /// Energy per rad².
    pub k: f64,
    /// ξ₀, radians.
    pub xi0: f64,
}

#[derive(Clone, Debug)]
pub struct HarmonicDihedrals {
    dihedrals: Vec<HarmonicDihedral>,
    periodic_box: Option<PeriodicBox>,
    /// The first phase of a parallel gradient ([`super::scratch`]).
    scratch: Scratch<DihedralGradient>,
}

/// `ξ − ξ₀` brought into (−π, π] by whole turns (a constant shift: the derivative is 1).
#[inline(always)]
fn wrapped<T: Scalar>(xi: T, xi0: f64) -> T {
    let d = xi - T::constant(xi0);
    let value = d.real();
    if value > PI {
        d - T::constant(2.0 * PI * ((value + PI) / (2.0 * PI)).floor())
    } else if value <= -PI {
        d + T::constant(2.0 * PI * ((PI - value) / (2.0 * PI)).floor())
    } else {
        d
    }
}

impl HarmonicDihedrals {
    pub fn new(dihedrals: Vec<HarmonicDihedral>, periodic_box: Option<PeriodicBox>) -> Self {
        HarmonicDihedrals {
            scratch: Scratch::with_len_from(dihedrals.len(), PARALLEL_MIN_DIHEDRALS),
            dihedrals,
            periodic_box,
        }
    }

    pub fn dihedrals(&self) -> &[HarmonicDihedral] {
        &self.dihedrals
    }

    /// ξ − ξ₀ (wrapped) and ∂ξ/∂r of one dihedral.
    #[inline(always)]
    fn offset<T: Scalar>(
        &self,
        d: &HarmonicDihedral,
        q: &[f64],
        v: Option<&[f64]>,
    ) -> (T, [[T; 3]; 4]) {
        let [i, j, k, l] = d.atoms;
        let b = self.periodic_box.as_ref();
        let (xi, g) = dihedral_gradient(
            &difference::<T>(b, q, v, i, j),
            &difference::<T>(b, q, v, k, j),
            &difference::<T>(b, q, v, k, l),
        );
        (wrapped(xi, d.xi0), g)
    }

    /// One dihedral's `(k/2)(ξ − ξ₀)²`.
    fn energy_of(&self, d: &HarmonicDihedral, q: &[f64]) -> f64 {
        let (delta, _) = self.offset::<f64>(d, q, None);
        0.5 * d.k * delta * delta
    }

    /// `dV/dξ = k (ξ − ξ₀)` and `∂ξ/∂r` of one dihedral.
    #[inline(always)]
    fn derivative<T: Scalar>(
        &self,
        d: &HarmonicDihedral,
        q: &[f64],
        direction: Option<&[f64]>,
    ) -> (T, [[T; 3]; 4]) {
        let (delta, g) = self.offset::<T>(d, q, direction);
        (T::constant(d.k) * delta, g)
    }
}

impl ForceTerm for HarmonicDihedrals {
    fn kind(&self) -> &'static str {
        "harmonic-dihedral"
    }

    dihedral_term_methods!();
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A skewed quartet, ξ₀ on either side of ±π so the wrap matters.
    fn quartet(xi0: f64) -> (HarmonicDihedrals, Vec<f64>) {
        let q = vec![
            1.1, 0.2, -0.3, 0.0, 0.0, 0.0, 0.1, 1.5, 0.2, -1.2, 1.9, -0.4,
        ];
        let d = HarmonicDihedral {
            atoms: [0, 1, 2, 3],
            k: 3.0,
            xi0,
        };
        (HarmonicDihedrals::new(vec![d], None), q)
    }

    #[test]
    fn gradient_and_hessian_match_finite_differences() {
        for xi0 in [0.3, 3.0, -3.0, 2.5] {
            let (term, q) = quartet(xi0);
            let mut g = vec![0.0; q.len()];
            term.add_gradient(&q, &mut g);
            let v: Vec<f64> = (0..q.len())
                .map(|k| ((k * 7 % 5) as f64 - 2.0) * 0.3)
                .collect();
            let mut hv = vec![0.0; q.len()];
            term.add_hessian_vector(&q, &v, &mut hv);
            // Central differences with step 1e-6: truncation O(ε²) ~ 1e-12 and round-off
            // ~ 1e-16 / 1e-6 relative to terms of order 1; 1e-6 leaves a wide margin.
            let eps = 1e-6;
            for k in 0..q.len() {
                let (mut plus, mut minus) = (q.clone(), q.clone());
                plus[k] += eps;
                minus[k] -= eps;
                let fd = (term.energy(&plus) - term.energy(&minus)) / (2.0 * eps);
                assert!(
                    (fd - g[k]).abs() < 1e-6,
                    "xi0 {xi0} k {k}: {fd} vs {}",
                    g[k]
                );
            }
            let (mut plus, mut minus) = (q.clone(), q.clone());
            for k in 0..q.len() {
                plus[k] += eps * v[k];
                minus[k] -= eps * v[k];
            }
            let (mut gp, mut gm) = (vec![0.0; q.len()], vec![0.0; q.len()]);
            term.add_gradient(&plus, &mut gp);
            term.add_gradient(&minus, &mut gm);
            for k in 0..q.len() {
                let fd = (gp[k] - gm[k]) / (2.0 * eps);
                assert!(
                    (fd - hv[k]).abs() < 1e-6,
                    "xi0 {xi0} k {k}: {fd} vs {}",
                    hv[k]
                );
            }
        }
    }

    #[test]
    fn the_offset_wraps_across_plus_minus_pi() {
        // ξ₀ = ξ ± 2π gives the energy of ξ₀ = ξ: zero.
        let (term, q) = quartet(0.0);
        let xi = super::super::torsion::dihedral_angle(
            [q[0], q[1], q[2]],
            [q[3], q[4], q[5]],
            [q[6], q[7], q[8]],
            [q[9], q[10], q[11]],
        );
        for shift in [-2.0 * PI, 0.0, 2.0 * PI] {
            let d = HarmonicDihedral {
                xi0: xi + shift,
                ..term.dihedrals()[0]
            };
            let e = HarmonicDihedrals::new(vec![d], None).energy(&q);
            assert!(e.abs() < 1e-20, "shift {shift}: {e}");
        }
    }
}
