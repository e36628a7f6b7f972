//! The nonlinear string of MEMM18 3.3 (after Chabassier–Joly), discretised with P1 finite
//! elements: coordinates are nodal displacements `u_i ∈ R^dim`, axis 0 along the string.
//!
//! The energy density is `V(u′) = |u′|²/2 − α(√((1 + u′₁)² + u′₂²) − (1 + u′₁))`
//! (`α ∈ [0, 1)`: 0 linear, towards 1 strongly nonlinear); on an element of length `Δx`
//! the strain is constant, `u′ = d/Δx` with `d = u_b − u_a`, so the element energy is
//! `Δx V(d/Δx) = |d|²/(2Δx) − α(|w| − w₀)` with `w = Δx e₀ + d` (the deformed element).
//!
//! * `∇_b = d/Δx − α(w/|w| − e₀)`, `∇_a = −∇_b`;
//! * Hessian block `I/Δx − α(I/|w| − w wᵀ/|w|³)` (positive definite for `α < 1`).
//!
//! `|w| − w₀` is computed as `(Σ_{a≥1} d_a²)/(|w| + w₀)` (for `w₀ > 0`): the direct
//! difference loses `log₁₀(Δx/|u′|²)` digits at small strains (the energy of a 1 %-high
//! bump would keep only about 4 of them), and so does the axial gradient `w₀/|w| − 1`.
//!
//! The mass matrix that goes with it is the consistent P1 one, `Δx tridiag(1/6, 2/3, 1/6)`
//! per axis (the scene's `[mass_matrix]`). Bonded: fast by default. An end of the string
//! may be an anchor (Dirichlet condition: zero displacement when the anchor is at 0).

use super::{ForceTerm, Site, TermClass, add_to_site, dot, site_position, site_vector, with_dim};

#[derive(Clone, Debug)]
pub struct FemString {
    dim: usize,
    /// Consecutive sites: elements join `sites[k]` and `sites[k + 1]`.
    sites: Vec<Site>,
    element_length: f64,
    alpha: f64,
}

impl FemString {
    /// `sites` in order along the string (at least two), element length `Δx > 0`,
    /// nonlinearity `α ∈ [0, 1)`.
    pub fn new(dim: usize, sites: Vec<Site>, element_length: f64, alpha: f64) -> Self {
        assert!((1..=3).contains(&dim), "dimension must be 1, 2 or 3");
        assert!(sites.len() >= 2 && element_length > 0.0);
        FemString {
            dim,
            sites,
            element_length,
            alpha,
        }
    }

    /// `(d, w, |w|, |w| − w₀)` of the element `k`.
    #[inline(always)]
    fn element<const D: usize>(&self, k: usize, q: &[f64]) -> ([f64; D], [f64; D], f64, f64) {
        let ua = site_position::<D>(&self.sites[k], q);
        let ub = site_position::<D>(&self.sites[k + 1], q);
        let d: [f64; D] = std::array::from_fn(|a| ub[a] - ua[a]);
        let mut w = d;
        w[0] += self.element_length;
        let r = dot(&w, &w).sqrt();
        let excess = if w[0] > 0.0 {
            let transverse: f64 = (1..D).map(|a| d[a] * d[a]).sum();
            transverse / (r + w[0])
        } else {
            r - w[0]
        };
        (d, w, r, excess)
    }

    fn energy_d<const D: usize>(&self, q: &[f64]) -> f64 {
        (0..self.sites.len() - 1)
            .map(|k| {
                let (d, _, _, excess) = self.element::<D>(k, q);
                0.5 * dot(&d, &d) / self.element_length - self.alpha * excess
            })
            .sum()
    }

    fn gradient_d<const D: usize>(&self, q: &[f64], gradient: &mut [f64]) {
        for k in 0..self.sites.len() - 1 {
            let (d, w, r, excess) = self.element::<D>(k, q);
            let mut on_b: [f64; D] =
                std::array::from_fn(|a| d[a] / self.element_length - self.alpha * w[a] / r);
            // Axial: −α(w₀/r − 1) = α (r − w₀)/r.
            on_b[0] = d[0] / self.element_length + self.alpha * excess / r;
            let on_a: [f64; D] = std::array::from_fn(|a| -on_b[a]);
            add_to_site(&self.sites[k + 1], gradient, &on_b);
            add_to_site(&self.sites[k], gradient, &on_a);
        }
    }

    fn hessian_vector_d<const D: usize>(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        for k in 0..self.sites.len() - 1 {
            let (_, w, r, _) = self.element::<D>(k, q);
            let va = site_vector::<D>(&self.sites[k], v);
            let vb = site_vector::<D>(&self.sites[k + 1], v);
            let dv: [f64; D] = std::array::from_fn(|a| vb[a] - va[a]);
            let along = self.alpha * dot(&w, &dv) / (r * r * r);
            let on_b: [f64; D] = std::array::from_fn(|a| {
                dv[a] / self.element_length - self.alpha * dv[a] / r + along * w[a]
            });
            let on_a: [f64; D] = std::array::from_fn(|a| -on_b[a]);
            add_to_site(&self.sites[k + 1], out, &on_b);
            add_to_site(&self.sites[k], out, &on_a);
        }
    }
}

impl ForceTerm for FemString {
    fn kind(&self) -> &'static str {
        "fem-string"
    }

    fn class(&self) -> TermClass {
        TermClass::Bonded
    }

    fn energy(&self, q: &[f64]) -> f64 {
        with_dim!(self.dim, D => self.energy_d::<D>(q))
    }

    fn add_gradient(&self, q: &[f64], gradient: &mut [f64]) {
        with_dim!(self.dim, D => self.gradient_d::<D>(q, gradient))
    }

    fn add_hessian_vector(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        with_dim!(self.dim, D => self.hessian_vector_d::<D>(q, v, out))
    }

    fn couplings(&self) -> Vec<Vec<usize>> {
        self.sites
            .windows(2)
            .map(|pair| pair.iter().filter_map(Site::particle).collect())
            .collect()
    }

    fn interaction_count(&self) -> usize {
        self.sites.len() - 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn string(alpha: f64) -> (FemString, Vec<f64>) {
        let sites = vec![
            Site::Fixed([0.0; 3]),
            Site::Particle(0),
            Site::Particle(1),
            Site::Fixed([0.0; 3]),
        ];
        (
            FemString::new(2, sites, 0.25, alpha),
            vec![0.03, 0.11, -0.02, 0.07],
        )
    }

    #[test]
    fn gradient_and_hessian_match_finite_differences() {
        let (term, q) = string(0.9);
        let mut gradient = vec![0.0; 4];
        term.add_gradient(&q, &mut gradient);
        // Central differences: error O(δ²·V‴) ≈ 1e-10 plus round-off ε·V/δ ≈ 1e-11.
        let delta = 1e-5;
        for i in 0..4 {
            let (mut plus, mut minus) = (q.clone(), q.clone());
            plus[i] += delta;
            minus[i] -= delta;
            let numeric = (term.energy(&plus) - term.energy(&minus)) / (2.0 * delta);
            assert!(
                (numeric - gradient[i]).abs() < 1e-8,
                "{i}: {numeric} vs {}",
                gradient[i]
            );
        }
        let v = [0.3, -0.2, 0.5, 0.1];
        let mut hv = vec![0.0; 4];
        term.add_hessian_vector(&q, &v, &mut hv);
        let (mut gp, mut gm) = (vec![0.0; 4], vec![0.0; 4]);
        let plus: Vec<f64> = q.iter().zip(&v).map(|(x, y)| x + delta * y).collect();
        let minus: Vec<f64> = q.iter().zip(&v).map(|(x, y)| x - delta * y).collect();
        term.add_gradient(&plus, &mut gp);
        term.add_gradient(&minus, &mut gm);
        for i in 0..4 {
            let numeric = (gp[i] - gm[i]) / (2.0 * delta);
            assert!(
                (numeric - hv[i]).abs() < 1e-7,
                "{i}: {numeric} vs {}",
                hv[i]
            );
        }
    }

    #[test]
    fn linear_case_is_a_spring_chain() {
        // α = 0: each element is |d|²/(2Δx), a rest-length-0 spring of stiffness 1/Δx.
        let (term, q) = string(0.0);
        let expected = 0.5 / 0.25
            * ((q[0] * q[0] + q[1] * q[1])
                + ((q[2] - q[0]).powi(2) + (q[3] - q[1]).powi(2))
                + (q[2] * q[2] + q[3] * q[3]));
        assert!((term.energy(&q) - expected).abs() < 1e-15);
    }
}
