//! Harmonic angle `V = (k/2)(θ − θ₀)²`, θ the angle at the middle site `j` of `i–j–k`.
//! Bonded: fast by default. Needs `dim ≥ 2` (in one dimension every angle is 0 or π,
//! where θ is not differentiable).
//!
//! With `u = r_i − r_j`, `w = r_k − r_j`: θ = atan2(|u × w|, u·w) (accurate near 0 and π,
//! unlike acos), `∂θ/∂u = ((u·w) u/|u|² − w)/|u × w|`, `∂θ/∂w = ((u·w) w/|w|² − u)/|u × w|`
//! and `∂θ/∂r_j = −∂θ/∂u − ∂θ/∂w`. The Hessian-vector product differentiates this
//! gradient in the direction `v` with dual numbers ([`super::dual`]): exact, and one code
//! path for both.

use super::PeriodicBox;
use super::dual::{Dual, Scalar};
use super::scratch::{Scratch, parallel};
use super::{
    ForceTerm, RestGeometry, Site, TermClass, add_to_site, site_in_block, site_position,
    site_vector, with_dim,
};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AngleBend {
    pub sites: [Site; 3],
    pub stiffness: f64,
    pub rest_angle: f64,
}

#[derive(Clone, Debug)]
pub struct HarmonicAngles {
    dim: usize,
    angles: Vec<AngleBend>,
    periodic_box: Option<PeriodicBox>,
    /// Gradients on the end sites `i`, `k` per angle, for large systems ([`super::scratch`]).
    scratch: Scratch<[f64; 6]>,
}

impl HarmonicAngles {
    pub fn new(dim: usize, angles: Vec<AngleBend>, periodic_box: Option<PeriodicBox>) -> Self {
        assert!((2..=3).contains(&dim), "angles need dimension 2 or 3");
        let scratch = Scratch::with_len(angles.len());
        HarmonicAngles {
            dim,
            angles,
            periodic_box,
            scratch,
        }
    }

    /// Arm vectors `u = r_i − r_j`, `w = r_k − r_j` (minimum image), shifted by `ε v`.
    #[inline(always)]
    fn arms<T: Scalar, const D: usize>(
        &self,
        angle: &AngleBend,
        q: &[f64],
        direction: Option<&[f64]>,
    ) -> ([T; D], [T; D]) {
        let [si, sj, sk] = &angle.sites;
        let (ri, rj, rk) = (
            site_position::<D>(si, q),
            site_position::<D>(sj, q),
            site_position::<D>(sk, q),
        );
        let (vi, vj, vk) = match direction {
            Some(v) => (
                site_vector::<D>(si, v),
                site_vector::<D>(sj, v),
                site_vector::<D>(sk, v),
            ),
            None => ([0.0; D], [0.0; D], [0.0; D]),
        };
        let arm = |ra: [f64; D], va: [f64; D]| -> [T; D] {
            std::array::from_fn(|a| {
                let mut d = ra[a] - rj[a];
                if let Some(periodic_box) = &self.periodic_box {
                    d = periodic_box.wrap(a, d);
                }
                T::seeded(d, va[a] - vj[a])
            })
        };
        (arm(ri, vi), arm(rk, vk))
    }

    fn energy_d<const D: usize>(&self, q: &[f64]) -> f64 {
        self.angles
            .iter()
            .map(|angle| {
                let (u, w) = self.arms::<f64, D>(angle, q, None);
                let stretch = bend_angle(&u, &w) - angle.rest_angle;
                0.5 * angle.stiffness * stretch * stretch
            })
            .sum()
    }

    /// Adds the gradient (`direction = None`) or the Hessian-vector product along
    /// `direction`, both from [`angle_gradient`], of the angles `range`, with particles
    /// numbered from `first` (a block's slices; `0` and every angle for the whole term).
    fn accumulate<T: Scalar, const D: usize>(
        &self,
        (q, direction): (&[f64], Option<&[f64]>),
        out: &mut [f64],
        part: impl Fn(T) -> f64,
        (first, range): (usize, std::ops::Range<usize>),
    ) {
        for angle in &self.angles[range] {
            let angle = AngleBend {
                sites: angle.sites.map(|site| site_in_block(site, first)),
                ..*angle
            };
            let (u, w) = self.arms::<T, D>(&angle, q, direction);
            let (on_i, on_k) = angle_gradient(&u, &w, angle.stiffness, angle.rest_angle);
            let gi: [f64; D] = std::array::from_fn(|a| part(on_i[a]));
            let gk: [f64; D] = std::array::from_fn(|a| part(on_k[a]));
            add_sites(&angle, out, gi, gk);
        }
    }

    /// The gradient in two phases ([`super::scratch`]): the same bits as
    /// [`HarmonicAngles::accumulate`].
    fn gradient_two_phase<const D: usize>(&self, q: &[f64], out: &mut [f64]) {
        let compute = |k: usize| {
            let angle = &self.angles[k];
            let (u, w) = self.arms::<f64, D>(angle, q, None);
            let (on_i, on_k) = angle_gradient(&u, &w, angle.stiffness, angle.rest_angle);
            let mut result = [0.0; 6];
            result[..D].copy_from_slice(&on_i);
            result[3..3 + D].copy_from_slice(&on_k);
            result
        };
        self.scratch
            .two_phase(self.angles.len(), compute, |k, result| {
                let gi: [f64; D] = std::array::from_fn(|a| result[a]);
                let gk: [f64; D] = std::array::from_fn(|a| result[3 + a]);
                add_sites(&self.angles[k], out, gi, gk);
            });
    }
}

/// `out += ` the gradient of one angle: `gi`, `gk` on its end sites, `−gi − gk` on the middle.
#[inline(always)]
fn add_sites<const D: usize>(angle: &AngleBend, out: &mut [f64], gi: [f64; D], gk: [f64; D]) {
    let gj: [f64; D] = std::array::from_fn(|a| -gi[a] - gk[a]);
    add_to_site(&angle.sites[0], out, &gi);
    add_to_site(&angle.sites[1], out, &gj);
    add_to_site(&angle.sites[2], out, &gk);
}

#[inline(always)]
fn dot_t<T: Scalar, const D: usize>(x: &[T; D], y: &[T; D]) -> T {
    let mut sum = T::constant(0.0);
    for a in 0..D {
        sum = sum + x[a] * y[a];
    }
    sum
}

/// θ between arms `u` and `w`.
#[inline(always)]
fn bend_angle<T: Scalar, const D: usize>(u: &[T; D], w: &[T; D]) -> T {
    let uu = dot_t(u, u);
    let ww = dot_t(w, w);
    let uw = dot_t(u, w);
    (uu * ww - uw * uw).sqrt().atan2(uw)
}

/// Gradient of `(k/2)(θ − θ₀)²` with respect to the two arm vectors.
#[inline(always)]
fn angle_gradient<T: Scalar, const D: usize>(
    u: &[T; D],
    w: &[T; D],
    stiffness: f64,
    rest_angle: f64,
) -> ([T; D], [T; D]) {
    let uu = dot_t(u, u);
    let ww = dot_t(w, w);
    let uw = dot_t(u, w);
    let cross = (uu * ww - uw * uw).sqrt();
    let theta = cross.atan2(uw);
    let scale = T::constant(stiffness) * (theta - T::constant(rest_angle)) / cross;
    let on_u = std::array::from_fn(|a| scale * (uw * u[a] / uu - w[a]));
    let on_w = std::array::from_fn(|a| scale * (uw * w[a] / ww - u[a]));
    (on_u, on_w)
}

impl ForceTerm for HarmonicAngles {
    fn kind(&self) -> &'static str {
        "angle"
    }

    fn class(&self) -> TermClass {
        TermClass::Bonded
    }

    fn energy(&self, q: &[f64]) -> f64 {
        with_dim!(self.dim, D => self.energy_d::<D>(q))
    }

    fn add_gradient(&self, q: &[f64], gradient: &mut [f64]) {
        // One thread: the serial loop (the two phases give the same bits).
        if parallel(self.angles.len()) {
            with_dim!(self.dim, D => self.gradient_two_phase::<D>(q, gradient))
        } else {
            let all = (0, 0..self.angles.len());
            with_dim!(self.dim, D => self.accumulate::<f64, D>((q, None), gradient, |x| x, all))
        }
    }

    fn add_hessian_vector(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        let all = (0, 0..self.angles.len());
        with_dim!(self.dim, D => self.accumulate::<Dual, D>((q, Some(v)), out, |x| x.derivative, all))
    }

    fn add_block_gradient(
        &self,
        q: &[f64],
        gradient: &mut [f64],
        first: usize,
        range: std::ops::Range<usize>,
    ) -> bool {
        with_dim!(self.dim, D => self.accumulate::<f64, D>((q, None), gradient, |x| x, (first, range)));
        true
    }

    fn couplings(&self) -> Vec<Vec<usize>> {
        self.angles
            .iter()
            .map(|angle| angle.sites.iter().filter_map(Site::particle).collect())
            .collect()
    }

    fn interaction_count(&self) -> usize {
        self.angles.len()
    }

    fn rest_geometry(&self) -> Vec<RestGeometry> {
        self.angles
            .iter()
            .filter(|angle| angle.stiffness > 0.0)
            .map(|angle| RestGeometry::Angle {
                sites: angle.sites,
                angle: angle.rest_angle,
            })
            .collect()
    }
}
