//! Fixed external potentials on single particles that are not central pair
//! interactions. One so far: the electric potential of CFM25 5.7.3,
//! `φ(x) = 2cos²x₁ + sin²x₁ (sin x₂ cos x₂ + sin x₃ cos x₃)`, scaled by the particle's
//! charge `e` (`V = e φ`). Non-bonded: slow by default. 3-D.
//!
//! With `g = (sin 2x₂ + sin 2x₃)/2`: `∂₁φ = sin 2x₁ (g − 2)`, `∂₂φ = sin²x₁ cos 2x₂`,
//! `∂₃φ = sin²x₁ cos 2x₃`; `∂₁₁φ = 2cos 2x₁ (g − 2)`, `∂₁₂φ = sin 2x₁ cos 2x₂`,
//! `∂₁₃φ = sin 2x₁ cos 2x₃`, `∂₂₂φ = −2sin²x₁ sin 2x₂`, `∂₃₃φ = −2sin²x₁ sin 2x₃`,
//! `∂₂₃φ = 0`.

use super::{ForceTerm, TermClass};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FieldShape {
    /// CFM25 5.7.3's `φ`.
    Cfm25Trigonometric,
}

#[derive(Clone, Debug)]
pub struct ExternalField {
    shape: FieldShape,
    /// `(particle, strength e)`; the particle's three coordinates are `3i..3i+3`.
    particles: Vec<(usize, f64)>,
}

impl ExternalField {
    /// A field on particles of a 3-D scene (the scene checks `dim = 3`).
    pub fn new(shape: FieldShape, particles: Vec<(usize, f64)>) -> Self {
        ExternalField { shape, particles }
    }

    fn point(q: &[f64], i: usize) -> [f64; 3] {
        [q[3 * i], q[3 * i + 1], q[3 * i + 2]]
    }

    fn value(&self, x: [f64; 3]) -> f64 {
        match self.shape {
            FieldShape::Cfm25Trigonometric => {
                let (s, c) = x[0].sin_cos();
                2.0 * c * c + s * s * (x[1].sin() * x[1].cos() + x[2].sin() * x[2].cos())
            }
        }
    }

    fn gradient(&self, x: [f64; 3]) -> [f64; 3] {
        match self.shape {
            FieldShape::Cfm25Trigonometric => {
                let s = x[0].sin();
                let g = 0.5 * ((2.0 * x[1]).sin() + (2.0 * x[2]).sin());
                [
                    (2.0 * x[0]).sin() * (g - 2.0),
                    s * s * (2.0 * x[1]).cos(),
                    s * s * (2.0 * x[2]).cos(),
                ]
            }
        }
    }

    fn hessian(&self, x: [f64; 3]) -> [[f64; 3]; 3] {
        match self.shape {
            FieldShape::Cfm25Trigonometric => {
                let s = x[0].sin();
                let g = 0.5 * ((2.0 * x[1]).sin() + (2.0 * x[2]).sin());
                let s2 = (2.0 * x[0]).sin();
                let h12 = s2 * (2.0 * x[1]).cos();
                let h13 = s2 * (2.0 * x[2]).cos();
                [
                    [2.0 * (2.0 * x[0]).cos() * (g - 2.0), h12, h13],
                    [h12, -2.0 * s * s * (2.0 * x[1]).sin(), 0.0],
                    [h13, 0.0, -2.0 * s * s * (2.0 * x[2]).sin()],
                ]
            }
        }
    }
}

impl ForceTerm for ExternalField {
    fn kind(&self) -> &'static str {
        "external-field"
    }

    fn class(&self) -> TermClass {
        TermClass::Nonbonded
    }

    fn energy(&self, q: &[f64]) -> f64 {
        self.particles
            .iter()
            .map(|&(i, e)| e * self.value(Self::point(q, i)))
            .sum()
    }

    fn add_gradient(&self, q: &[f64], gradient: &mut [f64]) {
        for &(i, e) in &self.particles {
            let g = self.gradient(Self::point(q, i));
            for a in 0..3 {
                gradient[3 * i + a] += e * g[a];
            }
        }
    }

    fn add_hessian_vector(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        for &(i, e) in &self.particles {
            let h = self.hessian(Self::point(q, i));
            let vi = Self::point(v, i);
            for a in 0..3 {
                out[3 * i + a] += e * (0..3).map(|b| h[a][b] * vi[b]).sum::<f64>();
            }
        }
    }

    fn couplings(&self) -> Vec<Vec<usize>> {
        self.particles.iter().map(|&(i, _)| vec![i]).collect()
    }

    fn interaction_count(&self) -> usize {
        self.particles.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Gradient and Hessian against central differences (step 1e-6 on O(1) values:
    /// truncation ~1e-12, round-off ~1e-10; 1e-7 is loose).
    #[test]
    fn derivatives_match_finite_differences() {
        let field = ExternalField::new(FieldShape::Cfm25Trigonometric, vec![(0, 1.0)]);
        let x = [0.5, -0.25, -0.3];
        let g = field.gradient(x);
        let h = field.hessian(x);
        let step = 1e-6;
        for a in 0..3 {
            let mut plus = x;
            let mut minus = x;
            plus[a] += step;
            minus[a] -= step;
            let numeric = (field.value(plus) - field.value(minus)) / (2.0 * step);
            assert!((numeric - g[a]).abs() < 1e-7, "gradient {a}");
            let (gp, gm) = (field.gradient(plus), field.gradient(minus));
            for b in 0..3 {
                let numeric = (gp[b] - gm[b]) / (2.0 * step);
                assert!((numeric - h[b][a]).abs() < 1e-7, "hessian {b}{a}");
            }
        }
    }
}
