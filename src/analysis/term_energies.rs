//! The energy of each force-field term in one frame, recomputed with longstep's force field
//! (`longstep analyze`): the series behind the per-term criteria (`studies::criterion::reference`).
//!
//! A term is a labelled term of the scene's split (`bonds`, `angles`, `torsions`,
//! `impropers`, `lj-14`, `coulomb-14`, `pme-reciprocal`, …), except that a term computing
//! Lennard-Jones and Coulomb in one pass (the non-bonded real-space term) is two series,
//! `nonbonded/lennard-jones` and `nonbonded/coulomb` ([`crate::forces::ForceTerm::energy_components`]).
//! Any other term with several parts (the reciprocal sum with its exclusion, self and
//! background corrections) is one series, the sum of its parts: the energy the run
//! integrates. The series sum to the potential energy.
//!
//! Cost: one energy evaluation of every term per frame (the non-bonded pass once).

use crate::split::LabelledTerm;

/// Parts of a term that are series of their own.
const SEPARATE_PARTS: [&str; 2] = ["lennard-jones", "coulomb"];

/// The names of the series of `terms` (module documentation), from the parts each term
/// reports at `q`.
pub fn series_names(terms: &[LabelledTerm], q: &[f64]) -> Vec<String> {
    let mut names = Vec::new();
    for labelled in terms {
        let parts = labelled.term.energy_components(q);
        if splits(&parts) {
            names.extend(
                parts
                    .iter()
                    .map(|(part, _)| format!("{}/{part}", labelled.name)),
            );
        } else {
            names.push(labelled.name.clone());
        }
    }
    names
}

fn splits(parts: &[(&'static str, f64)]) -> bool {
    parts.len() > 1 && parts.iter().all(|(p, _)| SEPARATE_PARTS.contains(p))
}

/// Each series' energy at `q` into `out` (cleared first), in the order of [`series_names`].
pub fn evaluate(terms: &[LabelledTerm], q: &[f64], out: &mut Vec<f64>) {
    out.clear();
    for labelled in terms {
        let parts = labelled.term.energy_components(q);
        if splits(&parts) {
            out.extend(parts.iter().map(|(_, e)| *e));
        } else {
            out.push(parts.iter().map(|(_, e)| *e).sum());
        }
    }
}
