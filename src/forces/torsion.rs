//! Proper torsions, a cosine series `V = Σ_m k_m (1 + cos(n_m φ − δ_m))` in the dihedral
//! angle φ of `i–j–k–l` (IUPAC sign: trans is ±π; the form of OpenMM's
//! `PeriodicTorsionForce` and of AMBER/CHARMM proper dihedrals). Bonded: fast by default.
//! 3-D only.
//!
//! With `r_ij = r_i − r_j`, `r_kj = r_k − r_j`, `r_kl = r_k − r_l`, `m = r_ij × r_kj`,
//! `n = r_kj × r_kl`: `φ = atan2(|r_kj| (r_ij·n), m·n)` (since `|m × n| = |r_kj| |r_ij·n|`),
//! and (Bekker; Blondel & Karplus, J. Comput. Chem. 17, 1132 (1996))
//! `∂φ/∂r_i = |r_kj| m/|m|²`, `∂φ/∂r_l = −|r_kj| n/|n|²`,
//! `∂φ/∂r_j = −(1 − p) ∂φ/∂r_i − s ∂φ/∂r_l`, `∂φ/∂r_k = −(1 − s) ∂φ/∂r_l − p ∂φ/∂r_i`
//! with `p = r_ij·r_kj/|r_kj|²`, `s = r_kl·r_kj/|r_kj|²`. The Hessian-vector product runs the
//! same code on dual numbers ([`super::dual`]), as the angle term does.

use super::PeriodicBox;
use super::dual::{Dual, Scalar};
use super::scratch::{PARALLEL_MIN_DIHEDRALS, Scratch};
use super::{ForceTerm, TermClass};

/// One dihedral's first phase of a parallel gradient: `dV/dξ` and `∂ξ/∂r`, one row per atom.
pub(crate) type DihedralGradient = (f64, [[f64; 3]; 4]);

/// One cosine `k (1 + cos(n φ − δ))`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cosine {
    pub k: f64,
    pub periodicity: f64,
    /// δ in radians.
    pub phase: f64,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Dihedral {
    pub atoms: [usize; 4],
    pub series: Vec<Cosine>,
}

#[derive(Clone, Debug)]
pub struct Torsions {
    dihedrals: Vec<Dihedral>,
    periodic_box: Option<PeriodicBox>,
    /// The first phase of a parallel gradient ([`super::scratch`]).
    scratch: Scratch<DihedralGradient>,
}

#[inline(always)]
fn cross<T: Scalar>(a: &[T; 3], b: &[T; 3]) -> [T; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[inline(always)]
fn dot<T: Scalar>(a: &[T; 3], b: &[T; 3]) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The dihedral angle and `∂φ/∂r` for the four atoms, from the bond vectors.
#[inline(always)]
pub(crate) fn dihedral_gradient<T: Scalar>(
    r_ij: &[T; 3],
    r_kj: &[T; 3],
    r_kl: &[T; 3],
) -> (T, [[T; 3]; 4]) {
    let m = cross(r_ij, r_kj);
    let n = cross(r_kj, r_kl);
    let kj2 = dot(r_kj, r_kj);
    let kj = kj2.sqrt();
    let mm = dot(&m, &m);
    let nn = dot(&n, &n);
    let phi = (kj * dot(r_ij, &n)).atan2(dot(&m, &n));
    let gi: [T; 3] = std::array::from_fn(|a| kj * m[a] / mm);
    let gl: [T; 3] = std::array::from_fn(|a| -(kj * n[a] / nn));
    let p = dot(r_ij, r_kj) / kj2;
    let s = dot(r_kl, r_kj) / kj2;
    let one = T::constant(1.0);
    let gj: [T; 3] = std::array::from_fn(|a| -((one - p) * gi[a]) - s * gl[a]);
    let gk: [T; 3] = std::array::from_fn(|a| -((one - s) * gl[a]) - p * gi[a]);
    (phi, [gi, gj, gk, gl])
}

impl Torsions {
    pub fn new(dihedrals: Vec<Dihedral>, periodic_box: Option<PeriodicBox>) -> Self {
        Torsions {
            scratch: Scratch::with_len_from(dihedrals.len(), PARALLEL_MIN_DIHEDRALS),
            dihedrals,
            periodic_box,
        }
    }

    pub fn dihedrals(&self) -> &[Dihedral] {
        &self.dihedrals
    }

    #[inline(always)]
    fn difference<T: Scalar>(&self, q: &[f64], v: Option<&[f64]>, a: usize, b: usize) -> [T; 3] {
        difference(self.periodic_box.as_ref(), q, v, a, b)
    }

    fn angle_of(&self, dihedral: &Dihedral, q: &[f64]) -> f64 {
        let [i, j, k, l] = dihedral.atoms;
        let (phi, _) = dihedral_angle_only(
            &self.difference::<f64>(q, None, i, j),
            &self.difference::<f64>(q, None, k, j),
            &self.difference::<f64>(q, None, k, l),
        );
        phi
    }

    /// One dihedral's `Σ_m k_m (1 + cos(n_m φ − δ_m))`.
    fn energy_of(&self, dihedral: &Dihedral, q: &[f64]) -> f64 {
        let phi = self.angle_of(dihedral, q);
        dihedral
            .series
            .iter()
            .map(|c| c.k * (1.0 + (c.periodicity * phi - c.phase).cos()))
            .sum::<f64>()
    }

    /// `dV/dφ` and `∂φ/∂r` of one dihedral (shifted along `direction` for dual numbers).
    #[inline(always)]
    fn derivative<T: Scalar>(
        &self,
        dihedral: &Dihedral,
        q: &[f64],
        direction: Option<&[f64]>,
    ) -> (T, [[T; 3]; 4]) {
        let [i, j, k, l] = dihedral.atoms;
        let r_ij = self.difference::<T>(q, direction, i, j);
        let r_kj = self.difference::<T>(q, direction, k, j);
        let r_kl = self.difference::<T>(q, direction, k, l);
        let (phi, g) = dihedral_gradient(&r_ij, &r_kj, &r_kl);
        // dV/dφ = −Σ k n sin(nφ − δ)
        let mut dv = T::constant(0.0);
        for c in &dihedral.series {
            let arg = T::constant(c.periodicity) * phi - T::constant(c.phase);
            dv = dv - T::constant(c.k * c.periodicity) * arg.sin();
        }
        (dv, g)
    }
}

/// Adds `part(dV/dξ · ∂ξ/∂r)` of one dihedral (`∂ξ/∂r` in `g`, one row per atom) to `out`.
#[inline(always)]
pub(crate) fn scatter<T: Scalar>(
    out: &mut [f64],
    atoms: [usize; 4],
    dv: T,
    g: &[[T; 3]; 4],
    part: impl Fn(T) -> f64,
) {
    for (atom, gradient) in atoms.into_iter().zip(g) {
        for axis in 0..3 {
            out[3 * atom + axis] += part(dv * gradient[axis]);
        }
    }
}

/// The [`ForceTerm`] methods a dihedral term shares, written into its `impl ForceTerm`: the
/// class (bonded); the energy, the sum of its `energy_of` over `dihedrals`; the gradient and
/// the Hessian-vector product from its per-dihedral `derivative` (on `f64` and on dual
/// numbers; `Dual` and [`scatter`] in scope, the gradient in two phases for large terms,
/// through a `scratch: Scratch<DihedralGradient>` field); the couplings and the count.
macro_rules! dihedral_term_methods {
    () => {
        fn class(&self) -> TermClass {
            TermClass::Bonded
        }

        fn energy(&self, q: &[f64]) -> f64 {
            self.dihedrals.iter().map(|d| self.energy_of(d, q)).sum()
        }

        /// From `PARALLEL_MIN_DIHEDRALS` dihedrals on, in a pool of several threads, in two
        /// phases ([`crate::forces::scratch`]): every dihedral's `derivative` in parallel,
        /// then the same [`scatter`] in dihedral order: the bits of the serial loop.
        fn add_gradient(&self, q: &[f64], gradient: &mut [f64]) {
            use crate::forces::scratch::{PARALLEL_MIN_DIHEDRALS, parallel_from};
            let n = self.dihedrals.len();
            if parallel_from(n, PARALLEL_MIN_DIHEDRALS) {
                let compute = |k: usize| self.derivative::<f64>(&self.dihedrals[k], q, None);
                self.scratch.two_phase(n, compute, |k, (dv, g)| {
                    scatter(gradient, self.dihedrals[k].atoms, *dv, g, |x| x)
                });
                return;
            }
            for d in &self.dihedrals {
                let (dv, g) = self.derivative::<f64>(d, q, None);
                scatter(gradient, d.atoms, dv, &g, |x| x);
            }
        }

        fn add_hessian_vector(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
            for d in &self.dihedrals {
                let (dv, g) = self.derivative::<Dual>(d, q, Some(v));
                scatter(out, d.atoms, dv, &g, |x| x.derivative);
            }
        }

        fn couplings(&self) -> Vec<Vec<usize>> {
            self.dihedrals.iter().map(|d| d.atoms.to_vec()).collect()
        }

        fn interaction_count(&self) -> usize {
            self.dihedrals.len()
        }
    };
}
pub(crate) use dihedral_term_methods;

/// `r_a − r_b` (minimum image), shifted by `ε (v_a − v_b)`.
#[inline(always)]
pub(crate) fn difference<T: Scalar>(
    periodic_box: Option<&PeriodicBox>,
    q: &[f64],
    v: Option<&[f64]>,
    a: usize,
    b: usize,
) -> [T; 3] {
    std::array::from_fn(|axis| {
        let mut d = q[3 * a + axis] - q[3 * b + axis];
        if let Some(periodic_box) = periodic_box {
            d = periodic_box.wrap(axis, d);
        }
        let tangent = v.map_or(0.0, |v| v[3 * a + axis] - v[3 * b + axis]);
        T::seeded(d, tangent)
    })
}

/// φ alone (for the energy).
#[inline(always)]
fn dihedral_angle_only(r_ij: &[f64; 3], r_kj: &[f64; 3], r_kl: &[f64; 3]) -> (f64, ()) {
    let m = cross(r_ij, r_kj);
    let n = cross(r_kj, r_kl);
    let kj = dot(r_kj, r_kj).sqrt();
    ((kj * dot(r_ij, &n)).atan2(dot(&m, &n)), ())
}

/// The dihedral angle of four points (for reports and tests), IUPAC sign.
pub fn dihedral_angle(ri: [f64; 3], rj: [f64; 3], rk: [f64; 3], rl: [f64; 3]) -> f64 {
    let d = |a: [f64; 3], b: [f64; 3]| -> [f64; 3] { std::array::from_fn(|k| a[k] - b[k]) };
    dihedral_angle_only(&d(ri, rj), &d(rk, rj), &d(rk, rl)).0
}

impl ForceTerm for Torsions {
    fn kind(&self) -> &'static str {
        "torsion"
    }

    dihedral_term_methods!();
}
