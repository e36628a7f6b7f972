//! Normal modes of the fast subsystem and the outer steps where MTS methods resonate.
//!
//! The Hessian of the fast forces (level 0) in mass-weighted coordinates,
//! `M^{-1/2} W_qq M^{-1/2}`, is block-diagonal over the connected components of the fast
//! graph; each block is built from Hessian-vector products and diagonalised densely
//! (nalgebra). Its eigenvalues are the squared angular frequencies ω².
//!
//! Where the methods fail (GSS98 section 3 and Lemma 5, with the census of ERRATA.md):
//! * type 3 — `hω ≈ 2πk`: eigenvalues coalesce at +1; impulse only;
//! * type 2 — `hω ≈ (2k − 1)π`: coalescence at −1; impulse, ShortAverage, LinearAverage;
//! * type 1 — `h(ω_i + ω_j) ≈ 2πk`, two modes coupled by the slow force: all four methods,
//!   LongAverage included (its only kind).

use nalgebra::{DMatrix, SymmetricEigen};
use serde::Serialize;

use crate::system::System;

/// One normal mode of the fast subsystem.
#[derive(Clone, Debug, Serialize)]
pub struct Mode {
    /// Angular frequency ω (per unit time); 0 for rigid-body and free motions.
    pub frequency: f64,
    /// `2π/ω` (infinite for ω = 0).
    pub period: f64,
    /// Index of the fast component (molecule) the mode lives in.
    pub component: usize,
    /// True when ω² < 0: the geometry is not at a minimum of the fast forces.
    pub unstable: bool,
}

/// The fast modes at the system's current positions, fastest first. Eigenvalues with
/// |ω²| below `1e-9 × max ω²` count as zero modes.
pub fn fast_modes(system: &mut System) -> Vec<Mode> {
    fast_modes_with(system, &mut |_, _| {})
}

/// [`fast_modes`], calling `progress(done, total)` after each batched Hessian column (one
/// Hessian-vector product; `total` is the largest component's degrees of freedom).
pub fn fast_modes_with(system: &mut System, progress: &mut dyn FnMut(usize, usize)) -> Vec<Mode> {
    let n = system.n_dofs();
    let dim = system.dim;
    let components = system.forces.fast_components(system.n_particles());
    let dofs: Vec<Vec<usize>> = components
        .iter()
        .map(|c| c.iter().flat_map(|&i| (i * dim)..(i * dim + dim)).collect())
        .collect();
    let largest = dofs.iter().map(Vec::len).max().unwrap_or(0);
    let mut hessians: Vec<DMatrix<f64>> = dofs
        .iter()
        .map(|d| DMatrix::zeros(d.len(), d.len()))
        .collect();
    // Batched columns: one Hessian-vector product gives column j of every block.
    let q = system.state.q.clone();
    let mut column = vec![0.0; n];
    let mut product = vec![0.0; n];
    for j in 0..largest {
        column.fill(0.0);
        for d in &dofs {
            if j < d.len() {
                column[d[j]] = 1.0;
            }
        }
        system.forces.hessian_vector(0, &q, &column, &mut product);
        for (d, hessian) in dofs.iter().zip(&mut hessians) {
            if j < d.len() {
                for (r, &dof) in d.iter().enumerate() {
                    hessian[(r, j)] = product[dof];
                }
            }
        }
        progress(j + 1, largest);
    }
    let mut modes = Vec::new();
    for (component, (d, mut hessian)) in dofs.iter().zip(hessians).enumerate() {
        for (r, &a) in d.iter().enumerate() {
            for (c, &b) in d.iter().enumerate() {
                hessian[(r, c)] *= (system.inverse_mass[a] * system.inverse_mass[b]).sqrt();
            }
        }
        // Symmetrise against round-off before the symmetric eigensolver.
        let hessian = (&hessian + hessian.transpose()) * 0.5;
        let eigen = SymmetricEigen::new(hessian);
        for &lambda in eigen.eigenvalues.iter() {
            modes.push((component, lambda));
        }
    }
    let scale = modes.iter().map(|m| m.1.abs()).fold(0.0, f64::max);
    let mut modes: Vec<Mode> = modes
        .into_iter()
        .map(|(component, lambda)| {
            let zero = lambda.abs() <= 1e-9 * scale;
            let frequency = if zero { 0.0 } else { lambda.abs().sqrt() };
            Mode {
                frequency,
                period: if zero {
                    f64::INFINITY
                } else {
                    std::f64::consts::TAU / frequency
                },
                component,
                unstable: !zero && lambda < 0.0,
            }
        })
        .collect();
    modes.sort_by(|a, b| b.frequency.total_cmp(&a.frequency));
    modes
}

/// The kind of resonance (GSS98 section 3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ResonanceType {
    /// Sum of two frequencies: `h(ω_i + ω_j) = 2πk`.
    Type1,
    /// `hω = (2k − 1)π`.
    Type2,
    /// `hω = 2πk`.
    Type3,
}

impl ResonanceType {
    /// Whether `method` has instabilities of this type (Lemma 4 census, ERRATA.md).
    pub fn affects(self, method: &str) -> bool {
        match self {
            ResonanceType::Type1 => matches!(
                method,
                "impulse"
                    | "impulse-midpoint"
                    | "short-average"
                    | "long-average"
                    | "linear-average"
            ),
            ResonanceType::Type2 => matches!(
                method,
                "impulse" | "impulse-midpoint" | "short-average" | "linear-average"
            ),
            ResonanceType::Type3 => matches!(method, "impulse" | "impulse-midpoint"),
        }
    }
}

/// A predicted dangerous outer step.
#[derive(Clone, Debug, Serialize)]
pub struct Resonance {
    pub h: f64,
    #[serde(rename = "type")]
    pub kind: ResonanceType,
    /// The multiple k.
    pub k: usize,
    /// The frequencies involved (one, or two for type 1).
    pub frequencies: Vec<f64>,
}

/// Dangerous outer steps in `[h_min, h_max]` from the `distinct` fastest distinct
/// frequencies. Frequencies within 1 % of one already taken count once: a box of identical
/// molecules has hundreds of O–H stretches a fraction of a percent apart, and their
/// resonances are one band, not hundreds of predictions.
pub fn predicted_resonances(
    modes: &[Mode],
    h_min: f64,
    h_max: f64,
    distinct: usize,
) -> Vec<Resonance> {
    let mut frequencies: Vec<f64> = Vec::new();
    for mode in modes.iter().filter(|m| m.frequency > 0.0 && !m.unstable) {
        if frequencies
            .iter()
            .all(|f| (f - mode.frequency).abs() > 0.01 * f)
        {
            frequencies.push(mode.frequency);
        }
        if frequencies.len() == distinct {
            break;
        }
    }
    let tau = std::f64::consts::TAU;
    let mut resonances = Vec::new();
    let mut add = |phase: f64, kind, k, involved: Vec<f64>, sum: f64| {
        let h = phase / sum;
        if h >= h_min && h <= h_max {
            resonances.push(Resonance {
                h,
                kind,
                k,
                frequencies: involved,
            });
        }
    };
    for &omega in &frequencies {
        let k_max = (h_max * omega / std::f64::consts::PI).floor() as usize;
        for m in 1..=k_max {
            let phase = m as f64 * std::f64::consts::PI;
            if m % 2 == 0 {
                add(phase, ResonanceType::Type3, m / 2, vec![omega], omega);
            } else {
                add(
                    phase,
                    ResonanceType::Type2,
                    m.div_ceil(2),
                    vec![omega],
                    omega,
                );
            }
        }
    }
    for (i, &a) in frequencies.iter().enumerate() {
        for &b in &frequencies[i + 1..] {
            let k_max = (h_max * (a + b) / tau).floor() as usize;
            for k in 1..=k_max {
                add(k as f64 * tau, ResonanceType::Type1, k, vec![a, b], a + b);
            }
        }
    }
    resonances.sort_by(|x, y| x.h.total_cmp(&y.h));
    resonances
}
