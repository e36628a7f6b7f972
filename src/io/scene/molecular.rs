//! The bonded topology of a molecular scene (elements, bonds and angles with their
//! force-field rest values), for constraints and hydrogen mass repartitioning.

use serde_json::Value;

use super::Scene;
use crate::error::{Error, Result};
use crate::settings::MethodSettings;
use crate::system::constraints::Constraints;
use crate::system::topology::{Angle, Bond, BondedTopology};

impl Scene {
    /// The elements of the particles and the bonds and angles of the scene's force field,
    /// with the rest lengths and angles its bonded terms use. Only a molecular scene (a
    /// `[forcefield]` over a `[structure]`) has one.
    pub fn bonded_topology(&self) -> Result<BondedTopology> {
        if let Some(bonded) = &self.bonded {
            return Ok(bonded.clone());
        }
        let Some(parameters) = &self.forcefield_parameters else {
            return Err(Error::scene(
                &self.path,
                "constraints and hydrogen_mass need a molecular scene: a [forcefield] over the \
                 atoms of a [structure], or a [topology] (its bonds and elements)",
            ));
        };
        let bonds = rows(parameters, "bonds", 4)?
            .map(|r| Bond {
                i: r[0] as usize,
                j: r[1] as usize,
                length: r[3],
            })
            .collect();
        let angles = rows(parameters, "angles", 5)?
            .map(|r| Angle {
                i: r[0] as usize,
                centre: r[1] as usize,
                k: r[2] as usize,
                theta0: r[4],
            })
            .collect();
        BondedTopology::new(self.elements.clone(), bonds, angles)
    }

    /// What the settings ask of the molecule before a run: hydrogen mass repartitioning
    /// (`hydrogen_mass`), then the constraints (`constraints`, `rigid_water`,
    /// `constraint_tolerance`) built, the positions and momenta put on them, and attached
    /// to the system ([`System::constraints`](crate::system::System)). What was done goes
    /// into the force-field report (the run header and `check`).
    pub fn apply_molecular_settings(
        &mut self,
        settings: &MethodSettings,
        notices: &mut Vec<String>,
    ) -> Result<()> {
        let required = self.bonded.as_ref().is_some_and(|b| b.rigid_water_required);
        if required && !settings.rigid_water {
            return Err(Error::scene(
                &self.path,
                "the topology's water is [ settles ] (rigid, no bonded terms): it runs with \
                 rigid water; leave rigid_water on, or define FLEXIBLE for a flexible water \
                 (--define FLEXIBLE, or [topology] defines = [\"FLEXIBLE\"])",
            )
            .key("rigid_water"));
        }
        if settings.hydrogen_mass.is_none() && !settings.constrained() {
            return Ok(());
        }
        let topology = self.bonded_topology()?;
        if let Some(mass) = settings.hydrogen_mass {
            let report = self
                .system
                .repartition_hydrogen_mass(&topology, mass, self.units)?;
            self.forcefield_report.extend(report.lines);
        }
        if !settings.constrained() {
            return Ok(());
        }
        let system = &mut self.system;
        let mut constraints = Constraints::from_topology(
            &topology,
            settings.constraints,
            settings.rigid_water,
            system.periodic_box,
        )?;
        if let Some(tolerance) = settings.constraint_tolerance {
            constraints = constraints.with_tolerance(tolerance)?;
        }
        constraints.check_masses(&system.inverse_mass)?;
        let (state, w) = (&mut system.state, &system.inverse_mass);
        let unsolvable = |e: crate::system::constraints::ConstraintFailure| {
            Error::input(format!("the start positions cannot be constrained: {e}"))
        };
        constraints
            .project_positions(&mut state.q, w)
            .map_err(unsolvable)?;
        constraints
            .constrain_velocities(&state.q, &mut state.p, w)
            .map_err(unsolvable)?;
        if constraints.is_empty() {
            notices.push(format!(
                "constraints {}{}: the scene has no such bond and no water, so nothing is \
                 constrained",
                settings.constraints.name(),
                if settings.rigid_water {
                    " with rigid water"
                } else {
                    ""
                }
            ));
        }
        self.forcefield_report.push(format!(
            "constraints: {}{} ({} bonds by SHAKE/RATTLE, {} rigid waters by SETTLE: {} scalar \
             constraints), relative tolerance {:e}; the start was put on them; constrained bonds \
             keep their force-field terms, at their rest length (no force along them)",
            settings.constraints.name(),
            match (settings.rigid_water, required) {
                (true, true) => " + rigid water (the topology's [ settles ])",
                (true, false) => " + rigid water",
                _ => "",
            },
            constraints.pairs().len(),
            constraints.waters().len(),
            constraints.count(),
            constraints.tolerance()
        ));
        system.constraints = Some(constraints);
        Ok(())
    }
}

/// The numeric rows of `key` in the force field's parameter dump, `width` numbers each.
fn rows<'a>(
    parameters: &'a Value,
    key: &str,
    width: usize,
) -> Result<impl Iterator<Item = Vec<f64>> + 'a> {
    let list = match parameters.get(key) {
        Some(Value::Array(list)) => list.as_slice(),
        _ => &[],
    };
    let parsed: Option<Vec<Vec<f64>>> = list
        .iter()
        .map(|row| {
            let row = row.as_array()?;
            let numbers: Option<Vec<f64>> = row.iter().take(width).map(Value::as_f64).collect();
            numbers.filter(|n| n.len() == width)
        })
        .collect();
    parsed.map(Vec::into_iter).ok_or_else(|| {
        Error::input(format!(
            "the force field's {key} are not rows of {width} numbers (internal error)"
        ))
    })
}
