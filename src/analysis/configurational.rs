//! Configurational temperature `k_B T_conf = ⟨|∇U|²⟩ / ⟨∇²U⟩` (Rugh, Phys. Rev. Lett.
//! 78:772, 1997; Butler, Ayton, Jepps & Evans, J. Chem. Phys. 109:6519, 1998): in the
//! canonical ensemble `⟨∇U·∇U⟩ = k_B T ⟨∇²U⟩` by integration by parts, whatever the masses
//! and the velocities, so it checks what a thermostat does to configurations even where the
//! kinetic temperature is not `T` (SIN(R) holds it at `L/(L+1)·T`).
//!
//! Per frame: one gradient of every term gives `|∇U|²`; the Laplacian `∇²U = tr ∇²U` comes
//! from Hessian-vector products, which every force term has:
//!
//! * **bonded terms, exactly.** Their Hessian couples only atoms that share a bond, angle
//!   or torsion. With the atoms coloured so that no two atoms of a colour share a bonded
//!   term (greedy colouring of that graph: 3 colours for water), `tr H = Σ_{c,a} e_{c,a}ᵀ H
//!   e_{c,a}` over colours `c` and axes `a`, `e_{c,a}` being 1 on axis `a` of the atoms of
//!   colour `c`: `colours × 3` products, independent of the number of atoms. A bonded graph
//!   needing more than [`MAX_COLOURS`] colours is estimated like the non-bonded terms.
//! * **non-bonded terms, by Hutchinson's estimator** with `K` seeded Rademacher vectors
//!   `z` (entries ±1): `E[zᵀHz] = tr H`, unbiased, with variance `2 Σ_{i≠j} H_ij²` per
//!   probe (the diagonal contributes none) — `K` products per frame. The frame's estimate
//!   is the mean over the probes; its variance, estimated from their spread, is reported.
//!   The probes are independent between frames, so the block-average error bar of
//!   `T_conf` includes their noise.
//!
//! Not seen by Hessian-vector products: delta functions where a force jumps. An
//! energy-shifted Lennard-Jones cutoff has one (the force jumps by `u′(r_c)` at `r_c`); for
//! the water box (O–O, 9 Å) it adds about `2 u′(r_c) · ½ N_O ρ_O 4π r_c² ≈ 6 kcal/mol/Å²`
//! to `⟨∇²U⟩ ≈ 10⁶`, a relative 10⁻⁵, below every error bar here.
//! The random vectors are drawn from `rand`'s `StdRng` seeded per frame from the seed and the
//! frame's index, so a frame's estimate does not depend on which other frames are analysed.

use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

use crate::forces::TermClass;
use crate::split::LabelledTerm;

/// Most colours for the exact bonded Laplacian (then `3 × 32` products per frame).
pub const MAX_COLOURS: usize = 32;

/// Hutchinson probes per frame by default (`analyze --probes`, and the scan's sampling
/// criterion, which analyses as `analyze` does).
pub const DEFAULT_PROBES: usize = 4;

/// Most Hutchinson probes per frame (a bound on a user-given cost).
pub const MAX_PROBES: usize = 10_000;

/// One frame's configurational sums.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameSample {
    /// `|∇U|²`.
    pub gradient_squared: f64,
    /// `∇²U`: exact part plus the Hutchinson mean.
    pub laplacian: f64,
    /// Variance of the Hutchinson mean of this frame (0 when every term is exact).
    pub laplacian_variance: f64,
}

pub struct ConfigurationalProbe {
    dim: usize,
    probes: usize,
    seed: u64,
    exact_terms: Vec<usize>,
    stochastic_terms: Vec<usize>,
    /// Colour of each particle (exact terms).
    colour_of: Vec<usize>,
    colours: usize,
    gradient: Vec<f64>,
    direction: Vec<f64>,
    product: Vec<f64>,
}

/// Greedy colouring of the graph whose cliques are `groups`: no two particles of one group
/// share a colour.
fn greedy_colouring(n: usize, groups: &[Vec<usize>]) -> (Vec<usize>, usize) {
    let mut neighbours = vec![Vec::new(); n];
    for group in groups {
        for &i in group {
            neighbours[i].extend(group.iter().copied().filter(|&j| j != i));
        }
    }
    let mut colour_of = vec![usize::MAX; n];
    let mut colours = 0;
    let mut used = Vec::new();
    for i in 0..n {
        used.clear();
        used.extend(
            neighbours[i]
                .iter()
                .map(|&j| colour_of[j])
                .filter(|&c| c != usize::MAX),
        );
        let colour = (0..).find(|c| !used.contains(c)).unwrap_or(0);
        colour_of[i] = colour;
        colours = colours.max(colour + 1);
    }
    (colour_of, colours)
}

impl ConfigurationalProbe {
    /// A probe for `terms` over `n` particles in `dim` dimensions, with `probes` Hutchinson
    /// vectors per frame for the terms not done exactly (`exact_bonded = false` estimates
    /// every term, for tests).
    pub fn new(
        terms: &[LabelledTerm],
        n: usize,
        dim: usize,
        probes: usize,
        seed: u64,
        exact_bonded: bool,
    ) -> Self {
        let bonded = |t: &LabelledTerm| exact_bonded && t.term.class() == TermClass::Bonded;
        let mut exact_terms: Vec<usize> = (0..terms.len()).filter(|&t| bonded(&terms[t])).collect();
        let groups: Vec<Vec<usize>> = exact_terms
            .iter()
            .flat_map(|&t| terms[t].term.couplings())
            .collect();
        let (mut colour_of, mut colours) = greedy_colouring(n, &groups);
        if colours > MAX_COLOURS {
            exact_terms.clear();
            colour_of = vec![0; n];
            colours = 0;
        }
        let stochastic_terms = (0..terms.len())
            .filter(|t| !exact_terms.contains(t))
            .collect();
        ConfigurationalProbe {
            dim,
            probes,
            seed,
            exact_terms,
            stochastic_terms,
            colour_of,
            colours,
            gradient: vec![0.0; n * dim],
            direction: vec![0.0; n * dim],
            product: vec![0.0; n * dim],
        }
    }

    /// Names of the terms whose Laplacian is exact, and of those estimated.
    pub fn term_names(&self, terms: &[LabelledTerm]) -> (Vec<String>, Vec<String>) {
        let names = |list: &[usize]| list.iter().map(|&t| terms[t].name.clone()).collect();
        (names(&self.exact_terms), names(&self.stochastic_terms))
    }

    pub fn colours(&self) -> usize {
        self.colours
    }

    /// Hessian-vector products per frame: exact ones, then Hutchinson ones.
    pub fn products_per_frame(&self) -> (usize, usize) {
        let stochastic = if self.stochastic_terms.is_empty() {
            0
        } else {
            self.probes
        };
        (self.colours * self.dim, stochastic)
    }

    /// `vᵀ (Σ_terms H) v` for the current `self.direction`.
    fn quadratic_form(&mut self, terms: &[LabelledTerm], which: &[usize], q: &[f64]) -> f64 {
        self.product.fill(0.0);
        for &t in which {
            terms[t]
                .term
                .add_hessian_vector(q, &self.direction, &mut self.product);
        }
        self.direction
            .iter()
            .zip(&self.product)
            .map(|(v, hv)| v * hv)
            .sum()
    }

    /// `|∇U|²` and `∇²U` at `q`; `frame` seeds this frame's random vectors.
    pub fn sample(&mut self, terms: &[LabelledTerm], q: &[f64], frame: u64) -> FrameSample {
        self.gradient.fill(0.0);
        for labelled in terms {
            labelled.term.add_gradient(q, &mut self.gradient);
        }
        let gradient_squared = self.gradient.iter().map(|g| g * g).sum();

        let exact_terms = std::mem::take(&mut self.exact_terms);
        let mut laplacian = 0.0;
        for colour in 0..self.colours {
            for axis in 0..self.dim {
                for (i, &c) in self.colour_of.iter().enumerate() {
                    for a in 0..self.dim {
                        self.direction[i * self.dim + a] =
                            if c == colour && a == axis { 1.0 } else { 0.0 };
                    }
                }
                laplacian += self.quadratic_form(terms, &exact_terms, q);
            }
        }
        self.exact_terms = exact_terms;

        let mut laplacian_variance = 0.0;
        if !self.stochastic_terms.is_empty() && self.probes > 0 {
            let stochastic = std::mem::take(&mut self.stochastic_terms);
            let mut rng = StdRng::seed_from_u64(
                self.seed ^ frame.wrapping_add(1).wrapping_mul(0x9E37_79B9_7F4A_7C15),
            );
            let (mut sum, mut sum_squares) = (0.0, 0.0);
            for _ in 0..self.probes {
                for v in &mut self.direction {
                    *v = if rng.random::<bool>() { 1.0 } else { -1.0 };
                }
                let estimate = self.quadratic_form(terms, &stochastic, q);
                sum += estimate;
                sum_squares += estimate * estimate;
            }
            self.stochastic_terms = stochastic;
            let k = self.probes as f64;
            let mean = sum / k;
            laplacian += mean;
            if self.probes > 1 {
                laplacian_variance = (sum_squares - k * mean * mean).max(0.0) / (k - 1.0) / k;
            }
        }
        FrameSample {
            gradient_squared,
            laplacian,
            laplacian_variance,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colouring_separates_every_group() {
        let groups = vec![vec![0, 1], vec![0, 2], vec![1, 0, 2], vec![3, 4]];
        let (colour_of, colours) = greedy_colouring(5, &groups);
        assert_eq!(colours, 3);
        for g in &groups {
            for (x, &i) in g.iter().enumerate() {
                for &j in &g[x + 1..] {
                    assert_ne!(colour_of[i], colour_of[j]);
                }
            }
        }
    }
}
