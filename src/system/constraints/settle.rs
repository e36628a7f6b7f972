//! SETTLE (MK92): a rigid three-site water moved onto its constraints analytically.
//!
//! **Positions.** The constraint forces of a water lie in the plane of its old positions
//! and conserve its centre of mass and (about the old positions) its angular momentum.
//! In a frame with the new centre of mass `d` at the origin, `z` normal to the old plane,
//! and the new oxygen in the `y–z` plane, the out-of-plane coordinates are therefore
//! unchanged, which fixes two tilt angles of the rigid triangle (MK92 (A1)–(A3)):
//! `sin φ = z_O / r_a` and `sin ψ = (z_H₁ − z_H₂) / (2 r_c cos φ)`, where the canonical
//! triangle has the oxygen at `(0, r_a, 0)` and the hydrogens at `(∓r_c, −r_b, 0)` about
//! its centre of mass (`r_c = d_HH/2`, `r_a + r_b = √(d_OH² − r_c²)`, `m_O r_a = 2 m_H r_b`).
//! The in-plane turn `θ` follows from the vanishing torque of the constraint forces about
//! the old positions, `α sin θ + β cos θ = γ` (MK92 (A8)–(A10); the root near `θ = 0`).
//! The momenta take `Δp = m Δq / dt`.
//!
//! **Velocities.** The three conditions `rₐᵦ·(vₐ − vᵦ) = 0` are linear in the three
//! multipliers of the impulses `λₐᵦ rₐᵦ`; the symmetric 3×3 system is solved exactly (by
//! its adjugate)
//! (MK92's analytic velocity step, what RATTLE's iteration on the three distances converges
//! to).
//!
//! Cost: ~200 flops per water for positions, ~100 for velocities; to round-off. What
//! depends only on a water's geometry and masses (`r_a`, `r_b`, `r_c`, the masses and their
//! inverses) is computed once ([`Settle::new`]) and kept by [`super::Constraints`]; a pass
//! is a loop over these flat records with no allocation, the minimum image taken once per
//! bond (the H–H vector is the difference of the two O–H ones).
//!
//! **Lanes.** A pass over all waters ([`positions_all`], [`velocities_all`]) takes the
//! waters a register of SIMD lanes at a time (8 with AVX-512, 4 with AVX2 or on the
//! portable path; [`Isa::best`]): their coordinates and constants are gathered into lanes,
//! one branch-free step runs in the crate's lane operations ([`Simd`], through the
//! operators of [`L`]; the checks become bit masks, the minimum image
//! [`near_image`]'s compare and select), and the changes are scattered back and added
//! once every water of a block of [`LANES`] has passed. Plain IEEE arithmetic (add,
//! subtract, multiply, divide, square root; no fused multiply-add) in the order of the
//! formulas above, so every lane and every instruction set gives the same bits; one
//! water alone ([`positions`]) is the pass on the portable path with one water, which the
//! unit tests set against every lane of every set. A failing lane is reported with its
//! water.

use std::ops::{Add, Div, Mul, Sub};

use super::{ConstraintFailure, PeriodicBox, RigidWater};
use crate::forces::near_image;
use crate::forces::scratch::{Scratch, parallel};
use crate::forces::simd::{Isa, Simd, simd_dispatch};

type V3 = [f64; 3];

/// A register of SIMD lanes (one water each) with the lanes' IEEE operations as operators,
/// so that a formula reads, and rounds, as it does for one water.
struct L<S: Simd<R = f64>> {
    s: S,
    v: S::V,
}

impl<S: Simd<R = f64>> Clone for L<S> {
    #[inline(always)]
    fn clone(&self) -> Self {
        *self
    }
}

impl<S: Simd<R = f64>> Copy for L<S> {}

impl<S: Simd<R = f64>> L<S> {
    /// `x` in every lane.
    #[inline(always)]
    fn splat(s: S, x: f64) -> Self {
        L { s, v: s.splat(x) }
    }
    #[inline(always)]
    fn with(self, v: S::V) -> Self {
        L { s: self.s, v }
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        self.with(self.s.sqrt(self.v))
    }
    #[inline(always)]
    fn abs(self) -> Self {
        self.with(self.s.abs(self.v))
    }
    /// `−self`, exactly (a multiplication by −1).
    #[inline(always)]
    fn neg(self) -> Self {
        self * L::splat(self.s, -1.0)
    }
    /// Bit `l` set where lane `l` of `self < b` (false at NaN).
    #[inline(always)]
    fn below(self, b: Self) -> u32 {
        self.s.bits(self.s.less(self.v, b.v))
    }
    /// Bit `l` set where lane `l` of `self ≤ b` (false at NaN).
    #[inline(always)]
    fn at_most(self, b: Self) -> u32 {
        self.s.bits(self.s.less_equal(self.v, b.v))
    }
}

/// The operators of [`L`]: one lane operation each.
macro_rules! lane_operator {
    ($($trait:ident $method:ident),*) => {$(
        impl<S: Simd<R = f64>> $trait for L<S> {
            type Output = Self;
            #[inline(always)]
            fn $method(self, b: Self) -> Self {
                self.with(self.s.$method(self.v, b.v))
            }
        }
    )*};
}
lane_operator!(Add add, Sub sub, Mul mul, Div div);

/// Arithmetic of one water's numbers: `f64`, or [`L`]'s lanes.
trait Arith: Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> {}
impl Arith for f64 {}
impl<S: Simd<R = f64>> Arith for L<S> {}

#[inline(always)]
fn sub<T: Arith>(a: [T; 3], b: [T; 3]) -> [T; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline(always)]
fn add<T: Arith>(a: [T; 3], b: [T; 3]) -> [T; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

#[inline(always)]
fn scale<T: Arith>(a: [T; 3], s: T) -> [T; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}

#[inline(always)]
fn dot<T: Arith>(a: [T; 3], b: [T; 3]) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline(always)]
fn cross<T: Arith>(a: [T; 3], b: [T; 3]) -> [T; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `−a`, exactly (a multiplication by −1 in each lane).
#[inline(always)]
fn neg<S: Simd<R = f64>>(a: [L<S>; 3]) -> [L<S>; 3] {
    [a[0].neg(), a[1].neg(), a[2].neg()]
}

#[inline(always)]
fn add_to(q: &mut [f64], i: usize, v: V3) {
    let x = &mut q[3 * i..3 * i + 3];
    x[0] += v[0];
    x[1] += v[1];
    x[2] += v[2];
}

/// One rigid water with what SETTLE needs of it, computed once for its masses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settle {
    pub oxygen: usize,
    pub hydrogens: [usize; 2],
    /// Inverse masses of the oxygen and of each hydrogen.
    w_o: f64,
    w_h: f64,
    m_o: f64,
    m_h: f64,
    /// `m_H / (m_O + 2 m_H)`: a hydrogen's weight in the centre of mass.
    h_share: f64,
    /// The canonical triangle: oxygen at `(0, r_a, 0)`, hydrogens at `(∓r_c, −r_b, 0)`.
    ra: f64,
    rb: f64,
    rc: f64,
}

impl Settle {
    /// The constants of `water` for the inverse masses `inverse_mass` (3 per particle; its
    /// hydrogens weigh the same, [`super::Constraints::check_masses`]).
    pub fn new(water: &RigidWater, inverse_mass: &[f64]) -> Self {
        let [h1, _] = water.hydrogens;
        Settle::with_masses(water, inverse_mass[3 * water.oxygen], inverse_mass[3 * h1])
    }

    /// The constants of `water` for the inverse masses `w_o` and `w_h` (NaN: none yet,
    /// [`Settle::fits`] no masses).
    pub fn with_masses(water: &RigidWater, w_o: f64, w_h: f64) -> Self {
        let [h1, h2] = water.hydrogens;
        let (m_o, m_h) = (1.0 / w_o, 1.0 / w_h);
        let h_share = m_h / (m_o + 2.0 * m_h);
        let rc = 0.5 * water.hh;
        let height = (water.oh * water.oh - rc * rc).sqrt();
        let ra = 2.0 * h_share * height;
        Settle {
            oxygen: water.oxygen,
            hydrogens: [h1, h2],
            w_o,
            w_h,
            m_o,
            m_h,
            h_share,
            ra,
            rb: height - ra,
            rc,
        }
    }

    /// Whether these constants were computed for the masses `inverse_mass`.
    pub fn fits(&self, inverse_mass: &[f64]) -> bool {
        let [h1, h2] = self.hydrogens;
        inverse_mass[3 * self.oxygen] == self.w_o
            && inverse_mass[3 * h1] == self.w_h
            && inverse_mass[3 * h2] == self.w_h
    }
}

/// Waters per block of a SETTLE pass: a failing water leaves its block unapplied
/// ([`apply_changes`]). A multiple of every lane width (8 doubles: one AVX-512 register,
/// two AVX2 ones or two of the portable path).
const LANES: usize = 8;

/// Why a water could not be SETTLE'd (0: it could).
const OK: u8 = 0;
const COLLINEAR: u8 = 1;
const OXYGEN_OUT: u8 = 2;
const HYDROGENS_OUT: u8 = 3;
const TURNED: u8 = 4;
const SINGULAR: u8 = 5;

/// One water's result of a pass: the changes of its three atoms (positions or momenta) and
/// [`OK`] or why it failed.
pub(super) type Change = ([V3; 3], u8);

const NO_CHANGE: Change = ([[0.0; 3]; 3], OK);

/// Three atoms' coordinates in lanes: `[atom][axis]`.
type Atoms<S> = [[L<S>; 3]; 3];

// The lane code below calls no closure and no generic helper of `core` that takes one
// (`array::from_fn`, `map`): those are compiled apart from the instruction set's
// `target_feature` copy when not inlined, and each lane operation then becomes a call.
// Its loops are counted loops over fixed arrays, indexed.

/// The registers of `lanes` (component `c` of lane `l` at `[c][l]`).
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn load<S: Simd<R = f64>, const N: usize>(s: S, lanes: &[[f64; 16]; N]) -> [L<S>; N] {
    let mut v = [L::splat(s, 0.0); N];
    for c in 0..N {
        v[c] = L {
            s,
            v: s.load(&lanes[c]),
        };
    }
    v
}

/// Lane `l`'s water of `group` (at most `S::WIDTH` waters): lanes past it repeat its last.
#[inline(always)]
fn lane_water(group: &[Settle], l: usize) -> &Settle {
    &group[l.min(group.len() - 1)]
}

/// The memory between a group's numbers and its lanes (`[component][lane]`), made once
/// per pass and reused by each group, so that no group zeroes its own (a lane is written
/// before it is read: lanes past a group's last water repeat it, [`lane_water`]).
///
/// The inputs are filled one group ahead: a group's numbers are stored lane by lane
/// (scalar stores) while the group before it computes, and loaded as registers when its
/// turn comes. A register load right after the narrow stores that fill it waits for them
/// to reach the cache (store forwarding fails from several narrow stores to one wide load);
/// one group's arithmetic later they are there.
struct Stage {
    /// Two groups' inputs: rows 0–8 the three atoms of the first array (`[atom][axis]`),
    /// 9–17 those of the second, 18–21 the constants ([`fill`]).
    inputs: [[[f64; 16]; 22]; 2],
    /// Which of `inputs` holds the group to compute now.
    current: usize,
    changes: [[[f64; 16]; 3]; 3],
}

impl Stage {
    /// A stage holding the first group of `waters` (read from `sources`) as the current one.
    #[inline(always)]
    fn primed<S: Simd<R = f64>>(waters: &[Settle], sources: Sources) -> Self {
        let mut stage = Stage {
            inputs: [[[0.0; 16]; 22]; 2],
            current: 0,
            changes: [[[0.0; 16]; 3]; 3],
        };
        fill::<S>(first_group(waters, S::WIDTH), sources, &mut stage.inputs[0]);
        stage
    }

    /// The current group's inputs as lanes: the two arrays' atoms and the constants.
    #[inline(always)]
    fn load<S: Simd<R = f64>>(&self, s: S) -> ([Atoms<S>; 2], [L<S>; 4]) {
        let v: [L<S>; 22] = load(s, &self.inputs[self.current]);
        let (a, b) = (&v[0..9], &v[9..18]);
        let atoms = [
            [[a[0], a[1], a[2]], [a[3], a[4], a[5]], [a[6], a[7], a[8]]],
            [[b[0], b[1], b[2]], [b[3], b[4], b[5]], [b[6], b[7], b[8]]],
        ];
        (atoms, [v[18], v[19], v[20], v[21]])
    }

    /// Fill the other set with the group after group `g` of `waters` (after the last,
    /// `ahead`, which may be empty) and make it the current one for the next group.
    #[inline(always)]
    fn advance<S: Simd<R = f64>>(
        &mut self,
        waters: &[Settle],
        g: usize,
        ahead: &[Settle],
        sources: Sources,
    ) {
        let rest = &waters[((g + 1) * S::WIDTH).min(waters.len())..];
        let next = if rest.is_empty() {
            ahead
        } else {
            first_group(rest, S::WIDTH)
        };
        self.current ^= 1;
        fill::<S>(next, sources, &mut self.inputs[self.current]);
    }
}

/// What a pass reads of its waters: two arrays of coordinates (positions: `q_old`,
/// `q_new`; velocities: `q`, `p`) and, for the velocity pass, the inverse masses
/// (`None`: the position pass, whose constants are the fitted records').
#[derive(Clone, Copy)]
struct Sources<'a> {
    first: &'a [f64],
    second: &'a [f64],
    inverse_mass: Option<&'a [f64]>,
}

impl<'a> Sources<'a> {
    #[inline(always)]
    fn of(first: &'a [f64], second: &'a [f64], inverse_mass: Option<&'a [f64]>) -> Self {
        Sources {
            first,
            second,
            inverse_mass,
        }
    }
}

/// Store `group`'s inputs (none if it is empty) into `rows`: the three atoms (oxygen, hydrogen 1, hydrogen 2)
/// of both arrays, then the position step's `[m_H/(m_O + 2m_H), r_a, r_b, r_c]` or the
/// velocity step's `[w_O, w_H]`, read from the inverse masses as [`Settle::new`] reads
/// them (so the velocity pass needs no fitted record).
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn fill<S: Simd<R = f64>>(group: &[Settle], sources: Sources, rows: &mut [[f64; 16]; 22]) {
    if group.is_empty() {
        return;
    }
    for l in 0..S::WIDTH {
        let w = lane_water(group, l);
        let atoms = [w.oxygen, w.hydrogens[0], w.hydrogens[1]];
        let arrays = [sources.first, sources.second];
        for k in 0..2 {
            for a in 0..3 {
                let x = &arrays[k][3 * atoms[a]..3 * atoms[a] + 3];
                for axis in 0..3 {
                    rows[9 * k + 3 * a + axis][l] = x[axis];
                }
            }
        }
        let constants = match sources.inverse_mass {
            None => [w.h_share, w.ra, w.rb, w.rc],
            Some(m) => [m[3 * w.oxygen], m[3 * w.hydrogens[0]], 0.0, 0.0],
        };
        for c in 0..4 {
            rows[18 + c][l] = constants[c];
        }
    }
}

/// The first group (at most `width` waters) of `waters`, empty if none.
#[inline(always)]
fn first_group(waters: &[Settle], width: usize) -> &[Settle] {
    &waters[..waters.len().min(width)]
}

/// The changes `atoms` of a group's lanes and their failure codes `codes` into `out` (one
/// per water of the group), through `lanes`.
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn scatter<S: Simd<R = f64>>(
    atoms: Atoms<S>,
    codes: &[u8; 16],
    out: &mut [Change],
    lanes: &mut [[[f64; 16]; 3]; 3],
) {
    for a in 0..3 {
        for k in 0..3 {
            let x = atoms[a][k];
            x.s.store(x.v, &mut lanes[a][k]);
        }
    }
    for l in 0..out.len() {
        let mut change = [[0.0; 3]; 3];
        for a in 0..3 {
            for k in 0..3 {
                change[a][k] = lanes[a][k][l];
            }
        }
        out[l] = (change, codes[l]);
    }
}

/// The lanes of the box edges `lengths`.
#[inline(always)]
fn edges<S: Simd<R = f64>>(s: S, pbc: Option<&PeriodicBox>) -> [L<S>; 3] {
    let lengths = match pbc {
        Some(b) => b.lengths,
        None => [0.0; 3],
    };
    [
        L::splat(s, lengths[0]),
        L::splat(s, lengths[1]),
        L::splat(s, lengths[2]),
    ]
}

/// `a − b` in lanes, the minimum image ([`near_image`]: a water spans less than half a
/// box) when `PERIODIC` (box edges `lengths`).
#[inline(always)]
fn image_of<S: Simd<R = f64>, const PERIODIC: bool>(
    lengths: [L<S>; 3],
    a: [L<S>; 3],
    b: [L<S>; 3],
) -> [L<S>; 3] {
    let r = sub(a, b);
    if PERIODIC {
        let s = r[0].s;
        [
            r[0].with(near_image(s, r[0].v, lengths[0].v)),
            r[1].with(near_image(s, r[1].v, lengths[1].v)),
            r[2].with(near_image(s, r[2].v, lengths[2].v)),
        ]
    } else {
        r
    }
}

/// The failures of a group's position step, bit `l` for lane `l`.
#[derive(Clone, Copy)]
struct PositionFailures {
    not_planar: u32,
    oxygen_out: u32,
    hydrogens_out: u32,
    not_turned: u32,
}

impl PositionFailures {
    /// Each lane's code: the first check that failed, in the order of the step.
    #[inline(always)]
    fn codes(self) -> [u8; 16] {
        let mut codes = [OK; 16];
        for (l, code) in codes.iter_mut().enumerate() {
            *code = if self.not_planar >> l & 1 == 1 {
                COLLINEAR
            } else if self.oxygen_out >> l & 1 == 1 {
                OXYGEN_OUT
            } else if self.hydrogens_out >> l & 1 == 1 {
                HYDROGENS_OUT
            } else if self.not_turned >> l & 1 == 1 {
                TURNED
            } else {
                OK
            };
        }
        codes
    }
}

/// The position step (module doc) of a group's lanes, branch-free: the displacements `Δq`
/// of the three atoms for old positions `old` and drifted ones `new`, and the failures
/// (a failing lane's displacements are meaningless). `shape` holds the lanes'
/// `[m_H/(m_O + 2m_H), r_a, r_b, r_c]`. ~200 flops, 7 square roots, 6 divisions per lane.
#[inline(always)]
fn position_step<S: Simd<R = f64>, const PERIODIC: bool>(
    shape: [L<S>; 4],
    lengths: [L<S>; 3],
    old: Atoms<S>,
    new: Atoms<S>,
) -> (Atoms<S>, PositionFailures) {
    let [h_share, ..] = shape;
    let (zero, one) = (L::splat(h_share.s, 0.0), L::splat(h_share.s, 1.0));
    // Old bond vectors, and the new positions relative to the new oxygen (unwrapped).
    let b0 = image_of::<S, PERIODIC>(lengths, old[1], old[0]);
    let c0 = image_of::<S, PERIODIC>(lengths, old[2], old[0]);
    let b1 = image_of::<S, PERIODIC>(lengths, new[1], new[0]);
    let c1 = image_of::<S, PERIODIC>(lengths, new[2], new[0]);
    // Relative to the new centre of mass.
    let com = scale(add(b1, c1), h_share);
    let a1 = [com[0].neg(), com[1].neg(), com[2].neg()];
    let (b1, c1) = (sub(b1, com), sub(c1, com));
    // The frame: z normal to the old plane, x ⟂ (a1, z), y = z × x.
    let z = cross(b0, c0);
    let x = cross(a1, z);
    let y = cross(z, x);
    let (nx, ny, nz) = (dot(x, x).sqrt(), dot(y, y).sqrt(), dot(z, z).sqrt());
    let planar = zero.below(nx) & zero.below(ny) & zero.below(nz);
    let (x, y, z) = (scale(x, one / nx), scale(y, one / ny), scale(z, one / nz));
    let frame = [x, y, z];
    let (b0, c0) = (in_frame(b0, frame), in_frame(c0, frame));
    let (a1, b1, c1) = (
        in_frame(a1, frame),
        in_frame(b1, frame),
        in_frame(c1, frame),
    );
    let ([a2, b2, c2], [oxygen_out, hydrogens_out]) = tilted_triangle(shape, [a1[2], b1[2], c1[2]]);
    let (sin_theta, cos_theta, turned) = in_plane_turn([b0, c0], [b1, c1], [b2, c2]);
    // Displacements of the three atoms (turned in the plane, back in the lab frame).
    let turn = [cos_theta, sin_theta];
    let moved = [
        displacement(a1, a2, turn, frame),
        displacement(b1, b2, turn, frame),
        displacement(c1, c2, turn, frame),
    ];
    let all = (1u32 << S::WIDTH) - 1;
    let failures = PositionFailures {
        not_planar: !planar & all,
        oxygen_out,
        hydrogens_out,
        not_turned: !turned & all,
    };
    (moved, failures)
}

/// `v` in the frame of the orthonormal axes `[x, y, z]`.
#[inline(always)]
fn in_frame<S: Simd<R = f64>>(v: [L<S>; 3], [x, y, z]: [[L<S>; 3]; 3]) -> [L<S>; 3] {
    [dot(v, x), dot(v, y), dot(v, z)]
}

/// The displacement, in the lab frame, of an atom at `now` (in the frame `[x, y, z]`) to
/// `moved` turned in the plane by `[cos θ, sin θ]`.
#[inline(always)]
fn displacement<S: Simd<R = f64>>(
    now: [L<S>; 3],
    moved: [L<S>; 3],
    [cos_theta, sin_theta]: [L<S>; 2],
    [x, y, z]: [[L<S>; 3]; 3],
) -> [L<S>; 3] {
    let turned = [
        moved[0] * cos_theta - moved[1] * sin_theta,
        moved[0] * sin_theta + moved[1] * cos_theta,
        moved[2],
    ];
    let d = sub(turned, now);
    add(add(scale(x, d[0]), scale(y, d[1])), scale(z, d[2]))
}

/// The canonical triangle (oxygen at `(0, r_a, 0)`, hydrogens at `(∓r_c, −r_b, 0)` about the
/// centre of mass; `shape` as [`position_step`]'s) tilted by φ about x and ψ about y so that
/// its out-of-plane coordinates are `z = [z_O, z_H₁, z_H₂]` (MK92 (A1)–(A3)), and the lanes
/// where it cannot be: `|sin φ| ≥ 1` (the oxygen out of reach), `|sin ψ| ≥ 1` (the
/// hydrogens).
#[inline(always)]
fn tilted_triangle<S: Simd<R = f64>>(
    [_, ra, rb, rc]: [L<S>; 4],
    z: [L<S>; 3],
) -> (Atoms<S>, [u32; 2]) {
    let s = ra.s;
    let (zero, one, two) = (L::splat(s, 0.0), L::splat(s, 1.0), L::splat(s, 2.0));
    let sin_phi = z[0] / ra;
    let cos_phi = (one - sin_phi * sin_phi).sqrt();
    let sin_psi = (z[1] - z[2]) / (two * rc * cos_phi);
    let cos_psi = (one - sin_psi * sin_psi).sqrt();
    let out = [one.at_most(sin_phi.abs()), one.at_most(sin_psi.abs())];
    let (minus_rb, minus_rc) = (rb.neg(), rc.neg());
    let triangle = [
        [zero, ra * cos_phi, ra * sin_phi],
        [
            minus_rc * cos_psi,
            minus_rb * cos_phi - rc * sin_psi * sin_phi,
            minus_rb * sin_phi + rc * sin_psi * cos_phi,
        ],
        [
            rc * cos_psi,
            minus_rb * cos_phi + rc * sin_psi * sin_phi,
            minus_rb * sin_phi - rc * sin_psi * cos_phi,
        ],
    ];
    (triangle, out)
}

/// `(sin θ, cos θ)` of the in-plane turn: zero torque of the in-plane constraint
/// displacements about the old positions, `α sin θ + β cos θ = γ` (MK92 (A8)–(A10)), the
/// root near `θ = 0`, and the lanes where there is one (the others fail as [`TURNED`]).
/// `old` are the old hydrogens relative to the old oxygen, `new` the new ones and `tilted`
/// the tilted triangle's, relative to the new centre of mass.
#[inline(always)]
fn in_plane_turn<S: Simd<R = f64>>(
    [b0, c0]: [[L<S>; 3]; 2],
    [b1, c1]: [[L<S>; 3]; 2],
    [b2, c2]: [[L<S>; 3]; 2],
) -> (L<S>, L<S>, u32) {
    let (zero, one) = (L::splat(b0[0].s, 0.0), L::splat(b0[0].s, 1.0));
    let alpha = b2[0] * (b0[0] - c0[0]) + b0[1] * b2[1] + c0[1] * c2[1];
    let beta = b2[0] * (c0[1] - b0[1]) + b0[0] * b2[1] + c0[0] * c2[1];
    let gamma = b0[0] * b1[1] - b1[0] * b0[1] + c0[0] * c1[1] - c1[0] * c0[1];
    let norm2 = alpha * alpha + beta * beta;
    let discriminant = norm2 - gamma * gamma;
    let turned = zero.at_most(discriminant) & zero.below(norm2);
    let sin_theta = (alpha * gamma - beta * discriminant.sqrt()) / norm2;
    (sin_theta, (one - sin_theta * sin_theta).sqrt(), turned)
}

/// `Δq` added to one water's positions in `q_new`, and `m Δq / dt` to its momenta.
#[inline(always)]
fn apply_positions(water: &Settle, delta: [V3; 3], inverse_dt: f64, q: &mut [f64], p: &mut [f64]) {
    let [h1, h2] = water.hydrogens;
    let masses = [water.m_o, water.m_h, water.m_h];
    for ((atom, d), m) in [water.oxygen, h1, h2].into_iter().zip(delta).zip(masses) {
        add_to(q, atom, d);
        add_to(p, atom, scale(d, m * inverse_dt));
    }
}

/// SETTLE one water's positions (`q_old` rigid, `q_new` after a drift of `dt`) and its
/// momenta: the lane pass on the portable path with this water alone.
pub(super) fn positions(
    water: &Settle,
    pbc: Option<&PeriodicBox>,
    q_old: &[f64],
    q_new: &mut [f64],
    p: &mut [f64],
    dt: f64,
) -> Result<(), ConstraintFailure> {
    let one = std::slice::from_ref(water);
    positions_on(Isa::Portable, one, pbc, q_old, q_new, p, dt)
}

/// SETTLE every water's positions and momenta ([`positions`] for each, the same bits):
/// a group of waters at a time in the SIMD lanes of the widest instruction set
/// ([`Isa::best`]; plain IEEE arithmetic, no fused multiply-add, so every set gives the
/// same bits). From [`PARALLEL_MIN_INTERACTIONS`](crate::forces::scratch::PARALLEL_MIN_INTERACTIONS) waters on, in a pool
/// of several threads, the changes of fixed blocks of waters are computed in parallel into
/// `scratch` and added on this thread in water order: each water's arithmetic is its own
/// (no two waters share an atom), so the same bits at any thread count. Allocates nothing.
pub(super) fn positions_all(
    waters: &[Settle],
    pbc: Option<&PeriodicBox>,
    q_old: &[f64],
    q_new: &mut [f64],
    p: &mut [f64],
    dt: f64,
    scratch: &Scratch<Change>,
) -> Result<(), ConstraintFailure> {
    let isa = Isa::best();
    if !parallel(waters.len()) {
        return positions_on(isa, waters, pbc, q_old, q_new, p, dt);
    }
    let changes = scratch.computed(waters.len(), |first, out| {
        let (waters, q_new) = (&waters[first..first + out.len()], &*q_new);
        position_changes_on(isa, waters, pbc, q_old, q_new, out)
    });
    let inverse_dt = 1.0 / dt;
    apply_changes(waters, &changes[..waters.len()], |water, delta| {
        apply_positions(water, delta, inverse_dt, q_new, p)
    })
}

simd_dispatch! {
    /// [`positions_all`] on the instruction set `isa` (available on this processor), on
    /// this thread.
    fn positions_on[][](
        waters: &[Settle],
        pbc: Option<&PeriodicBox>,
        q_old: &[f64],
        q_new: &mut [f64],
        p: &mut [f64],
        dt: f64,
    ) -> Result<(), ConstraintFailure> = positions_lanes, lanes f64;
}

simd_dispatch! {
    /// [`position_changes`] on the instruction set `isa` (available on this processor).
    fn position_changes_on[][](
        waters: &[Settle],
        pbc: Option<&PeriodicBox>,
        q_old: &[f64],
        q_new: &[f64],
        out: &mut [Change],
    ) = position_changes_alone, lanes f64;
}

/// The position pass on this thread: [`LANES`] waters' changes at a time, then added.
#[inline(always)]
fn positions_lanes<S: Simd<R = f64>>(
    s: S,
    waters: &[Settle],
    pbc: Option<&PeriodicBox>,
    q_old: &[f64],
    q_new: &mut [f64],
    p: &mut [f64],
    dt: f64,
) -> Result<(), ConstraintFailure> {
    let inverse_dt = 1.0 / dt;
    let mut block = [NO_CHANGE; LANES];
    let mut stage = Stage::primed::<S>(waters, Sources::of(q_old, q_new, None));
    for (k, chunk) in waters.chunks(LANES).enumerate() {
        let changes = &mut block[..chunk.len()];
        let ahead = first_group(&waters[k * LANES + chunk.len()..], S::WIDTH);
        let sources = Sources::of(q_old, q_new, None);
        position_changes(s, chunk, pbc, sources, changes, &mut stage, ahead);
        apply_changes(chunk, changes, |water, delta| {
            apply_positions(water, delta, inverse_dt, q_new, p)
        })?;
    }
    Ok(())
}

/// The position step ([`position_step`]) of every water of `waters` into `out`,
/// `S::WIDTH` at a time: their coordinates and constants gathered into lanes (`stage`
/// holds the first group's already; each group fills the next one's, after the last
/// the group `ahead`, which may be empty), the step, the changes scattered back.
#[inline(always)]
fn position_changes<S: Simd<R = f64>>(
    s: S,
    waters: &[Settle],
    pbc: Option<&PeriodicBox>,
    sources: Sources,
    out: &mut [Change],
    stage: &mut Stage,
    ahead: &[Settle],
) {
    let lengths = edges(s, pbc);
    for (g, out) in out.chunks_mut(S::WIDTH).enumerate() {
        let ([old, new], shape) = stage.load(s);
        stage.advance::<S>(waters, g, ahead, sources);
        let (delta, failures) = match pbc {
            Some(_) => position_step::<S, true>(shape, lengths, old, new),
            None => position_step::<S, false>(shape, lengths, old, new),
        };
        scatter(delta, &failures.codes(), out, &mut stage.changes);
    }
}

/// [`position_changes`] with a stage of its own (a parallel task's).
#[inline(always)]
fn position_changes_alone<S: Simd<R = f64>>(
    s: S,
    waters: &[Settle],
    pbc: Option<&PeriodicBox>,
    q_old: &[f64],
    q_new: &[f64],
    out: &mut [Change],
) {
    let sources = Sources::of(q_old, q_new, None);
    let mut stage = Stage::primed::<S>(waters, sources);
    position_changes(s, waters, pbc, sources, out, &mut stage, &[]);
}

/// `apply(water, change)` for every water in order, or, at the first that failed, the
/// failure, with the changes of the [`LANES`] block it is in (counted from the first
/// water) left out: what the pass on one thread leaves, whatever the thread count.
#[inline(always)]
fn apply_changes(
    waters: &[Settle],
    changes: &[Change],
    mut apply: impl FnMut(&Settle, [V3; 3]),
) -> Result<(), ConstraintFailure> {
    let failed = changes.iter().position(|c| c.1 != OK);
    let applied = failed.map_or(waters.len(), |k| k - k % LANES);
    for (water, change) in waters[..applied].iter().zip(changes) {
        apply(water, change.0);
    }
    match failed {
        Some(k) => Err(failure(&waters[k], changes[k].1)),
        None => Ok(()),
    }
}

/// The velocity step of a group's lanes at rigid positions `q` (oxygen, hydrogens) with
/// momenta `p`, branch-free: the momentum changes of the three atoms, and the lanes whose
/// constraints are singular (the others fail as [`SINGULAR`]). `w` holds the lanes' inverse
/// masses `[w_O, w_H]`. ~100 flops and one division per lane.
#[inline(always)]
fn velocity_step<S: Simd<R = f64>, const PERIODIC: bool>(
    [wa, wh]: [L<S>; 2],
    lengths: [L<S>; 3],
    q: Atoms<S>,
    p: Atoms<S>,
) -> (Atoms<S>, u32) {
    let s = wa.s;
    let (one, two) = (L::splat(s, 1.0), L::splat(s, 2.0));
    let rab = image_of::<S, PERIODIC>(lengths, q[0], q[1]);
    let rac = image_of::<S, PERIODIC>(lengths, q[0], q[2]);
    // q_H₁ − q_H₂ of the same (unwrapped) water.
    let rbc = sub(rac, rab);
    let (va, vb, vc) = (scale(p[0], wa), scale(p[1], wh), scale(p[2], wh));
    // Impulses: a += λ₁ r_ab + λ₂ r_ac, b += −λ₁ r_ab + λ₃ r_bc, c += −λ₂ r_ac − λ₃ r_bc.
    // The conditions are M λ = r with M symmetric; solved by its adjugate (~50 flops).
    let (m11, m12, m13) = (
        (wa + wh) * dot(rab, rab),
        wa * dot(rab, rac),
        wh.neg() * dot(rab, rbc),
    );
    let (m22, m23, m33) = (
        (wa + wh) * dot(rac, rac),
        wh * dot(rac, rbc),
        two * wh * dot(rbc, rbc),
    );
    let rhs = [
        dot(rab, sub(va, vb)).neg(),
        dot(rac, sub(va, vc)).neg(),
        dot(rbc, sub(vb, vc)).neg(),
    ];
    let (c11, c12, c13) = (
        m22 * m33 - m23 * m23,
        m13 * m23 - m12 * m33,
        m12 * m23 - m13 * m22,
    );
    let (c22, c23, c33) = (
        m11 * m33 - m13 * m13,
        m12 * m13 - m11 * m23,
        m11 * m22 - m12 * m12,
    );
    let det = m11 * c11 + m12 * c12 + m13 * c13;
    // A collinear water makes M singular: det vanishes against the product of its diagonal;
    // a non-finite det (|det| < ∞ false) is singular too.
    let tiny = L::splat(s, 1e-12) * (m11 * m22 * m33).abs();
    let finite = det.abs().below(L::splat(s, f64::INFINITY));
    let singular = det.abs().at_most(tiny) | !finite & ((1u32 << S::WIDTH) - 1);
    let inverse_det = one / det;
    let l1 = (c11 * rhs[0] + c12 * rhs[1] + c13 * rhs[2]) * inverse_det;
    let l2 = (c12 * rhs[0] + c22 * rhs[1] + c23 * rhs[2]) * inverse_det;
    let l3 = (c13 * rhs[0] + c23 * rhs[1] + c33 * rhs[2]) * inverse_det;
    let dp = [
        add(scale(rab, l1), scale(rac, l2)),
        sub(scale(rbc, l3), scale(rab, l1)),
        neg(add(scale(rac, l2), scale(rbc, l3))),
    ];
    (dp, singular)
}

/// `Δp` added to one water's momenta.
#[inline(always)]
fn apply_momenta(water: &Settle, dp: [V3; 3], p: &mut [f64]) {
    let [h1, h2] = water.hydrogens;
    for (atom, d) in [water.oxygen, h1, h2].into_iter().zip(dp) {
        add_to(p, atom, d);
    }
}

/// Project one water's momenta at rigid positions `q` so no distance in it changes (the
/// reference of [`velocities_all`]'s lanes in the tests): the lane pass on the portable
/// path with this water alone.
#[cfg(test)]
fn velocities(
    water: &Settle,
    pbc: Option<&PeriodicBox>,
    q: &[f64],
    p: &mut [f64],
    inverse_mass: &[f64],
) -> Result<(), ConstraintFailure> {
    velocities_on(
        Isa::Portable,
        std::slice::from_ref(water),
        pbc,
        q,
        p,
        inverse_mass,
    )
}

/// Project every water's momenta ([`velocities`] for each, the same bits), a group at a
/// time in SIMD lanes and from [`PARALLEL_MIN_INTERACTIONS`](crate::forces::scratch::PARALLEL_MIN_INTERACTIONS) waters on in parallel, as
/// [`positions_all`]. The inverse masses are read from `inverse_mass` (3 per particle; a
/// water's hydrogens weigh the same, [`super::Constraints::check_masses`]), so `waters`
/// need not be fitted to them. Allocates nothing.
pub(super) fn velocities_all(
    waters: &[Settle],
    pbc: Option<&PeriodicBox>,
    q: &[f64],
    p: &mut [f64],
    inverse_mass: &[f64],
    scratch: &Scratch<Change>,
) -> Result<(), ConstraintFailure> {
    let isa = Isa::best();
    if !parallel(waters.len()) {
        return velocities_on(isa, waters, pbc, q, p, inverse_mass);
    }
    let changes = scratch.computed(waters.len(), |first, out| {
        let (waters, p) = (&waters[first..first + out.len()], &*p);
        velocity_changes_on(isa, waters, pbc, q, p, inverse_mass, out)
    });
    apply_changes(waters, &changes[..waters.len()], |water, dp| {
        apply_momenta(water, dp, p)
    })
}

simd_dispatch! {
    /// [`velocities_all`] on the instruction set `isa` (available on this processor), on
    /// this thread.
    fn velocities_on[][](
        waters: &[Settle],
        pbc: Option<&PeriodicBox>,
        q: &[f64],
        p: &mut [f64],
        inverse_mass: &[f64],
    ) -> Result<(), ConstraintFailure> = velocities_lanes, lanes f64;
}

simd_dispatch! {
    /// [`velocity_changes`] on the instruction set `isa` (available on this processor).
    fn velocity_changes_on[][](
        waters: &[Settle],
        pbc: Option<&PeriodicBox>,
        q: &[f64],
        p: &[f64],
        inverse_mass: &[f64],
        out: &mut [Change],
    ) = velocity_changes_alone, lanes f64;
}

/// The velocity pass on this thread: [`LANES`] waters' changes at a time, then added.
#[inline(always)]
fn velocities_lanes<S: Simd<R = f64>>(
    s: S,
    waters: &[Settle],
    pbc: Option<&PeriodicBox>,
    q: &[f64],
    p: &mut [f64],
    inverse_mass: &[f64],
) -> Result<(), ConstraintFailure> {
    let mut block = [NO_CHANGE; LANES];
    let mut stage = Stage::primed::<S>(waters, Sources::of(q, p, Some(inverse_mass)));
    for (k, chunk) in waters.chunks(LANES).enumerate() {
        let changes = &mut block[..chunk.len()];
        let ahead = first_group(&waters[k * LANES + chunk.len()..], S::WIDTH);
        let sources = Sources::of(q, p, Some(inverse_mass));
        velocity_changes(s, chunk, pbc, sources, changes, &mut stage, ahead);
        apply_changes(chunk, changes, |water, dp| apply_momenta(water, dp, p))?;
    }
    Ok(())
}

/// The velocity step ([`velocity_step`]) of every water of `waters` into `out`,
/// `S::WIDTH` at a time as [`position_changes`] (`sources`: the positions, the momenta
/// and the inverse masses).
#[inline(always)]
fn velocity_changes<S: Simd<R = f64>>(
    s: S,
    waters: &[Settle],
    pbc: Option<&PeriodicBox>,
    sources: Sources,
    out: &mut [Change],
    stage: &mut Stage,
    ahead: &[Settle],
) {
    let lengths = edges(s, pbc);
    for (g, out) in out.chunks_mut(S::WIDTH).enumerate() {
        let ([qw, pw], [wa, wh, ..]) = stage.load(s);
        let masses = [wa, wh];
        stage.advance::<S>(waters, g, ahead, sources);
        let (dp, singular) = match pbc {
            Some(_) => velocity_step::<S, true>(masses, lengths, qw, pw),
            None => velocity_step::<S, false>(masses, lengths, qw, pw),
        };
        let mut codes = [OK; 16];
        for (l, code) in codes.iter_mut().enumerate() {
            if singular >> l & 1 == 1 {
                *code = SINGULAR;
            }
        }
        scatter(dp, &codes, out, &mut stage.changes);
    }
}

/// [`velocity_changes`] with a stage of its own (a parallel task's).
#[inline(always)]
fn velocity_changes_alone<S: Simd<R = f64>>(
    s: S,
    waters: &[Settle],
    pbc: Option<&PeriodicBox>,
    q: &[f64],
    p: &[f64],
    inverse_mass: &[f64],
    out: &mut [Change],
) {
    let sources = Sources::of(q, p, Some(inverse_mass));
    let mut stage = Stage::primed::<S>(waters, sources);
    velocity_changes(s, waters, pbc, sources, out, &mut stage, &[]);
}

fn failure(water: &Settle, code: u8) -> ConstraintFailure {
    let what = match code {
        COLLINEAR => "is collinear or its oxygen sits at its centre of mass",
        OXYGEN_OUT => "oxygen moved out of the plane beyond reach",
        HYDROGENS_OUT => "hydrogens moved out of the plane beyond reach",
        TURNED => "turned in its plane beyond reach",
        _ => "is collinear: its velocity constraints are singular",
    };
    let [h1, h2] = water.hydrogens;
    ConstraintFailure(format!(
        "SETTLE: water {}-{h1}-{h2} {what}; the step is too long",
        water.oxygen
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::Xoshiro256PlusPlus;
    use rand::{RngExt, SeedableRng};

    const OH: f64 = 0.9572;
    const HH: f64 = 1.5139;

    /// `n` TIP3P-like waters scattered in a 10 Å box (some straddling its faces), rigid
    /// at `q_old`, drifted by a random displacement to `q_new`, with random momenta.
    fn scene(n: usize, seed: u64) -> (Vec<Settle>, Vec<f64>, Vec<f64>, Vec<f64>) {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        let (w_o, w_h) = (1.0 / 15.9994, 1.0 / 3.024);
        let mut q_old = vec![0.0; 9 * n];
        let mut waters = Vec::with_capacity(n);
        for k in 0..n {
            let water = RigidWater {
                oxygen: 3 * k,
                hydrogens: [3 * k + 1, 3 * k + 2],
                oh: OH,
                hh: HH,
            };
            // A rigid triangle in a random orientation (two orthonormal axes).
            let u: V3 = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
            let v: V3 = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
            let u = scale(u, 1.0 / dot(u, u).sqrt());
            let v = sub(v, scale(u, dot(u, v)));
            let v = scale(v, 1.0 / dot(v, v).sqrt());
            let o: V3 = std::array::from_fn(|_| rng.random_range(0.0..10.0));
            let height = (OH * OH - 0.25 * HH * HH).sqrt();
            let h1 = add(o, add(scale(u, height), scale(v, 0.5 * HH)));
            let h2 = add(o, sub(scale(u, height), scale(v, 0.5 * HH)));
            for (atom, x) in [o, h1, h2].into_iter().enumerate() {
                q_old[9 * k + 3 * atom..9 * k + 3 * atom + 3].copy_from_slice(&x);
            }
            waters.push(Settle::with_masses(&water, w_o, w_h));
        }
        let q_new = q_old
            .iter()
            .map(|x| x + rng.random_range(-0.05..0.05))
            .collect();
        let p = (0..9 * n).map(|_| rng.random_range(-1.0..1.0)).collect();
        (waters, q_old, q_new, p)
    }

    /// The inverse masses of [`scene`]'s `n` waters, 3 per particle.
    fn inverse_masses(n: usize) -> Vec<f64> {
        let (w_o, w_h) = (1.0 / 15.9994, 1.0 / 3.024);
        (0..9 * n)
            .map(|k| if k % 9 < 3 { w_o } else { w_h })
            .collect()
    }

    fn bits(x: &[f64]) -> Vec<u64> {
        x.iter().map(|v| v.to_bits()).collect()
    }

    /// The lane passes give the bits of the one-water functions on every instruction set,
    /// in and out of a box, over full chunks and a remainder.
    #[test]
    fn lanes_are_the_bits_of_one_water_at_a_time() {
        let pbc = PeriodicBox { lengths: [10.0; 3] };
        for (n, periodic) in [(21, true), (21, false), (5, true), (16, true)] {
            let pbc = periodic.then_some(&pbc);
            let (waters, q_old, q_new, p) = scene(n, n as u64);
            let w = inverse_masses(n);
            let (mut q_one, mut p_one) = (q_new.clone(), p.clone());
            for w in &waters {
                positions(w, pbc, &q_old, &mut q_one, &mut p_one, 2.0).unwrap();
            }
            let mut p_vel = p_one.clone();
            for water in &waters {
                velocities(water, pbc, &q_one, &mut p_vel, &w).unwrap();
            }
            for isa in Isa::available() {
                let (mut q_lanes, mut p_lanes) = (q_new.clone(), p.clone());
                positions_on(isa, &waters, pbc, &q_old, &mut q_lanes, &mut p_lanes, 2.0).unwrap();
                assert_eq!(bits(&q_lanes), bits(&q_one), "{isa:?} n {n}");
                assert_eq!(bits(&p_lanes), bits(&p_one), "{isa:?} n {n}");
                velocities_on(isa, &waters, pbc, &q_lanes, &mut p_lanes, &w).unwrap();
                assert_eq!(bits(&p_lanes), bits(&p_vel), "{isa:?} n {n}");
            }
        }
    }

    /// A water that cannot be SETTLE'd in the middle of a chunk fails the pass with the
    /// message of the one-water function.
    #[test]
    fn a_failing_lane_names_its_water() {
        let (waters, q_old, mut q_new, p) = scene(16, 3);
        // Water 5's oxygen thrown far out of its old plane: beyond reach.
        for a in 0..3 {
            q_new[9 * 5 + a] += 5.0;
        }
        let one = positions(
            &waters[5],
            None,
            &q_old,
            &mut q_new.clone(),
            &mut p.clone(),
            1.0,
        )
        .unwrap_err();
        for isa in Isa::available() {
            let lanes = positions_on(
                isa,
                &waters,
                None,
                &q_old,
                &mut q_new.clone(),
                &mut p.clone(),
                1.0,
            )
            .unwrap_err();
            assert_eq!(lanes, one);
            assert!(lanes.0.contains("water 15-16-17"), "{}", lanes.0);
        }
    }
}
