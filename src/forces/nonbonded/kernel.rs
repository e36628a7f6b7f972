//! The cluster-pair kernel: energies and gradients of the 16 atom pairs of each listed
//! cluster pair, SIMD over the pairs (see [`crate::forces::simd`] for the lanes and why
//! every instruction set gives the same bits), no branch on the pair: the cutoff, padding,
//! exclusions and `j > i` are lane masks.
//!
//! Per cluster pair and row of four lanes: `d = x_i − x_j`, `r² = d·d`, the mask, `1/r`
//! by Newton's iteration ([`Simd::rsqrt`]; masked lanes take `r² = 1`, so nothing
//! divides by zero), Lennard-Jones and the
//! Coulomb form as functions of `1/r`, `1/r²` and `r²`, and the scalar force `f = −V′/r`
//! (zero where masked): the i-gradient gains `−f d`, the j-gradient `+f d`. The i-gradients
//! stay in registers over an entry's j-clusters; the j-gradients go to the gradient buffer
//! once per cluster pair. Energies (when asked) are summed per lane in f64.
//!
//! **Only live groups.** About a third of the register groups of a pruned list (4 × 4 pairs
//! within the cutoff plus the prune buffer) have no pair within the cutoff, and on water,
//! two thirds of whose atoms are hydrogens without Lennard-Jones parameters, many groups
//! have only hydrogens as i-atoms (with a type table too: a type whose table row is all
//! zero has no Lennard-Jones lanes, as TIP3P's and Amber's hydroxyl hydrogens). Both would add
//! exact zeros, so an entry's j-clusters go in blocks through three passes: (1) `r²` of
//! every group, keeping the positions of the live ones per group; (2) each group over its
//! live cluster pairs, two side by side, with or without the Lennard-Jones lanes, the
//! i-gradient gaining `−f d` in list order and `f d` waiting in a scratch block; (3) each
//! live cluster pair's j-forces summed over its groups in the canonical order and added to
//! the buffer. Every non-zero term is added in the same order as a pass over all groups
//! would add it: the results are the same bits (`Job::every_group` computes every group;
//! `tests/nonbonded_engine.rs` checks both give the same bits), with a fifth to a quarter
//! fewer floating-point operations.
//!
//! Where one group is the whole cluster pair (AVX-512 in single precision), only an
//! i-cluster without any Lennard-Jones atom skips those lanes, and the grid's z order makes
//! few (6 % of Trp-cage's clusters). GROMACS's nbnxm (Páll & Hess, Comput. Phys. Commun.
//! 184, 2641 (2013)) orders the atoms of a cluster with Lennard-Jones first ("half LJ"), which
//! here helps only the two-group paths (−1 % of the kernel's AVX2 instructions); putting a
//! column's atoms without Lennard-Jones into clusters of their own (slabs of two clusters,
//! Lennard-Jones atoms first) makes the clusters taller and the list 14–16 % longer, for
//! lanes that are 9–20 % of the kernel: Trp-cage's step took 5 % more CPU time, the 5 184-atom
//! PME water box 9.5 % (`docs/data/sittings/kernel-2026-11-29-f.txt`). So the grid keeps the
//! z order.
//!
//! **erfc in the lanes.** The Ewald real space (`Q erfc(αr)/r`) and DSF with α > 0 take
//! `erfc(αr)` and `e^{−α²r²}` from [`erfc_exp`] in the lanes, in both precisions:
//! `erfc(x) = e^{−x²} · P(x)/Q(x)`, `P/Q` a rational fit of the scaled function
//! `erfcx(x) = e^{x²} erfc(x)` on `0 ≤ x ≤ 6.5` (degrees 8/9 in double, 4/5 in single;
//! relative error of the exact rationals 1.4e-17 and 2.0e-9; the fit and its check are
//! `scripts/fit_erfc.py`), `e^{−t}` by range reduction: `n = round(t/ln 2)` by adding
//! `1.5·2^p` in one fused multiply-add, `r = −t − n ln 2` in two fused steps, the Taylor
//! polynomial of `e^r` on `|r| ≤ ln 2/2` (degree 13 in double, 7 in single), `2ⁿ` from the
//! bits by integer shift and add; and `x² = t + δ` with the exact `δ` from a fused
//! multiply-subtract, so that `e^{−x²} = e^{−t}(1 − δ)` to the last bits. Only IEEE add,
//! multiply, divide, fused multiply-add and integer arithmetic: the same bits on every
//! instruction set. Measured against libm on `x ∈ [0, 6.5]` in steps of 1e-5
//! (`tests/nonbonded_engine.rs`): relative error ≤ 8.9e-16 (erfc) and ≤ 4.4e-16 (Gaussian)
//! in double, ≤ 3.8e-7 and ≤ 1.2e-7 in single; the bound the test asserts, derived from the
//! operations there, is 3.0e-15 and 1.8e-6. The pair energy and force are sums and
//! products of positive pieces, so their relative error is within a few ulp of these:
//! ~4e-15 in double, far below PME's own 1e-5 (and single precision's 6e-8 · (2x² + 2)
//! condition of erfc in its rounded argument). The range covers `α r_c ≤ 6.5` (erfc =
//! 3.8e-20 there; α ≤ 0.72 Å⁻¹ at r_c = 9 Å); a larger `α r_c` goes lane by lane through
//! libm, as before, the same bits on every set but 5–8× slower. On the 5 184-atom water
//! box (one thread, AVX-512) a DSF run with α = 0.3466 (erfc in the lanes, no reciprocal
//! sum) takes 1.44× the α = 0 run, and 500 PME steps took 5.75 s instead of 26.1 s in double, 2.29 s instead of 18.6 s in
//! mixed precision (`docs/data/sittings/pme-erfc-2026-11-26.txt`).
//!
//! **The Ewald force without erfc in single precision.** `−V′/r = Q (1/r³ − α³F(α²r²))`
//! with `F` the force of `erf(αr)/r` over `α³`, smooth in `z = α²r²`: [`ewald_force`]
//! takes it as a rational `P(z)/Q(z)` of degrees 6/5 (fitted by
//! `scripts/fit_ewald_force.py` on `z ≤ 16.5`, relative error 7.6e-8; the same idea as
//! GROMACS's `pmecorrF`), about 14 operations against ~40 for erfc and the Gaussian. Its
//! error is absolute, ≤ 1.9e-6 of `Q/r³` (`tests/nonbonded_engine.rs` derives and checks
//! it; measured 9.6 u = 5.7e-7 at Trp-cage's `α r_c` = 3.12), where erfc's route was
//! relative: near the cutoff, where the force is `erfc`-small, the relative error grows (to
//! 2.1e-3 at `α r_c` = 3.12, of a force of 2.2e-4 `Q/r³` that the truncation drops just
//! beyond). Energies
//! (steps that write them, and switched pairs) still take erfc from [`erfc_exp`]. Double
//! precision keeps erfc's route, and `α r_c > 4` (outside the fit) too.
//!
//! **Switched pairs.** The short-range part of a distance split by atom pair
//! ([`crate::forces::distance_split`]) is this kernel with the Coulomb form wrapped in
//! [`Switched`]: its list is cut at `r_out`, the pair energy (Lennard-Jones and Coulomb) is
//! computed for the force too, and [`switch_lanes`] multiplies it by the quintic `S(r)`,
//! `−W′/r = S(−V′/r) − S′V/r` — `SWITCHED` is a constant of the form, so the unswitched
//! kernels compile as before.
//!
//! Mixed precision: the same code with `f32` lanes. The i-positions (with their image
//! shift) are formed in f64 and rounded once, the j-positions are rounded once per
//! evaluation; every cluster pair's contributions go into f64 buffers.

use super::{
    CoulombForm, DampedShiftedForce, EwaldReal, Plain, ReactionField, ShiftedForce,
    TWO_OVER_SQRT_PI,
};
use crate::forces::clusters::{CLUSTER, Cluster, Entry, PairList};
use crate::forces::simd::{Real, Simd, erfc_exp, ewald_force, row, row_lanes, simd_dispatch};

/// Gradient of a cluster's four atoms, in f64.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(32))]
pub struct Gradient4 {
    pub x: [f64; 4],
    pub y: [f64; 4],
    pub z: [f64; 4],
}

/// Lennard-Jones parameters of the clusters.
#[derive(Clone, Copy, Debug)]
pub enum LjData<'a, R> {
    /// `c₁₂ = a_i a_j`, `c₆ = b_i b_j`: per slot `[a₀..a₃, b₀..b₃]`.
    Geometric(&'a [[R; 8]]),
    /// Type per slot and the `n × n` table of `[c₁₂, c₆, shift]`; per j-cluster and
    /// i-type `t` (index `n c_j + t`) the lanes `[12 c₁₂, 6 c₆]` of `t` against the
    /// cluster's atoms, each rounded to `R` and multiplied in `R` as the kernel would; and
    /// per cluster the bits of the slots whose type has a Lennard-Jones partner.
    Table {
        types: &'a [[u32; 4]],
        table: &'a [[R; 3]],
        by_type: &'a [[[R; 4]; 2]],
        lj_rows: &'a [u8],
        n_types: usize,
    },
}

/// One chunk's work: its list and what the kernel reads.
#[derive(Clone, Copy)]
pub struct Job<'a, R> {
    pub list: &'a PairList,
    /// j-side positions and charges in the lanes' precision.
    pub clusters: &'a [Cluster<R>],
    /// i-side positions and charges in f64 (shifted, then rounded).
    pub clusters64: &'a [Cluster<f64>],
    pub shifts: &'a [[f64; 3]; 27],
    pub cutoff2: f64,
    /// `r_c⁻⁶` when the Lennard-Jones energy is shifted, else 0 (geometric parameters).
    pub inverse_cutoff6: f64,
    pub lj: LjData<'a, R>,
    /// Compute every register group, Lennard-Jones lanes included: what the kernel leaves
    /// out must be exact zeros, and tests check the bits do not change.
    pub every_group: bool,
}

/// Where a chunk's results go: the gradient buffer (indexed by cluster) and the
/// Lennard-Jones and Coulomb energies per lane.
pub struct Out<'a> {
    pub gradient: &'a mut [Gradient4],
    pub lj: [f64; 4],
    pub coulomb: [f64; 4],
}

/// A Coulomb form in lanes: `(V, −V′/r)` at `r²` with `1/r`, `1/r²` and `Q = k_e q_i q_j`.
pub trait Coulomb: Copy + Send + Sync {
    /// Whether the pair energy (Lennard-Jones and Coulomb) is multiplied by a switch
    /// ([`Switched`]): then the energy lanes are computed for the force too.
    const SWITCHED: bool = false;

    /// The energy lanes are only meaningful when `ENERGY`.
    fn lanes<S: Simd, const ENERGY: bool>(
        &self,
        s: S,
        qq: S::V,
        r2: S::V,
        rinv: S::V,
        rinv2: S::V,
    ) -> (S::V, S::V);

    /// `(r_in, 1/(r_out − r_in))` of the switch (with `SWITCHED`).
    fn switch_range(&self) -> (f64, f64) {
        (0.0, 0.0)
    }
}

/// A Coulomb form whose pairs, Lennard-Jones included, are multiplied by the quintic
/// switch `S(r)` from 1 at `r_in` to 0 at `r_out` ([`crate::forces::distance_split::Switch`]):
/// `W = S V` and `−W′/r = S (−V′/r) − S′ V/r`, the short-range part of a distance split.
#[derive(Clone, Copy)]
pub struct Switched<C> {
    pub inner: C,
    pub r_in: f64,
    pub inverse_width: f64,
}

impl<C: Coulomb> Coulomb for Switched<C> {
    const SWITCHED: bool = true;

    #[inline(always)]
    fn lanes<S: Simd, const ENERGY: bool>(
        &self,
        s: S,
        qq: S::V,
        r2: S::V,
        rinv: S::V,
        rinv2: S::V,
    ) -> (S::V, S::V) {
        self.inner.lanes::<S, true>(s, qq, r2, rinv, rinv2)
    }

    fn switch_range(&self) -> (f64, f64) {
        (self.r_in, self.inverse_width)
    }
}

/// `(S f + (−S′) V/r, S E_LJ, S E_C)`: the switch of [`Switched`] on a pair's force
/// `f = −V′/r` and energies, `V = E_LJ + E_C`, at `r² = r2`. `S` in the form without
/// cancellation at each end, as [`crate::forces::distance_split::Switch::value_slope`];
/// only add, multiply, fused multiply-add and select: the same bits on every instruction set.
#[inline(always)]
fn switch_lanes<S: Simd>(
    s: S,
    (r_in, inverse_width): (f64, f64),
    (r2, rinv): (S::V, S::V),
    (f, e_lj, e_q): (S::V, S::V, S::V),
) -> (S::V, S::V, S::V) {
    let c = |x: f64| s.splat(S::R::of(x));
    let (zero, one) = (c(0.0), c(1.0));
    let t = s.mul(s.sub(s.mul(r2, rinv), c(r_in)), c(inverse_width));
    let t = s.select(s.less(t, zero), zero, t);
    let t = s.select(s.less(one, t), one, t);
    let u = s.sub(one, t);
    // 10 − 15x + 6x² at x = t and x = u.
    let poly = |x: S::V| s.fma(x, s.fma(x, c(6.0), c(-15.0)), c(10.0));
    let (t2, u2) = (s.mul(t, t), s.mul(u, u));
    let near = s.fnma(s.mul(t2, t), poly(t), one);
    let far = s.mul(s.mul(u2, u), poly(u));
    let switch = s.select(s.less(t, c(0.5)), near, far);
    // −S′ = 30 t² u² / w.
    let minus_slope = s.mul(s.mul(t2, u2), c(30.0 * inverse_width));
    let v = s.add(e_lj, e_q);
    let f = s.fma(s.mul(minus_slope, v), rinv, s.mul(switch, f));
    (f, s.mul(switch, e_lj), s.mul(switch, e_q))
}

/// No Coulomb term.
#[derive(Clone, Copy)]
pub struct NoCoulomb;

impl Coulomb for NoCoulomb {
    #[inline(always)]
    fn lanes<S: Simd, const ENERGY: bool>(
        &self,
        s: S,
        _: S::V,
        _: S::V,
        _: S::V,
        _: S::V,
    ) -> (S::V, S::V) {
        let zero = s.splat(S::R::of(0.0));
        (zero, zero)
    }
}

impl Coulomb for Plain {
    /// `V = Q/r`, `−V′/r = V/r²`.
    #[inline(always)]
    fn lanes<S: Simd, const ENERGY: bool>(
        &self,
        s: S,
        qq: S::V,
        _: S::V,
        rinv: S::V,
        rinv2: S::V,
    ) -> (S::V, S::V) {
        let e = s.mul(qq, rinv);
        (e, s.mul(e, rinv2))
    }
}

impl Coulomb for ShiftedForce {
    /// `V = Q (1/r − 2/r_c + r/r_c²)`, `−V′/r = (Q/r)(1/r² − 1/r_c²)`.
    #[inline(always)]
    fn lanes<S: Simd, const ENERGY: bool>(
        &self,
        s: S,
        qq: S::V,
        r2: S::V,
        rinv: S::V,
        rinv2: S::V,
    ) -> (S::V, S::V) {
        let inv_rc2 = s.splat(S::R::of(self.inv_rc2));
        let f = s.mul(s.mul(qq, rinv), s.sub(rinv2, inv_rc2));
        let mut e = f;
        if ENERGY {
            let two_over_rc = s.splat(S::R::of(self.two_over_rc));
            let r = s.mul(r2, rinv);
            e = s.mul(qq, s.fma(r, inv_rc2, s.sub(rinv, two_over_rc)));
        }
        (e, f)
    }
}

impl Coulomb for ReactionField {
    /// `V = Q (1/r + k r² − c)`, `−V′/r = Q (1/r³ − 2k)`.
    #[inline(always)]
    fn lanes<S: Simd, const ENERGY: bool>(
        &self,
        s: S,
        qq: S::V,
        r2: S::V,
        rinv: S::V,
        rinv2: S::V,
    ) -> (S::V, S::V) {
        let k = s.splat(S::R::of(self.k));
        let c = s.splat(S::R::of(self.c));
        let two_k = s.splat(S::R::of(2.0 * self.k));
        let e = s.mul(qq, s.sub(s.add(rinv, s.mul(k, r2)), c));
        let f = s.mul(qq, s.sub(s.mul(rinv, rinv2), two_k));
        (e, f)
    }
}

impl Coulomb for DampedShiftedForce {
    /// `V = Q (erfc(αr)/r − e_s + (r − r_c) f_s)`, `−V′/r = (Q/r)((erfc(αr)/r + g)/r − f_s)`
    /// with `g = (2α/√π) e^{−α²r²}`, erfc and the Gaussian from [`erfc_exp`] (module doc);
    /// lane by lane through libm where `α r_c` is beyond the fit's range.
    #[inline(always)]
    fn lanes<S: Simd, const ENERGY: bool>(
        &self,
        s: S,
        qq: S::V,
        r2: S::V,
        rinv: S::V,
        _: S::V,
    ) -> (S::V, S::V) {
        if !self.simd {
            let form = |qq, s, inv_r| self.energy_force(qq, s, inv_r);
            return scalar_lanes(s, form, qq, r2, rinv);
        }
        let r = s.mul(r2, rinv);
        let (erfc_r, gauss) = erfc_over_r(s, self.alpha, r, rinv);
        let near = s.mul(s.add(erfc_r, gauss), rinv);
        let f_shift = s.splat(S::R::of(self.f_shift));
        let f = s.mul(s.mul(qq, rinv), s.sub(near, f_shift));
        let mut e = f;
        if ENERGY {
            let rc = s.splat(S::R::of(self.rc));
            let e_shift = s.splat(S::R::of(self.e_shift));
            e = s.mul(qq, s.fma(s.sub(r, rc), f_shift, s.sub(erfc_r, e_shift)));
        }
        (e, f)
    }
}

/// The route of [`EwaldReal`]'s lanes, chosen once per evaluation ([`EwaldReal::route`])
/// and fixed in the kernel's type ([`Ewald`]), so that the group loop tests no flag.
pub(super) mod ewald_route {
    /// Lane by lane through libm (`α r_c` beyond the fit's range).
    pub const SCALAR: u8 = 0;
    /// erfc and the Gaussian from `erfc_exp`, force and energy.
    pub const ERFC: u8 = 1;
    /// Single precision within the rational's range: the force from `ewald_force`.
    pub const RATIONAL: u8 = 2;
}

impl EwaldReal {
    /// The route of the lanes in precision `R`: [`ewald_route`].
    pub(super) fn route<R: Real>(&self) -> u8 {
        if !self.simd {
            ewald_route::SCALAR
        } else if std::mem::size_of::<R>() == 4 && self.rational {
            ewald_route::RATIONAL
        } else {
            ewald_route::ERFC
        }
    }
}

/// [`EwaldReal`] on the route `ROUTE` ([`ewald_route`]); the dispatch builds it only on
/// the route [`EwaldReal::route`] gives, so the results are those of that route.
#[derive(Clone, Copy)]
pub(super) struct Ewald<const ROUTE: u8>(pub(super) EwaldReal);

impl<const ROUTE: u8> Coulomb for Ewald<ROUTE> {
    /// `V = Q erfc(αr)/r`, `−V′/r = (Q/r²)(erfc(αr)/r + (2α/√π) e^{−α²r²})`, erfc and the
    /// Gaussian from [`erfc_exp`] (module doc); lane by lane through libm where `α r_c` is
    /// beyond the fit's range. In single precision with `α r_c ≤ 4` the force is
    /// [`ewald_force`]'s rational `Q (1/r³ − α³F(α²r²))` instead, and erfc is computed
    /// only for the energy (module doc).
    #[inline(always)]
    fn lanes<S: Simd, const ENERGY: bool>(
        &self,
        s: S,
        qq: S::V,
        r2: S::V,
        rinv: S::V,
        rinv2: S::V,
    ) -> (S::V, S::V) {
        let ewald = &self.0;
        if ROUTE == ewald_route::SCALAR {
            let form = |qq, s, inv_r| ewald.energy_force(qq, s, inv_r);
            return scalar_lanes(s, form, qq, r2, rinv);
        }
        let r = s.mul(r2, rinv);
        if ROUTE == ewald_route::RATIONAL && std::mem::size_of::<S::R>() == 4 {
            // Single precision: the force without erfc; the energy only when asked.
            let f = s.mul(qq, ewald_force(s, &ewald.force, r2, rinv, rinv2));
            let mut e = f;
            if ENERGY {
                e = s.mul(qq, erfc_over_r(s, ewald.alpha, r, rinv).0);
            }
            return (e, f);
        }
        let (erfc_r, gauss) = erfc_over_r(s, ewald.alpha, r, rinv);
        let e = s.mul(qq, erfc_r);
        let f = s.mul(s.mul(qq, rinv2), s.add(erfc_r, gauss));
        (e, f)
    }
}

/// The route chosen per call ([`EwaldReal::route`]): for the distance split's lanes, whose
/// precision is a type parameter of the call; the engine fixes the route at dispatch.
impl Coulomb for EwaldReal {
    #[inline(always)]
    fn lanes<S: Simd, const ENERGY: bool>(
        &self,
        s: S,
        qq: S::V,
        r2: S::V,
        rinv: S::V,
        rinv2: S::V,
    ) -> (S::V, S::V) {
        let args = (s, qq, r2, rinv, rinv2);
        match self.route::<S::R>() {
            ewald_route::SCALAR => {
                Ewald::<{ ewald_route::SCALAR }>(*self).lanes_of::<S, ENERGY>(args)
            }
            ewald_route::RATIONAL => {
                Ewald::<{ ewald_route::RATIONAL }>(*self).lanes_of::<S, ENERGY>(args)
            }
            _ => Ewald::<{ ewald_route::ERFC }>(*self).lanes_of::<S, ENERGY>(args),
        }
    }
}

impl<const ROUTE: u8> Ewald<ROUTE> {
    #[inline(always)]
    fn lanes_of<S: Simd, const ENERGY: bool>(
        &self,
        (s, qq, r2, rinv, rinv2): (S, S::V, S::V, S::V, S::V),
    ) -> (S::V, S::V) {
        Coulomb::lanes::<S, ENERGY>(self, s, qq, r2, rinv, rinv2)
    }
}

/// `(erfc(αr)/r, (2α/√π) e^{−α²r²})` in lanes.
#[inline(always)]
fn erfc_over_r<S: Simd>(s: S, alpha: f64, r: S::V, rinv: S::V) -> (S::V, S::V) {
    let (erfc, e) = erfc_exp(s, s.mul(s.splat(S::R::of(alpha)), r));
    let g = s.splat(S::R::of(TWO_OVER_SQRT_PI * alpha));
    (s.mul(erfc, rinv), s.mul(g, e))
}

/// `(V, −V′/r)` lane by lane in f64 through a scalar form.
#[inline(always)]
fn scalar_lanes<S: Simd>(
    s: S,
    form: impl Fn(f64, f64, f64) -> (f64, f64),
    qq: S::V,
    r2: S::V,
    rinv: S::V,
) -> (S::V, S::V) {
    {
        let (mut q, mut r, mut i) = (
            [S::R::default(); 16],
            [S::R::default(); 16],
            [S::R::default(); 16],
        );
        s.store(qq, &mut q);
        s.store(r2, &mut r);
        s.store(rinv, &mut i);
        let (mut e, mut f) = ([S::R::default(); 16], [S::R::default(); 16]);
        for k in 0..S::WIDTH {
            let (ek, fk) = form(q[k].to_f64(), r[k].to_f64(), i[k].to_f64());
            e[k] = S::R::of(ek);
            f[k] = S::R::of(fk);
        }
        (s.load(&e), s.load(&f))
    }
}

/// Lennard-Jones in lanes: per-group i data, per-cluster j data, and at `1/r²` the energy
/// (when `ENERGY`) and `(r⁻⁸, 12 c₁₂ r⁻⁶ − 6 c₆)`, whose product is `−V′/r` (left to the
/// caller to fuse with the Coulomb force).
pub trait Lj<S: Simd>: Copy {
    type I: Copy;
    type J: Copy;
    fn i(&self, s: S, ci: usize, group: usize) -> Self::I;
    fn j(&self, s: S, cj: usize) -> Self::J;
    /// Whether an i-atom of the group has Lennard-Jones parameters (when not, its lanes are
    /// exact zeros and the kernel leaves them out).
    fn has_lj(&self, ci: usize, group: usize) -> bool;
    fn lanes<const ENERGY: bool>(
        &self,
        s: S,
        i: &Self::I,
        j: &Self::J,
        rinv2: S::V,
    ) -> (S::V, S::V, S::V);
}

/// Geometric Lennard-Jones lanes: `12 c₁₂ = (12 A_i) A_j`, `6 c₆ = (6 B_i) B_j`.
#[derive(Clone, Copy)]
struct Geometric<'a, S: Simd> {
    params: &'a [[S::R; 8]],
    inverse_cutoff6: S::V,
    twelve: S::V,
    six: S::V,
}

impl<S: Simd> Lj<S> for Geometric<'_, S> {
    /// `(12 A_i, 6 B_i)` lanes.
    type I = (S::V, S::V);
    type J = (S::V, S::V);
    #[inline(always)]
    fn i(&self, s: S, ci: usize, group: usize) -> (S::V, S::V) {
        let p = &self.params[ci];
        let mut a = [S::R::default(); 16];
        let mut b = [S::R::default(); 16];
        for k in 0..S::WIDTH {
            a[k] = p[row::<S>(group, k)];
            b[k] = p[4 + row::<S>(group, k)];
        }
        (s.mul(self.twelve, s.load(&a)), s.mul(self.six, s.load(&b)))
    }
    #[inline(always)]
    fn has_lj(&self, ci: usize, group: usize) -> bool {
        let p = &self.params[ci];
        let zero = S::R::of(0.0);
        (0..S::WIDTH).any(|k| {
            let row = row::<S>(group.min(16 / S::WIDTH - 1), k);
            p[row] != zero || p[4 + row] != zero
        })
    }
    #[inline(always)]
    fn j(&self, s: S, cj: usize) -> (S::V, S::V) {
        let p = &self.params[cj];
        let (a, b) = p.split_at(4);
        (
            s.load4(a.try_into().expect("four")),
            s.load4(b.try_into().expect("four")),
        )
    }
    #[inline(always)]
    fn lanes<const ENERGY: bool>(
        &self,
        s: S,
        i: &Self::I,
        j: &Self::J,
        rinv2: S::V,
    ) -> (S::V, S::V, S::V) {
        let c12x12 = s.mul(i.0, j.0);
        let c6x6 = s.mul(i.1, j.1);
        let (rinv8, rinv6, bracket) = lennard_jones_force(s, c12x12, c6x6, rinv2);
        let mut energy = rinv8;
        if ENERGY {
            let c12 = s.div(c12x12, self.twelve);
            let c6 = s.div(c6x6, self.six);
            let shift = s.mul(
                s.sub(s.mul(c12, self.inverse_cutoff6), c6),
                self.inverse_cutoff6,
            );
            energy = lennard_jones_energy(s, c12, c6, shift, rinv6);
        }
        (energy, rinv8, bracket)
    }
}

/// `(r⁻⁸, r⁻⁶, 12 c₁₂ r⁻⁶ − 6 c₆)`: `−V′/r` is the product of the first and last.
#[inline(always)]
pub(crate) fn lennard_jones_force<S: Simd>(
    s: S,
    c12x12: S::V,
    c6x6: S::V,
    rinv2: S::V,
) -> (S::V, S::V, S::V) {
    let rinv4 = s.mul(rinv2, rinv2);
    let rinv6 = s.mul(rinv4, rinv2);
    let rinv8 = s.mul(rinv4, rinv4);
    (rinv8, rinv6, s.fms(c12x12, rinv6, c6x6))
}

/// `V = r⁻⁶(c₁₂ r⁻⁶ − c₆) − shift`.
#[inline(always)]
pub(crate) fn lennard_jones_energy<S: Simd>(
    s: S,
    c12: S::V,
    c6: S::V,
    shift: S::V,
    rinv6: S::V,
) -> S::V {
    s.sub(s.mul(rinv6, s.sub(s.mul(c12, rinv6), c6)), shift)
}

/// Tabulated Lennard-Jones lanes. Forces read, per j-cluster and i-type, the four lanes
/// `(12 c₁₂, 6 c₆)` of that type against the cluster's atoms ([`LjData::Table`]'s `by_type`,
/// made at each list build): one vector load per row, no gather per pair. Energies gather
/// `c₁₂, c₆` and the shift per pair from the table (they are asked for rarely).
#[derive(Clone, Copy)]
struct Table<'a, S: Simd> {
    types: &'a [[u32; 4]],
    table: &'a [[S::R; 3]],
    by_type: &'a [[[S::R; 4]; 2]],
    lj_rows: &'a [u8],
    n_types: usize,
    twelve: S::V,
    six: S::V,
}

impl<S: Simd> Lj<S> for Table<'_, S> {
    /// Type of each row of the group (rows past the register's repeat the last).
    type I = [usize; 4];
    /// The j-cluster.
    type J = usize;
    #[inline(always)]
    fn i(&self, _s: S, ci: usize, group: usize) -> [usize; 4] {
        std::array::from_fn(|r| {
            let r = r.min(S::WIDTH / 4 - 1);
            self.types[ci][row::<S>(group, 4 * r)] as usize
        })
    }
    #[inline(always)]
    fn j(&self, _s: S, cj: usize) -> usize {
        cj
    }
    /// Whether a row atom of the group has a type with a Lennard-Jones partner (else its
    /// lanes are exact zeros): bit `row` of `lj_rows`.
    #[inline(always)]
    fn has_lj(&self, ci: usize, group: usize) -> bool {
        let group = group.min(16 / S::WIDTH - 1);
        let rows = ((1u32 << (S::WIDTH / 4)) - 1) << (group * (S::WIDTH / 4));
        u32::from(self.lj_rows[ci]) & rows != 0
    }
    #[inline(always)]
    fn lanes<const ENERGY: bool>(
        &self,
        s: S,
        i: &Self::I,
        &cj: &Self::J,
        rinv2: S::V,
    ) -> (S::V, S::V, S::V) {
        if ENERGY {
            let j = &self.types[cj];
            let mut p = [[S::R::default(); 16]; 3];
            for k in 0..S::WIDTH {
                let entry = self.table[i[k / 4] * self.n_types + j[k % 4] as usize];
                for (c, &v) in entry.iter().enumerate() {
                    p[c][k] = v;
                }
            }
            let (c12, c6) = (s.load(&p[0]), s.load(&p[1]));
            let (c12x12, c6x6) = (s.mul(self.twelve, c12), s.mul(self.six, c6));
            let (rinv8, rinv6, bracket) = lennard_jones_force(s, c12x12, c6x6, rinv2);
            let energy = lennard_jones_energy(s, c12, c6, s.load(&p[2]), rinv6);
            return (energy, rinv8, bracket);
        }
        let at = |r: usize| &self.by_type[cj * self.n_types + i[r]];
        // Rows past the register's (`r ≥ WIDTH / 4`, not read) repeat its last: one lookup.
        let rows: [_; 4] = std::array::from_fn(|r| at(r.min(S::WIDTH / 4 - 1)));
        let c12x12 = s.load_rows(rows.map(|p| &p[0]));
        let c6x6 = s.load_rows(rows.map(|p| &p[1]));
        let (rinv8, _, bracket) = lennard_jones_force(s, c12x12, c6x6, rinv2);
        (rinv8, rinv8, bracket)
    }
}

/// The i-cluster of an entry in lanes: positions (shifted), charges, Lennard-Jones data, one
/// register per group.
struct Rows<S: Simd, I> {
    x: [S::V; 4],
    y: [S::V; 4],
    z: [S::V; 4],
    q: [S::V; 4],
    lj: [I; 4],
}

/// Splatted constants.
#[derive(Clone, Copy)]
struct Constants<S: Simd> {
    zero: S::V,
    one: S::V,
    cutoff2: S::V,
    /// No lane and every lane: a dead and a live group's mask in pass 3.
    lanes: [S::M; 2],
}

#[inline(always)]
fn rows<S: Simd, L: Lj<S>>(s: S, job: &Job<S::R>, lj: &L, entry: &Entry) -> Rows<S, L::I> {
    let c = &job.clusters64[entry.ci as usize];
    let shift = &job.shifts[entry.shift as usize];
    let ci = entry.ci as usize;
    let last = 16 / S::WIDTH - 1;
    let zero = s.splat(S::R::of(0.0));
    let mut rows = Rows {
        x: [zero; 4],
        y: [zero; 4],
        z: [zero; 4],
        q: [zero; 4],
        lj: [lj.i(s, ci, 0); 4],
    };
    for g in 0..4 {
        rows.x[g] = row_lanes(s, &c.x, shift[0], g);
        rows.y[g] = row_lanes(s, &c.y, shift[1], g);
        rows.z[g] = row_lanes(s, &c.z, shift[2], g);
        rows.q[g] = row_lanes(s, &c.q, 0.0, g);
        rows.lj[g] = lj.i(s, ci, g.min(last));
    }
    rows
}

/// Add the i-gradients of an entry to the buffer: per row, lanes `(l₀ + l₂) + (l₁ + l₃)`.
#[inline(always)]
pub(crate) fn finish_rows<S: Simd>(s: S, gi: &[[S::V; 3]; 4], out: &mut Gradient4) {
    for (g, components) in gi.iter().enumerate().take(16 / S::WIDTH) {
        for (d, &v) in components.iter().enumerate() {
            let mut lanes = [S::R::default(); 16];
            s.store(v, &mut lanes);
            for r in 0..S::WIDTH / 4 {
                let l = |k: usize| lanes[4 * r + k].to_f64();
                let sum = (l(0) + l(2)) + (l(1) + l(3));
                let target = match d {
                    0 => &mut out.x,
                    1 => &mut out.y,
                    _ => &mut out.z,
                };
                target[g * (S::WIDTH / 4) + r] += sum;
            }
        }
    }
}

/// `acc[g % 2] (+)= v`: rows 0, 2 and 1, 3 apart (the canonical order, module doc of simd).
#[inline(always)]
pub(crate) fn gather<S: Simd>(s: S, acc: &mut [S::V; 2], group: usize, v: S::V) {
    if group < 2 {
        acc[group] = v;
    } else {
        acc[group % 2] = s.add(acc[group % 2], v);
    }
}

/// A group's pair forces `f d` (`f = −V′/r`, `d = x_i − x_j`): `−f d` into the row atoms'
/// gradients `gi`, `+f d` into the column sums `fj` in the canonical row order.
#[inline(always)]
pub(crate) fn add_pair_force<S: Simd>(
    s: S,
    f: S::V,
    d: [S::V; 3],
    group: usize,
    gi: &mut [S::V; 3],
    fj: &mut [[S::V; 2]; 3],
) {
    for c in 0..3 {
        let fd = s.mul(f, d[c]);
        gi[c] = s.sub(gi[c], fd);
        gather(s, &mut fj[c], group, fd);
    }
}

#[inline(always)]
pub(crate) fn combine<S: Simd>(s: S, acc: &[S::V; 2]) -> S::V {
    if 16 / S::WIDTH == 1 {
        acc[0]
    } else {
        s.add(acc[0], acc[1])
    }
}

/// Cluster pairs per pass of [`entries`]: a block's j-forces wait in [`Scratch`] until
/// its last group is done.
const BLOCK: usize = 32;

/// Per block position and group: the j-forces `f d` (x, y, z) and, with energies, the
/// Lennard-Jones and Coulomb energy lanes.
type Scratch<S> = [[[<S as Simd>::V; 5]; 4]; BLOCK];

/// Pass 1 of a block: which groups of which cluster pairs have a pair within the cutoff.
struct Live {
    /// Per group, the block positions where it has one, in list order.
    groups: [[u8; BLOCK]; 4],
    counts: [usize; 4],
    /// Per block position, bit `g` set where group `g` has one.
    bits: [u8; BLOCK],
    /// Block positions where any group has one, in list order.
    any: [u8; BLOCK],
    any_count: usize,
}

/// `d = x_i − x_j` of a group and `r² = d·d`: the same operations in both passes.
#[inline(always)]
fn separation<S: Simd, I>(s: S, rows: &Rows<S, I>, g: usize, j: [S::V; 3]) -> ([S::V; 3], S::V) {
    let dx = s.sub(rows.x[g], j[0]);
    let dy = s.sub(rows.y[g], j[1]);
    let dz = s.sub(rows.z[g], j[2]);
    ([dx, dy, dz], s.fma(dz, dz, s.fma(dy, dy, s.mul(dx, dx))))
}

/// Every lane of a register set: the low `S::WIDTH` bits.
#[inline(always)]
fn all_lanes<S: Simd>() -> u32 {
    if S::WIDTH >= 16 {
        0xFFFF
    } else {
        (1u32 << S::WIDTH) - 1
    }
}

/// The pairs of a group to compute: the list's mask bits of the group, within the cutoff.
#[inline(always)]
fn within<S: Simd>(s: S, k: &Constants<S>, mask: u16, g: usize, r2: S::V) -> S::M {
    let bits = (mask as u32 >> (g * S::WIDTH)) & all_lanes::<S>();
    s.and(s.mask(bits), s.less(r2, k.cutoff2))
}

#[inline(always)]
fn positions<S: Simd>(s: S, j: &Cluster<S::R>) -> [S::V; 3] {
    [s.load4(&j.x), s.load4(&j.y), s.load4(&j.z)]
}

/// Pass 1: the live groups of a block (cluster pairs `js`): those with a pair within the
/// cutoff, the list's mask not consulted. A group with no pair within the cutoff contributes
/// exact zeros, so leaving it out changes no bit; a group whose pairs within the cutoff are
/// all masked (excluded, `j ≤ i` in a self pair) is computed and adds zeros of either sign,
/// which change no sum that is not zero and leave a zero sum `+0` (every buffer starts at
/// `+0`): the same bits either way, without the mask's four instructions per group here.
/// Indices are taken modulo [`BLOCK`] (they are below it): an `and`, not a bounds check.
#[inline(always)]
#[allow(clippy::needless_range_loop)] // `g` indexes four arrays
fn live<S: Simd, I>(
    s: S,
    k: &Constants<S>,
    rows: &Rows<S, I>,
    clusters: &[Cluster<S::R>],
    js: &[u32],
    (every, live): (bool, &mut Live),
) {
    // Counters in registers, not through `live`.
    let (mut counts, mut any_count) = ([0; 4], 0);
    for (p, &cj) in js.iter().enumerate() {
        let j = positions(s, &clusters[cj as usize]);
        let mut any = 0u8;
        for g in 0..16 / S::WIDTH {
            let (_, r2) = separation(s, rows, g, j);
            let alive = every || s.bits(s.less(r2, k.cutoff2)) != 0;
            live.groups[g][counts[g] % BLOCK] = p as u8;
            counts[g] += usize::from(alive);
            any |= u8::from(alive) << g;
        }
        live.bits[p % BLOCK] = any;
        live.any[any_count % BLOCK] = p as u8;
        any_count += usize::from(any != 0);
    }
    (live.counts, live.any_count) = (counts, any_count);
}

/// One group against one cluster pair (block position `p`): `[f d, E_LJ, E_C]`, zero
/// outside the cutoff. `LJ` false: the group's i-atoms have no Lennard-Jones parameters,
/// whose lanes would be exact zeros.
#[inline(always)]
fn group_pair<S: Simd, C: Coulomb, L: Lj<S>, const LJ: bool, const ENERGY: bool>(
    s: S,
    k: &Constants<S>,
    (coulomb, lj): (C, &L),
    rows: &Rows<S, L::I>,
    g: usize,
    (job, js, masks): (&Job<S::R>, &[u32], &[u16]),
    p: usize,
) -> [S::V; 5] {
    let cj = js[p] as usize;
    let j = &job.clusters[cj];
    let (d, r2) = separation(s, rows, g, positions(s, j));
    let m = within(s, k, masks[p], g, r2);
    let r2 = s.select(m, r2, k.one);
    let rinv = s.rsqrt(r2);
    let rinv2 = s.mul(rinv, rinv);
    let qq = s.mul(rows.q[g], s.load4(&j.q));
    let (mut e_q, f_q) = coulomb.lanes::<S, ENERGY>(s, qq, r2, rinv, rinv2);
    let (mut f, mut e_lj) = (f_q, k.zero);
    if LJ {
        let (i, j) = (&rows.lj[g], &lj.j(s, cj));
        let (e, rinv8, bracket) = if C::SWITCHED {
            lj.lanes::<true>(s, i, j, rinv2)
        } else {
            lj.lanes::<ENERGY>(s, i, j, rinv2)
        };
        (f, e_lj) = (s.fma(rinv8, bracket, f_q), e);
    }
    if C::SWITCHED {
        (f, e_lj, e_q) = switch_lanes(s, coulomb.switch_range(), (r2, rinv), (f, e_lj, e_q));
    }
    let f = s.select(m, f, k.zero);
    let mut out = [k.zero; 5];
    for c in 0..3 {
        out[c] = s.mul(f, d[c]);
    }
    if ENERGY {
        out[3] = s.select(m, e_lj, k.zero);
        out[4] = s.select(m, e_q, k.zero);
    }
    out
}

/// Pass 2: group `g` against the cluster pairs of its stream, two at a time (independent
/// work side by side). The i-gradient gains `−f d` in list order; `f d` waits in the
/// scratch for pass 3.
#[inline(always)]
fn group<S: Simd, C: Coulomb, L: Lj<S>, const LJ: bool, const ENERGY: bool>(
    s: S,
    k: &Constants<S>,
    terms: (C, &L),
    rows: &Rows<S, L::I>,
    (g, stream): (usize, &[u8]),
    data: (&Job<S::R>, &[u32], &[u16]),
    (gi, scratch): (&mut [S::V; 3], &mut Scratch<S>),
) {
    let one = |p: u8| group_pair::<S, C, L, LJ, ENERGY>(s, k, terms, rows, g, data, p as usize);
    let mut sum = *gi;
    let mut add = |p: u8, v: [S::V; 5]| {
        for c in 0..3 {
            sum[c] = s.sub(sum[c], v[c]);
        }
        // Without energies only the three force parts are read in pass 3.
        let parts = if ENERGY { 5 } else { 3 };
        scratch[p as usize % BLOCK][g][..parts].copy_from_slice(&v[..parts]);
    };
    let mut pairs = stream.chunks_exact(2);
    for two in &mut pairs {
        let (a, b) = (one(two[0]), one(two[1]));
        add(two[0], a);
        add(two[1], b);
    }
    for &p in pairs.remainder() {
        add(p, one(p));
    }
    *gi = sum;
}

/// Pass 3: each live cluster pair's j-forces (and energies), its groups summed in the
/// canonical order (a dead group as zero), into the buffer.
#[inline(always)]
#[allow(clippy::needless_range_loop)] // `g` indexes the bits and the scratch
fn fold_block<S: Simd, const ENERGY: bool>(
    s: S,
    k: &Constants<S>,
    live: &Live,
    js: &[u32],
    scratch: &Scratch<S>,
    out: &mut Out,
) {
    for &p in &live.any[..live.any_count] {
        let p = p as usize % BLOCK;
        let mut acc = [[k.zero; 2]; 5];
        for g in 0..16 / S::WIDTH {
            let alive = k.lanes[usize::from(live.bits[p] >> g & 1)];
            let parts = if ENERGY { 5 } else { 3 };
            for (c, acc) in acc.iter_mut().enumerate().take(parts) {
                gather(s, acc, g, s.select(alive, scratch[p][g][c], k.zero));
            }
        }
        let gj = &mut out.gradient[js[p] as usize];
        s.fold4(combine(s, &acc[0]), &mut gj.x);
        s.fold4(combine(s, &acc[1]), &mut gj.y);
        s.fold4(combine(s, &acc[2]), &mut gj.z);
        if ENERGY {
            s.fold4(combine(s, &acc[3]), &mut out.lj);
            s.fold4(combine(s, &acc[4]), &mut out.coulomb);
        }
    }
}

/// One entry: its j-clusters in blocks, each in the three passes.
#[inline(always)]
fn entry<S: Simd, C: Coulomb, L: Lj<S>, const ENERGY: bool>(
    s: S,
    k: &Constants<S>,
    (job, coulomb, lj): (&Job<S::R>, C, &L),
    entry: &Entry,
    (state, scratch): (&mut Live, &mut Scratch<S>),
    out: &mut Out,
) {
    let rows = rows(s, job, lj, entry);
    let mut gi = [[k.zero; 3]; 4];
    let range = entry.start as usize..entry.end as usize;
    let has_lj: [bool; 4] =
        std::array::from_fn(|g| job.every_group || lj.has_lj(entry.ci as usize, g));
    for (js, masks) in job.list.j[range.clone()]
        .chunks(BLOCK)
        .zip(job.list.masks[range].chunks(BLOCK))
    {
        live(s, k, &rows, job.clusters, js, (job.every_group, state));
        for g in 0..16 / S::WIDTH {
            let which = (g, &state.groups[g][..state.counts[g]]);
            let data = (job, js, masks);
            // One call, instantiated with and without the Lennard-Jones lanes.
            macro_rules! group_with {
                ($lj:literal) => {
                    group::<S, C, L, $lj, ENERGY>(
                        s,
                        k,
                        (coulomb, lj),
                        &rows,
                        which,
                        data,
                        (&mut gi[g], scratch),
                    )
                };
            }
            if has_lj[g] {
                group_with!(true)
            } else {
                group_with!(false)
            }
        }
        fold_block::<S, ENERGY>(s, k, state, js, scratch, out);
    }
    finish_rows(s, &gi, &mut out.gradient[entry.ci as usize]);
}

/// Every entry of the job's list.
#[inline(always)]
fn entries<S: Simd, C: Coulomb, L: Lj<S>, const ENERGY: bool>(
    s: S,
    job: &Job<S::R>,
    coulomb: C,
    lj: L,
    out: &mut Out,
) {
    let k = Constants::<S> {
        zero: s.splat(S::R::of(0.0)),
        one: s.splat(S::R::of(1.0)),
        cutoff2: s.splat(S::R::of(job.cutoff2)),
        lanes: [s.mask(0), s.mask(all_lanes::<S>())],
    };
    let mut state = Live {
        groups: [[0; BLOCK]; 4],
        counts: [0; 4],
        bits: [0; BLOCK],
        any: [0; BLOCK],
        any_count: 0,
    };
    let mut scratch: Scratch<S> = [[[k.zero; 5]; 4]; BLOCK];
    for e in &job.list.entries {
        let parts = (&mut state, &mut scratch);
        entry::<S, C, L, ENERGY>(s, &k, (job, coulomb, &lj), e, parts, out);
    }
}

/// The job with the Lennard-Jones form of its data.
#[inline(always)]
fn run<S: Simd, C: Coulomb, const ENERGY: bool>(s: S, job: &Job<S::R>, coulomb: C, out: &mut Out) {
    let twelve = s.splat(S::R::of(12.0));
    let six = s.splat(S::R::of(6.0));
    match job.lj {
        LjData::Geometric(params) => {
            let lj = Geometric::<S> {
                params,
                inverse_cutoff6: s.splat(S::R::of(job.inverse_cutoff6)),
                twelve,
                six,
            };
            entries::<S, C, _, ENERGY>(s, job, coulomb, lj, out)
        }
        LjData::Table {
            types,
            table,
            by_type,
            lj_rows,
            n_types,
        } => {
            let lj = Table::<S> {
                types,
                table,
                by_type,
                lj_rows,
                n_types,
                twelve,
                six,
            };
            entries::<S, C, _, ENERGY>(s, job, coulomb, lj, out)
        }
    }
}

simd_dispatch! {
    /// The kernel on the instruction set `isa`, in the job's precision.
    pub fn evaluate[R: Real, C: Coulomb, const ENERGY: bool][R, C, ENERGY](
        job: &Job<R>,
        coulomb: C,
        out: &mut Out,
    ) = run::<_, C, ENERGY>, lanes R;
}

const _: () = assert!(
    CLUSTER == 4,
    "the kernel's rows and masks assume clusters of four"
);
