//! Linear stability of the impulse and mollified impulse methods (GSS98 sections 3 and 7).
//!
//! The test problem is GSS98 eq. (27): two degrees of freedom with fast frequencies
//! Ω1, Ω2 and a constant slow coupling `U_qq = [[α1, β], [β, α2]]`,
//!
//! ```text
//! dp/dt = −Ω² q − U_qq q,   dq/dt = p.
//! ```
//!
//! The three-spring scene of GSS98 section 3 moving horizontally is exactly this problem
//! with α1 = α2 = 1/2, β = −1/2 (the middle spring is the slow force; ERRATA: the right
//! anchor is at (3, 0)). One outer step of a method is a linear map of (q, p); its
//! spectral radius ρ decides stability: ρ = 1 stable, ρ > 1 exponential growth.
//!
//! Two ways to get ρ:
//! - [`analytic`]: Lemma 4 — the 4×4 matrix A′ of its proof and the quartic (28) with
//!   exact reduced flow and exact averages, as functions of h, Γ1 = hΩ1, Γ2 = hΩ2.
//! - [`integrator`]: the propagation matrix of one outer step of a real integrator from
//!   the registry, measured on the three-spring scene by perturbing the equilibrium.
//!
//! [`map`] evaluates either over a (Γ1, Γ2) grid in parallel.
//!
//! # Instability types
//!
//! The propagation matrices are symplectic: eigenvalues come as λ, 1/λ and their
//! conjugates, all on the unit circle when stable. An unstable point is classified by its
//! dominant eigenvalue λ* (largest modulus), which tells where its pair or quadruple left
//! the unit circle (GSS98 Lemma 5 and the paragraph after it):
//! - **type 1**: λ* is not real — a quadruple {λ, λ̄, 1/λ, 1/λ̄} that coalesced at a
//!   non-real point e^{±iφ} of the circle; in terms of (28), D < 0;
//! - **type 2**: λ* is real and negative — a real pair that coalesced at −1;
//!   D ≥ 0 and S − √D < −2;
//! - **type 3**: λ* is real and positive — a real pair that coalesced at +1;
//!   D ≥ 0 and S + √D > 2.
//!
//! Where both real conditions hold at once (Impulse has a few such points, near
//! Γ1 ≈ odd·π, Γ2 ≈ even·π) the type is that of the larger root; a tie goes to type 2.
//! The classification is by the eigenvalues at the point itself; for every region that
//! touches the stable region it is the place where the eigenvalues collided on the circle.

pub mod analytic;
pub mod integrator;
pub mod map;

use nalgebra::{Complex, DMatrix};

use crate::error::{Error, Result};

/// The methods with an analytic stability theory (GSS98 Lemma 4), by their command-line
/// names. Each is the mollified impulse method (4) with the filter Φ of section 5.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AnalyticMethod {
    /// Φ = 1: the impulse method (r-RESPA, Verlet-I).
    Impulse,
    /// Φ(Γ) = sin(Γ/2)/(Γ/2).
    ShortAverage,
    /// Φ(Γ) = sin Γ / Γ.
    LongAverage,
    /// Φ(Γ) = (sin(Γ/2)/(Γ/2))².
    LinearAverage,
}

impl AnalyticMethod {
    pub const ALL: [AnalyticMethod; 4] = [
        AnalyticMethod::Impulse,
        AnalyticMethod::ShortAverage,
        AnalyticMethod::LongAverage,
        AnalyticMethod::LinearAverage,
    ];

    /// The name on the command line and in the integrator registry.
    pub fn name(self) -> &'static str {
        match self {
            AnalyticMethod::Impulse => "impulse",
            AnalyticMethod::ShortAverage => "short-average",
            AnalyticMethod::LongAverage => "long-average",
            AnalyticMethod::LinearAverage => "linear-average",
        }
    }

    /// The paper's name, for titles.
    pub fn paper_name(self) -> &'static str {
        match self {
            AnalyticMethod::Impulse => "Impulse",
            AnalyticMethod::ShortAverage => "ShortAverage",
            AnalyticMethod::LongAverage => "LongAverage",
            AnalyticMethod::LinearAverage => "LinearAverage",
        }
    }

    /// Look a method up by its command-line name.
    pub fn from_name(name: &str) -> Result<Self> {
        AnalyticMethod::ALL
            .into_iter()
            .find(|m| m.name() == name)
            .ok_or_else(|| {
                let known: Vec<&str> = AnalyticMethod::ALL.iter().map(|m| m.name()).collect();
                Error::flag("--method", format!("method \"{name}\" has no analytic stability theory; analytic mode knows: {}", known.join(", "))).expected(known.join(", ")).got_named(name)
            })
    }

    /// The filter Φ(Γ) of GSS98 section 5 (repeated before Lemma 5, where LinearAverage is
    /// missing from the list; its Φ is the section-5 one).
    pub fn filter(self, gamma: f64) -> f64 {
        match self {
            AnalyticMethod::Impulse => 1.0,
            AnalyticMethod::ShortAverage => sinc(0.5 * gamma),
            AnalyticMethod::LongAverage => sinc(gamma),
            AnalyticMethod::LinearAverage => {
                let s = sinc(0.5 * gamma);
                s * s
            }
        }
    }
}

/// sin x / x, continuous at 0.
pub fn sinc(x: f64) -> f64 {
    // Below |x| = 1e-4 the series 1 − x²/6 is exact to round-off (next term x⁴/120 < 1e-18).
    if x.abs() < 1e-4 {
        1.0 - x * x / 6.0
    } else {
        x.sin() / x
    }
}

/// The slow coupling `U_qq = [[α1, β], [β, α2]]` of GSS98 eq. (27); symmetric positive
/// semidefinite. The default is the three-spring system's α1 = α2 = 1/2, β = −1/2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coupling {
    pub alpha1: f64,
    pub alpha2: f64,
    pub beta: f64,
}

impl Default for Coupling {
    fn default() -> Self {
        Coupling {
            alpha1: 0.5,
            alpha2: 0.5,
            beta: -0.5,
        }
    }
}

impl Coupling {
    /// Check that `U_qq` is finite and positive semidefinite, as Lemma 4 assumes.
    pub fn validate(&self) -> Result<()> {
        let Coupling {
            alpha1,
            alpha2,
            beta,
        } = *self;
        if !(alpha1.is_finite() && alpha2.is_finite() && beta.is_finite()) {
            return Err(Error::input("slow coupling must be finite")
                .expected("finite numbers")
                .got(format!(
                    "alpha1 = {alpha1}, alpha2 = {alpha2}, beta = {beta}"
                )));
        }
        // Semidefinite: α1, α2 ≥ 0 and β² ≤ α1 α2 (a relative round-off slack on the
        // determinant lets a user type a singular matrix such as α = 1/3, β = −1/3).
        let slack = 1e-12 * (alpha1 * alpha2).abs().max(beta * beta);
        if alpha1 < 0.0 || alpha2 < 0.0 || beta * beta > alpha1 * alpha2 + slack {
            return Err(Error::input(format!(
                "the slow coupling U = [[alpha1, beta], [beta, alpha2]] = [[{alpha1}, {beta}], \
                 [{beta}, {alpha2}]] is not positive semidefinite (GSS98 eq. (27) needs \
                 alpha1, alpha2 >= 0 and beta^2 <= alpha1*alpha2)"
            )));
        }
        Ok(())
    }

    /// ω², the largest eigenvalue of `U_qq` (GSS98 proof of Proposition 4).
    pub fn omega_squared(&self) -> f64 {
        let mean = 0.5 * (self.alpha1 + self.alpha2);
        let half_difference = 0.5 * (self.alpha1 - self.alpha2);
        mean + half_difference.hypot(self.beta)
    }
}

/// What an unstable point's eigenvalues did (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum InstabilityType {
    Stable,
    /// Non-real dominant eigenvalue (D < 0).
    Type1,
    /// Real negative dominant eigenvalue (coalesced at −1).
    Type2,
    /// Real positive dominant eigenvalue (coalesced at +1).
    Type3,
    /// The step overflowed (a non-finite propagation matrix): unstable, type unknown.
    Overflow,
}

impl InstabilityType {
    /// The number written in CSV and JSON: 0 stable, 1–3 the type, −1 overflow.
    pub fn code(self) -> i32 {
        match self {
            InstabilityType::Stable => 0,
            InstabilityType::Type1 => 1,
            InstabilityType::Type2 => 2,
            InstabilityType::Type3 => 3,
            InstabilityType::Overflow => -1,
        }
    }

    pub fn from_code(code: i32) -> Option<Self> {
        match code {
            0 => Some(InstabilityType::Stable),
            1 => Some(InstabilityType::Type1),
            2 => Some(InstabilityType::Type2),
            3 => Some(InstabilityType::Type3),
            -1 => Some(InstabilityType::Overflow),
            _ => None,
        }
    }

    pub fn is_stable(self) -> bool {
        self == InstabilityType::Stable
    }
}

/// The spectral radius of one outer step and the instability type.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StabilityPoint {
    pub spectral_radius: f64,
    /// ρ − 1, computed without the cancellation of `spectral_radius - 1.0` where the
    /// method allows (analytic mode: to relative round-off, so an instability with
    /// ρ − 1 = 1e-14 is resolved; integrator mode: `spectral_radius - 1.0`).
    pub excess: f64,
    pub kind: InstabilityType,
}

/// Spectral radius and type from the eigenvalues of a propagation matrix.
///
/// `tolerance` is how far above 1 the computed spectral radius may lie and still count as
/// stable: round-off in the matrix moves eigenvalues on the unit circle off it (by
/// ε‖A‖ at simple eigenvalues, by √(ε‖A‖) near a collision). The dominant eigenvalue
/// counts as non-real when its imaginary part exceeds `tolerance · ρ`.
pub fn classify_eigenvalues(eigenvalues: &[Complex<f64>], tolerance: f64) -> StabilityPoint {
    let Some(dominant) = eigenvalues
        .iter()
        .copied()
        .max_by(|a, b| a.norm().total_cmp(&b.norm()))
    else {
        return StabilityPoint {
            spectral_radius: 0.0,
            excess: -1.0,
            kind: InstabilityType::Stable,
        };
    };
    let rho = dominant.norm();
    if !rho.is_finite() {
        return StabilityPoint {
            spectral_radius: f64::INFINITY,
            excess: f64::INFINITY,
            kind: InstabilityType::Overflow,
        };
    }
    let kind = if rho <= 1.0 + tolerance {
        InstabilityType::Stable
    } else if dominant.im.abs() > tolerance * rho {
        InstabilityType::Type1
    } else if dominant.re < 0.0 {
        InstabilityType::Type2
    } else {
        InstabilityType::Type3
    };
    StabilityPoint {
        spectral_radius: rho,
        excess: rho - 1.0,
        kind,
    }
}

/// Eigenvalues of a real square matrix (real Schur form), or `None` when the matrix is not
/// finite or the iteration does not converge.
pub fn eigenvalues(matrix: &DMatrix<f64>) -> Option<Vec<Complex<f64>>> {
    if matrix.iter().any(|x| !x.is_finite()) {
        return None;
    }
    // Machine epsilon as the deflation threshold; 10⁴ sweeps is far beyond what a small
    // matrix needs (typically a handful per eigenvalue) but bounds a pathological case.
    let schur = nalgebra::linalg::Schur::try_new(matrix.clone(), f64::EPSILON, 10_000)?;
    Some(schur.complex_eigenvalues().iter().copied().collect())
}

/// Spectral radius and type of a propagation matrix (see [`classify_eigenvalues`]).
pub fn classify_matrix(matrix: &DMatrix<f64>, tolerance: f64) -> StabilityPoint {
    match eigenvalues(matrix) {
        Some(values) => classify_eigenvalues(&values, tolerance),
        None => StabilityPoint {
            spectral_radius: f64::INFINITY,
            excess: f64::INFINITY,
            kind: InstabilityType::Overflow,
        },
    }
}
