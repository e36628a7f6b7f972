//! The staggered-momentum state both pseudo-energy schemes step: the half-step momenta
//! `p^{n−1/2}`, `p^{n+1/2}` of MEMM18 (6) (of (20)–(24) in the asynchronous scheme, with
//! `p^{n,∓1/2}` for fast and mixed particles), their velocities `v = M⁻¹p`, and the
//! statistics of the pseudo-energy (13)/(25) at the nodes where it is conserved.
//!
//! How a step moves them differs (whole vectors in [`super::PseudoEnergy`], fine and
//! coarse coordinate sets in the asynchronous scheme, [`AsyncPseudoEnergy`]); what they
//! are, how they start (5)/(7), the state vector `Z` of Prop. 6, the state's momentum
//! `(p^{n−1/2} + p^{n+1/2})/2`, the energies of (13) and Remark 8 and what a checkpoint
//! holds of them are here, once. Cost: the energies are one (uncounted) energy evaluation
//! and two dot products; everything else is O(n_dofs) copies.
//!
//! [`AsyncPseudoEnergy`]: crate::integrators::async_pseudo_energy::AsyncPseudoEnergy

use serde::{Deserialize, Serialize};

use super::{PseudoEnergyMonitor, pseudo_and_discrete_energy};
use crate::error::Result;
use crate::integrators::integrator::restore_vector;
use crate::system::System;

/// `p^{n∓1/2}`, `v^{n∓1/2} = M⁻¹ p^{n∓1/2}` and the pseudo-energy monitor; also what a
/// checkpoint holds of them (its keys `p_minus`, `p_plus`, `v_minus`, `v_plus`, `monitor`).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct StaggeredMomenta {
    /// `p^{n−1/2}`: the momentum of the step just taken.
    pub p_minus: Vec<f64>,
    /// `p^{n+1/2}`: the momentum of the free flight (4) to come.
    pub p_plus: Vec<f64>,
    /// `H̃^n` and `H^n` at the nodes so far.
    pub monitor: PseudoEnergyMonitor,
    /// `M⁻¹ p^{n−1/2}`.
    pub v_minus: Vec<f64>,
    /// `M⁻¹ p^{n+1/2}`.
    pub v_plus: Vec<f64>,
}

impl StaggeredMomenta {
    /// Initialisation (5)/(7): `p^{−1/2} = p^{1/2} = p(t⁰)`, sized to the system.
    pub fn start(&mut self, system: &System) {
        let n = system.n_dofs();
        self.p_minus = system.state.p.clone();
        self.p_plus = system.state.p.clone();
        self.v_minus = vec![0.0; n];
        system.velocity(&self.p_minus, &mut self.v_minus);
        self.v_plus = self.v_minus.clone();
    }

    /// A fresh monitor at the current state: `H̃⁰`, on the scale `K₀ + |V₀|`.
    pub fn start_monitor(&mut self, system: &System) {
        let (pseudo, _) = self.energies(system);
        let potential = system.forces.total_energy(&system.state.q);
        self.monitor =
            PseudoEnergyMonitor::new(pseudo, (pseudo - potential).abs() + potential.abs());
    }

    /// Record `H̃^n` and `H^n` at the current state in the monitor.
    pub fn record(&mut self, system: &System) {
        let (pseudo, discrete) = self.energies(system);
        self.monitor.record(pseudo, discrete);
    }

    /// `(H̃^n, H^n)`: MEMM18 (13) (summed per particle set, (25)) and Remark 8.
    pub fn energies(&self, system: &System) -> (f64, f64) {
        pseudo_and_discrete_energy(
            system.forces.total_energy(&system.state.q),
            &self.p_minus,
            &self.p_plus,
            &self.v_minus,
            &self.v_plus,
        )
    }

    /// `state.p = (p^{n−1/2} + p^{n+1/2})/2`.
    pub fn sync_state(&self, system: &mut System) {
        for ((p, a), b) in system
            .state
            .p
            .iter_mut()
            .zip(&self.p_minus)
            .zip(&self.p_plus)
        {
            *p = 0.5 * (a + b);
        }
    }

    /// `Z = (q, p^{n−1/2}, p^{n+1/2})` (length `3 n_dofs`), as in the proof of MEMM18
    /// Prop. 6.
    pub fn state_vector(&self, system: &System, z: &mut [f64]) {
        let n = system.n_dofs();
        z[..n].copy_from_slice(&system.state.q);
        z[n..2 * n].copy_from_slice(&self.p_minus);
        z[2 * n..3 * n].copy_from_slice(&self.p_plus);
    }

    /// Replace the positions and momenta by `Z` (see [`StaggeredMomenta::state_vector`]);
    /// the caller drops any force it cached at the old positions.
    pub fn set_state_vector(&mut self, system: &mut System, z: &[f64]) {
        let n = system.n_dofs();
        system.state.q.copy_from_slice(&z[..n]);
        self.p_minus.copy_from_slice(&z[n..2 * n]);
        self.p_plus.copy_from_slice(&z[2 * n..3 * n]);
        system.velocity(&self.p_minus, &mut self.v_minus);
        system.velocity(&self.p_plus, &mut self.v_plus);
        self.sync_state(system);
    }

    /// Reverse time (MEMM18 Prop. 4): `(q^n, p^{n−1/2}, p^{n+1/2}) → (q^n, −p^{n+1/2},
    /// −p^{n−1/2})`.
    pub fn reverse(&mut self, system: &mut System) {
        std::mem::swap(&mut self.p_minus, &mut self.p_plus);
        std::mem::swap(&mut self.v_minus, &mut self.v_plus);
        for x in self
            .p_minus
            .iter_mut()
            .chain(self.p_plus.iter_mut())
            .chain(self.v_minus.iter_mut())
            .chain(self.v_plus.iter_mut())
        {
            *x = -*x;
        }
        self.sync_state(system);
    }

    /// Take a checkpoint's momenta, velocities and monitor into the buffers `start` sized,
    /// refusing another length; `method` names the scheme in the message.
    pub fn restore(&mut self, method: &str, saved: StaggeredMomenta) -> Result<()> {
        restore_vector(method, "p^{n-1/2}", &saved.p_minus, &mut self.p_minus)?;
        restore_vector(method, "p^{n+1/2}", &saved.p_plus, &mut self.p_plus)?;
        restore_vector(method, "v^{n-1/2}", &saved.v_minus, &mut self.v_minus)?;
        restore_vector(method, "v^{n+1/2}", &saved.v_plus, &mut self.v_plus)?;
        self.monitor = saved.monitor;
        Ok(())
    }
}
