//! The `[forcefield]` section: a molecular force field over a structure's atoms and bonds
//! (built by [`crate::io::forcefield`]), and the masses and elements it settles.

use super::particles::Start;
use super::{Builder, OVERLAP_LIMIT, SceneFile, Terms};
use crate::error::Result;
use crate::io::forcefield::{
    FfAtom, ForcefieldInput, build_forcefield, check_box, closest_overlap,
};
use crate::system::PeriodicBox;
use crate::system::topology::BondedTopology;
use crate::units::Units;

/// What the force field adds to a scene besides its terms.
pub(super) struct Molecule {
    /// Element (or name) of each particle.
    pub elements: Vec<String>,
    /// Which force-field parameter came from where (empty without `[forcefield]`).
    pub report: Vec<String>,
    /// Every force-field parameter per interaction (`None` without `[forcefield]`).
    pub parameters: Option<serde_json::Value>,
    /// Elements, bonds and angles with their rest values, where the source gives them
    /// directly (a topology file); a `[forcefield]` scene's come from `parameters`.
    pub bonded: Option<BondedTopology>,
}

impl Builder<'_> {
    /// Build the `[forcefield]` terms into `terms` and its masses into `start`; without
    /// the section, the elements are the particles' names.
    pub(super) fn apply_forcefield(
        &self,
        file: &SceneFile,
        start: &mut Start,
        periodic_box: Option<PeriodicBox>,
        units: Units,
        terms: &mut Terms,
    ) -> Result<Molecule> {
        let (Some(ff), Some(structure)) = (&file.forcefield, &start.structure) else {
            return Ok(Molecule {
                elements: start.names.clone(),
                report: Vec::new(),
                parameters: None,
                bonded: None,
            });
        };
        let offset = ff.span().start;
        let n_particles = start.masses.len();
        let structure_spec = file.structure.as_ref().map(|s| s.get_ref());
        let bonds = self.structure_bonds(structure, structure_spec, n_particles)?;
        // A box too small for the cutoff folds atoms onto each other: say so first.
        check_box(ff.get_ref(), periodic_box, &start.q).map_err(|e| self.error(e))?;
        if let Some((i, j, r)) = closest_overlap(&start.q, periodic_box, OVERLAP_LIMIT) {
            return Err(self.error(format!(
                "atoms {i} ({}) and {j} ({}) overlap: they are {r:.4} Å apart (closer than \
                 {OVERLAP_LIMIT} Å)",
                start.names[i], start.names[j]
            )));
        }
        let atoms: Vec<FfAtom> = structure
            .atoms
            .iter()
            .map(|a| FfAtom {
                type_name: a.name.clone(),
                element: a.element.clone(),
                element_mass: a.mass,
            })
            .collect();
        let built = build_forcefield(&ForcefieldInput {
            spec: ff.get_ref(),
            units,
            atoms: &atoms,
            q: &start.q,
            bonds: &bonds,
            periodic_box,
        })
        .map_err(|e| self.error_at(offset, e))?;
        start.masses = built.masses;
        let mut report = built.report;
        report.insert(
            0,
            format!(
                "force field: {} atoms, {} bonds ({}), box {}; units real: Å, fs, amu, kcal/mol, e",
                n_particles,
                bonds.len(),
                if structure.bonds.is_empty() {
                    "none perceived or listed"
                } else {
                    "from the file or perceived by chemfiles"
                },
                match periodic_box {
                    // Ten digits and the unit, as `check`'s particles line: 18.64449108 Å.
                    Some(b) => b
                        .lengths
                        .iter()
                        .map(|&l| units.length(l))
                        .collect::<Vec<_>>()
                        .join(" × "),
                    None => "none".into(),
                }
            ),
        );
        terms.extend(built.terms);
        Ok(Molecule {
            elements: built.elements,
            report,
            parameters: Some(built.parameters),
            bonded: None,
        })
    }
}
