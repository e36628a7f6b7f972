//! `[[terms]]`: the level of each term, and what every term builder shares (numbers with
//! their checks, sites, pairs, rest lengths from the geometry). One builder per term kind
//! lives in `bonds.rs`, `pairs.rs` and `fields.rs`.

use std::collections::BTreeMap;

use toml::Spanned;

use super::sites::Names;
use super::{Builder, Group, Reference, TermSpec};
use crate::error::{Error, Result};
use crate::forces::{ForceTerm, Site};
use crate::settings::Value;
use crate::split::Assignment;
use crate::system::PeriodicBox;

/// The scene as the terms see it.
pub(super) struct SceneSoFar<'a> {
    pub dim: usize,
    pub parameters: &'a BTreeMap<String, f64>,
    pub names: &'a Names,
    /// Starting positions, `n × dim`.
    pub q: &'a [f64],
    pub masses: &'a [f64],
    pub periodic_box: Option<PeriodicBox>,
}

/// One term being built: the scene, where the term is in the file and what to call it.
pub(super) struct TermBuilder<'a> {
    pub builder: &'a Builder<'a>,
    pub scene: &'a SceneSoFar<'a>,
    pub offset: usize,
    /// `term "name"`, for messages.
    pub what: String,
}

impl Builder<'_> {
    /// A term, its name (`term {index}` when it has none) and its level.
    pub(super) fn build_term(
        &self,
        spanned: &Spanned<TermSpec>,
        index: usize,
        scene: &SceneSoFar,
    ) -> Result<(String, Box<dyn ForceTerm>, Assignment)> {
        let offset = spanned.span().start;
        let spec = spanned.get_ref();
        let (name, group, level) = spec.placement();
        let label = name.clone().unwrap_or_else(|| format!("term {index}"));
        let what = format!("term \"{label}\"");
        let assignment = match (group, level) {
            (Some(_), Some(_)) => {
                return Err(self.error_at(
                    offset,
                    format!("{what} gives both group and level; give one"),
                ));
            }
            (Some(Group::Fast), None) => Assignment::Fast,
            (Some(Group::Slow), None) => Assignment::Slow,
            (None, Some(level)) => Assignment::Level(level),
            (None, None) => Assignment::Default,
        };
        let t = TermBuilder {
            builder: self,
            scene,
            offset,
            what,
        };
        let term = match spec {
            TermSpec::Spring(s) => t.spring(s)?,
            TermSpec::Chain(s) => t.chain(s)?,
            TermSpec::QuarticSpring(s) => t.quartic_spring(s)?,
            TermSpec::Angle(s) => t.angle(s)?,
            TermSpec::LennardJones(s) => t.lennard_jones(s)?,
            TermSpec::Gravity(s) => t.gravity(s)?,
            TermSpec::Field(s) => t.field(s)?,
            TermSpec::FemString(s) => t.fem_string(s)?,
            TermSpec::Pendulum(s) => t.pendulum(s)?,
            TermSpec::InversePower(s) => t.inverse_power(s)?,
            TermSpec::Magnetic(s) => t.magnetic(s)?,
            TermSpec::ExternalField(s) => t.external_field(s)?,
        };
        Ok((label, term, assignment))
    }
}

impl TermBuilder<'_> {
    /// An error at the term's line.
    pub fn error(&self, message: impl Into<String>) -> Error {
        self.builder.error_at(self.offset, message)
    }

    pub fn number(&self, v: &Value, key: &str) -> Result<f64> {
        let what = format!("{}: {key}", self.what);
        self.builder
            .evaluate(v, self.scene.parameters, &what, self.offset)
            .map_err(|e| e.key(key))
    }

    pub fn non_negative(&self, v: &Value, key: &str) -> Result<f64> {
        let x = self.number(v, key)?;
        if x < 0.0 {
            return Err(self
                .error(format!("{}: {key} must be ≥ 0", self.what))
                .key(key)
                .expected("≥ 0")
                .got(x.to_string()));
        }
        Ok(x)
    }

    pub fn positive(&self, v: &Value, key: &str) -> Result<f64> {
        let x = self.number(v, key)?;
        if x <= 0.0 {
            return Err(self
                .error(format!("{}: {key} must be positive", self.what))
                .key(key)
                .expected("a positive number")
                .got(x.to_string()));
        }
        Ok(x)
    }

    /// A particle's or anchor's charge, default 1.
    pub fn charge(&self, v: &Option<Value>) -> Result<f64> {
        match v {
            Some(v) => self.number(v, "charge"),
            None => Ok(1.0),
        }
    }

    pub fn site(&self, reference: &Reference) -> Result<Site> {
        let names = self.scene.names;
        self.builder.site(reference, names, &self.what, self.offset)
    }

    pub fn particle(&self, reference: &Reference) -> Result<usize> {
        let names = self.scene.names;
        self.builder
            .particle(reference, names, &self.what, self.offset)
    }

    /// The listed particles, default all.
    pub fn members(&self, list: &Option<Vec<Reference>>) -> Result<Vec<usize>> {
        let names = self.scene.names;
        self.builder
            .particle_list(list, names, &self.what, self.offset)
    }

    /// A site's starting position, padded to 3-D.
    pub fn position(&self, site: &Site) -> [f64; 3] {
        let dim = self.scene.dim;
        match *site {
            Site::Particle(i) => {
                let mut x = [0.0; 3];
                x[..dim].copy_from_slice(&self.scene.q[i * dim..(i + 1) * dim]);
                x
            }
            Site::Fixed(x) => x,
        }
    }

    /// The starting distance between two sites (nearest image in a box).
    fn distance(&self, a: &Site, b: &Site) -> f64 {
        let (xa, xb) = (self.position(a), self.position(b));
        (0..self.scene.dim)
            .map(|k| {
                let mut d = xb[k] - xa[k];
                if let Some(pb) = &self.scene.periodic_box {
                    d = pb.wrap(k, d);
                }
                d * d
            })
            .sum::<f64>()
            .sqrt()
    }

    /// A rest length: given, or `"geometry"` (the default where `default_geometry`) for the
    /// starting distance, else 0.
    pub fn rest_length(
        &self,
        value: &Option<Value>,
        a: &Site,
        b: &Site,
        default_geometry: bool,
    ) -> Result<f64> {
        match value {
            Some(Value::Expression(text)) if text == "geometry" => Ok(self.distance(a, b)),
            Some(v) => self.non_negative(v, "rest_length"),
            None if default_geometry => Ok(self.distance(a, b)),
            None => Ok(0.0),
        }
    }

    /// The pairs of `between` (one) or `pairs` (a list): never two anchors, never a
    /// particle with itself.
    pub fn pairs_of(
        &self,
        between: &Option<[Reference; 2]>,
        pairs: &Option<Vec<[Reference; 2]>>,
    ) -> Result<Vec<(Site, Site)>> {
        let what = &self.what;
        let list: Vec<&[Reference; 2]> = match (between, pairs) {
            (Some(one), None) => vec![one],
            (None, Some(many)) => many.iter().collect(),
            _ => {
                return Err(self.error(format!("{what} needs exactly one of `between` or `pairs`")));
            }
        };
        list.into_iter()
            .map(|[a, b]| {
                let (sa, sb) = (self.site(a)?, self.site(b)?);
                if matches!((sa, sb), (Site::Fixed(_), Site::Fixed(_))) {
                    return Err(self.error(format!(
                        "{what} joins two anchors ({a} and {b}); one end must be a particle"
                    )));
                }
                if sa.particle().is_some() && sa == sb {
                    return Err(self.error(format!("{what} joins {a} to itself")));
                }
                Ok((sa, sb))
            })
            .collect()
    }

    /// The pairs of a spring-like term, each with the potential `bond` makes of its rest
    /// length (default 0).
    pub fn springs<B>(
        &self,
        between: &Option<[Reference; 2]>,
        pairs: &Option<Vec<[Reference; 2]>>,
        rest: &Option<Value>,
        bond: impl Fn(f64) -> B,
    ) -> Result<Vec<(Site, Site, B)>> {
        self.pairs_of(between, pairs)?
            .into_iter()
            .map(|(a, b)| Ok((a, b, bond(self.rest_length(rest, &a, &b, false)?))))
            .collect()
    }
}
