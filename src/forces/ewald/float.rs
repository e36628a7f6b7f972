//! The float type the PME mesh computes in: `f64` (double precision) or `f32` (mixed
//! precision, as GROMACS's mixed build spreads, transforms and gathers). One generic body
//! serves both, with the same operations in the same order in either type.

use std::ops::AddAssign;

use realfft::FftNum;

/// A float the mesh computes in: what the FFT crates take, plus conversions from and to the
/// `f64` of positions, charges, forces and energies.
pub trait MeshFloat: FftNum + Default + AddAssign {
    /// `x` rounded to this type (exact for `f64`).
    fn of(x: f64) -> Self;
    /// This value as an `f64` (exact).
    fn wide(self) -> f64;
}

impl MeshFloat for f64 {
    #[inline(always)]
    fn of(x: f64) -> Self {
        x
    }
    #[inline(always)]
    fn wide(self) -> f64 {
        self
    }
}

impl MeshFloat for f32 {
    #[inline(always)]
    fn of(x: f64) -> Self {
        x as f32
    }
    #[inline(always)]
    fn wide(self) -> f64 {
        self as f64
    }
}
