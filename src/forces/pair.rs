//! The chain rule shared by all central pair interactions.
//!
//! A pair potential is `V = χ(s)` with `s = |d|²`, `d = r_b − r_a` (minimum image in a
//! periodic box). Then
//!
//! * `∇_b V = 2χ′(s) d`, `∇_a V = −∇_b V`;
//! * the Hessian block is `H = 2χ′(s) I + 4χ″(s) d dᵀ`, with `∂²V/∂r_b² = ∂²V/∂r_a² = H`
//!   and `∂²V/∂r_a∂r_b = −H`, so `(∇²V v)_b = H (v_b − v_a) = −(∇²V v)_a`.
//!
//! Each kind of pair term (spring, FPU spring, Lennard-Jones, gravity) only supplies
//! `χ`, `χ′`, `χ″` through [`PairPotential`].

use super::PeriodicBox;
use super::scratch::{Scratch, parallel};
use super::{
    ForceTerm, RestGeometry, Site, TermClass, add_to_site, dot, site_in_block, site_position,
    site_vector, with_dim,
};

/// A radial potential written in the squared distance `s`.
pub trait PairPotential: Copy + Send + Sync {
    /// `χ(s)`.
    fn value(&self, s: f64) -> f64;
    /// `χ′(s)`.
    fn d1(&self, s: f64) -> f64;
    /// `(χ′(s), χ″(s))`.
    fn d1_d2(&self, s: f64) -> (f64, f64);
    /// The distance at which the potential has a strict minimum, if it is a bond that
    /// holds one ([`ForceTerm::rest_geometry`]).
    fn rest_length(&self) -> Option<f64> {
        None
    }
}

#[derive(Clone, Copy, Debug)]
pub struct Pair<P> {
    pub a: Site,
    pub b: Site,
    pub potential: P,
}

/// A list of pair interactions of one kind.
#[derive(Clone, Debug)]
pub struct PairTerm<P> {
    kind: &'static str,
    class: TermClass,
    dim: usize,
    pairs: Vec<Pair<P>>,
    periodic_box: Option<PeriodicBox>,
    /// The gradient on site `b` per pair, for large systems ([`super::scratch`]).
    scratch: Scratch<[f64; 3]>,
}

impl<P: PairPotential> PairTerm<P> {
    pub fn new(
        kind: &'static str,
        class: TermClass,
        dim: usize,
        pairs: Vec<Pair<P>>,
        periodic_box: Option<PeriodicBox>,
    ) -> Self {
        assert!((1..=3).contains(&dim), "dimension must be 1, 2 or 3");
        let scratch = Scratch::with_len(pairs.len());
        PairTerm {
            kind,
            class,
            dim,
            pairs,
            periodic_box,
            scratch,
        }
    }

    pub fn pairs(&self) -> &[Pair<P>] {
        &self.pairs
    }

    #[inline(always)]
    fn displacement<const D: usize>(&self, pair: &Pair<P>, q: &[f64]) -> [f64; D] {
        let ra = site_position::<D>(&pair.a, q);
        let rb = site_position::<D>(&pair.b, q);
        let mut d: [f64; D] = std::array::from_fn(|k| rb[k] - ra[k]);
        if let Some(periodic_box) = &self.periodic_box {
            for (axis, component) in d.iter_mut().enumerate() {
                *component = periodic_box.wrap(axis, *component);
            }
        }
        d
    }

    fn min_distance_d<const D: usize>(&self, q: &[f64]) -> f64 {
        self.pairs
            .iter()
            .map(|pair| {
                let d = self.displacement::<D>(pair, q);
                dot(&d, &d)
            })
            .fold(f64::INFINITY, f64::min)
            .sqrt()
    }

    fn energy_d<const D: usize>(&self, q: &[f64]) -> f64 {
        self.pairs
            .iter()
            .map(|pair| {
                let d = self.displacement::<D>(pair, q);
                pair.potential.value(dot(&d, &d))
            })
            .sum()
    }

    /// `∇_b V = 2χ′(s) d` of one pair.
    #[inline(always)]
    fn on_b<const D: usize>(&self, pair: &Pair<P>, q: &[f64]) -> [f64; D] {
        let d = self.displacement::<D>(pair, q);
        let scale = 2.0 * pair.potential.d1(dot(&d, &d));
        std::array::from_fn(|k| scale * d[k])
    }

    fn gradient_d<const D: usize>(&self, q: &[f64], gradient: &mut [f64]) {
        self.block_gradient_d::<D>(q, gradient, 0, 0..self.pairs.len());
    }

    /// The gradient of the pairs `range`, in a block starting at particle `first` (the
    /// whole gradient is the block of all pairs from particle 0).
    fn block_gradient_d<const D: usize>(
        &self,
        q: &[f64],
        gradient: &mut [f64],
        first: usize,
        range: std::ops::Range<usize>,
    ) {
        for pair in &self.pairs[range] {
            let pair = Pair {
                a: site_in_block(pair.a, first),
                b: site_in_block(pair.b, first),
                potential: pair.potential,
            };
            add_pair(&pair, gradient, self.on_b::<D>(&pair, q));
        }
    }

    /// The gradient in two phases ([`super::scratch`]): the same bits as
    /// [`PairTerm::gradient_d`].
    fn gradient_two_phase<const D: usize>(&self, q: &[f64], gradient: &mut [f64]) {
        let compute = |k: usize| {
            let on_b = self.on_b::<D>(&self.pairs[k], q);
            std::array::from_fn(|a| if a < D { on_b[a] } else { 0.0 })
        };
        self.scratch
            .two_phase(self.pairs.len(), compute, |k, on_b| {
                add_pair(
                    &self.pairs[k],
                    gradient,
                    std::array::from_fn::<f64, D, _>(|a| on_b[a]),
                );
            });
    }

    fn hessian_vector_d<const D: usize>(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        for pair in &self.pairs {
            let d = self.displacement::<D>(pair, q);
            let (chi1, chi2) = pair.potential.d1_d2(dot(&d, &d));
            let va = site_vector::<D>(&pair.a, v);
            let vb = site_vector::<D>(&pair.b, v);
            let dv: [f64; D] = std::array::from_fn(|k| vb[k] - va[k]);
            let along = 4.0 * chi2 * dot(&d, &dv);
            let on_b: [f64; D] = std::array::from_fn(|k| 2.0 * chi1 * dv[k] + along * d[k]);
            let on_a: [f64; D] = std::array::from_fn(|k| -on_b[k]);
            add_to_site(&pair.b, out, &on_b);
            add_to_site(&pair.a, out, &on_a);
        }
    }
}

/// `gradient += ` one pair's gradient: `on_b` on site `b`, `−on_b` on site `a`.
#[inline(always)]
fn add_pair<P, const D: usize>(pair: &Pair<P>, gradient: &mut [f64], on_b: [f64; D]) {
    let on_a: [f64; D] = std::array::from_fn(|k| -on_b[k]);
    add_to_site(&pair.b, gradient, &on_b);
    add_to_site(&pair.a, gradient, &on_a);
}

impl<P: PairPotential> ForceTerm for PairTerm<P> {
    fn kind(&self) -> &'static str {
        self.kind
    }

    fn class(&self) -> TermClass {
        self.class
    }

    fn energy(&self, q: &[f64]) -> f64 {
        with_dim!(self.dim, D => self.energy_d::<D>(q))
    }

    fn add_gradient(&self, q: &[f64], gradient: &mut [f64]) {
        // One thread: the serial loop (the two phases give the same bits).
        if parallel(self.pairs.len()) {
            with_dim!(self.dim, D => self.gradient_two_phase::<D>(q, gradient))
        } else {
            with_dim!(self.dim, D => self.gradient_d::<D>(q, gradient))
        }
    }

    fn add_hessian_vector(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        with_dim!(self.dim, D => self.hessian_vector_d::<D>(q, v, out))
    }

    fn add_block_gradient(
        &self,
        q: &[f64],
        gradient: &mut [f64],
        first: usize,
        range: std::ops::Range<usize>,
    ) -> bool {
        with_dim!(self.dim, D => self.block_gradient_d::<D>(q, gradient, first, range));
        true
    }

    fn couplings(&self) -> Vec<Vec<usize>> {
        self.pairs
            .iter()
            .map(|pair| [pair.a, pair.b].iter().filter_map(Site::particle).collect())
            .collect()
    }

    fn interaction_count(&self) -> usize {
        self.pairs.len()
    }

    fn rest_geometry(&self) -> Vec<RestGeometry> {
        self.pairs
            .iter()
            .filter_map(|pair| {
                let length = pair.potential.rest_length()?;
                Some(RestGeometry::Distance {
                    sites: [pair.a, pair.b],
                    length,
                })
            })
            .collect()
    }

    fn min_distance(&self, q: &[f64]) -> Option<f64> {
        if self.pairs.is_empty() {
            return None;
        }
        Some(with_dim!(self.dim, D => self.min_distance_d::<D>(q)))
    }
}
