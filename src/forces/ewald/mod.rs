//! Ewald electrostatics of a periodic box: the parameters (splitting coefficient α, grid,
//! spline order) as users know them from GROMACS and OpenMM, a plain Ewald sum as the
//! reference ([`direct`]), and the smooth particle-mesh Ewald reciprocal term
//! ([`reciprocal::PmeReciprocal`], Essmann et al., J. Chem. Phys. 103, 8577 (1995):
//! "EPBDLP95").
//!
//! With `k_e q_i q_j = Q_ij`, box volume `V` and net charge `Q = Σ q_i`:
//!
//! * real space `E_real = Σ_{i<j, r<r_c, not excluded} Q_ij erfc(αr)/r` — in the
//!   cluster-pair engine ([`crate::forces::nonbonded::Electrostatics::Ewald`]);
//! * reciprocal space `E_rec = (k_e/2πV) Σ_{m≠0} exp(−π²m²/α²)/m² |S(m)|²`,
//!   `S(m) = Σ q_j exp(2πi m·r_j)` (EPBDLP95 eq. (2.49) with B-spline interpolation);
//! * self `E_self = −k_e α/√π Σ q_i²`;
//! * excluded pairs `E_excl = −Σ_{excluded} Q_ij erf(αr)/r` (the reciprocal sum holds
//!   every pair, excluded ones too);
//! * neutralising background for a charged box `E_bg = −k_e π Q²/(2Vα²)`.
//!
//! **Parameters.** `ewald_tolerance` has GROMACS's `ewald-rtol` meaning: α solves
//! `erfc(α r_c) = tolerance` (default 1e-5; OpenMM's `ewaldErrorTolerance` is another
//! quantity). `fourier_spacing` (default 1.2 in the scene's length unit, GROMACS's 0.12 nm)
//! gives each grid dimension from GROMACS's `calcFftGrid` sizes less 44 and 52: the
//! smallest (factors 2, 3, 5 and 7, even but 25) ≥ `L/spacing` and ≥ `2 × order`
//! ([`grid_size`]). The order is 4 to 6 (default 5, as OpenMM; GROMACS uses 4). An
//! explicit `ewald_alpha` or `pme_grid` overrides the derived value.

pub mod direct;
mod exclusions;
mod fft;
mod float;
pub mod reciprocal;
mod spline;

use crate::units::Units;
pub use reciprocal::PmeReciprocal;

/// GROMACS's `ewald-rtol` default.
pub const DEFAULT_TOLERANCE: f64 = 1e-5;
/// GROMACS's `fourier-spacing` default, 0.12 nm, in Å.
pub const DEFAULT_SPACING: f64 = 1.2;
/// OpenMM's (fixed) PME order.
pub const DEFAULT_ORDER: usize = 5;
/// The B-spline orders accepted.
pub const ORDERS: std::ops::RangeInclusive<usize> = 4..=6;

/// What a scene or the command line asks for; unset values take the defaults.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EwaldRequest {
    pub tolerance: Option<f64>,
    pub spacing: Option<f64>,
    pub alpha: Option<f64>,
    pub grid: Option<[usize; 3]>,
    pub order: Option<usize>,
}

/// The resolved parameters of an Ewald sum.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EwaldParameters {
    /// Splitting coefficient α (inverse length).
    pub alpha: f64,
    /// PME grid points per box axis.
    pub grid: [usize; 3],
    /// B-spline order.
    pub order: usize,
}

impl EwaldParameters {
    /// One line for reports, α in the scene's `units` (1/Å in a real scene).
    pub fn describe(&self, units: Units) -> String {
        let [nx, ny, nz] = self.grid;
        format!(
            "PME, alpha = {}, grid {nx}x{ny}x{nz}, order {}",
            units.inverse_length(self.alpha),
            self.order
        )
    }
}

/// Resolve `request` for a real-space `cutoff` in a periodic box of `lengths` (`None`:
/// no box). Errors name the scene key at fault.
pub fn resolve(
    request: &EwaldRequest,
    cutoff: f64,
    lengths: Option<[f64; 3]>,
) -> Result<EwaldParameters, String> {
    let Some(lengths) = lengths else {
        return Err("coulomb = \"pme\" needs a periodic box (give box = [lx, ly, lz])".into());
    };
    let shortest = lengths.iter().cloned().fold(f64::INFINITY, f64::min);
    if !(cutoff.is_finite() && cutoff > 0.0 && 2.0 * cutoff < shortest) {
        return Err(format!(
            "cutoff {cutoff} must be positive and shorter than half the shortest box length \
             ({shortest}) for PME's real-space sum"
        ));
    }
    let order = request.order.unwrap_or(DEFAULT_ORDER);
    if !ORDERS.contains(&order) {
        return Err(format!("pme_order must be 4, 5 or 6, got {order}"));
    }
    let alpha = match request.alpha {
        Some(a) if a > 0.0 && a.is_finite() => a,
        Some(a) => return Err(format!("ewald_alpha must be positive, got {a}")),
        None => {
            let tolerance = request.tolerance.unwrap_or(DEFAULT_TOLERANCE);
            if !(tolerance > 0.0 && tolerance < 1.0) {
                return Err(format!(
                    "ewald_tolerance must be between 0 and 1 (exclusive), got {tolerance}"
                ));
            }
            alpha_for_tolerance(tolerance, cutoff)
        }
    };
    let grid = match request.grid {
        Some(grid) => {
            if let Some(&n) = grid.iter().find(|&&n| n < 2 * order) {
                return Err(format!(
                    "pme_grid {grid:?}: a dimension of {n} is coarser than order {order} \
                     allows (at least 2 × pme_order = {})",
                    2 * order
                ));
            }
            grid
        }
        None => {
            let spacing = request.spacing.unwrap_or(DEFAULT_SPACING);
            if !(spacing > 0.0 && spacing.is_finite()) {
                return Err(format!("fourier_spacing must be positive, got {spacing}"));
            }
            lengths.map(|l| grid_size(l, spacing, order))
        }
    };
    Ok(EwaldParameters { alpha, grid, order })
}

/// α with `erfc(α r_c) = tolerance` (GROMACS `ewald-rtol`), by bisection to the last bit:
/// erfc decreases strictly, so the bracket `[0, x_hi]` with `erfc(x_hi) < tolerance` holds
/// one root.
pub fn alpha_for_tolerance(tolerance: f64, cutoff: f64) -> f64 {
    let mut high = 1.0;
    while libm::erfc(high) > tolerance {
        high *= 2.0;
    }
    let mut low = 0.0;
    for _ in 0..200 {
        let mid = 0.5 * (low + high);
        if mid <= low || mid >= high {
            break;
        }
        if libm::erfc(mid) > tolerance {
            low = mid;
        } else {
            high = mid;
        }
    }
    0.5 * (low + high) / cutoff
}

/// GROMACS's grid sizes up to 42 (`grid_init` of its `calcgrid.cpp`): where a larger size
/// transformed faster than a smaller one, the smaller one is left out (no 18, 30, 35).
/// GROMACS's 44 (4 × 11) is left out too: rustfft transforms 48³ in fewer instructions.
const SMALL_SIZES: [usize; 14] = [6, 8, 10, 12, 14, 16, 20, 24, 25, 28, 32, 36, 40, 42];
/// Beyond: a power of two times one of these (GROMACS's `grid_base` without its 45, which
/// its search never reaches, and without 52 = 4 × 13, as 44), a multiple of 4 and not 140.
const BASE_SIZES: [usize; 12] = [48, 50, 54, 56, 60, 64, 70, 72, 75, 80, 81, 84];

/// The grid size GROMACS's `calcFftGrid` picks for at least `length/spacing` points and at
/// least `2 × order`, but from its sizes with the factors 2, 3, 5 and 7 only (those with 11
/// or 13 cost rustfft more than the next size up): all even but 25. An even size halves the
/// real-to-complex row transforms (`fft.rs`): on Trp-cage's 42 Å box, 36³ costs 26 % fewer
/// FFT instructions than 35³ (the smallest size with those factors, taken before), 32³ 37 %
/// fewer than 30³, and 48³ 15 % fewer than 44³ (docs/data/sittings/pme-2026-11-29-f.txt).
/// Unlike GROMACS, `length/spacing` is rounded up exactly (GROMACS adds 0.999), so the
/// spacing never exceeds the one asked for.
pub fn grid_size(length: f64, spacing: f64, order: usize) -> usize {
    let least = ((length / spacing).ceil() as usize).max(2 * order);
    if let Some(&n) = SMALL_SIZES.iter().find(|&&n| n >= least) {
        return n;
    }
    let mut power = 1;
    while power * BASE_SIZES[BASE_SIZES.len() - 1] < least {
        power *= 2;
    }
    BASE_SIZES
        .iter()
        .map(|b| power * b)
        .filter(|&n| n.is_multiple_of(4) && n != 140 && n >= least)
        .min()
        .unwrap_or(power * BASE_SIZES[BASE_SIZES.len() - 1])
}

/// `E_self = −k_e α/√π Σ q_i²`.
pub fn self_energy(alpha: f64, coulomb_constant: f64, charges: &[f64]) -> f64 {
    let sum: f64 = charges.iter().map(|q| q * q).sum();
    -coulomb_constant * alpha / std::f64::consts::PI.sqrt() * sum
}

/// `E_bg = −k_e π Q²/(2Vα²)` for a net charge `Q` (zero for a neutral box).
pub fn background_energy(alpha: f64, coulomb_constant: f64, charges: &[f64], volume: f64) -> f64 {
    let net: f64 = charges.iter().sum();
    -coulomb_constant * std::f64::consts::PI * net * net / (2.0 * volume * alpha * alpha)
}

/// `(f, f′, f″)` of `f(r) = erf(αr)/r`, the excluded-pair correction's radial function.
pub fn erf_over_r(alpha: f64, r: f64) -> (f64, f64, f64) {
    let erf = libm::erf(alpha * r);
    let gauss = std::f64::consts::FRAC_2_SQRT_PI * alpha * (-alpha * alpha * r * r).exp();
    let f = erf / r;
    let d1 = gauss / r - erf / (r * r);
    let d2 = -2.0 * alpha * alpha * gauss - 2.0 * gauss / (r * r) + 2.0 * erf / (r * r * r);
    (f, d1, d2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alpha_solves_the_tolerance_and_grids_are_smooth() {
        let alpha = alpha_for_tolerance(1e-5, 9.0);
        // The root to the last bits: erfc′ = −(2/√π) e^{−x²} ≈ −6.5e-5 there, so an α off
        // by one ulp moves erfc by ~1e-20; 1e-15 absolute is 1e-10 relative.
        assert!((libm::erfc(alpha * 9.0) - 1e-5).abs() < 1e-15, "{alpha}");
        // GROMACS's 3.47 /nm for r_c = 0.9 nm at its default rtol.
        assert!((alpha - 0.347).abs() < 5e-4, "{alpha}");
        assert_eq!(grid_size(18.64, 1.2, 4), 16);
        assert_eq!(grid_size(37.3, 1.2, 4), 32);
        assert_eq!(grid_size(3.0, 1.2, 5), 10);
        assert_eq!(grid_size(13.0, 1.0, 4), 14);
        assert_eq!(grid_size(12.5, 1.0, 4), 14);
        // GROMACS's picks (calcgrid.cpp) where they have no factor 11 or 13: Trp-cage's
        // 42 Å box at 1.2 Å, the 41 472-atom water box's 74.58 Å, and the steps of its
        // table (30 → 32, 45 → 48, 85 → 96 with one power of two, 130 → 144 past the 140
        // it leaves out).
        assert_eq!(grid_size(42.0, 1.2, 4), 36);
        assert_eq!(grid_size(74.58, 1.2, 4), 64);
        assert_eq!(grid_size(30.0, 1.0, 4), 32);
        assert_eq!(grid_size(45.0, 1.0, 4), 48);
        assert_eq!(grid_size(85.0, 1.0, 4), 96);
        assert_eq!(grid_size(130.0, 1.0, 4), 144);
        assert_eq!(grid_size(25.0, 1.0, 4), 25);
        // Where GROMACS takes 44 or 52, the next size with factors 2, 3, 5 and 7.
        assert_eq!(grid_size(44.0, 1.0, 4), 48);
        assert_eq!(grid_size(52.0, 1.0, 4), 56);
        assert_eq!(grid_size(100.0, 1.0, 4), 100);
        assert_eq!(grid_size(101.0, 1.0, 4), 108);
        // Every size has only the factors 2, 3, 5 and 7.
        for length in 1..400 {
            let mut n = grid_size(length as f64, 1.0, 4);
            for p in [2, 3, 5, 7] {
                while n.is_multiple_of(p) {
                    n /= p;
                }
            }
            assert_eq!(n, 1, "{length}");
        }
    }
}
