//! Pair terms over particle lists: Lennard-Jones, gravity and inverse powers.

use super::terms::TermBuilder;
use super::{GravitySpec, InversePowerSpec, LennardJonesSpec};
use crate::error::Result;
use crate::forces::gravity::{CentralMass, gravity};
use crate::forces::inverse_power::{InversePower, inverse_power_pairs};
use crate::forces::lennard_jones::{LennardJones, lennard_jones_pairs};
use crate::forces::{ForceTerm, Site};

impl TermBuilder<'_> {
    /// `lennard-jones`: 12-6 between all pairs of a list (default all) but the excluded.
    pub fn lennard_jones(&self, spec: &LennardJonesSpec) -> Result<Box<dyn ForceTerm>> {
        let epsilon = self.non_negative(&spec.epsilon, "epsilon")?;
        let sigma = self.positive(&spec.sigma, "sigma")?;
        let cutoff = match &spec.cutoff {
            Some(v) => self.positive(v, "cutoff")?,
            None => f64::INFINITY,
        };
        let members = self.members(&spec.particles)?;
        let excluded = spec
            .exclude
            .iter()
            .map(|[a, b]| Ok((self.particle(a)?, self.particle(b)?)))
            .collect::<Result<Vec<_>>>()?;
        let shift = spec.shift.unwrap_or(true);
        Ok(Box::new(lennard_jones_pairs(
            self.scene.dim,
            &members,
            &excluded,
            LennardJones::new(epsilon, sigma, cutoff, shift),
            self.scene.periodic_box,
        )))
    }

    /// `gravity`: Newtonian gravity among particles and towards an optional central mass
    /// at an anchor.
    pub fn gravity(&self, spec: &GravitySpec) -> Result<Box<dyn ForceTerm>> {
        let what = &self.what;
        let g = match &spec.constant {
            Some(v) => self.non_negative(v, "constant")?,
            None => 1.0,
        };
        let members = self.members(&spec.particles)?;
        let center = match (&spec.center, &spec.center_mass) {
            (Some(anchor), mass) => {
                let position = match self.scene.names.sites.get(anchor) {
                    Some(Site::Fixed(x)) => *x,
                    _ => {
                        return Err(
                            self.error(format!("{what}: center \"{anchor}\" is not an anchor"))
                        );
                    }
                };
                let mass = match mass {
                    Some(v) => self.non_negative(v, "center_mass")?,
                    None => 1.0,
                };
                Some(CentralMass { position, mass })
            }
            (None, Some(_)) => {
                return Err(self.error(format!("{what}: center_mass needs a center anchor")));
            }
            (None, None) => None,
        };
        let scene = self.scene;
        Ok(Box::new(gravity(
            scene.dim,
            g,
            &members,
            scene.masses,
            center,
        )))
    }

    /// `inverse-power`: `c (r + a)^(−n)` between pairs.
    pub fn inverse_power(&self, spec: &InversePowerSpec) -> Result<Box<dyn ForceTerm>> {
        let coefficient = self.number(&spec.coefficient, "coefficient")?;
        let power = self.positive(&spec.power, "power")?;
        let softening = match &spec.softening {
            Some(v) => self.non_negative(v, "softening")?,
            None => 0.0,
        };
        let potential = InversePower {
            coefficient,
            power,
            softening,
        };
        let interactions = self
            .pairs_of(&spec.between, &spec.pairs)?
            .into_iter()
            .map(|(a, b)| (a, b, potential))
            .collect();
        let (dim, periodic_box) = (self.scene.dim, self.scene.periodic_box);
        Ok(Box::new(inverse_power_pairs(
            dim,
            interactions,
            periodic_box,
        )))
    }
}
