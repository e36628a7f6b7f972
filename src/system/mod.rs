//! The mechanical system: particles, their state, and the split forces acting on them.
//!
//! Positions and momenta are flat `n_particles × dim` arrays (`q[i * dim + a]` is
//! coordinate `a` of particle `i`), with `dim ∈ {1, 2, 3}` chosen by the scene, so a
//! 1-D chain stores one number per particle. The mass matrix is diagonal; its inverse is
//! kept per degree of freedom so drifts are one multiply per coordinate. A scene may ask
//! for a banded non-diagonal mass matrix instead ([`MassMatrix`], the consistent P1 mass of
//! MEMM18 3.3); then the masses are its diagonal and only methods that solve with it run.

pub mod constraints;
pub mod exact;
pub mod hydrogen_mass;
mod mass;
pub mod topology;
pub mod velocities;

pub use crate::forces::PeriodicBox;
pub use mass::{MAX_BANDWIDTH, MassMatrix};

use crate::split::ForceSplit;

/// Positions, momenta and time: everything an integrator advances.
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    pub t: f64,
    pub q: Vec<f64>,
    pub p: Vec<f64>,
}

/// Names and masses of the particles (the degrees of freedom; anchors are not particles).
#[derive(Clone, Debug)]
pub struct Particles {
    pub names: Vec<String>,
    pub masses: Vec<f64>,
}

impl Particles {
    pub fn len(&self) -> usize {
        self.masses.len()
    }

    pub fn is_empty(&self) -> bool {
        self.masses.is_empty()
    }
}

pub struct System {
    pub dim: usize,
    pub particles: Particles,
    /// `1 / m` repeated `dim` times per particle: the diagonal of `M⁻¹` over all coordinates.
    pub inverse_mass: Vec<f64>,
    pub state: State,
    pub forces: ForceSplit,
    pub periodic_box: Option<PeriodicBox>,
    /// A non-diagonal mass matrix, when the scene gives one (`None`: `M` is diagonal and
    /// `inverse_mass` is `M⁻¹`). Its diagonal is `particles.masses`.
    pub mass_matrix: Option<MassMatrix>,
    /// Rigid bonds and waters the integrator holds ([`constraints`]); `None`: none.
    /// Their count comes off the degrees of freedom and the start velocities are drawn
    /// on them.
    pub constraints: Option<constraints::Constraints>,
}

impl System {
    /// Assemble a system; masses must already be validated positive and finite.
    pub fn new(
        dim: usize,
        particles: Particles,
        state: State,
        forces: ForceSplit,
        periodic_box: Option<PeriodicBox>,
    ) -> Self {
        let inverse_mass = particles
            .masses
            .iter()
            .flat_map(|&m| std::iter::repeat_n(1.0 / m, dim))
            .collect();
        System {
            dim,
            particles,
            inverse_mass,
            state,
            forces,
            periodic_box,
            mass_matrix: None,
            constraints: None,
        }
    }

    /// This system with a non-diagonal mass matrix (its diagonal must be the masses).
    pub fn with_mass_matrix(mut self, mass_matrix: MassMatrix) -> Self {
        self.mass_matrix = Some(mass_matrix);
        self
    }

    /// `velocity = M⁻¹ p`: a multiply per coordinate, or a banded solve with a mass matrix.
    /// Allocates nothing.
    pub fn velocity(&self, p: &[f64], velocity: &mut [f64]) {
        match &self.mass_matrix {
            Some(mass) => mass.solve(p, velocity),
            None => {
                for ((v, pi), wi) in velocity.iter_mut().zip(p).zip(&self.inverse_mass) {
                    *v = wi * pi;
                }
            }
        }
    }

    pub fn n_particles(&self) -> usize {
        self.particles.len()
    }

    /// Number of coordinates, `n_particles × dim`.
    pub fn n_dofs(&self) -> usize {
        self.state.q.len()
    }

    /// `pᵀ M⁻¹ p / 2` (with the mass matrix when there is one).
    pub fn kinetic_energy(&self) -> f64 {
        match &self.mass_matrix {
            Some(mass) => 0.5 * mass.inverse_quadratic_form(&self.state.p),
            None => kinetic_energy(&self.state.p, &self.inverse_mass),
        }
    }

    /// Potential energy of every level, innermost (fastest) first.
    pub fn potential_energies(&self) -> Vec<f64> {
        let mut energies = vec![0.0; self.forces.n_levels()];
        self.potential_energies_into(&mut energies);
        energies
    }

    /// [`System::potential_energies`] into a buffer of one entry per level, without
    /// allocating (the run loop records them every row).
    pub fn potential_energies_into(&self, energies: &mut [f64]) {
        for (level, energy) in energies.iter_mut().enumerate() {
            *energy = self.forces.energy(level, &self.state.q);
        }
    }

    /// Kinetic plus all potential energy.
    pub fn total_energy(&self) -> f64 {
        self.kinetic_energy() + self.forces.total_energy(&self.state.q)
    }
}

/// `pᵀ M⁻¹ p / 2` for a flat momentum array and the per-coordinate inverse masses.
pub fn kinetic_energy(p: &[f64], inverse_mass: &[f64]) -> f64 {
    0.5 * p
        .iter()
        .zip(inverse_mass)
        .map(|(pi, wi)| pi * pi * wi)
        .sum::<f64>()
}
