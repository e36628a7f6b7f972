//! Where the asynchronous pseudo-energy scheme fails: the spectral radius of its one-step
//! amplification matrix on a linear scene, over the coarse step and the ratio `K`.
//!
//! Pseudo-energy conservation does not give stability: `H̃` is indefinite (MEMM18 Remark 8).
//! For a linear scene (quadratic potential) one coarse step of the asynchronous scheme
//! (20)–(24), or one step of the synchronous one (3), is a linear map `Z ↦ A Z` of the state
//! `Z = (q, p^{n−1/2}, p^{n+1/2})` (the vector of the proof of MEMM18 Prop. 6). Its columns
//! are the images of unit perturbations of the zero state, `A e_j = Φ(e_j) − Φ(0)` — exact
//! for a linear scene (a rest-length-0 spring network about `q = 0`); a random state checks
//! that `Φ` is indeed affine before anything is reported. The scheme is unstable when the
//! spectral radius `ρ(A)` exceeds 1; the perturbation then grows like `ρ^{t/h_S}`.
//!
//! Two ways to get `ρ`:
//! * dense: build `A` (`3 n_dofs` coarse steps) and take its eigenvalues (real Schur form,
//!   nalgebra) — exact up to round-off, for state sizes up to a few thousand;
//! * power: iterate `Φ` on a pseudo-random state and compare the largest `‖Z_k‖` of the
//!   second half of the iterations with that of the first half — for large scenes. The
//!   norm of a neutral superposition of modes beats (positions and momenta differ in
//!   scale by the largest frequency), so comparing maxima over long windows, not two
//!   single values, is what keeps a neutral scheme at `ρ ≈ 1`. It resolves `ρ − 1` down to
//!   about `ln(G)/(iterations/2)`, `G` the beat of the maxima; see
//!   [`RadiusOptions::power_growth`].
//!
//! Cost: dense `3 n_dofs` coarse steps plus `O((3 n_dofs)³)` for the eigenvalues; power
//! `iterations` coarse steps.

use std::path::Path;

use nalgebra::DMatrix;
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::integrators::quadrature::Quadrature;
use crate::integrators::{AsyncPseudoEnergy, Integrator, PseudoEnergy};
use crate::io::csv::write_table;
use crate::system::System;

/// A pseudo-energy scheme seen as a map of its state vector.
pub enum Scheme {
    Synchronous(Box<PseudoEnergy>),
    Asynchronous(Box<AsyncPseudoEnergy>),
}

impl Scheme {
    pub fn synchronous(h: f64, quadrature: Quadrature) -> Result<Self> {
        Ok(Scheme::Synchronous(Box::new(
            PseudoEnergy::new(h, quadrature)?.with_monitor(false),
        )))
    }

    pub fn asynchronous(h_slow: f64, ratio: usize, quadrature: Quadrature) -> Result<Self> {
        Ok(Scheme::Asynchronous(Box::new(
            AsyncPseudoEnergy::new(h_slow, ratio, quadrature)?.with_monitor(false),
        )))
    }

    fn integrator(&mut self) -> &mut dyn Integrator {
        match self {
            Scheme::Synchronous(s) => s.as_mut(),
            Scheme::Asynchronous(s) => s.as_mut(),
        }
    }

    /// `out = Φ(z)`: one (coarse) step from the state `z`.
    fn apply(&mut self, system: &mut System, z: &[f64], out: &mut [f64]) -> Result<()> {
        match self {
            Scheme::Synchronous(s) => s.set_state_vector(system, z),
            Scheme::Asynchronous(s) => s.set_state_vector(system, z),
        }
        self.integrator()
            .step(system)
            .map_err(|failure| Error::input(failure.0))?;
        match self {
            Scheme::Synchronous(s) => s.state_vector(system, out),
            Scheme::Asynchronous(s) => s.state_vector(system, out),
        }
        Ok(())
    }
}

/// How a spectral radius was obtained.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RadiusMethod {
    Dense,
    Power,
}

impl RadiusMethod {
    pub fn name(&self) -> &'static str {
        match self {
            RadiusMethod::Dense => "dense",
            RadiusMethod::Power => "power",
        }
    }
}

/// Options of [`spectral_radius`].
#[derive(Clone, Debug)]
pub struct RadiusOptions {
    /// Largest state size `3 n_dofs` for the dense method; the power method beyond.
    pub max_dense: usize,
    /// Coarse steps of the power method.
    pub power_iterations: usize,
    /// The power method calls a point unstable when the largest state norm grows by more
    /// than this factor from the first half of the iterations to the second.
    pub power_growth: f64,
}

impl RadiusOptions {
    /// `ρ` above which a power-method estimate counts as unstable.
    pub fn power_threshold(&self) -> f64 {
        let iterations = self.power_iterations.max(2);
        let window = (iterations - iterations / 2) as f64;
        (self.power_growth.ln() / window).exp()
    }
}

impl Default for RadiusOptions {
    fn default() -> Self {
        RadiusOptions {
            max_dense: 1500,
            power_iterations: 20_000,
            power_growth: 4.0,
        }
    }
}

/// The one-step amplification matrix of `scheme` on the linear `system` (see the module
/// documentation); fails when the step map is not affine.
pub fn amplification_matrix(system: &mut System, scheme: &mut Scheme) -> Result<DMatrix<f64>> {
    let size = 3 * system.n_dofs();
    scheme.integrator().setup(system)?;
    let zero = vec![0.0; size];
    let mut offset = vec![0.0; size];
    scheme.apply(system, &zero, &mut offset)?;
    let mut matrix = DMatrix::zeros(size, size);
    let mut unit = vec![0.0; size];
    let mut image = vec![0.0; size];
    for j in 0..size {
        unit[j] = 1.0;
        scheme.apply(system, &unit, &mut image)?;
        unit[j] = 0.0;
        for i in 0..size {
            matrix[(i, j)] = image[i] - offset[i];
        }
    }
    check_affine(system, scheme, &matrix, &offset)?;
    Ok(matrix)
}

/// `Φ(z) = A z + Φ(0)` for a pseudo-random `z`, to round-off (relative 1e-9: the columns
/// are exact to a few ulps of `‖A‖`, summed over `3 n_dofs` entries).
fn check_affine(
    system: &mut System,
    scheme: &mut Scheme,
    matrix: &DMatrix<f64>,
    offset: &[f64],
) -> Result<()> {
    let size = offset.len();
    let z = pseudo_random(size, 7);
    let mut image = vec![0.0; size];
    scheme.apply(system, &z, &mut image)?;
    let predicted = matrix * nalgebra::DVector::from_column_slice(&z);
    let scale = image.iter().map(|x| x.abs()).fold(1.0, f64::max);
    let mismatch = (0..size)
        .map(|i| (predicted[i] + offset[i] - image[i]).abs())
        .fold(0.0, f64::max);
    if mismatch > 1e-9 * scale * size as f64 {
        return Err(Error::input(format!(
            "the step map is not linear on this scene (mismatch {mismatch:.3e} of {scale:.3e}): \
             the stability map needs a quadratic potential about q = 0 (springs of rest length 0)"
        )));
    }
    Ok(())
}

/// Deterministic values in `[−1, 1]` (a linear congruential generator: the map must not
/// depend on a random seed).
fn pseudo_random(size: usize, seed: u64) -> Vec<f64> {
    let mut state = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (0..size)
        .map(|_| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        })
        .collect()
}

/// Largest eigenvalue modulus of a square matrix: balanced (Parlett–Reinsch, the
/// state mixes positions and momenta of very different sizes), then the real Schur form.
/// If the QR iteration does not converge in `100 n` sweeps, Gelfand's formula
/// `ρ = lim ‖A^k‖^{1/k}` by repeated squaring (`k = 2⁴⁰`) estimates it instead.
pub fn dense_spectral_radius(matrix: &DMatrix<f64>) -> f64 {
    let n = matrix.nrows();
    let mut balanced = matrix.clone();
    nalgebra::linalg::balancing::balance_parlett_reinsch(&mut balanced);
    match nalgebra::linalg::Schur::try_new(balanced.clone(), f64::EPSILON, 100 * n.max(1)) {
        Some(schur) => schur
            .complex_eigenvalues()
            .iter()
            .map(|z| z.norm())
            .fold(0.0, f64::max),
        None => gelfand_radius(&balanced, 40),
    }
}

/// `‖A^{2^s}‖^{2^{−s}}`, renormalising at each squaring.
pub fn gelfand_radius(matrix: &DMatrix<f64>, squarings: u32) -> f64 {
    let mut power = matrix.clone();
    let mut log_norm = 0.0;
    let mut exponent = 1.0;
    for _ in 0..squarings {
        let norm = power.norm();
        if norm == 0.0 || !norm.is_finite() {
            return if norm == 0.0 { 0.0 } else { f64::INFINITY };
        }
        log_norm += norm.ln() / exponent;
        power /= norm;
        power = &power * &power;
        exponent *= 2.0;
    }
    (log_norm + power.norm().ln() / exponent).exp()
}

/// `ρ(A)` of `scheme` on the linear `system`, dense or by power iteration.
pub fn spectral_radius(
    system: &mut System,
    scheme: &mut Scheme,
    options: &RadiusOptions,
) -> Result<(f64, RadiusMethod)> {
    let size = 3 * system.n_dofs();
    if size <= options.max_dense {
        let matrix = amplification_matrix(system, scheme)?;
        return Ok((dense_spectral_radius(&matrix), RadiusMethod::Dense));
    }
    scheme.integrator().setup(system)?;
    let mut z = pseudo_random(size, 11);
    let mut next = vec![0.0; size];
    let zero = vec![0.0; size];
    let mut offset = vec![0.0; size];
    scheme.apply(system, &zero, &mut offset)?;
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let iterations = options.power_iterations.max(2);
    let half = iterations / 2;
    // log ‖Z_k‖ accumulated over renormalised iterates; the largest value in each half.
    let mut log_norm = 0.0;
    let (mut first_max, mut second_max) = (f64::NEG_INFINITY, f64::NEG_INFINITY);
    for k in 0..iterations {
        scheme.apply(system, &z, &mut next)?;
        for (n, o) in next.iter_mut().zip(&offset) {
            *n -= o;
        }
        let size_next = norm(&next);
        if !size_next.is_finite() || size_next == 0.0 {
            return Err(Error::input("power iteration lost the state (not finite)"));
        }
        log_norm += (size_next / norm(&z)).ln();
        if k < half {
            first_max = first_max.max(log_norm);
        } else {
            second_max = second_max.max(log_norm);
        }
        for (a, b) in z.iter_mut().zip(&next) {
            *a = b / size_next;
        }
    }
    Ok((
        ((second_max - first_max) / (iterations - half) as f64).exp(),
        RadiusMethod::Power,
    ))
}

/// The parameter a map varies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MapParameter {
    /// The coarse step `h_S`; `h_F = h_S / K`.
    HSlow,
    /// The fine step `h_F`; `h_S = K h_F`.
    HFast,
}

impl MapParameter {
    pub fn parse(text: &str) -> Result<Self> {
        match text {
            "h-slow" | "h_slow" => Ok(MapParameter::HSlow),
            "h-fast" | "h_fast" => Ok(MapParameter::HFast),
            other => Err(Error::flag(
                "--param",
                format!("unknown map parameter \"{other}\"; use h-slow or h-fast"),
            )
            .expected("h-slow or h-fast")
            .got_named(other)),
        }
    }
}

#[derive(Clone, Debug)]
pub struct MapSpec {
    pub parameter: MapParameter,
    pub values: Vec<f64>,
    pub ratios: Vec<usize>,
    pub quadrature: Quadrature,
    /// The scene's cell size, for the `h_slow_over_dx` column (when it has a `dx`).
    pub dx: Option<f64>,
    /// `ρ > 1 + tolerance` counts as unstable (dense method; the power method uses
    /// [`RadiusOptions::power_threshold`]).
    pub tolerance: f64,
    pub options: RadiusOptions,
}

#[derive(Clone, Debug)]
pub struct MapPoint {
    pub h_slow: f64,
    pub h_fast: f64,
    pub ratio: usize,
    pub spectral_radius: f64,
    pub method: RadiusMethod,
    pub unstable: bool,
}

/// `ρ` over every (value, ratio) pair, in parallel; `make_system` builds a fresh system
/// (the scene) for each point.
pub fn async_stability_map(
    make_system: &(dyn Fn() -> Result<System> + Sync),
    spec: &MapSpec,
) -> Result<Vec<MapPoint>> {
    let points: Vec<(f64, usize)> = spec
        .ratios
        .iter()
        .flat_map(|&k| spec.values.iter().map(move |&v| (v, k)))
        .collect();
    points
        .par_iter()
        .map(|&(value, ratio)| {
            let (h_slow, h_fast) = match spec.parameter {
                MapParameter::HSlow => (value, value / ratio as f64),
                MapParameter::HFast => (value * ratio as f64, value),
            };
            let mut system = make_system()?;
            let mut scheme = Scheme::asynchronous(h_slow, ratio, spec.quadrature.clone())?;
            let (radius, method) = spectral_radius(&mut system, &mut scheme, &spec.options)?;
            Ok(MapPoint {
                h_slow,
                h_fast,
                ratio,
                spectral_radius: radius,
                method,
                unstable: match method {
                    RadiusMethod::Dense => radius > 1.0 + spec.tolerance,
                    RadiusMethod::Power => radius > spec.options.power_threshold(),
                },
            })
        })
        .collect()
}

/// Write a map as CSV: `h_slow,h_fast,ratio,h_slow_over_dx,spectral_radius,
/// growth_per_time,unstable,method` (`growth_per_time = ln ρ / h_S`, the exponential rate
/// of the unstable mode; `h_slow_over_dx` empty without a `dx`).
pub fn write_map_csv(path: &Path, points: &[MapPoint], dx: Option<f64>) -> Result<()> {
    let header = [
        "h_slow",
        "h_fast",
        "ratio",
        "h_slow_over_dx",
        "spectral_radius",
        "growth_per_time",
        "unstable",
        "method",
    ];
    let rows = points.iter().map(|p| {
        [
            p.h_slow.to_string(),
            p.h_fast.to_string(),
            p.ratio.to_string(),
            dx.map(|dx| (p.h_slow / dx).to_string()).unwrap_or_default(),
            p.spectral_radius.to_string(),
            (p.spectral_radius.ln() / p.h_slow).to_string(),
            u8::from(p.unstable).to_string(),
            p.method.name().to_string(),
        ]
    });
    write_table(path, None, header, rows)
}

/// Contiguous runs of unstable points along the parameter, per ratio:
/// `(ratio, first value, last value, largest ρ)`.
pub fn unstable_bands(points: &[MapPoint], parameter: MapParameter) -> Vec<(usize, f64, f64, f64)> {
    let mut bands = Vec::new();
    let mut ratios: Vec<usize> = points.iter().map(|p| p.ratio).collect();
    ratios.sort_unstable();
    ratios.dedup();
    for k in ratios {
        let mut row: Vec<&MapPoint> = points.iter().filter(|p| p.ratio == k).collect();
        let value = |p: &MapPoint| match parameter {
            MapParameter::HSlow => p.h_slow,
            MapParameter::HFast => p.h_fast,
        };
        row.sort_by(|a, b| value(a).total_cmp(&value(b)));
        let mut current: Option<(f64, f64, f64)> = None;
        for p in row {
            match (&mut current, p.unstable) {
                (Some((_, last, worst)), true) => {
                    *last = value(p);
                    *worst = worst.max(p.spectral_radius);
                }
                (None, true) => current = Some((value(p), value(p), p.spectral_radius)),
                (Some(band), false) => {
                    bands.push((k, band.0, band.1, band.2));
                    current = None;
                }
                (None, false) => {}
            }
        }
        if let Some(band) = current {
            bands.push((k, band.0, band.1, band.2));
        }
    }
    bands
}

/// The warning a run or a safety scan gives before the asynchronous scheme enters an
/// instability band: the spectral radius of one coarse step of the scheme `settings` asks
/// for on `system`, when it exceeds 1 + 1e-8. `None` when the step is stable, when the scene
/// is not linear (the amplification matrix does not exist), or when the state is too large
/// for the dense check. `system` is used as scratch: pass a copy you will not run.
pub fn band_warning(
    system: &mut System,
    settings: &crate::settings::MethodSettings,
) -> Option<String> {
    if 3 * system.n_dofs() > RadiusOptions::default().max_dense {
        return None;
    }
    let scheme = AsyncPseudoEnergy::from_settings(settings, &mut Vec::new()).ok()?;
    let (h_slow, h_fast) = (scheme.h_slow(), scheme.h_fast());
    let mut scheme = Scheme::Asynchronous(Box::new(scheme.with_monitor(false)));
    let matrix = amplification_matrix(system, &mut scheme).ok()?;
    let rho = dense_spectral_radius(&matrix);
    (rho > 1.0 + 1e-8).then(|| {
        format!(
            "async-pseudo-energy at h_slow = {h_slow}, h_fast = {h_fast}: the coarse step's \
             amplification matrix has spectral radius {rho:.8} > 1 — this step lies in an \
             instability band of the asynchronous scheme (MEMM18 (20)–(24); docs/pseudo-energy.md), \
             and perturbations grow like {rho:.6}^n"
        )
    })
}
