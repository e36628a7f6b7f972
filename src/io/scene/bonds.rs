//! Bonded terms: springs, chains, quartic springs, angles and the finite-element string.

use super::terms::TermBuilder;
use super::{AngleSpec, ChainSpec, FemStringSpec, QuarticSpringSpec, Reference, SpringSpec};
use crate::error::Result;
use crate::forces::ForceTerm;
use crate::forces::angle::{AngleBend, HarmonicAngles};
use crate::forces::quartic::{QuarticBond, quartic_springs};
use crate::forces::spring::{HarmonicBond, harmonic_springs};
use crate::forces::string::FemString;
use crate::settings::Value;

impl TermBuilder<'_> {
    /// `spring`: harmonic springs `(k/2)(r − L)²` between pairs.
    pub fn spring(&self, spec: &SpringSpec) -> Result<Box<dyn ForceTerm>> {
        let stiffness = self.non_negative(&spec.stiffness, "stiffness")?;
        let springs = self.springs(
            &spec.between,
            &spec.pairs,
            &spec.rest_length,
            |rest_length| HarmonicBond {
                stiffness,
                rest_length,
            },
        )?;
        let (dim, periodic_box) = (self.scene.dim, self.scene.periodic_box);
        Ok(Box::new(harmonic_springs(dim, springs, periodic_box)))
    }

    /// `chain`: harmonic springs between consecutive sites; the stiffness may vary along
    /// the chain (it sees the link index `i`), rest lengths default to the geometry.
    pub fn chain(&self, spec: &ChainSpec) -> Result<Box<dyn ForceTerm>> {
        let what = &self.what;
        let chain = self.chain_sites(&spec.particles, &spec.range, &spec.start, &spec.end)?;
        if chain.len() < 2 {
            return Err(self.error(format!("{what}: a chain needs at least two particles")));
        }
        let mut local = self.scene.parameters.clone();
        let springs = chain
            .windows(2)
            .enumerate()
            .map(|(i, link)| {
                local.insert("i".to_string(), i as f64);
                let stiffness = self.builder.evaluate(
                    &spec.stiffness,
                    &local,
                    &format!("{what}: stiffness"),
                    self.offset,
                )?;
                if stiffness < 0.0 {
                    return Err(self.error(format!(
                        "{what}: stiffness of link {i} must be ≥ 0, got {stiffness}"
                    )));
                }
                let (a, b) = (link[0], link[1]);
                let rest_length = self.rest_length(&spec.rest_length, &a, &b, true)?;
                let bond = HarmonicBond {
                    stiffness,
                    rest_length,
                };
                Ok((a, b, bond))
            })
            .collect::<Result<Vec<_>>>()?;
        let (dim, periodic_box) = (self.scene.dim, self.scene.periodic_box);
        Ok(Box::new(harmonic_springs(dim, springs, periodic_box)))
    }

    /// The sites of a chain-like term (see [`super::Builder::chain_sites`]).
    fn chain_sites(
        &self,
        particles: &Option<Vec<Reference>>,
        range: &Option<[Value; 2]>,
        start: &Option<Reference>,
        end: &Option<Reference>,
    ) -> Result<Vec<crate::forces::Site>> {
        let scene = self.scene;
        self.builder.chain_sites(
            particles,
            range,
            start,
            end,
            scene.names,
            scene.parameters,
            &self.what,
            self.offset,
        )
    }

    /// `quartic-spring`: FPU springs `c (r − L)⁴` between pairs.
    pub fn quartic_spring(&self, spec: &QuarticSpringSpec) -> Result<Box<dyn ForceTerm>> {
        let coefficient = self.non_negative(&spec.coefficient, "coefficient")?;
        let springs = self.springs(
            &spec.between,
            &spec.pairs,
            &spec.rest_length,
            |rest_length| QuarticBond {
                coefficient,
                rest_length,
            },
        )?;
        let (dim, periodic_box) = (self.scene.dim, self.scene.periodic_box);
        Ok(Box::new(quartic_springs(dim, springs, periodic_box)))
    }

    /// `angle`: harmonic angles `(k/2)(θ − θ₀)²` at the middle site of each triple; θ₀
    /// defaults to the starting geometry.
    pub fn angle(&self, spec: &AngleSpec) -> Result<Box<dyn ForceTerm>> {
        let (what, dim) = (&self.what, self.scene.dim);
        if dim < 2 {
            return Err(self.error(format!(
                "{what}: angles need dim = 2 or 3 (in 1-D every angle is 0 or π)"
            )));
        }
        let stiffness = self.non_negative(&spec.stiffness, "stiffness")?;
        let list: Vec<&[Reference; 3]> = match (&spec.between, &spec.triples) {
            (Some(one), None) => vec![one],
            (None, Some(many)) => many.iter().collect(),
            _ => {
                return Err(self.error(format!(
                    "{what} needs exactly one of `between` or `triples`"
                )));
            }
        };
        let angles = list
            .into_iter()
            .map(|triple| {
                let sites = [
                    self.site(&triple[0])?,
                    self.site(&triple[1])?,
                    self.site(&triple[2])?,
                ];
                let [a, vertex, c] = sites.map(|s| self.position(&s));
                let rest_angle = match &spec.rest_angle {
                    Some(Value::Expression(text)) if text == "geometry" => {
                        geometric_angle(a, vertex, c)
                    }
                    Some(v) => self.number(v, "rest_angle")?,
                    None => geometric_angle(a, vertex, c),
                };
                Ok(AngleBend {
                    sites,
                    stiffness,
                    rest_angle,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        let periodic_box = self.scene.periodic_box;
        Ok(Box::new(HarmonicAngles::new(dim, angles, periodic_box)))
    }

    /// `fem-string`: the P1 finite-element nonlinear string of MEMM18 3.3.
    pub fn fem_string(&self, spec: &FemStringSpec) -> Result<Box<dyn ForceTerm>> {
        let what = &self.what;
        let sites = self.chain_sites(&spec.particles, &spec.range, &spec.start, &spec.end)?;
        if sites.len() < 2 {
            return Err(self.error(format!("{what}: a string needs at least two sites")));
        }
        let length = self.positive(&spec.element_length, "element_length")?;
        let alpha = self.number(&spec.alpha, "alpha")?;
        if !(0.0..1.0).contains(&alpha) {
            return Err(self.error(format!(
                "{what}: alpha must be in [0, 1) (convex energy), got {alpha}"
            )));
        }
        Ok(Box::new(FemString::new(
            self.scene.dim,
            sites,
            length,
            alpha,
        )))
    }
}

/// The angle at `vertex` between the directions to `a` and `c` (radians, in [0, π]).
fn geometric_angle(a: [f64; 3], vertex: [f64; 3], c: [f64; 3]) -> f64 {
    let u: Vec<f64> = (0..3).map(|k| a[k] - vertex[k]).collect();
    let w: Vec<f64> = (0..3).map(|k| c[k] - vertex[k]).collect();
    let dot: f64 = u.iter().zip(&w).map(|(x, y)| x * y).sum();
    let cross = [
        u[1] * w[2] - u[2] * w[1],
        u[2] * w[0] - u[0] * w[2],
        u[0] * w[1] - u[1] * w[0],
    ];
    let cross_norm = cross.iter().map(|x| x * x).sum::<f64>().sqrt();
    cross_norm.atan2(dot)
}
