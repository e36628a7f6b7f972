//! The bonded topology of a molecular scene (elements, bonds and angles with their
//! force-field rest values), for constraints and hydrogen mass repartitioning.

use serde_json::Value;

use super::Scene;
use crate::error::{Error, Result};
use crate::system::topology::{Angle, Bond, BondedTopology};

impl Scene {
    /// The elements of the particles and the bonds and angles of the scene's force field,
    /// with the rest lengths and angles its bonded terms use. Only a molecular scene (a
    /// `[forcefield]` over a `[structure]`) has one.
    pub fn bonded_topology(&self) -> Result<BondedTopology> {
        let Some(parameters) = &self.forcefield_parameters else {
            return Err(Error::Scene {
                location: self.path.display().to_string(),
                message: "constraints and hydrogen_mass need a molecular scene: a \
                          [forcefield] over the atoms of a [structure] (its bonds and elements)"
                    .into(),
            });
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
