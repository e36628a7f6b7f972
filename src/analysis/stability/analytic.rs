//! GSS98 Lemma 4: the error-propagation matrix of the mollified impulse method (4) on the
//! linear problem (27), with exact reduced flow and exact averages.
//!
//! One step is `A = K R K` with the half kick `K = [[I, −(h/2)ΦUΦ], [0, I]]` and the
//! exact rotation `R` of the fast springs (state `(p, q)`). `A` is similar to
//! `K² R` (a cyclic shift), and scaling `p` by `h` turns that into the matrix of the
//! lemma's proof,
//!
//! ```text
//! A′ = [[I, −h² Φ U Φ], [0, I]] · [[cos Γ, −Γ sin Γ], [Γ⁻¹ sin Γ, cos Γ]],
//! ```
//!
//! in the state `(h p1, h p2, q1, q2)`, with Γ = diag(Γ1, Γ2), Φ = diag(Φ(Γ1), Φ(Γ2)).
//! Its characteristic polynomial is the palindromic quartic (28),
//! `λ⁴ − 2Sλ³ + (2 + S² − D)λ² − 2Sλ + 1`, with
//!
//! ```text
//! S = c1 + c2,  D = (c1 − c2)² + 4θ²ε1ε2,  c_i = cos Γ_i − ε_i,
//! ε_i = ½ h² α_i Φ(Γ_i)² Γ_i⁻¹ sin Γ_i,   θ = β / √(α1 α2).
//! ```
//!
//! Readings taken from the PDF conversion: ε_i as printed (`Γ_i⁻¹ sin Γ_i` is sinc Γ_i,
//! continuous at Γ_i = 0); `4θ²ε1ε2` is evaluated as `h⁴ β² Φ1² Φ2² sinc Γ1 sinc Γ2`,
//! the same number without the division by α1 α2 (so α_i = 0 is allowed). The test
//! `stability_lemma4` checks that this S and D are the characteristic polynomial of A′.
//!
//! The spectral radius used for maps comes from the exact roots of (28), not from a
//! general eigenvalue solver: the quartic factors as
//! `(λ² − c₊λ + 1)(λ² − c₋λ + 1)`, `c± = S ± √D` (Lemma 5's proof), and each factor's
//! roots have modulus `a + √(a² − 1)` with `a = (|c − 2| + |c + 2|)/4` (the Joukowski map;
//! Lemma 6 for complex c). Written so that `a − 1` is a sum of non-negative terms, this
//! resolves spectral radii down to `1 + 1e-15` and the LongAverage strip near (π, π)
//! whose width is below 1e-6 — where a Schur solver on A′ (error √(ε‖A′‖) ≈ 1e-7 at a
//! collision) cannot tell stable from unstable.

use nalgebra::{Complex, DMatrix, Matrix4};

use super::{AnalyticMethod, Coupling, InstabilityType, StabilityPoint, sinc};
use crate::error::{Error, Result};

/// Lemma 4 for one method, outer step and slow coupling.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinearProblem {
    pub method: AnalyticMethod,
    pub h: f64,
    pub coupling: Coupling,
}

impl LinearProblem {
    pub fn new(method: AnalyticMethod, h: f64, coupling: Coupling) -> Result<Self> {
        if !(h.is_finite() && h > 0.0) {
            return Err(
                Error::setting("h", "outer step h must be positive and finite")
                    .expected("a positive finite step")
                    .got(h.to_string()),
            );
        }
        coupling.validate()?;
        Ok(LinearProblem {
            method,
            h,
            coupling,
        })
    }

    /// The three-spring system's coupling (α1 = α2 = 1/2, β = −1/2).
    pub fn three_spring(method: AnalyticMethod, h: f64) -> Result<Self> {
        LinearProblem::new(method, h, Coupling::default())
    }

    /// ε1, ε2 of Lemma 4.
    pub fn epsilons(&self, gamma1: f64, gamma2: f64) -> (f64, f64) {
        let h2 = self.h * self.h;
        let phi1 = self.method.filter(gamma1);
        let phi2 = self.method.filter(gamma2);
        (
            0.5 * h2 * self.coupling.alpha1 * phi1 * phi1 * sinc(gamma1),
            0.5 * h2 * self.coupling.alpha2 * phi2 * phi2 * sinc(gamma2),
        )
    }

    /// S and D of the quartic (28) at (Γ1, Γ2).
    pub fn quartic(&self, gamma1: f64, gamma2: f64) -> Quartic {
        let h2 = self.h * self.h;
        let phi1 = self.method.filter(gamma1);
        let phi2 = self.method.filter(gamma2);
        let (sinc1, sinc2) = (sinc(gamma1), sinc(gamma2));
        let epsilon1 = 0.5 * h2 * self.coupling.alpha1 * phi1 * phi1 * sinc1;
        let epsilon2 = 0.5 * h2 * self.coupling.alpha2 * phi2 * phi2 * sinc2;
        // 1 ± c_i through half angles (1 + cos Γ = 2cos²(Γ/2), 1 − cos Γ = 2sin²(Γ/2)):
        // accurate to relative round-off where c_i is near ∓1, at the edges of the type-2
        // and type-3 regions.
        let (sin_half1, cos_half1) = (0.5 * gamma1).sin_cos();
        let (sin_half2, cos_half2) = (0.5 * gamma2).sin_cos();
        let c1 = gamma1.cos() - epsilon1;
        let c2 = gamma2.cos() - epsilon2;
        // c1 − c2 with cos Γ1 − cos Γ2 as a product, accurate to relative round-off where
        // the two cosines nearly cancel (along the type-1 strips, Γ1 + Γ2 ≈ 2πk).
        let cosine_difference =
            -2.0 * (0.5 * (gamma1 + gamma2)).sin() * (0.5 * (gamma1 - gamma2)).sin();
        let difference = cosine_difference - (epsilon1 - epsilon2);
        let beta = self.coupling.beta;
        let cross = h2 * h2 * beta * beta * (phi1 * phi1) * (phi2 * phi2) * sinc1 * sinc2;
        Quartic {
            c1,
            c2,
            one_plus_c: [
                2.0 * cos_half1 * cos_half1 - epsilon1,
                2.0 * cos_half2 * cos_half2 - epsilon2,
            ],
            one_minus_c: [
                2.0 * sin_half1 * sin_half1 + epsilon1,
                2.0 * sin_half2 * sin_half2 + epsilon2,
            ],
            difference,
            cross,
            s: c1 + c2,
            d: difference * difference + cross,
        }
    }

    /// Spectral radius and type at (Γ1, Γ2), from the exact roots of (28).
    pub fn point(&self, gamma1: f64, gamma2: f64) -> StabilityPoint {
        self.quartic(gamma1, gamma2).classify()
    }

    /// The matrix A′ of Lemma 4's proof, in the state `(h p1, h p2, q1, q2)`.
    pub fn a_prime(&self, gamma1: f64, gamma2: f64) -> Matrix4<f64> {
        let h2 = self.h * self.h;
        let gamma = [gamma1, gamma2];
        let phi = [self.method.filter(gamma1), self.method.filter(gamma2)];
        let u = [
            [self.coupling.alpha1, self.coupling.beta],
            [self.coupling.beta, self.coupling.alpha2],
        ];
        // The kick block −h² Φ U Φ.
        let mut kick = [[0.0; 2]; 2];
        for i in 0..2 {
            for j in 0..2 {
                kick[i][j] = -h2 * phi[i] * u[i][j] * phi[j];
            }
        }
        let mut rotation = Matrix4::zeros();
        for i in 0..2 {
            let (sin, cos) = gamma[i].sin_cos();
            rotation[(i, i)] = cos;
            rotation[(i, i + 2)] = -gamma[i] * sin;
            rotation[(i + 2, i)] = sinc(gamma[i]);
            rotation[(i + 2, i + 2)] = cos;
        }
        let mut kick_matrix = Matrix4::identity();
        for i in 0..2 {
            for j in 0..2 {
                kick_matrix[(i, j + 2)] = kick[i][j];
            }
        }
        kick_matrix * rotation
    }

    /// Spectral radius and type from a general eigenvalue solver on A′; a cross-check of
    /// [`LinearProblem::point`], reliable away from eigenvalue collisions (see the module
    /// documentation for why maps do not use it).
    pub fn point_from_matrix(&self, gamma1: f64, gamma2: f64, tolerance: f64) -> StabilityPoint {
        let a = self.a_prime(gamma1, gamma2);
        let dynamic = DMatrix::from_iterator(4, 4, a.iter().copied());
        super::classify_matrix(&dynamic, tolerance)
    }
}

/// The quartic (28) through its pieces: `c_i = cos Γ_i − ε_i` and `cross = 4θ²ε1ε2`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quartic {
    pub c1: f64,
    pub c2: f64,
    /// 1 + c_i and 1 − c_i, computed without cancellation.
    pub one_plus_c: [f64; 2],
    pub one_minus_c: [f64; 2],
    /// c1 − c2, without the cancellation of the two cosines along Γ1 + Γ2 ≈ 2πk.
    pub difference: f64,
    /// 4θ²ε1ε2 = h⁴β²Φ1²Φ2² sinc Γ1 sinc Γ2; D = (c1 − c2)² + cross.
    pub cross: f64,
    /// S of Lemma 4.
    pub s: f64,
    /// D of Lemma 4.
    pub d: f64,
}

impl Quartic {
    /// Coefficients of (28), highest power first.
    pub fn coefficients(&self) -> [f64; 5] {
        let s = self.s;
        [1.0, -2.0 * s, 2.0 + s * s - self.d, -2.0 * s, 1.0]
    }

    /// The four roots, from the factors `λ² − c±λ + 1`.
    pub fn roots(&self) -> [Complex<f64>; 4] {
        let root_d = Complex::new(self.d, 0.0).sqrt();
        let s = Complex::new(self.s, 0.0);
        let mut roots = [Complex::new(0.0, 0.0); 4];
        for (k, c) in [s + root_d, s - root_d].into_iter().enumerate() {
            let discriminant = (c * c - Complex::new(4.0, 0.0)).sqrt();
            roots[2 * k] = (c + discriminant) * 0.5;
            roots[2 * k + 1] = (c - discriminant) * 0.5;
        }
        roots
    }

    /// Lemma 5: all roots on or inside the unit circle iff D ≥ 0 and |S| ≤ 2 − √D.
    pub fn lemma5_stable(&self) -> bool {
        self.d >= 0.0 && self.s.abs() <= 2.0 - self.d.sqrt()
    }

    /// Left-hand side minus right-hand side of the type-2 boundary (30):
    /// `(1 + cos Γ1 − ε1)(1 + cos Γ2 − ε2) − θ²ε1ε2`; equals `((2 + S)² − D)/4`.
    pub fn type2_boundary(&self) -> f64 {
        self.one_plus_c[0] * self.one_plus_c[1] - 0.25 * self.cross
    }

    /// Left-hand side minus right-hand side of the type-3 boundary (31):
    /// `(1 − cos Γ1 + ε1)(1 − cos Γ2 + ε2) − θ²ε1ε2`; equals `((2 − S)² − D)/4`.
    pub fn type3_boundary(&self) -> f64 {
        self.one_minus_c[0] * self.one_minus_c[1] - 0.25 * self.cross
    }

    /// Spectral radius and type from the exact roots.
    ///
    /// With `m = a − 1 ≥ 0` for the dominant factor, `ρ = a + √(a² − 1) = 1 + m +
    /// √(m(m + 2))`. Every `m` is formed without cancellation, from `2 + S = (1 + c1) +
    /// (1 + c2)` and `2 − S = (1 − c1) + (1 − c2)` (accurate half-angle forms), so ρ − 1 is
    /// accurate to relative round-off even when it is 1e-12: near a collision at −1,
    /// `2 + c₋ = ((2 + S)² − D)/(2 + S + √D) = 4·(30)/(2 + c₊)`, and likewise at +1 with (31).
    pub fn classify(&self) -> StabilityPoint {
        let d = self.d;
        let two_plus_s = self.one_plus_c[0] + self.one_plus_c[1];
        let two_minus_s = self.one_minus_c[0] + self.one_minus_c[1];
        let (m, kind) = if d < 0.0 {
            // Complex c = S ± i√|D|: |c ± 2| = |S ± 2| + g(S ± 2) with
            // g(x) = √(x² + |D|) − |x| = |D| / (√(x² + |D|) + |x|), and
            // |S + 2| + |S − 2| − 4 = 2 max(0, |S| − 2) = 2 max(0, −(2 + S), −(2 − S)).
            let magnitude = -d;
            let g = |x: f64| magnitude / ((x * x + magnitude).sqrt() + x.abs());
            let beyond = (-two_plus_s).max(-two_minus_s).max(0.0);
            let m = 0.5 * beyond + 0.25 * (g(two_plus_s) + g(two_minus_s));
            (m, InstabilityType::Type1)
        } else {
            let root_d = d.sqrt();
            // 2 + c₋ and 2 − c₊: by the quotient where its denominator is a sum of
            // non-negative terms, else directly (then no cancellation either).
            let two_plus_minus = if two_plus_s >= 0.0 && two_plus_s + root_d > 0.0 {
                4.0 * self.type2_boundary() / (two_plus_s + root_d)
            } else {
                two_plus_s - root_d
            };
            let two_minus_plus = if two_minus_s >= 0.0 && two_minus_s + root_d > 0.0 {
                4.0 * self.type3_boundary() / (two_minus_s + root_d)
            } else {
                two_minus_s - root_d
            };
            // c₋ < −2 or c₊ > 2 leaves the circle; the other cases are dominated.
            let m_minus = (-0.5 * two_plus_minus).max(0.0);
            let m_plus = (-0.5 * two_minus_plus).max(0.0);
            if m_minus >= m_plus {
                (m_minus, InstabilityType::Type2)
            } else {
                (m_plus, InstabilityType::Type3)
            }
        };
        // A |D| so small that m underflows to 0 is on the circle to machine precision.
        let kind = if m > 0.0 {
            kind
        } else {
            InstabilityType::Stable
        };
        let excess = m + (m * (m + 2.0)).sqrt();
        StabilityPoint {
            spectral_radius: 1.0 + excess,
            excess,
            kind,
        }
    }
}
