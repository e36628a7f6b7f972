//! The propagation matrix of one outer step of a real integrator, measured.
//!
//! The scene (by default the three-spring system of GSS98 section 3) is built with the
//! asked Ω1, Ω2 (`--set omega1=…, omega2=…`), its starting positions checked to be an
//! equilibrium, and the integrator from the registry ([`study_integrator`]) takes
//! one outer step from the equilibrium displaced by `±δ` along each horizontal coordinate
//! and momentum in turn. The central difference of the results divided by `2δ` is one
//! column of the propagation matrix of the horizontal motion, state
//! `(x_1, …, x_n, p_x1, …, p_xn)` — for the three-spring scene the 4×4 matrix of (27).
//!
//! Horizontal motion of the springs is exactly linear as long as no spring length changes
//! sign, so the difference quotient is the matrix up to round-off: the positions are
//! stored absolutely (≈ 1–2), so each column carries a relative error of about
//! `ε_mach · |x| / δ` times the operations of a step. δ starts at 2⁻⁷ (error ≈ 1e-13)
//! and is halved when a step is not linear in the perturbation (`out(+δ) + out(−δ)`
//! differs from twice the equilibrium), which happens only when the step itself grows
//! the perturbation enough to flip a spring — an inner step far beyond its own limit.
//! This works for any method in the registry: nothing here knows how it steps.

use std::path::{Path, PathBuf};

use nalgebra::DMatrix;

use super::{StabilityPoint, classify_matrix};
use crate::error::{Error, Result};
use crate::integrators::Integrator;
use crate::io::scene::{SceneFile, build_parsed_scene, parse_scene};
use crate::run::prepare::study_integrator;
use crate::settings::MethodSettings;
use crate::system::System;

/// The three-spring scene shipped in `systems/`, compiled in so the command works from
/// any directory.
pub const THREE_SPRING_SCENE: &str = include_str!("../../../systems/three-spring.toml");

/// How far above 1 a measured spectral radius may be and still count as stable.
///
/// The measured matrix carries a relative error η ≈ 1e-13 (see the module
/// documentation; the verlet test finds ≤ 1e-14 at K = 1). At a simple eigenvalue that
/// moves |λ| by about η‖A‖ ≤ 1e-11 for ‖A‖ ≤ 100; at a collision of two eigenvalues (the
/// edge of every instability region) by √(η‖A‖) ≈ 3e-6 at ‖A‖ = 100 and 1e-6 at ‖A‖ ≈ 10,
/// the size of A for Γ ≤ 4π. So 1e-6: instabilities weaker than that (growth by e in
/// more than 10⁶ steps) are reported as stable in integrator mode.
pub const INTEGRATOR_TOLERANCE: f64 = 1e-6;

/// First perturbation size (exact in binary, so `x + δ` is exact for x ∈ [1, 4)).
const FIRST_DELTA: f64 = 1.0 / 128.0;
/// Halvings of δ tried before the step is declared non-linear (δ down to 2⁻³⁷ ≈ 7e-12).
const MAX_HALVINGS: usize = 30;

/// The scene whose horizontal linearisation is probed, kept as text so each point builds a
/// fresh system with its own parameter values.
#[derive(Clone, Debug)]
pub struct ProbeScene {
    pub text: String,
    pub path: PathBuf,
}

impl ProbeScene {
    /// The built-in copy of `systems/three-spring.toml`.
    pub fn three_spring() -> Self {
        ProbeScene {
            text: THREE_SPRING_SCENE.to_string(),
            path: PathBuf::from("systems/three-spring.toml"),
        }
    }

    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Ok(ProbeScene {
            text,
            path: path.to_path_buf(),
        })
    }
}

/// Refuse a scene without the parameters `omega1` and `omega2` that integrator mode sets
/// for every (Γ1, Γ2) point, in the user's terms (the `--scene` they gave), before the
/// override machinery blames a `--set omega1` the user never typed.
fn check_frequency_parameters(parsed: &SceneFile, path: &Path) -> Result<()> {
    let missing: Vec<&str> = ["omega1", "omega2"]
        .into_iter()
        .filter(|name| !parsed.parameters.contains_key(*name))
        .collect();
    if missing.is_empty() {
        return Ok(());
    }
    let has = if parsed.parameters.is_empty() {
        "none".to_string()
    } else {
        parsed
            .parameters
            .keys()
            .cloned()
            .collect::<Vec<_>>()
            .join(", ")
    };
    Err(Error::flag(
        "--scene",
        format!(
            "--scene {}: stability-map --mode integrator sets Γ1 = h·omega1 and Γ2 = h·omega2 at \
         every point, so the scene needs [parameters] omega1 and omega2 (the two frequencies \
         the map varies); it lacks {} (its parameters: {has}). Leave out --scene for the \
         three-spring system of GSS98, or use `longstep scan steps` for a molecule",
            path.display(),
            missing.join(" and ")
        ),
    )
    .expected("a scene with [parameters] omega1 and omega2")
    .got_named(path.display().to_string()))
}

/// One method with its settings on one scene: measures propagation matrices.
pub struct IntegratorProbe {
    scene: ProbeScene,
    /// The scene's TOML parsed once: each point only rebuilds the system with its own
    /// parameter values (parsing cost about a tenth of a LongAverage K = 20 point).
    parsed: SceneFile,
    settings: MethodSettings,
    notices: Vec<String>,
}

impl IntegratorProbe {
    /// Check that the method builds (collecting its notices) and that the scene builds
    /// with the scene's own parameters.
    pub fn new(scene: ProbeScene, settings: MethodSettings) -> Result<Self> {
        let mut notices = Vec::new();
        study_integrator(&settings, &mut notices)?;
        let parsed = parse_scene(&scene.text, &scene.path)?;
        check_frequency_parameters(&parsed, &scene.path)?;
        build_parsed_scene(&parsed, &scene.text, &scene.path, &[])?;
        Ok(IntegratorProbe {
            scene,
            parsed,
            settings,
            notices,
        })
    }

    /// What the user should know about the settings (from [`study_integrator`]).
    pub fn notices(&self) -> &[String] {
        &self.notices
    }

    pub fn settings(&self) -> &MethodSettings {
        &self.settings
    }

    /// The scene's overrides for Γ1 = hΩ1, Γ2 = hΩ2.
    pub fn gamma_overrides(&self, gamma1: f64, gamma2: f64) -> Vec<String> {
        let h = self.settings.h;
        vec![
            format!("omega1={:e}", gamma1 / h),
            format!("omega2={:e}", gamma2 / h),
        ]
    }

    /// The propagation matrix at (Γ1, Γ2) on the scene's `omega1`, `omega2`.
    pub fn matrix_at(&self, gamma1: f64, gamma2: f64) -> Result<DMatrix<f64>> {
        if !(gamma1.is_finite() && gamma2.is_finite() && gamma1 >= 0.0 && gamma2 >= 0.0) {
            return Err(Error::input("Γ1 and Γ2 must be finite and non-negative")
                .expected("finite non-negative numbers")
                .got(format!("({gamma1}, {gamma2})")));
        }
        self.propagation_matrix(&self.gamma_overrides(gamma1, gamma2))
    }

    /// Spectral radius and type at (Γ1, Γ2), with [`INTEGRATOR_TOLERANCE`].
    pub fn point(&self, gamma1: f64, gamma2: f64) -> Result<StabilityPoint> {
        Ok(classify_matrix(
            &self.matrix_at(gamma1, gamma2)?,
            INTEGRATOR_TOLERANCE,
        ))
    }

    /// The matrix of one outer step of the horizontal motion, state
    /// `(x_1, …, x_n, p_x1, …, p_xn)`, with the scene parameters overridden by `overrides`
    /// (`name=value`).
    pub fn propagation_matrix(&self, overrides: &[String]) -> Result<DMatrix<f64>> {
        let scene =
            build_parsed_scene(&self.parsed, &self.scene.text, &self.scene.path, overrides)?;
        let mut system = scene.system;
        let q0 = system.state.q.clone();
        let scale = q0.iter().fold(1.0_f64, |acc, x| acc.max(x.abs()));

        // One integrator for the point's nine steps: `setup` sizes its buffers and
        // evaluates the forces at each new starting state, so nothing carries over.
        let mut integrator: Box<dyn Integrator> =
            study_integrator(&self.settings, &mut Vec::new())?;
        let integrator = integrator.as_mut();
        self.check_equilibrium(&mut system, integrator, &q0, scale)?;

        let size = 2 * system.n_particles();
        let mut matrix = DMatrix::zeros(size, size);
        for column in 0..size {
            self.matrix_column(&mut system, integrator, &q0, scale, column, &mut matrix)?;
        }
        Ok(matrix)
    }

    /// One outer step from `(q, p)` at t = 0: the positions and momenta after it.
    fn step_from(
        &self,
        system: &mut System,
        integrator: &mut dyn Integrator,
        q: &[f64],
        p: &[f64],
    ) -> Result<(Vec<f64>, Vec<f64>)> {
        system.state.q.copy_from_slice(q);
        system.state.p.copy_from_slice(p);
        system.state.t = 0.0;
        integrator.setup(system)?;
        integrator.step(system).map_err(|failure| {
            Error::input(format!(
                "{} failed on its first step: {}",
                self.settings.method, failure.0
            ))
        })?;
        Ok((system.state.q.clone(), system.state.p.clone()))
    }

    /// The starting positions must be an equilibrium at rest: one step leaves them.
    fn check_equilibrium(
        &self,
        system: &mut System,
        integrator: &mut dyn Integrator,
        q0: &[f64],
        scale: f64,
    ) -> Result<()> {
        let zero_p = vec![0.0; q0.len()];
        let (q_rest, p_rest) = self.step_from(system, integrator, q0, &zero_p)?;
        let drift = q_rest
            .iter()
            .zip(q0)
            .map(|(a, b)| (a - b).abs())
            .chain(p_rest.iter().map(|x| x.abs()))
            .fold(0.0_f64, f64::max);
        // Round-off of one step from rest at exact rest lengths is zero; allow 1e3 ε of
        // the coordinates' size for scenes whose anchors are not exact binary numbers.
        if drift > 1e3 * f64::EPSILON * scale {
            return Err(Error::input(format!(
                "{}: the starting positions are not an equilibrium at rest (one outer step \
                 moves them by {drift:e}); the integrator mode linearises about them",
                self.scene.path.display()
            )));
        }
        Ok(())
    }

    /// Column `column` of the matrix: the central difference at ±δ, δ halved from
    /// [`FIRST_DELTA`] until the step is linear in the perturbation.
    fn matrix_column(
        &self,
        system: &mut System,
        integrator: &mut dyn Integrator,
        q0: &[f64],
        scale: f64,
        column: usize,
        matrix: &mut DMatrix<f64>,
    ) -> Result<()> {
        let mut delta = FIRST_DELTA;
        for _ in 0..=MAX_HALVINGS {
            let (defect, response) =
                self.difference_column(system, integrator, q0, column, delta, matrix)?;
            // Linear up to round-off: the even part (a nonlinear effect, O(δ²) or
            // O(1) at a flipped spring) below 1e-6 of the response, beyond the
            // round-off of absolute positions (1e3 ε · scale as above).
            if response.is_finite() && defect <= 1e-6 * response + 1e3 * f64::EPSILON * scale {
                return Ok(());
            }
            delta *= 0.5;
        }
        Err(Error::input(format!(
            "{} (h = {}): one outer step is not linear in a perturbation of the \
             equilibrium even at δ = {delta:e}; the step amplifies it beyond the \
             linear range of the springs",
            self.settings.method, self.settings.h
        )))
    }

    /// Fills `column` of `matrix` with `(out(+δ) − out(−δ)) / 2δ` for a perturbation of
    /// that coordinate (positions first, then momenta). Returns the largest even part
    /// `|out(+δ) + out(−δ) − 2 rest|` and the largest response `|out(+δ) − out(−δ)|`.
    fn difference_column(
        &self,
        system: &mut System,
        integrator: &mut dyn Integrator,
        q0: &[f64],
        column: usize,
        delta: f64,
        matrix: &mut DMatrix<f64>,
    ) -> Result<(f64, f64)> {
        let (n, dim) = (system.n_particles(), system.dim);
        let coordinate = |j: usize| (j % n) * dim; // axis 0 of particle j mod n
        let zero_p = vec![0.0; q0.len()];
        let mut responses = Vec::with_capacity(2);
        for sign in [1.0, -1.0] {
            let (mut q, mut p) = (q0.to_vec(), zero_p.clone());
            if column < n {
                q[coordinate(column)] += sign * delta;
            } else {
                p[coordinate(column)] += sign * delta;
            }
            responses.push(self.step_from(system, integrator, &q, &p)?);
        }
        let (plus, minus) = (&responses[0], &responses[1]);
        let mut defect = 0.0_f64;
        let mut response = 0.0_f64;
        for row in 0..2 * n {
            let k = coordinate(row);
            let (a, b, rest) = if row < n {
                (plus.0[k], minus.0[k], q0[k])
            } else {
                (plus.1[k], minus.1[k], 0.0)
            };
            defect = defect.max((a + b - 2.0 * rest).abs());
            response = response.max((a - b).abs());
            matrix[(row, column)] = (a - b) / (2.0 * delta);
        }
        Ok((defect, response))
    }
}

/// The 4×4 propagation matrix of velocity Verlet with step `h` on the horizontal
/// three-spring system, state `(x1, x2, p1, p2)`: with the stiffness matrix
/// `K = [[Ω1² + ½, −½], [−½, Ω2² + ½]]`,
/// `[[I − h²K/2, h I], [−hK + h³K²/4, I − h²K/2]]`. The reference for the integrator mode.
pub fn verlet_three_spring_matrix(h: f64, omega1: f64, omega2: f64) -> DMatrix<f64> {
    let k = nalgebra::Matrix2::new(omega1 * omega1 + 0.5, -0.5, -0.5, omega2 * omega2 + 0.5);
    let identity = nalgebra::Matrix2::identity();
    let diagonal = identity - k * (0.5 * h * h);
    let lower = -k * h + k * k * (0.25 * h * h * h);
    let mut matrix = DMatrix::zeros(4, 4);
    for i in 0..2 {
        for j in 0..2 {
            matrix[(i, j)] = diagonal[(i, j)];
            matrix[(i, j + 2)] = h * identity[(i, j)];
            matrix[(i + 2, j)] = lower[(i, j)];
            matrix[(i + 2, j + 2)] = diagonal[(i, j)];
        }
    }
    matrix
}
