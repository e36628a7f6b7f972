//! SIMD lanes for the non-bonded cluster-pair kernel, chosen at run time.
//!
//! The kernel ([`super::nonbonded`]) is written once over the [`Simd`] trait and compiled
//! for each instruction set: the portable path (plain arrays of four, any processor), AVX2
//! (4 doubles or 8 floats per register) and AVX-512 (8 doubles or 16 floats). A register
//! holds `WIDTH / 4` rows of a 4 × 4 cluster pair: one i-atom broadcast over four lanes
//! against the four j-atoms of the j-cluster.
//!
//! **The same bits on every path.** Lane arithmetic is IEEE add, subtract, multiply and
//! fused multiply-add (all correctly rounded; the portable path's `mul_add` is the same
//! single rounding), and `1/√x` is Newton's iteration from a seed made by integer
//! arithmetic on the bits (no approximate-reciprocal instruction, whose results differ
//! between processors): each lane computes exactly what the portable path computes. So
//! are [`exp_neg`] and [`erfc_exp`] (`e^{−t}` and erfc for the Ewald real space): range
//! reduction, polynomials and a rational in those operations, `2ⁿ` by integer arithmetic
//! on the bits. The only
//! cross-lane operation, [`Simd::fold4`], folds a register to four lanes by adding its
//! upper half to its lower half until four remain; together with the kernel's order of
//! rows (rows 0, 2 summed first, then 1, 3: `(r₀ + r₂) + (r₁ + r₃)`) every width sums a
//! cluster pair's contributions in the same order. Results are therefore bit-for-bit the
//! same on every path, which `tests/nonbonded_engine.rs` checks.
//!
//! A value of an implementing type is a token proving that the processor has the
//! instructions: it is only made by [`Isa`] dispatch after detection, which is what makes
//! the trait's methods safe to call.

use std::marker::PhantomData;
use std::ops::{Add, Div, Mul, Neg, Sub};

/// Seeds of `1/√x` (C. Lomont, "Fast inverse square root", 2003): relative error below
/// 3.5 %, so four Newton steps reach double precision and three single.
const RSQRT_MAGIC_F64: u64 = 0x5FE6_EB50_C7B5_37A9;
const RSQRT_MAGIC_F32: u32 = 0x5F37_5A86;

/// The floating-point type of the pair arithmetic (f64, or f32 in mixed precision).
pub trait Real:
    Copy
    + Default
    + PartialOrd
    + Send
    + Sync
    + std::fmt::Debug
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// Newton iterations from [`Real::rsqrt_seed`] to full precision (module doc).
    const NEWTON: usize;
    fn of(x: f64) -> Self;
    fn to_f64(self) -> f64;
    fn sqrt(self) -> Self;
    /// `|self|`: the sign bit cleared.
    fn abs(self) -> Self;
    /// `self · b + c`, rounded once.
    fn mul_add(self, b: Self, c: Self) -> Self;
    /// `1/√x` within 3.5 %: the exponent halved and negated by integer arithmetic on the
    /// bits (Lomont's constants).
    fn rsqrt_seed(self) -> Self;
    /// `1.5 · 2^p` (`p` the mantissa bits): `y + ROUND_MAGIC` rounds `y` to an integer `n`,
    /// held in the low mantissa bits of the sum (for `|n| < 2^(p−1)`).
    const ROUND_MAGIC: f64;
    /// The largest `t` [`exp_neg`] takes: `2^n` of `e^{−t}` stays normal.
    const EXP_T_MAX: f64;
    /// Degree of the Taylor polynomial of `e^r` on `|r| ≤ ln 2 / 2` in [`exp_neg`].
    const EXP_DEGREE: usize;
    /// `2^n` from `self = n + ROUND_MAGIC`: the low bits of `self`, shifted into the exponent
    /// field, plus the bias (exact integer arithmetic; `−bias < n ≤ bias`).
    fn pow2_from_magic(self) -> Self;
    /// The AVX2 lanes of this precision, for [`simd_dispatch!`].
    #[cfg(target_arch = "x86_64")]
    type Avx2: Simd<R = Self>;
    /// The AVX-512 lanes of this precision, for [`simd_dispatch!`].
    #[cfg(target_arch = "x86_64")]
    type Avx512: Simd<R = Self>;
    /// # Safety
    /// The processor must have AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    unsafe fn avx2() -> Self::Avx2;
    /// # Safety
    /// The processor must have AVX-512 F, VL and DQ.
    #[cfg(target_arch = "x86_64")]
    unsafe fn avx512() -> Self::Avx512;
}

/// [`Real`]'s lanes of each instruction set, from their types.
macro_rules! real_lanes {
    ($avx2:ident, $avx512:ident) => {
        #[cfg(target_arch = "x86_64")]
        type Avx2 = $avx2;
        #[cfg(target_arch = "x86_64")]
        type Avx512 = $avx512;
        #[cfg(target_arch = "x86_64")]
        #[inline(always)]
        unsafe fn avx2() -> $avx2 {
            // SAFETY: the caller's contract is the constructor's.
            unsafe { $avx2::new_unchecked() }
        }
        #[cfg(target_arch = "x86_64")]
        #[inline(always)]
        unsafe fn avx512() -> $avx512 {
            // SAFETY: the caller's contract is the constructor's.
            unsafe { $avx512::new_unchecked() }
        }
    };
}

impl Real for f64 {
    real_lanes!(Avx2F64, Avx512F64);
    const NEWTON: usize = 4;
    const ROUND_MAGIC: f64 = 6_755_399_441_055_744.0; // 1.5 · 2^52
    const EXP_T_MAX: f64 = 708.0;
    const EXP_DEGREE: usize = 13;
    #[inline(always)]
    fn pow2_from_magic(self) -> Self {
        f64::from_bits((self.to_bits() << 52).wrapping_add(1023 << 52))
    }
    #[inline(always)]
    fn mul_add(self, b: Self, c: Self) -> Self {
        f64::mul_add(self, b, c)
    }
    #[inline(always)]
    fn rsqrt_seed(self) -> Self {
        f64::from_bits(RSQRT_MAGIC_F64.wrapping_sub(self.to_bits() >> 1))
    }
    #[inline(always)]
    fn of(x: f64) -> Self {
        x
    }
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f64::abs(self)
    }
}

impl Real for f32 {
    real_lanes!(Avx2F32, Avx512F32);
    const NEWTON: usize = 3;
    const ROUND_MAGIC: f64 = 12_582_912.0; // 1.5 · 2^23
    const EXP_T_MAX: f64 = 87.0;
    const EXP_DEGREE: usize = 7;
    #[inline(always)]
    fn pow2_from_magic(self) -> Self {
        f32::from_bits((self.to_bits() << 23).wrapping_add(127 << 23))
    }
    #[inline(always)]
    fn mul_add(self, b: Self, c: Self) -> Self {
        f32::mul_add(self, b, c)
    }
    #[inline(always)]
    fn rsqrt_seed(self) -> Self {
        f32::from_bits(RSQRT_MAGIC_F32.wrapping_sub(self.to_bits() >> 1))
    }
    #[inline(always)]
    fn of(x: f64) -> Self {
        x as f32
    }
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self as f64
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f32::sqrt(self)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f32::abs(self)
    }
}

/// Lanes of one instruction set and precision (see the module doc).
pub trait Simd: Copy + Send + Sync {
    type R: Real;
    type V: Copy;
    type M: Copy;
    /// Lanes per register: 4, 8 or 16.
    const WIDTH: usize;
    fn splat(self, x: Self::R) -> Self::V;
    /// The first `WIDTH` values.
    fn load(self, values: &[Self::R; 16]) -> Self::V;
    /// Four values repeated `WIDTH / 4` times.
    fn load4(self, values: &[Self::R; 4]) -> Self::V;
    /// Row `r` of the register (lanes `4r..4r + 4`) from `rows[r]`, for `r < WIDTH / 4`
    /// (the other rows are not read).
    fn load_rows(self, rows: [&[Self::R; 4]; 4]) -> Self::V;
    /// Lanes into the first `WIDTH` values.
    fn store(self, v: Self::V, out: &mut [Self::R; 16]);
    fn add(self, a: Self::V, b: Self::V) -> Self::V;
    fn sub(self, a: Self::V, b: Self::V) -> Self::V;
    fn mul(self, a: Self::V, b: Self::V) -> Self::V;
    fn div(self, a: Self::V, b: Self::V) -> Self::V;
    fn sqrt(self, a: Self::V) -> Self::V;
    /// `|a|`: the sign bit of each lane cleared (exact, as [`Real::abs`]).
    fn abs(self, a: Self::V) -> Self::V;
    /// `a · b + c`, rounded once.
    fn fma(self, a: Self::V, b: Self::V, c: Self::V) -> Self::V;
    /// `c − a · b`, rounded once.
    fn fnma(self, a: Self::V, b: Self::V, c: Self::V) -> Self::V;
    /// `a · b − c`, rounded once.
    fn fms(self, a: Self::V, b: Self::V, c: Self::V) -> Self::V;
    /// [`Real::rsqrt_seed`] of each lane.
    fn rsqrt_seed(self, x: Self::V) -> Self::V;
    /// [`Real::pow2_from_magic`] of each lane.
    fn pow2_from_magic(self, y: Self::V) -> Self::V;
    /// `1/√x` to about one unit in the last place: Newton's step `y ← y (3/2 − (x/2) y²)`
    /// from the seed, the same operations on every path (no approximate-reciprocal
    /// instruction, whose results differ between processors).
    #[inline(always)]
    fn rsqrt(self, x: Self::V) -> Self::V {
        let three_halves = self.splat(Self::R::of(1.5));
        let half_x = self.mul(x, self.splat(Self::R::of(0.5)));
        let mut y = self.rsqrt_seed(x);
        for _ in 0..Self::R::NEWTON {
            y = self.mul(y, self.fnma(self.mul(half_x, y), y, three_halves));
        }
        y
    }
    /// Lanes where `a < b` (false where either is NaN).
    fn less(self, a: Self::V, b: Self::V) -> Self::M;
    /// Lanes where `a ≤ b` (false where either is NaN).
    fn less_equal(self, a: Self::V, b: Self::V) -> Self::M;
    /// Lane `k` set where bit `k` of `bits` is.
    fn mask(self, bits: u32) -> Self::M;
    fn and(self, a: Self::M, b: Self::M) -> Self::M;
    /// `a` where `m`, else `b`.
    fn select(self, m: Self::M, a: Self::V, b: Self::V) -> Self::V;
    /// Bit `k` set where lane `k` of `m` is.
    fn bits(self, m: Self::M) -> u32;
    /// `out[l] += ` the lanes `l` of every row, folded as the module doc says, in f64.
    fn fold4(self, v: Self::V, out: &mut [f64; 4]);
}

/// Row (atom of a cluster of four) of lane `k` in register group `group`: a register holds
/// `WIDTH / 4` rows of four lanes.
#[inline(always)]
pub fn row<S: Simd>(group: usize, k: usize) -> usize {
    group * (S::WIDTH / 4) + k / 4
}

/// The lanes of group `group`: each lane's row of `values`, plus `offset`, rounded to
/// `S::R`. Groups past the last (`group ≥ 16 / WIDTH`) repeat the last one.
#[inline(always)]
pub fn row_lanes<S: Simd>(s: S, values: &[f64; 4], offset: f64, group: usize) -> S::V {
    let group = group.min(16 / S::WIDTH - 1);
    let mut a = [S::R::default(); 16];
    for k in 0..S::WIDTH {
        a[k] = S::R::of(values[row::<S>(group, k)] + offset);
    }
    s.load(&a)
}

/// `e^{−t}` for `0 ≤ t` (clamped at [`Real::EXP_T_MAX`], where it is below 1e-307 in f64
/// and 2e-38 in f32): `n = round(−t/ln 2)` by adding [`Real::ROUND_MAGIC`] in one fused
/// multiply-add, the reduced `r = −t − n ln 2` by two fused steps (Cody & Waite's split of
/// ln 2, here exact products in the fma), `e^r` by its Taylor polynomial of degree
/// [`Real::EXP_DEGREE`] (remainder below `0.347^14/14! = 4.4e-18` in f64 and
/// `0.347^8/8! = 5e-9` in f32) and `2^n` by integer arithmetic on the bits. Only
/// correctly rounded operations: the same bits on every instruction set.
#[inline(always)]
pub fn exp_neg<S: Simd>(s: S, t: S::V) -> S::V {
    let r = |x: f64| s.splat(S::R::of(x));
    let t = s.select(s.less(r(S::R::EXP_T_MAX), t), r(S::R::EXP_T_MAX), t);
    let ln2_hi = S::R::of(std::f64::consts::LN_2);
    // ln 2 − ln2_hi: the f64 difference plus ln 2's own rounding error in f64.
    let ln2_lo = (std::f64::consts::LN_2 - ln2_hi.to_f64()) + LN2_F64_ERROR;
    let y = s.fnma(t, r(std::f64::consts::LOG2_E), r(S::R::ROUND_MAGIC));
    let n = s.sub(y, r(S::R::ROUND_MAGIC));
    let reduced = s.fnma(n, s.splat(ln2_hi), s.sub(r(0.0), t));
    let reduced = s.fnma(n, r(ln2_lo), reduced);
    let mut p = r(1.0 / factorial(S::R::EXP_DEGREE));
    for k in (0..S::R::EXP_DEGREE).rev() {
        p = s.fma(p, reduced, r(1.0 / factorial(k)));
    }
    s.mul(p, s.pow2_from_magic(y))
}

/// `ln 2 − fl₆₄(ln 2)`.
const LN2_F64_ERROR: f64 = 2.319_046_813_846_299_6e-17;

/// `k!` as a double (exact for the degrees used).
#[inline(always)]
const fn factorial(k: usize) -> f64 {
    let mut f = 1.0;
    let mut i = 2;
    while i <= k {
        f *= i as f64;
        i += 1;
    }
    f
}

/// Largest argument of [`erfc_exp`]: the range of its fit (`scripts/fit_erfc.py`).
pub const ERFC_X_MAX: f64 = 6.5;

/// `erfcx(x) = e^{x²} erfc(x) ≈ P(x)/Q(x)` on `[0, 6.5]` in double, coefficients of
/// `x⁰, x¹, …` from `python3 scripts/fit_erfc.py 8 6.5 f64`, which printed
/// `m = 8, x_max = 6.5: max |P/Q / erfcx - 1| = 1.41e-17 exact, 9.04e-16 in float64 Horner`.
const ERFCX_P64: [f64; 9] = [
    1.0,
    1.8815960140267078,
    1.7644072431015372,
    1.0389474834510497,
    0.41463642394123335,
    0.11419690481065771,
    0.021184475475905407,
    0.0024292458938850103,
    0.0001330332605307374,
];
const ERFCX_Q64: [f64; 10] = [
    1.0,
    3.0099751811222246,
    4.1608005309542,
    3.476185717964869,
    1.940553629958927,
    0.753578754788258,
    0.20456172029455857,
    0.037666396758551886,
    0.004305726443542722,
    0.00023579531163551873,
];
/// As above for single precision: `python3 scripts/fit_erfc.py 4 6.5 f32`,
/// `m = 4, x_max = 6.5: max |P/Q / erfcx - 1| = 2.0e-9 exact, 3.58e-7 in float32 Horner`.
const ERFCX_P32: [f64; 5] = [
    1.0000000020026314,
    1.1968106201356192,
    0.6888287489993737,
    0.2091107506063759,
    0.028670602082449273,
];
const ERFCX_Q32: [f64; 6] = [
    1.0,
    2.325190005822822,
    2.312520876029662,
    1.2456002992988735,
    0.370692468481339,
    0.05081556252399063,
];

/// `P(x)` by Horner's rule in fused multiply-adds.
#[inline(always)]
fn horner<S: Simd>(s: S, coefficients: &[f64], x: S::V) -> S::V {
    let (last, rest) = coefficients.split_last().expect("a coefficient");
    let mut p = s.splat(S::R::of(*last));
    for &c in rest.iter().rev() {
        p = s.fma(p, x, s.splat(S::R::of(c)));
    }
    p
}

/// `(erfc(x), e^{−x²})` for `0 ≤ x ≤` [`ERFC_X_MAX`] (larger `x` is clamped there):
/// `erfc(x) = e^{−x²} · erfcx(x)` with the scaled function `erfcx` as the rational `P/Q`
/// fitted by `scripts/fit_erfc.py` (degrees 8/9 in double, 4/5 in single), and `e^{−x²}`
/// by [`exp_neg`] of `t = x²` corrected by the rounding error `δ = x² − t` (one fused
/// multiply-subtract, exact): `e^{−t}(1 − δ)`. Relative error of both at the lanes' `x`,
/// against libm on a dense grid (`tests/nonbonded_engine.rs`, which derives its bounds
/// 3.0e-15 and 1.8e-6): see the measured figures in the kernel's module doc
/// (`forces/nonbonded/kernel.rs`).
#[inline(always)]
pub fn erfc_exp<S: Simd>(s: S, x: S::V) -> (S::V, S::V) {
    let x_max = s.splat(S::R::of(ERFC_X_MAX));
    let x = s.select(s.less(x_max, x), x_max, x);
    let t = s.mul(x, x);
    let delta = s.fms(x, x, t);
    let e = exp_neg(s, t);
    let gauss = s.fnma(e, delta, e);
    let (p, q) = if std::mem::size_of::<S::R>() == 8 {
        (horner(s, &ERFCX_P64, x), horner(s, &ERFCX_Q64, x))
    } else {
        (horner(s, &ERFCX_P32, x), horner(s, &ERFCX_Q32, x))
    };
    (s.mul(gauss, s.div(p, q)), gauss)
}

/// Largest `z = β²r²` of [`ewald_force`]: the range of its fit
/// (`scripts/fit_ewald_force.py`), `β r_c ≤ 4` with room for the rounding of `r²` in f32.
pub const EWALD_Z_MAX: f64 = 16.5;

/// `F(z) = (erf(√z) − 2√(z/π) e^{−z}) / z^{3/2} ≈ P(z)/Q(z)` on `[0, 16.5]`, the force of
/// `erf(βr)/r` over `β³`, coefficients of `z⁰, z¹, …` from
/// `python3 scripts/fit_ewald_force.py 6 5 16.5` (its output: `docs/data/fit-ewald-force.txt`),
/// which printed `max |P/Q / F - 1| = 7.59e-8 exact, 3.23e-7 in f32` and the Horner
/// conditions `Σ|c_k| z^k / |P(z)|` 1.68 (P) and 1.0 (Q).
const EWALD_FORCE_P: [f64; 7] = [
    0.7522528351404922,
    -0.03349818048472594,
    0.017970736117061136,
    -0.0001468255242470236,
    4.957275138109474e-05,
    -9.820240813769844e-07,
    1.0127606120122833e-08,
];
const EWALD_FORCE_Q: [f64; 6] = [
    1.0,
    0.5554719927388765,
    0.14287317420477572,
    0.0220842171986286,
    0.0021617579953696485,
    0.0001374125476179042,
];

/// The rational of [`ewald_force`] at one `β`, in `r²`: `P(β²r²) β³` and `Q(β²r²)` with
/// `β^{2k+3}` and `β^{2k}` folded into the coefficients (no product `β²r²` in the lanes).
#[derive(Clone, Copy, Debug)]
pub struct EwaldForce {
    p: [f64; 7],
    q: [f64; 6],
}

impl EwaldForce {
    pub fn new(beta: f64) -> Self {
        let b2 = beta * beta;
        EwaldForce {
            p: std::array::from_fn(|k| EWALD_FORCE_P[k] * beta * b2.powi(k as i32 + 1)),
            q: std::array::from_fn(|k| EWALD_FORCE_Q[k] * b2.powi(k as i32)),
        }
    }
}

/// `1/r³ − β³ F(β²r²)`: the Ewald real-space force `−V′/r` of `V = erfc(βr)/r` (per unit
/// `Q`) without erfc or `e^{−x²}`: `1/r³` from the lanes' `1/r` and `1/r²`, the smooth
/// part `erf(βr)/r`'s force as the rational [`EwaldForce`] in `r²` (Horner in fused
/// multiply-adds, one division: 13 operations and a subtraction, against ~40 for
/// [`erfc_exp`]'s route). Valid for `β²r² ≤` [`EWALD_Z_MAX`]. Only IEEE operations in a
/// fixed order: the same bits on every instruction set. Error: at most `30.8 u` of `1/r³`
/// (plus the fit's 7.6e-8), derived and checked in `tests/nonbonded_engine.rs`; as
/// `β³F ≤ 1/r³`, an absolute error that near the cutoff, where the force is
/// `erfc`-small, is a larger relative one (GROMACS's mixed-precision kernels do the same).
#[inline(always)]
pub fn ewald_force<S: Simd>(s: S, fit: &EwaldForce, r2: S::V, rinv: S::V, rinv2: S::V) -> S::V {
    let smooth = s.div(horner(s, &fit.p, r2), horner(s, &fit.q, r2));
    s.sub(s.mul(rinv, rinv2), smooth)
}

/// The instruction set of the kernel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Isa {
    /// Arrays of four, any processor.
    Portable,
    /// x86-64 AVX2 with FMA.
    Avx2,
    /// x86-64 AVX-512 (F, VL, DQ).
    Avx512,
}

impl Isa {
    /// Every instruction set this processor runs, portable first.
    pub fn available() -> Vec<Isa> {
        [Isa::Portable, Isa::Avx2, Isa::Avx512]
            .into_iter()
            .filter(|isa| isa.is_available())
            .collect()
    }

    pub fn is_available(self) -> bool {
        match self {
            Isa::Portable => true,
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => {
                std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")
            }
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 => {
                std::is_x86_feature_detected!("avx512f")
                    && std::is_x86_feature_detected!("avx512vl")
                    && std::is_x86_feature_detected!("avx512dq")
            }
            #[cfg(not(target_arch = "x86_64"))]
            _ => false,
        }
    }

    /// The widest available (no allocation: callers may ask once per step).
    pub fn best() -> Isa {
        [Isa::Avx512, Isa::Avx2]
            .into_iter()
            .find(|isa| isa.is_available())
            .unwrap_or(Isa::Portable)
    }

    /// `f` with its body compiled for this instruction set: `f` is inlined into a function
    /// with the set's target features (made by [`simd_dispatch!`]), so its loops vectorise
    /// for it (mark the closure `#[inline(always)]`, and what it calls). Rust never fuses a
    /// multiply and an add on its own, so plain arithmetic gives the same bits on every set.
    /// Panics if the processor lacks the set.
    #[inline(always)]
    pub fn run<T>(self, f: impl FnOnce() -> T) -> T {
        run_on(self, f)
    }

    pub fn name(self) -> &'static str {
        match self {
            Isa::Portable => "portable",
            Isa::Avx2 => "avx2",
            Isa::Avx512 => "avx512",
        }
    }

    pub fn parse(name: &str) -> Option<Isa> {
        [Isa::Portable, Isa::Avx2, Isa::Avx512]
            .into_iter()
            .find(|isa| isa.name() == name)
    }
}

/// `fn $name<$generics>(isa: Isa, $args) -> $ret`: `$body(s, $args)` with `s` the lanes
/// of `isa` in precision `$real` (`lanes $real`), the body compiled for the instruction
/// set. This is the one place where a function with target features is written: for AVX2
/// and AVX-512 it emits a copy of the body with the set's `#[target_feature]`, whose lanes
/// token is made only after [`Isa::is_available`] said so, and the portable path calls the
/// body directly. `$body` is generic over the lanes and `#[inline(always)]` (with what it
/// calls), so it is compiled inside each copy. The generics are given twice, declared and
/// then by name (`[C: Coulomb, const G: bool] [C, G]`), as the copies redeclare them.
///
/// The copies take the arguments one by one, as a hand-written one would: one generic copy
/// per set taking them packed in a struct (a trait with a method generic over the lanes,
/// as `pulp::WithSimd`) ran the molecule blocks of `distance_split::lanes` with 7 % more
/// instructions (callgrind, AVX2), the cluster kernel and pruning as before.
///
/// ```ignore
/// simd_dispatch! {
///     /// `prune` on the instruction set `isa`.
///     fn prune_on[][](work: &Work, inner: &mut PairList) = prune, lanes f64;
/// }
/// ```
macro_rules! simd_dispatch {
    (
        $(#[$attr:meta])*
        $vis:vis fn $name:ident [$($generics:tt)*] [$($names:tt)*]
            ($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)? = $body:expr, lanes $real:ty;
    ) => {
        $(#[$attr])*
        $vis fn $name<$($generics)*>(
            isa: $crate::forces::simd::Isa,
            $($arg: $ty),*
        ) $(-> $ret)? {
            use $crate::forces::simd::{Isa, Portable, Real};
            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx2,fma")]
            fn avx2<$($generics)*>($($arg: $ty),*) $(-> $ret)? {
                // SAFETY: this copy runs only where AVX2 and FMA are (a target-feature
                // function is called in an `unsafe` block, below after the check).
                let s = unsafe { <$real as Real>::avx2() };
                $body(s, $($arg),*)
            }
            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx512f,avx512vl,avx512dq")]
            fn avx512<$($generics)*>($($arg: $ty),*) $(-> $ret)? {
                // SAFETY: this copy runs only where AVX-512 F, VL and DQ are (as above).
                let s = unsafe { <$real as Real>::avx512() };
                $body(s, $($arg),*)
            }
            assert!(isa.is_available(), "{} is not available", isa.name());
            match isa {
                #[cfg(target_arch = "x86_64")]
                // SAFETY: AVX2 and FMA are available (asserted above).
                Isa::Avx2 => unsafe { avx2::<$($names)*>($($arg),*) },
                #[cfg(target_arch = "x86_64")]
                // SAFETY: AVX-512 F, VL and DQ are available (asserted above).
                Isa::Avx512 => unsafe { avx512::<$($names)*>($($arg),*) },
                _ => $body(Portable::<$real>::new(), $($arg),*),
            }
        }
    };
}
pub(crate) use simd_dispatch;

simd_dispatch! {
    /// [`Isa::run`].
    #[inline(always)]
    fn run_on[T, F: FnOnce() -> T][T, F](f: F) -> T = call, lanes f64;
}

/// `f()`, whatever the lanes.
#[inline(always)]
fn call<S, T>(_: S, f: impl FnOnce() -> T) -> T {
    f()
}

/// Plain arrays of four: the reference path, on any processor.
#[derive(Clone, Copy, Default)]
pub struct Portable<R>(PhantomData<R>);

impl<R: Real> Portable<R> {
    pub fn new() -> Self {
        Portable(PhantomData)
    }
}

impl<R: Real> Simd for Portable<R> {
    type R = R;
    type V = [R; 4];
    type M = [bool; 4];
    const WIDTH: usize = 4;
    #[inline(always)]
    fn splat(self, x: R) -> [R; 4] {
        [x; 4]
    }
    #[inline(always)]
    fn load(self, values: &[R; 16]) -> [R; 4] {
        [values[0], values[1], values[2], values[3]]
    }
    #[inline(always)]
    fn load4(self, values: &[R; 4]) -> [R; 4] {
        *values
    }
    #[inline(always)]
    fn load_rows(self, rows: [&[R; 4]; 4]) -> [R; 4] {
        *rows[0]
    }
    #[inline(always)]
    fn store(self, v: [R; 4], out: &mut [R; 16]) {
        out[..4].copy_from_slice(&v);
    }
    #[inline(always)]
    fn add(self, a: [R; 4], b: [R; 4]) -> [R; 4] {
        std::array::from_fn(|k| a[k] + b[k])
    }
    #[inline(always)]
    fn sub(self, a: [R; 4], b: [R; 4]) -> [R; 4] {
        std::array::from_fn(|k| a[k] - b[k])
    }
    #[inline(always)]
    fn mul(self, a: [R; 4], b: [R; 4]) -> [R; 4] {
        std::array::from_fn(|k| a[k] * b[k])
    }
    #[inline(always)]
    fn div(self, a: [R; 4], b: [R; 4]) -> [R; 4] {
        std::array::from_fn(|k| a[k] / b[k])
    }
    #[inline(always)]
    fn sqrt(self, a: [R; 4]) -> [R; 4] {
        std::array::from_fn(|k| a[k].sqrt())
    }
    #[inline(always)]
    fn abs(self, a: [R; 4]) -> [R; 4] {
        std::array::from_fn(|k| a[k].abs())
    }
    #[inline(always)]
    fn fma(self, a: [R; 4], b: [R; 4], c: [R; 4]) -> [R; 4] {
        std::array::from_fn(|k| a[k].mul_add(b[k], c[k]))
    }
    #[inline(always)]
    fn fnma(self, a: [R; 4], b: [R; 4], c: [R; 4]) -> [R; 4] {
        std::array::from_fn(|k| (-a[k]).mul_add(b[k], c[k]))
    }
    #[inline(always)]
    fn fms(self, a: [R; 4], b: [R; 4], c: [R; 4]) -> [R; 4] {
        std::array::from_fn(|k| a[k].mul_add(b[k], -c[k]))
    }
    #[inline(always)]
    fn rsqrt_seed(self, x: [R; 4]) -> [R; 4] {
        std::array::from_fn(|k| x[k].rsqrt_seed())
    }
    #[inline(always)]
    fn pow2_from_magic(self, y: [R; 4]) -> [R; 4] {
        std::array::from_fn(|k| y[k].pow2_from_magic())
    }
    #[inline(always)]
    fn less(self, a: [R; 4], b: [R; 4]) -> [bool; 4] {
        std::array::from_fn(|k| a[k] < b[k])
    }
    #[inline(always)]
    fn less_equal(self, a: [R; 4], b: [R; 4]) -> [bool; 4] {
        std::array::from_fn(|k| a[k] <= b[k])
    }
    #[inline(always)]
    fn mask(self, bits: u32) -> [bool; 4] {
        std::array::from_fn(|k| bits >> k & 1 == 1)
    }
    #[inline(always)]
    fn and(self, a: [bool; 4], b: [bool; 4]) -> [bool; 4] {
        std::array::from_fn(|k| a[k] & b[k])
    }
    #[inline(always)]
    fn select(self, m: [bool; 4], a: [R; 4], b: [R; 4]) -> [R; 4] {
        std::array::from_fn(|k| if m[k] { a[k] } else { b[k] })
    }
    #[inline(always)]
    fn bits(self, m: [bool; 4]) -> u32 {
        (m[0] as u32) | (m[1] as u32) << 1 | (m[2] as u32) << 2 | (m[3] as u32) << 3
    }
    #[inline(always)]
    fn fold4(self, v: [R; 4], out: &mut [f64; 4]) {
        for k in 0..4 {
            out[k] += v[k].to_f64();
        }
    }
}

#[cfg(target_arch = "x86_64")]
pub use x86::{Avx2F32, Avx2F64, Avx512F32, Avx512F64};

#[cfg(target_arch = "x86_64")]
mod x86 {
    //! AVX2 and AVX-512 lanes. Every intrinsic call is safe because a token exists only
    //! after [`super::Isa::is_available`] said so (see the constructors).

    use super::Simd;
    use std::arch::x86_64::*;

    /// AVX2, 4 doubles.
    #[derive(Clone, Copy)]
    pub struct Avx2F64(());
    /// AVX2, 8 floats (two rows).
    #[derive(Clone, Copy)]
    pub struct Avx2F32(());
    /// AVX-512, 8 doubles (two rows).
    #[derive(Clone, Copy)]
    pub struct Avx512F64(());
    /// AVX-512, 16 floats (four rows).
    #[derive(Clone, Copy)]
    pub struct Avx512F32(());

    impl Avx2F64 {
        /// # Safety
        /// The processor must have AVX2 and FMA.
        pub unsafe fn new_unchecked() -> Self {
            Avx2F64(())
        }
    }
    impl Avx2F32 {
        /// # Safety
        /// The processor must have AVX2 and FMA.
        pub unsafe fn new_unchecked() -> Self {
            Avx2F32(())
        }
    }
    impl Avx512F64 {
        /// # Safety
        /// The processor must have AVX-512 F, VL and DQ.
        pub unsafe fn new_unchecked() -> Self {
            Avx512F64(())
        }
    }
    impl Avx512F32 {
        /// # Safety
        /// The processor must have AVX-512 F, VL and DQ.
        pub unsafe fn new_unchecked() -> Self {
            Avx512F32(())
        }
    }

    /// The methods written the same for every type, from their intrinsics: the lane
    /// arithmetic, and moving `WIDTH` values (at most 16) between memory and a register.
    macro_rules! common {
        ($v:ty, $r:ty;
         splat $splat:ident, load $load:ident, store $store:ident,
         add $add:ident, sub $sub:ident, mul $mul:ident, div $div:ident, sqrt $sqrt:ident,
         fma $fma:ident, fnma $fnma:ident, fms $fms:ident) => {
            #[inline(always)]
            fn splat(self, x: $r) -> $v {
                // SAFETY (every method here): the token proves the instruction set (module
                // doc), and the loads and stores touch `WIDTH ≤ 16` values of 16.
                unsafe { $splat(x) }
            }
            #[inline(always)]
            fn load(self, values: &[$r; 16]) -> $v {
                // SAFETY: as above.
                unsafe { $load(values.as_ptr()) }
            }
            #[inline(always)]
            fn store(self, v: $v, out: &mut [$r; 16]) {
                // SAFETY: as above.
                unsafe { $store(out.as_mut_ptr(), v) }
            }
            #[inline(always)]
            fn add(self, a: $v, b: $v) -> $v {
                // SAFETY: as above.
                unsafe { $add(a, b) }
            }
            #[inline(always)]
            fn sub(self, a: $v, b: $v) -> $v {
                // SAFETY: as above.
                unsafe { $sub(a, b) }
            }
            #[inline(always)]
            fn mul(self, a: $v, b: $v) -> $v {
                // SAFETY: as above.
                unsafe { $mul(a, b) }
            }
            #[inline(always)]
            fn div(self, a: $v, b: $v) -> $v {
                // SAFETY: as above.
                unsafe { $div(a, b) }
            }
            #[inline(always)]
            fn sqrt(self, a: $v) -> $v {
                // SAFETY: as above.
                unsafe { $sqrt(a) }
            }
            #[inline(always)]
            fn fma(self, a: $v, b: $v, c: $v) -> $v {
                // SAFETY: as above.
                unsafe { $fma(a, b, c) }
            }
            #[inline(always)]
            fn fnma(self, a: $v, b: $v, c: $v) -> $v {
                // SAFETY: as above.
                unsafe { $fnma(a, b, c) }
            }
            #[inline(always)]
            fn fms(self, a: $v, b: $v, c: $v) -> $v {
                // SAFETY: as above.
                unsafe { $fms(a, b, c) }
            }
        };
    }

    impl Simd for Avx2F64 {
        type R = f64;
        type V = __m256d;
        type M = __m256d;
        const WIDTH: usize = 4;
        common!(
            __m256d, f64;
            splat _mm256_set1_pd, load _mm256_loadu_pd, store _mm256_storeu_pd,
            add _mm256_add_pd, sub _mm256_sub_pd, mul _mm256_mul_pd, div _mm256_div_pd,
            sqrt _mm256_sqrt_pd, fma _mm256_fmadd_pd, fnma _mm256_fnmadd_pd, fms _mm256_fmsub_pd
        );
        #[inline(always)]
        fn load4(self, values: &[f64; 4]) -> __m256d {
            // SAFETY: AVX2; exactly 4 values are read.
            unsafe { _mm256_loadu_pd(values.as_ptr()) }
        }
        #[inline(always)]
        fn load_rows(self, rows: [&[f64; 4]; 4]) -> __m256d {
            self.load4(rows[0])
        }
        #[inline(always)]
        fn rsqrt_seed(self, x: __m256d) -> __m256d {
            // SAFETY: AVX2.
            unsafe {
                let magic = _mm256_set1_epi64x(super::RSQRT_MAGIC_F64 as i64);
                let bits = _mm256_srli_epi64::<1>(_mm256_castpd_si256(x));
                _mm256_castsi256_pd(_mm256_sub_epi64(magic, bits))
            }
        }
        #[inline(always)]
        fn pow2_from_magic(self, y: __m256d) -> __m256d {
            // SAFETY: the token proves the instruction set.
            unsafe {
                let low = _mm256_slli_epi64::<52>(_mm256_castpd_si256(y));
                _mm256_castsi256_pd(_mm256_add_epi64(low, _mm256_set1_epi64x(1023 << 52)))
            }
        }
        #[inline(always)]
        fn less(self, a: __m256d, b: __m256d) -> __m256d {
            // SAFETY: AVX2.
            unsafe { _mm256_cmp_pd::<_CMP_LT_OQ>(a, b) }
        }
        #[inline(always)]
        fn less_equal(self, a: __m256d, b: __m256d) -> __m256d {
            // SAFETY: AVX2.
            unsafe { _mm256_cmp_pd::<_CMP_LE_OQ>(a, b) }
        }
        #[inline(always)]
        fn abs(self, a: __m256d) -> __m256d {
            // SAFETY: AVX2. The sign bit cleared.
            unsafe { _mm256_andnot_pd(_mm256_set1_pd(-0.0), a) }
        }
        #[inline(always)]
        fn mask(self, bits: u32) -> __m256d {
            // SAFETY: AVX2. Lane k tests bit k.
            unsafe {
                let select = _mm256_set_epi64x(8, 4, 2, 1);
                let b = _mm256_and_si256(_mm256_set1_epi64x(bits as i64), select);
                _mm256_castsi256_pd(_mm256_cmpeq_epi64(b, select))
            }
        }
        #[inline(always)]
        fn and(self, a: __m256d, b: __m256d) -> __m256d {
            // SAFETY: AVX2.
            unsafe { _mm256_and_pd(a, b) }
        }
        #[inline(always)]
        fn select(self, m: __m256d, a: __m256d, b: __m256d) -> __m256d {
            // SAFETY: AVX2.
            unsafe { _mm256_blendv_pd(b, a, m) }
        }
        #[inline(always)]
        fn bits(self, m: __m256d) -> u32 {
            // SAFETY: AVX2.
            unsafe { _mm256_movemask_pd(m) as u32 }
        }
        #[inline(always)]
        fn fold4(self, v: __m256d, out: &mut [f64; 4]) {
            // SAFETY: AVX2; 4 values read and written.
            unsafe {
                let o = _mm256_loadu_pd(out.as_ptr());
                _mm256_storeu_pd(out.as_mut_ptr(), _mm256_add_pd(o, v));
            }
        }
    }

    impl Simd for Avx2F32 {
        type R = f32;
        type V = __m256;
        type M = __m256;
        const WIDTH: usize = 8;
        common!(
            __m256, f32;
            splat _mm256_set1_ps, load _mm256_loadu_ps, store _mm256_storeu_ps,
            add _mm256_add_ps, sub _mm256_sub_ps, mul _mm256_mul_ps, div _mm256_div_ps,
            sqrt _mm256_sqrt_ps, fma _mm256_fmadd_ps, fnma _mm256_fnmadd_ps, fms _mm256_fmsub_ps
        );
        #[inline(always)]
        fn load4(self, values: &[f32; 4]) -> __m256 {
            // SAFETY: AVX2; exactly 4 values are read.
            unsafe { _mm256_broadcast_ps(&*(values.as_ptr() as *const __m128)) }
        }
        #[inline(always)]
        fn load_rows(self, rows: [&[f32; 4]; 4]) -> __m256 {
            // SAFETY: AVX2; 4 values read from each of the first two rows.
            unsafe {
                let low = _mm256_castps128_ps256(_mm_loadu_ps(rows[0].as_ptr()));
                _mm256_insertf128_ps::<1>(low, _mm_loadu_ps(rows[1].as_ptr()))
            }
        }
        #[inline(always)]
        fn rsqrt_seed(self, x: __m256) -> __m256 {
            // SAFETY: AVX2.
            unsafe {
                let magic = _mm256_set1_epi32(super::RSQRT_MAGIC_F32 as i32);
                let bits = _mm256_srli_epi32::<1>(_mm256_castps_si256(x));
                _mm256_castsi256_ps(_mm256_sub_epi32(magic, bits))
            }
        }
        #[inline(always)]
        fn pow2_from_magic(self, y: __m256) -> __m256 {
            // SAFETY: the token proves the instruction set.
            unsafe {
                let low = _mm256_slli_epi32::<23>(_mm256_castps_si256(y));
                _mm256_castsi256_ps(_mm256_add_epi32(low, _mm256_set1_epi32(127 << 23)))
            }
        }
        #[inline(always)]
        fn less(self, a: __m256, b: __m256) -> __m256 {
            // SAFETY: AVX2.
            unsafe { _mm256_cmp_ps::<_CMP_LT_OQ>(a, b) }
        }
        #[inline(always)]
        fn less_equal(self, a: __m256, b: __m256) -> __m256 {
            // SAFETY: AVX2.
            unsafe { _mm256_cmp_ps::<_CMP_LE_OQ>(a, b) }
        }
        #[inline(always)]
        fn abs(self, a: __m256) -> __m256 {
            // SAFETY: AVX2. The sign bit cleared.
            unsafe { _mm256_andnot_ps(_mm256_set1_ps(-0.0), a) }
        }
        #[inline(always)]
        fn mask(self, bits: u32) -> __m256 {
            // SAFETY: AVX2. Lane k tests bit k.
            unsafe {
                let select = _mm256_set_epi32(128, 64, 32, 16, 8, 4, 2, 1);
                let b = _mm256_and_si256(_mm256_set1_epi32(bits as i32), select);
                _mm256_castsi256_ps(_mm256_cmpeq_epi32(b, select))
            }
        }
        #[inline(always)]
        fn and(self, a: __m256, b: __m256) -> __m256 {
            // SAFETY: AVX2.
            unsafe { _mm256_and_ps(a, b) }
        }
        #[inline(always)]
        fn select(self, m: __m256, a: __m256, b: __m256) -> __m256 {
            // SAFETY: AVX2.
            unsafe { _mm256_blendv_ps(b, a, m) }
        }
        #[inline(always)]
        fn bits(self, m: __m256) -> u32 {
            // SAFETY: AVX2.
            unsafe { _mm256_movemask_ps(m) as u32 }
        }
        #[inline(always)]
        fn fold4(self, v: __m256, out: &mut [f64; 4]) {
            // SAFETY: AVX2; [r₀+r₂|r₁+r₃] → (r₀+r₂)+(r₁+r₃) in f32, then f64, added.
            unsafe {
                let low = _mm256_castps256_ps128(v);
                let high = _mm256_extractf128_ps::<1>(v);
                let sum = _mm256_cvtps_pd(_mm_add_ps(low, high));
                let o = _mm256_loadu_pd(out.as_ptr());
                _mm256_storeu_pd(out.as_mut_ptr(), _mm256_add_pd(o, sum));
            }
        }
    }

    impl Simd for Avx512F64 {
        type R = f64;
        type V = __m512d;
        type M = __mmask8;
        const WIDTH: usize = 8;
        common!(
            __m512d, f64;
            splat _mm512_set1_pd, load _mm512_loadu_pd, store _mm512_storeu_pd,
            add _mm512_add_pd, sub _mm512_sub_pd, mul _mm512_mul_pd, div _mm512_div_pd,
            sqrt _mm512_sqrt_pd, fma _mm512_fmadd_pd, fnma _mm512_fnmadd_pd, fms _mm512_fmsub_pd
        );
        #[inline(always)]
        fn load4(self, values: &[f64; 4]) -> __m512d {
            // SAFETY: AVX-512F; exactly 4 values are read.
            unsafe { _mm512_broadcast_f64x4(_mm256_loadu_pd(values.as_ptr())) }
        }
        #[inline(always)]
        fn load_rows(self, rows: [&[f64; 4]; 4]) -> __m512d {
            // SAFETY: AVX-512F; 4 values read from each of the first two rows.
            unsafe {
                let low = _mm512_castpd256_pd512(_mm256_loadu_pd(rows[0].as_ptr()));
                _mm512_insertf64x4::<1>(low, _mm256_loadu_pd(rows[1].as_ptr()))
            }
        }
        #[inline(always)]
        fn rsqrt_seed(self, x: __m512d) -> __m512d {
            // SAFETY: AVX-512F.
            unsafe {
                let magic = _mm512_set1_epi64(super::RSQRT_MAGIC_F64 as i64);
                let bits = _mm512_srli_epi64::<1>(_mm512_castpd_si512(x));
                _mm512_castsi512_pd(_mm512_sub_epi64(magic, bits))
            }
        }
        #[inline(always)]
        fn pow2_from_magic(self, y: __m512d) -> __m512d {
            // SAFETY: the token proves the instruction set.
            unsafe {
                let low = _mm512_slli_epi64::<52>(_mm512_castpd_si512(y));
                _mm512_castsi512_pd(_mm512_add_epi64(low, _mm512_set1_epi64(1023 << 52)))
            }
        }
        #[inline(always)]
        fn less(self, a: __m512d, b: __m512d) -> __mmask8 {
            // SAFETY: AVX-512F.
            unsafe { _mm512_cmp_pd_mask::<_CMP_LT_OQ>(a, b) }
        }
        #[inline(always)]
        fn less_equal(self, a: __m512d, b: __m512d) -> __mmask8 {
            // SAFETY: AVX-512F.
            unsafe { _mm512_cmp_pd_mask::<_CMP_LE_OQ>(a, b) }
        }
        #[inline(always)]
        fn abs(self, a: __m512d) -> __m512d {
            // SAFETY: AVX-512F. The sign bit cleared.
            unsafe { _mm512_abs_pd(a) }
        }
        #[inline(always)]
        fn mask(self, bits: u32) -> __mmask8 {
            bits as __mmask8
        }
        #[inline(always)]
        fn and(self, a: __mmask8, b: __mmask8) -> __mmask8 {
            a & b
        }
        #[inline(always)]
        fn select(self, m: __mmask8, a: __m512d, b: __m512d) -> __m512d {
            // SAFETY: AVX-512F. Lanes with the mask bit set take the second operand.
            unsafe { _mm512_mask_blend_pd(m, b, a) }
        }
        #[inline(always)]
        fn bits(self, m: __mmask8) -> u32 {
            m as u32
        }
        #[inline(always)]
        fn fold4(self, v: __m512d, out: &mut [f64; 4]) {
            // SAFETY: AVX-512F/DQ; [r₀+r₂|r₁+r₃] → (r₀+r₂)+(r₁+r₃), added to the 4 values.
            unsafe {
                let low = _mm512_castpd512_pd256(v);
                let high = _mm512_extractf64x4_pd::<1>(v);
                let o = _mm256_loadu_pd(out.as_ptr());
                _mm256_storeu_pd(out.as_mut_ptr(), _mm256_add_pd(o, _mm256_add_pd(low, high)));
            }
        }
    }

    impl Simd for Avx512F32 {
        type R = f32;
        type V = __m512;
        type M = __mmask16;
        const WIDTH: usize = 16;
        common!(
            __m512, f32;
            splat _mm512_set1_ps, load _mm512_loadu_ps, store _mm512_storeu_ps,
            add _mm512_add_ps, sub _mm512_sub_ps, mul _mm512_mul_ps, div _mm512_div_ps,
            sqrt _mm512_sqrt_ps, fma _mm512_fmadd_ps, fnma _mm512_fnmadd_ps, fms _mm512_fmsub_ps
        );
        #[inline(always)]
        fn load4(self, values: &[f32; 4]) -> __m512 {
            // SAFETY: AVX-512F; exactly 4 values are read.
            unsafe { _mm512_broadcast_f32x4(_mm_loadu_ps(values.as_ptr())) }
        }
        #[inline(always)]
        fn load_rows(self, rows: [&[f32; 4]; 4]) -> __m512 {
            // SAFETY: AVX-512F; 4 values read from each of the four rows.
            unsafe {
                let v = _mm512_castps128_ps512(_mm_loadu_ps(rows[0].as_ptr()));
                let v = _mm512_insertf32x4::<1>(v, _mm_loadu_ps(rows[1].as_ptr()));
                let v = _mm512_insertf32x4::<2>(v, _mm_loadu_ps(rows[2].as_ptr()));
                _mm512_insertf32x4::<3>(v, _mm_loadu_ps(rows[3].as_ptr()))
            }
        }
        #[inline(always)]
        fn rsqrt_seed(self, x: __m512) -> __m512 {
            // SAFETY: AVX-512F.
            unsafe {
                let magic = _mm512_set1_epi32(super::RSQRT_MAGIC_F32 as i32);
                let bits = _mm512_srli_epi32::<1>(_mm512_castps_si512(x));
                _mm512_castsi512_ps(_mm512_sub_epi32(magic, bits))
            }
        }
        #[inline(always)]
        fn pow2_from_magic(self, y: __m512) -> __m512 {
            // SAFETY: the token proves the instruction set.
            unsafe {
                let low = _mm512_slli_epi32::<23>(_mm512_castps_si512(y));
                _mm512_castsi512_ps(_mm512_add_epi32(low, _mm512_set1_epi32(127 << 23)))
            }
        }
        #[inline(always)]
        fn less(self, a: __m512, b: __m512) -> __mmask16 {
            // SAFETY: AVX-512F.
            unsafe { _mm512_cmp_ps_mask::<_CMP_LT_OQ>(a, b) }
        }
        #[inline(always)]
        fn less_equal(self, a: __m512, b: __m512) -> __mmask16 {
            // SAFETY: AVX-512F.
            unsafe { _mm512_cmp_ps_mask::<_CMP_LE_OQ>(a, b) }
        }
        #[inline(always)]
        fn abs(self, a: __m512) -> __m512 {
            // SAFETY: AVX-512F. The sign bit cleared.
            unsafe { _mm512_abs_ps(a) }
        }
        #[inline(always)]
        fn mask(self, bits: u32) -> __mmask16 {
            bits as __mmask16
        }
        #[inline(always)]
        fn and(self, a: __mmask16, b: __mmask16) -> __mmask16 {
            a & b
        }
        #[inline(always)]
        fn select(self, m: __mmask16, a: __m512, b: __m512) -> __m512 {
            // SAFETY: AVX-512F. Lanes with the mask bit set take the second operand.
            unsafe { _mm512_mask_blend_ps(m, b, a) }
        }
        #[inline(always)]
        fn bits(self, m: __mmask16) -> u32 {
            m as u32
        }
        #[inline(always)]
        fn fold4(self, v: __m512, out: &mut [f64; 4]) {
            // SAFETY: AVX-512F/DQ; [r₀|r₁|r₂|r₃] → [r₀+r₂|r₁+r₃] → (r₀+r₂)+(r₁+r₃).
            unsafe {
                let low = _mm512_castps512_ps256(v);
                let high = _mm512_extractf32x8_ps::<1>(v);
                let eight = _mm256_add_ps(low, high);
                let four = _mm_add_ps(
                    _mm256_castps256_ps128(eight),
                    _mm256_extractf128_ps::<1>(eight),
                );
                let o = _mm256_loadu_pd(out.as_ptr());
                _mm256_storeu_pd(out.as_mut_ptr(), _mm256_add_pd(o, _mm256_cvtps_pd(four)));
            }
        }
    }
}
