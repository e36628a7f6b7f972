//! One-body terms: a uniform field, pendulums, a magnetic field and an external potential.

use super::terms::TermBuilder;
use super::{ExternalFieldSpec, FieldSpec, MagneticSpec, PendulumSpec};
use crate::error::Result;
use crate::forces::ForceTerm;
use crate::forces::external_field::{ExternalField, FieldShape};
use crate::forces::field::UniformField;
use crate::forces::magnetic::{MagneticTerm, VectorPotential};
use crate::forces::pendulum::Pendulum;

impl TermBuilder<'_> {
    /// `field`: a uniform force `f` on each listed particle (default all).
    pub fn field(&self, spec: &FieldSpec) -> Result<Box<dyn ForceTerm>> {
        let dim = self.scene.dim;
        let members = self.members(&spec.particles)?;
        let what = format!("{}: force", self.what);
        let vector =
            self.builder
                .vector(&spec.force, dim, self.scene.parameters, &what, self.offset)?;
        let mut force = [0.0; 3];
        force[..dim].copy_from_slice(&vector);
        Ok(Box::new(UniformField::new(dim, members, force)))
    }

    /// `pendulum`: `k(1 − cos x)` on one coordinate (`axis`, default 0) of each particle.
    pub fn pendulum(&self, spec: &PendulumSpec) -> Result<Box<dyn ForceTerm>> {
        let dim = self.scene.dim;
        let strength = self.number(&spec.strength, "strength")?;
        let axis = spec.axis.unwrap_or(0);
        if axis >= dim {
            return Err(self.error(format!(
                "{}: axis {axis} does not exist in dim = {dim}",
                self.what
            )));
        }
        let members = self.members(&spec.particles)?;
        Ok(Box::new(Pendulum::new(
            dim,
            members.into_iter().map(|i| (i, axis, strength)).collect(),
        )))
    }

    /// `magnetic`: a static magnetic field through its vector potential on charged
    /// particles (CFM25 5.7).
    pub fn magnetic(&self, spec: &MagneticSpec) -> Result<Box<dyn ForceTerm>> {
        let (what, field) = (&self.what, &spec.field);
        let vector_potential = match (field.as_str(), &spec.strength) {
            ("uniform", Some(b)) => VectorPotential::Uniform {
                strength: self.number(b, "strength")?,
            },
            ("uniform", None) => {
                return Err(self.error(format!("{what}: the uniform field needs its strength B")));
            }
            ("cfm25-singular", None) => VectorPotential::Cfm25Singular,
            ("cfm25-singular", Some(_)) => {
                return Err(self.error(format!(
                    "{what}: the cfm25-singular field takes no strength"
                )));
            }
            (other, _) => {
                return Err(self.error(format!(
                    "{what}: unknown magnetic field \"{other}\"; known: uniform, cfm25-singular"
                )));
            }
        };
        let needed = match vector_potential {
            VectorPotential::Uniform { .. } => 2,
            VectorPotential::Cfm25Singular => 3,
        };
        let dim = self.scene.dim;
        if dim < needed {
            return Err(self.error(format!(
                "{what}: the {field} magnetic field needs dim ≥ {needed}"
            )));
        }
        let charge = self.charge(&spec.charge)?;
        let members = self.members(&spec.particles)?;
        Ok(Box::new(MagneticTerm::new(
            dim,
            vector_potential,
            members.into_iter().map(|i| (i, charge)).collect(),
        )))
    }

    /// `external-field`: a fixed potential `e φ(x)` on 3-D particles (CFM25 5.7.3).
    pub fn external_field(&self, spec: &ExternalFieldSpec) -> Result<Box<dyn ForceTerm>> {
        let (what, field) = (&self.what, &spec.field);
        let shape = match field.as_str() {
            "cfm25-trigonometric" => FieldShape::Cfm25Trigonometric,
            other => {
                return Err(self.error(format!(
                    "{what}: unknown external field \"{other}\"; known: cfm25-trigonometric"
                )));
            }
        };
        if self.scene.dim != 3 {
            return Err(self.error(format!("{what}: the {field} field needs dim = 3")));
        }
        let charge = self.charge(&spec.charge)?;
        let members = self.members(&spec.particles)?;
        Ok(Box::new(ExternalField::new(
            shape,
            members.into_iter().map(|i| (i, charge)).collect(),
        )))
    }
}
