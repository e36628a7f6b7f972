//! Force terms: one file per kind of interaction.
//!
//! Every term gives its energy, adds its gradient, and adds a Hessian-vector product
//! `W_qq(q)·v` — the mollified impulse methods propagate Jacobians with it (GSS98
//! section 2). Every term also reports which particles each of its interactions couples:
//! the splitter builds the fast-force graph, its connected components (the blocks of the
//! averaging Jacobian) and the fast/mixed/slow particle classes of MEMM18 section 4.1 from
//! that list.
//!
//! Central pair interactions (springs, FPU springs, Lennard-Jones, gravity) share one
//! chain-rule kernel, [`pair`]: each is written as `χ(s)` with `s = |r_b − r_a|²`, the
//! form GSS98 section 2 recommends for Hessian products, and its file gives only
//! `χ`, `χ′` and `χ″`.

pub mod angle;
pub mod cell_list;
pub mod clusters;
pub mod components;
pub mod coulomb;
pub mod distance_split;
pub mod dual;
pub mod ewald;
pub mod external_field;
pub mod field;
pub mod gravity;
pub mod harmonic_dihedral;
pub mod inverse_power;
pub mod lennard_jones;
pub mod magnetic;
pub mod nonbonded;
pub mod pair;
pub mod pendulum;
mod periodic_box;
pub mod quartic;
pub mod scratch;
pub mod simd;
pub mod spring;
pub mod string;
pub mod switch;
pub mod torsion;

pub(crate) use periodic_box::MinimumImage;
pub use periodic_box::{PeriodicBox, minimum_image, minimum_image_baseline, near_image};

/// One end of an interaction: a particle (a degree of freedom) or a fixed point in space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Site {
    Particle(usize),
    /// A fixed anchor; only the first `dim` coordinates are used.
    Fixed([f64; 3]),
}

impl Site {
    pub fn particle(&self) -> Option<usize> {
        match *self {
            Site::Particle(i) => Some(i),
            Site::Fixed(_) => None,
        }
    }
}

/// How the splitter treats a term by default: bonded terms are fast, non-bonded slow.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TermClass {
    Bonded,
    Nonbonded,
}

/// A geometry at which a bonded term is at rest: what the equilibrium mollifier
/// ([`crate::integrators::equilibrium_molly`]) holds fixed when it projects the positions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RestGeometry {
    /// The distance between two sites is `length` at rest (a harmonic spring).
    Distance { sites: [Site; 2], length: f64 },
    /// The angle at the middle site is `angle` (radians) at rest (a harmonic angle).
    Angle { sites: [Site; 3], angle: f64 },
}

/// The floating-point precision of a term's arithmetic.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Precision {
    /// f64 throughout.
    #[default]
    Double,
    /// f32 arithmetic with f64 accumulation, where a term supports it (the non-bonded pair
    /// kernel and the PME mesh); f64 elsewhere.
    Mixed,
}

impl Precision {
    pub fn parse(name: &str) -> Option<Precision> {
        match name {
            "double" => Some(Precision::Double),
            "mixed" => Some(Precision::Mixed),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Precision::Double => "double",
            Precision::Mixed => "mixed",
        }
    }
}

/// A potential-energy term `V(q)` over the flat coordinate array `q` (`n × dim`).
pub trait ForceTerm: Send + Sync {
    /// Short kind name for tables and messages (`"spring"`, `"lennard-jones"`).
    fn kind(&self) -> &'static str;

    fn class(&self) -> TermClass;

    fn energy(&self, q: &[f64]) -> f64;

    /// `gradient += ∇V(q)` (the force is minus this).
    fn add_gradient(&self, q: &[f64], gradient: &mut [f64]);

    /// `out += ∇²V(q) · v`.
    fn add_hessian_vector(&self, q: &[f64], v: &[f64], out: &mut [f64]);

    /// `gradient += ∇V` of the interactions `range` only, all of whose particles lie in a
    /// block that starts at particle `first`: `q` and `gradient` are the block's slices.
    /// The additions are those of [`ForceTerm::add_gradient`] for these interactions, in
    /// the same order. `false` (and nothing added) for a term that cannot (the default).
    fn add_block_gradient(
        &self,
        _q: &[f64],
        _gradient: &mut [f64],
        _first: usize,
        _range: std::ops::Range<usize>,
    ) -> bool {
        false
    }

    /// The particles each interaction of this term couples (anchors left out).
    fn couplings(&self) -> Vec<Vec<usize>>;

    /// How many elementary interactions (one spring, one pair, one angle) the term holds.
    fn interaction_count(&self) -> usize;

    /// The smallest distance between the two ends of any of its interactions, for step
    /// controls based on particle separation (HL97 section 3, `R = r_min^{-α}`); `None`
    /// for a term that is not made of pair interactions.
    fn min_distance(&self, _q: &[f64]) -> Option<f64> {
        None
    }

    /// The geometry of each interaction at rest, for terms whose energy has a strict
    /// minimum there (harmonic springs of positive rest length and stiffness, harmonic
    /// angles); empty for the others.
    fn rest_geometry(&self) -> Vec<RestGeometry> {
        Vec::new()
    }

    /// The vector potential of a velocity-dependent (magnetic) term, CFM25 5.7; `None`
    /// for a potential-energy term. Such a term has no potential energy and no gradient:
    /// only integrators that say [`handles_magnetic`](crate::integrators::Integrator::handles_magnetic)
    /// can integrate a system with one, and the run refuses the others.
    fn magnetic(&self) -> Option<&magnetic::MagneticTerm> {
        None
    }

    /// Whether the term is translation invariant in exact arithmetic though its numbers
    /// are not to round-off: PME's mesh interpolation leaves a net force of ~1e-3 of its
    /// forces. The test of whether a system conserves its momentum (`system::velocities`)
    /// leaves such a term out rather than take it for an external field. By default
    /// `false`: a term is judged by its numbers.
    fn invariant_by_construction(&self) -> bool {
        false
    }

    /// The energy split into named parts, for reports (`longstep forces`): a term that
    /// computes several kinds of interaction in one pass (Lennard-Jones and Coulomb) names
    /// each. By default one part named after [`ForceTerm::kind`].
    fn energy_components(&self, q: &[f64]) -> Vec<(&'static str, f64)> {
        vec![(self.kind(), self.energy(q))]
    }

    /// Compute in `precision` from now on; whether the term has that choice (terms
    /// without one stay in double precision and say `false`).
    fn set_precision(&self, _precision: Precision) -> bool {
        false
    }

    /// Forget every pair list and cached result, so the next evaluation rebuilds its lists
    /// at the positions it is given, as a freshly built term would. A checkpoint does this
    /// only to a term that keeps lists but has no [`ForceTerm::list_state`]
    /// ([`crate::split::ForceSplit::rebuild_lists_without_state`]), as the continued run
    /// builds such a term's lists afresh. Nothing to do for a term without lists.
    fn rebuild_lists(&self) {}

    /// What a checkpoint must hold to rebuild this term's pair lists exactly as they are
    /// now (e.g. the positions each list was last built at): `None` for a term without
    /// lists or before its first build. A continued run hands it to
    /// [`ForceTerm::restore_lists`], so both runs sum over the same pairs in the same
    /// order without the run that writes the checkpoint rebuilding anything.
    fn list_state(&self) -> Option<serde_json::Value> {
        None
    }

    /// Rebuild this term's pair lists from [`ForceTerm::list_state`] of the same term in
    /// the run that wrote the checkpoint, and forget cached results. A state this term
    /// cannot use is an error naming what is wrong.
    fn restore_lists(&self, _state: &serde_json::Value) -> crate::error::Result<()> {
        Ok(())
    }

    /// The concrete term, for term-specific settings and reports (tests, benchmarks):
    /// `term.as_any().and_then(|t| t.downcast_ref::<Nonbonded>())`. `None` by default.
    fn as_any(&self) -> Option<&dyn std::any::Any> {
        None
    }
}

/// Run `$body` with `$d` bound to the const dimension `1`, `2` or `3`, so inner loops are
/// compiled once per dimension and a 1-D chain never touches a second coordinate.
macro_rules! with_dim {
    ($dim:expr, $d:ident => $body:expr) => {
        match $dim {
            1 => {
                const $d: usize = 1;
                $body
            }
            2 => {
                const $d: usize = 2;
                $body
            }
            3 => {
                const $d: usize = 3;
                $body
            }
            other => unreachable!("dimension {other} was validated to be 1, 2 or 3"),
        }
    };
}
pub(crate) use with_dim;

/// Coordinates of a site as a `D`-vector.
#[inline(always)]
pub(crate) fn site_position<const D: usize>(site: &Site, q: &[f64]) -> [f64; D] {
    match *site {
        Site::Particle(i) => std::array::from_fn(|a| q[i * D + a]),
        Site::Fixed(x) => std::array::from_fn(|a| x[a]),
    }
}

/// The site with its particle numbered from `first` (the start of a block).
#[inline(always)]
pub(crate) fn site_in_block(site: Site, first: usize) -> Site {
    match site {
        Site::Particle(i) => Site::Particle(i - first),
        fixed => fixed,
    }
}

/// Components of `v` on a site (zero for a fixed site, which does not move).
#[inline(always)]
pub(crate) fn site_vector<const D: usize>(site: &Site, v: &[f64]) -> [f64; D] {
    match *site {
        Site::Particle(i) => std::array::from_fn(|a| v[i * D + a]),
        Site::Fixed(_) => [0.0; D],
    }
}

/// `out[site] += value` (nothing for a fixed site).
#[inline(always)]
pub(crate) fn add_to_site<const D: usize>(site: &Site, out: &mut [f64], value: &[f64; D]) {
    if let Site::Particle(i) = *site {
        for a in 0..D {
            out[i * D + a] += value[a];
        }
    }
}

#[inline(always)]
pub(crate) fn dot<const D: usize>(x: &[f64; D], y: &[f64; D]) -> f64 {
    let mut sum = 0.0;
    for a in 0..D {
        sum += x[a] * y[a];
    }
    sum
}
