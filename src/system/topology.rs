//! The bonded topology of a molecular system, as constraints and hydrogen mass
//! repartitioning need it: each particle's element, the bonds with their rest lengths, and
//! the angles with their rest angles (from the force field; `io` builds it from a scene).

use std::collections::BTreeSet;

use crate::error::{Error, Result};

/// A bond `i–j` whose force-field rest length is `length`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bond {
    pub i: usize,
    pub j: usize,
    pub length: f64,
}

/// An angle `i–centre–k` whose force-field rest angle is `theta0` (radians).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Angle {
    pub i: usize,
    pub centre: usize,
    pub k: usize,
    pub theta0: f64,
}

/// Elements, bonds and angles of the particles of a system.
#[derive(Clone, Debug, Default)]
pub struct BondedTopology {
    /// Element symbol per particle (`"H"`, `"O"`, …).
    pub elements: Vec<String>,
    pub bonds: Vec<Bond>,
    pub angles: Vec<Angle>,
    /// The force field has no bonded terms for some of its waters (a GROMACS topology's
    /// `[settles]`): a run must hold them rigid.
    pub rigid_water_required: bool,
}

impl BondedTopology {
    /// A topology whose bonds and angles must name particles among `elements`.
    pub fn new(elements: Vec<String>, bonds: Vec<Bond>, angles: Vec<Angle>) -> Result<Self> {
        let n = elements.len();
        for b in &bonds {
            if b.i >= n || b.j >= n || b.i == b.j {
                return Err(Error::input(format!(
                    "bond {}-{} does not join two of the {n} particles",
                    b.i, b.j
                )));
            }
            if !(b.length.is_finite() && b.length > 0.0) {
                return Err(Error::input(format!(
                    "bond {}-{} has rest length {}; a constraint needs a positive one",
                    b.i, b.j, b.length
                )));
            }
        }
        for a in &angles {
            if a.i >= n || a.centre >= n || a.k >= n {
                return Err(Error::input(format!(
                    "angle {}-{}-{} names a particle beyond the {n} particles",
                    a.i, a.centre, a.k
                )));
            }
        }
        Ok(BondedTopology {
            elements,
            bonds,
            angles,
            rigid_water_required: false,
        })
    }

    pub fn len(&self) -> usize {
        self.elements.len()
    }

    pub fn is_empty(&self) -> bool {
        self.elements.is_empty()
    }

    /// Whether particle `i` is a hydrogen (element `H`, or its isotope `D`).
    pub fn is_hydrogen(&self, i: usize) -> bool {
        matches!(self.elements[i].as_str(), "H" | "D" | "h" | "d")
    }

    /// Whether particle `i` is an oxygen.
    fn is_oxygen(&self, i: usize) -> bool {
        matches!(self.elements[i].as_str(), "O" | "o")
    }

    /// The bonded neighbours of every particle, sorted.
    pub fn neighbours(&self) -> Vec<BTreeSet<usize>> {
        let mut neighbours = vec![BTreeSet::new(); self.len()];
        for b in &self.bonds {
            neighbours[b.i].insert(b.j);
            neighbours[b.j].insert(b.i);
        }
        neighbours
    }

    /// The water molecules: an oxygen bonded to exactly two hydrogens that are bonded to
    /// nothing else (a bond between the two hydrogens is allowed, as rigid models list
    /// one), `[oxygen, hydrogen, hydrogen]` in order of the oxygens.
    pub fn waters(&self) -> Vec<[usize; 3]> {
        let neighbours = self.neighbours();
        let mut waters = Vec::new();
        for (o, around) in neighbours.iter().enumerate() {
            if !self.is_oxygen(o) || around.len() != 2 {
                continue;
            }
            let h: Vec<usize> = around.iter().copied().collect();
            let alone = |a: usize, b: usize| {
                self.is_hydrogen(a) && neighbours[a].iter().all(|&x| x == o || x == b)
            };
            if alone(h[0], h[1]) && alone(h[1], h[0]) {
                waters.push([o, h[0], h[1]]);
            }
        }
        waters
    }

    /// The rest length of bond `i–j`, if there is one.
    pub fn bond_length(&self, i: usize, j: usize) -> Option<f64> {
        self.bonds
            .iter()
            .find(|b| (b.i == i && b.j == j) || (b.i == j && b.j == i))
            .map(|b| b.length)
    }

    /// The rest angle at `centre` between `i` and `k`, if there is one.
    pub fn rest_angle(&self, i: usize, centre: usize, k: usize) -> Option<f64> {
        self.angles
            .iter()
            .find(|a| a.centre == centre && ((a.i == i && a.k == k) || (a.i == k && a.k == i)))
            .map(|a| a.theta0)
    }
}
