//! Hydrogen mass repartitioning (HMR): heavier hydrogens, lighter heavy atoms, the same
//! total mass, so the fastest motions left after constraining bonds to hydrogen (the
//! H–X–H and H–X–Y bends) slow down and a longer step is stable (as OpenMM's
//! `hydrogenMass`: each hydrogen bonded to a heavy atom is set to the given mass, and the
//! difference is taken from that heavy atom; water is left alone).
//!
//! The momenta are rescaled with the masses (`p = m v`), so velocities are unchanged.
//! Cost: one pass over the bonds, once.

use std::collections::BTreeMap;

use super::System;
use super::topology::BondedTopology;
use crate::error::{Error, Result};
use crate::units::Units;

/// What [`System::repartition_hydrogen_mass`] changed, for `check` and the run header.
#[derive(Clone, Debug, PartialEq)]
pub struct Repartition {
    /// Hydrogens given the new mass.
    pub hydrogens: usize,
    /// Heavy atoms they took it from.
    pub heavy_atoms: usize,
    /// One line per element pair: `"H on C ×12: 1.008 → 3 amu; C: 12.011 → 9.011 amu …"`.
    pub lines: Vec<String>,
}

impl System {
    /// Give every hydrogen bonded to a heavy atom (outside water) the mass
    /// `hydrogen_mass` (in the scene's unit, `units`), taking the difference from the heavy
    /// atom. Fails when the scene has no such hydrogen, when a mass is not positive and
    /// finite, or when a heavy atom would end no heavier than one of its hydrogens.
    pub fn repartition_hydrogen_mass(
        &mut self,
        topology: &BondedTopology,
        hydrogen_mass: f64,
        units: Units,
    ) -> Result<Repartition> {
        if !(hydrogen_mass.is_finite() && hydrogen_mass > 0.0) {
            return Err(Error::setting(
                "hydrogen_mass",
                "hydrogen_mass must be positive and finite",
            )
            .expected("a positive finite mass")
            .got(hydrogen_mass.to_string()));
        }
        if topology.len() != self.n_particles() || self.mass_matrix.is_some() {
            return Err(Error::setting(
                "hydrogen_mass",
                "hydrogen_mass needs a molecular scene (a [forcefield] over a structure) with a \
                 diagonal mass matrix",
            )
            .expected("a molecular scene with a diagonal mass matrix"));
        }
        let target = units.mass(hydrogen_mass);
        let old = self.particles.masses.clone();
        let mut new = old.clone();
        let pairs = hydrogen_heavy_pairs(topology);
        if pairs.is_empty() {
            return Err(Error::setting(
                "hydrogen_mass",
                "hydrogen_mass: the scene has no hydrogen bonded to a heavy atom outside water \
                 (elements H, bonds from the structure), so there is no mass to repartition",
            )
            .expected("a scene with hydrogens bonded to heavy atoms"));
        }
        if let Some(&(h, _)) = pairs.iter().find(|(h, _)| target < old[*h]) {
            return Err(Error::setting(
                "hydrogen_mass",
                format!(
                    "hydrogen_mass {hydrogen_mass} {} is lighter than hydrogen {h}'s own {}: \
                     repartitioning makes hydrogens heavier (typically 3-4 amu), taking the \
                     difference from the heavy atom",
                    mass_unit(units),
                    units.mass_in_scene_units(old[h])
                ),
            )
            .expected("at least the hydrogens' own mass")
            .got(hydrogen_mass.to_string()));
        }
        for &(h, heavy) in &pairs {
            new[heavy] -= target - new[h];
            new[h] = target;
        }
        check_heavy_atoms(topology, &pairs, &old, &new, units, hydrogen_mass)?;
        let report = report(topology, &pairs, &old, &new, units);
        self.set_masses(&new);
        Ok(report)
    }

    /// Replace the masses (diagonal mass matrix), keeping the velocities.
    fn set_masses(&mut self, masses: &[f64]) {
        let dim = self.dim;
        for (i, &m) in masses.iter().enumerate() {
            let ratio = m / self.particles.masses[i];
            for a in 0..dim {
                self.state.p[i * dim + a] *= ratio;
                self.inverse_mass[i * dim + a] = 1.0 / m;
            }
            self.particles.masses[i] = m;
        }
    }
}

/// Every (hydrogen, heavy atom) bond outside water, in bond order.
fn hydrogen_heavy_pairs(topology: &BondedTopology) -> Vec<(usize, usize)> {
    let mut in_water = vec![false; topology.len()];
    for w in topology.waters() {
        for a in w {
            in_water[a] = true;
        }
    }
    topology
        .bonds
        .iter()
        .filter(|b| !in_water[b.i])
        .filter_map(
            |b| match (topology.is_hydrogen(b.i), topology.is_hydrogen(b.j)) {
                (true, false) => Some((b.i, b.j)),
                (false, true) => Some((b.j, b.i)),
                _ => None,
            },
        )
        .collect()
}

/// Every heavy atom must keep a positive mass above each of its hydrogens'. A heavy atom
/// of mass `M` with hydrogens of masses `mᵢ` (k of them) keeps `M − Σ(t − mᵢ) > t` when
/// the hydrogen mass `t < (M + Σmᵢ)/(k + 1)`: the refusal gives the smallest such bound.
fn check_heavy_atoms(
    topology: &BondedTopology,
    pairs: &[(usize, usize)],
    old: &[f64],
    new: &[f64],
    units: Units,
    hydrogen_mass: f64,
) -> Result<()> {
    let Some(&(h, heavy)) = pairs
        .iter()
        .find(|&&(h, heavy)| !(new[heavy].is_finite() && new[heavy] > new[h]))
    else {
        return Ok(());
    };
    // Per heavy atom: its mass and its hydrogens' (before), and their count.
    let mut groups: BTreeMap<usize, (f64, usize)> = BTreeMap::new();
    for &(h, heavy) in pairs {
        let group = groups.entry(heavy).or_insert((old[heavy], 0));
        group.0 += old[h];
        group.1 += 1;
    }
    let bound = groups
        .values()
        .map(|&(mass, k)| mass / (k + 1) as f64)
        .fold(f64::INFINITY, f64::min);
    let unit = mass_unit(units);
    let with_unit = |m: f64| format!("{m} {unit}").trim_end().to_string();
    let bound = with_unit(six_digits_down(units.mass_in_scene_units(bound)));
    Err(Error::setting(
        "hydrogen_mass",
        format!(
            "hydrogen_mass: it would leave atom {} ({}) with {}, not more than each of its \
             hydrogens (atom {} among them); the hydrogen mass must stay below {bound}",
            heavy + 1,
            topology.elements[heavy],
            with_unit(units.mass_in_scene_units(new[heavy])),
            h + 1,
        ),
    )
    .expected(format!("below {bound}"))
    .got(with_unit(hydrogen_mass)))
}

/// `x` (positive) rounded down to six significant digits, so that a bound printed stays a
/// bound.
fn six_digits_down(x: f64) -> f64 {
    let scale = 10f64.powi(5 - x.log10().floor() as i32);
    (x * scale).floor() / scale
}

fn mass_unit(units: Units) -> &'static str {
    if units == Units::Real { "amu" } else { "" }
}

/// One line per heavy element with the hydrogens on it, masses in the scene's unit.
fn report(
    topology: &BondedTopology,
    pairs: &[(usize, usize)],
    old: &[f64],
    new: &[f64],
    units: Units,
) -> Repartition {
    let scene = |m: f64| units.mass_in_scene_units(m);
    let unit = mass_unit(units);
    // Per heavy element: (hydrogens, the heavy atoms, their old and new mass ranges).
    let mut by_element: BTreeMap<&str, (usize, Vec<usize>)> = BTreeMap::new();
    for &(_, heavy) in pairs {
        let entry = by_element
            .entry(topology.elements[heavy].as_str())
            .or_default();
        entry.0 += 1;
        entry.1.push(heavy);
    }
    let mut heavy_atoms = 0;
    let mut lines = Vec::new();
    let h_old = scene(old[pairs[0].0]);
    for (element, (hydrogens, mut atoms)) in by_element {
        atoms.sort_unstable();
        atoms.dedup();
        heavy_atoms += atoms.len();
        let range = |masses: &[f64]| {
            let values = atoms.iter().map(|&a| scene(masses[a]));
            let lo = values.clone().fold(f64::INFINITY, f64::min);
            let hi = values.fold(f64::NEG_INFINITY, f64::max);
            if (hi - lo).abs() <= 1e-12 * hi.abs() {
                format!("{lo:.4}")
            } else {
                format!("{lo:.4}–{hi:.4}")
            }
        };
        lines.push(format!(
            "hydrogen mass: {hydrogens} H on {} {element}: H {h_old:.4} → {:.4} {unit}, \
             {element} {} → {} {unit}",
            atoms.len(),
            scene(new[pairs[0].0]),
            range(old),
            range(new),
        ));
    }
    Repartition {
        hydrogens: pairs.len(),
        heavy_atoms,
        lines,
    }
}
