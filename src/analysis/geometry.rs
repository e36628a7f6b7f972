//! Molecules, bonds and angles of a scene, and their lengths and angles in a frame.
//!
//! Molecules are the connected components of the graph of the scene's bonded terms (every
//! particle set a bond, angle, torsion or spring couples); a particle that no bonded term
//! touches is a molecule of its own. Bonds are the pairs of the terms of kind `bond` (and
//! `spring`), angles the triples `i–j–k` of the terms of kind `angle` (vertex `j`). Both are
//! grouped by the elements of their atoms: `H-O` (sorted) and `H-O-H` (ends sorted, the vertex
//! in the middle). Distances and angles are minimum-image in a periodic box.

use std::collections::BTreeMap;

use crate::forces::{TermClass, minimum_image};
use crate::split::LabelledTerm;

#[derive(Clone, Debug, Default)]
pub struct Topology {
    /// Molecule index of every particle (0, 1, … in order of each molecule's first atom).
    pub molecule_of: Vec<usize>,
    pub molecules: usize,
    /// Bonds by type name.
    pub bonds: BTreeMap<String, Vec<[usize; 2]>>,
    /// Angles by type name.
    pub angles: BTreeMap<String, Vec<[usize; 3]>>,
}

fn find(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

/// Connected components of the particle sets `groups` over `n` particles.
pub fn components<'a>(n: usize, groups: impl Iterator<Item = &'a [usize]>) -> (Vec<usize>, usize) {
    let mut parent: Vec<usize> = (0..n).collect();
    for group in groups {
        for pair in group.windows(2) {
            let (a, b) = (find(&mut parent, pair[0]), find(&mut parent, pair[1]));
            if a != b {
                parent[a.max(b)] = a.min(b);
            }
        }
    }
    let mut label = vec![usize::MAX; n];
    let mut molecule_of = vec![0; n];
    let mut count = 0;
    for (i, molecule) in molecule_of.iter_mut().enumerate() {
        let root = find(&mut parent, i);
        if label[root] == usize::MAX {
            label[root] = count;
            count += 1;
        }
        *molecule = label[root];
    }
    (molecule_of, count)
}

impl Topology {
    /// Molecules, bonds and angles of a scene's terms over `n` particles named `elements`.
    pub fn from_terms(terms: &[LabelledTerm], elements: &[String]) -> Self {
        let n = elements.len();
        let bonded: Vec<Vec<usize>> = terms
            .iter()
            .filter(|t| t.term.class() == TermClass::Bonded)
            .flat_map(|t| t.term.couplings())
            .collect();
        let (molecule_of, molecules) = components(n, bonded.iter().map(Vec::as_slice));
        let mut topology = Topology {
            molecule_of,
            molecules,
            ..Default::default()
        };
        for labelled in terms {
            let kind = labelled.term.kind();
            for coupling in labelled.term.couplings() {
                match (kind, coupling.as_slice()) {
                    ("bond" | "spring", &[i, j]) => {
                        let mut names = [elements[i].as_str(), elements[j].as_str()];
                        names.sort_unstable();
                        let key = names.join("-");
                        topology.bonds.entry(key).or_default().push([i, j]);
                    }
                    ("angle", &[i, j, k]) => {
                        let (a, c) = (elements[i].as_str(), elements[k].as_str());
                        let key = format!("{}-{}-{}", a.min(c), elements[j], a.max(c));
                        topology.angles.entry(key).or_default().push([i, j, k]);
                    }
                    _ => {}
                }
            }
        }
        topology
    }
}

/// `r_j − r_i` (minimum image when `lengths` is given), `q` being `n × 3`.
fn displacement(q: &[f64], lengths: Option<[f64; 3]>, i: usize, j: usize) -> [f64; 3] {
    std::array::from_fn(|a| {
        let d = q[3 * j + a] - q[3 * i + a];
        match lengths {
            Some(l) => minimum_image(d, l[a]),
            None => d,
        }
    })
}

fn norm(d: [f64; 3]) -> f64 {
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

/// Mean length of `bonds` in the frame `q`.
pub fn mean_bond_length(q: &[f64], lengths: Option<[f64; 3]>, bonds: &[[usize; 2]]) -> f64 {
    let sum: f64 = bonds
        .iter()
        .map(|&[i, j]| norm(displacement(q, lengths, i, j)))
        .sum();
    sum / bonds.len() as f64
}

/// Mean angle (radians) of `angles` in the frame `q`; `atan2(|u × w|, u·w)` is accurate
/// near 0 and π.
pub fn mean_angle(q: &[f64], lengths: Option<[f64; 3]>, angles: &[[usize; 3]]) -> f64 {
    let sum: f64 = angles
        .iter()
        .map(|&[i, j, k]| {
            let (u, w) = (
                displacement(q, lengths, j, i),
                displacement(q, lengths, j, k),
            );
            let cross = [
                u[1] * w[2] - u[2] * w[1],
                u[2] * w[0] - u[0] * w[2],
                u[0] * w[1] - u[1] * w[0],
            ];
            let dot = u[0] * w[0] + u[1] * w[1] + u[2] * w[2];
            norm(cross).atan2(dot)
        })
        .sum();
    sum / angles.len() as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn components_join_chains_and_keep_loners() {
        let groups = [vec![0, 1], vec![1, 2], vec![4, 5]];
        let (of, count) = components(6, groups.iter().map(Vec::as_slice));
        assert_eq!(count, 3);
        assert_eq!(of, vec![0, 0, 0, 1, 2, 2]);
    }

    #[test]
    fn bond_and_angle_across_the_box_edge_use_the_minimum_image() {
        // O at x = 0.1, H at x = 9.9 in a box of 10: bond 0.2; H–O–H a right angle.
        let q = [0.1, 5.0, 5.0, 9.9, 5.0, 5.0, 0.1, 5.2, 5.0];
        let box_lengths = Some([10.0; 3]);
        assert!((mean_bond_length(&q, box_lengths, &[[0, 1]]) - 0.2).abs() < 1e-12);
        let angle = mean_angle(&q, box_lengths, &[[1, 0, 2]]);
        assert!((angle - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    }
}
