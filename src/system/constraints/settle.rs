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
//! **Lanes.** A pass over all waters ([`positions_all`], [`velocities_all`]) takes
//! [`LANES`] waters at a time: their coordinates are read into arrays, one branch-free
//! step per water (the checks become a failure code, the minimum image a select) runs in a
//! loop the compiler vectorises for the widest instruction set ([`Isa::best`]), and the
//! displacements are written back once every lane has passed. Plain IEEE arithmetic in
//! the order of the one-water functions and no fused multiply-add, so every lane and every
//! instruction set gives the bits of [`positions`] one water at a time (the unit tests
//! check it); a failing lane is reported with its water, as one at a time.

use super::{ConstraintFailure, PeriodicBox, RigidWater};
use crate::forces::minimum_image;
use crate::forces::scratch::{Scratch, parallel};
use crate::forces::simd::Isa;

type V3 = [f64; 3];

#[inline(always)]
fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline(always)]
fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

#[inline(always)]
fn scale(a: V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}

#[inline(always)]
fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline(always)]
fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[inline(always)]
fn at(q: &[f64], i: usize) -> V3 {
    let x = &q[3 * i..3 * i + 3];
    [x[0], x[1], x[2]]
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

/// Lanes of a SETTLE pass: waters handled together, one per lane of a loop the compiler
/// vectorises (8 doubles: one AVX-512 register, two AVX2 ones).
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

/// The minimum image of a difference `d` along a box edge `length`: [`PeriodicBox::wrap`]'s
/// arithmetic with its branch as a select (both sides computed), so a lane loop vectorises.
#[inline(always)]
fn wrap(d: f64, length: f64) -> f64 {
    let far = minimum_image(d, length);
    if d.abs() < 0.5 * length { d } else { far }
}

/// `a − b` (three atoms' coordinates `x`, atoms `a` and `b`), the minimum image when
/// `PERIODIC` (box edges `lengths`).
#[inline(always)]
fn image_of<const PERIODIC: bool>(lengths: V3, a: V3, b: V3) -> V3 {
    let r = sub(a, b);
    if PERIODIC {
        [
            wrap(r[0], lengths[0]),
            wrap(r[1], lengths[1]),
            wrap(r[2], lengths[2]),
        ]
    } else {
        r
    }
}

/// One water's coordinates (oxygen, hydrogen 1, hydrogen 2) read from `q`.
#[inline(always)]
fn three(water: &Settle, q: &[f64]) -> [V3; 3] {
    let [h1, h2] = water.hydrogens;
    [at(q, water.oxygen), at(q, h1), at(q, h2)]
}

/// The position step of one water (module doc), branch-free: the displacements `Δq` of
/// its three atoms for old positions `old` and drifted ones `new`, and a failure code
/// ([`OK`] or the first check that failed; the displacements are then meaningless).
/// ~200 flops, 7 square roots, 6 divisions.
#[inline(always)]
fn position_step<const PERIODIC: bool>(
    water: &Settle,
    lengths: V3,
    old: [V3; 3],
    new: [V3; 3],
) -> ([V3; 3], u8) {
    // Old bond vectors, and the new positions relative to the new oxygen (unwrapped).
    let b0 = image_of::<PERIODIC>(lengths, old[1], old[0]);
    let c0 = image_of::<PERIODIC>(lengths, old[2], old[0]);
    let b1 = image_of::<PERIODIC>(lengths, new[1], new[0]);
    let c1 = image_of::<PERIODIC>(lengths, new[2], new[0]);
    // Relative to the new centre of mass.
    let com = scale(add(b1, c1), water.h_share);
    let (a1, b1, c1) = (scale(com, -1.0), sub(b1, com), sub(c1, com));
    // The frame: z normal to the old plane, x ⟂ (a1, z), y = z × x.
    let z = cross(b0, c0);
    let x = cross(a1, z);
    let y = cross(z, x);
    let (nx, ny, nz) = (dot(x, x).sqrt(), dot(y, y).sqrt(), dot(z, z).sqrt());
    let planar = nx > 0.0 && ny > 0.0 && nz > 0.0;
    let (x, y, z) = (scale(x, 1.0 / nx), scale(y, 1.0 / ny), scale(z, 1.0 / nz));
    let frame = |v: V3| [dot(v, x), dot(v, y), dot(v, z)];
    let (b0, c0) = (frame(b0), frame(c0));
    let (a1, b1, c1) = (frame(a1), frame(b1), frame(c1));
    let ([a2, b2, c2], tilt) = tilted_triangle(water, [a1[2], b1[2], c1[2]]);
    let (sin_theta, cos_theta, turn) = in_plane_turn([b0, c0], [b1, c1], [b2, c2]);
    // Displacements of the three atoms (turned in the plane, back in the lab frame).
    let moved = |now: V3, moved: V3| {
        let turned = [
            moved[0] * cos_theta - moved[1] * sin_theta,
            moved[0] * sin_theta + moved[1] * cos_theta,
            moved[2],
        ];
        let d = sub(turned, now);
        add(add(scale(x, d[0]), scale(y, d[1])), scale(z, d[2]))
    };
    let code = if !planar {
        COLLINEAR
    } else if tilt != OK {
        tilt
    } else {
        turn
    };
    ([moved(a1, a2), moved(b1, b2), moved(c1, c2)], code)
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
/// momenta.
pub(super) fn positions(
    water: &Settle,
    pbc: Option<&PeriodicBox>,
    q_old: &[f64],
    q_new: &mut [f64],
    p: &mut [f64],
    dt: f64,
) -> Result<(), ConstraintFailure> {
    let (old, new) = (three(water, q_old), three(water, q_new));
    let (delta, code) = match pbc {
        Some(b) => position_step::<true>(water, b.lengths, old, new),
        None => position_step::<false>(water, [0.0; 3], old, new),
    };
    if code != OK {
        return Err(failure(water, code));
    }
    apply_positions(water, delta, 1.0 / dt, q_new, p);
    Ok(())
}

/// SETTLE every water's positions and momenta ([`positions`] for each, the same bits):
/// [`LANES`] waters at a time through a lane loop compiled for the widest instruction set
/// ([`Isa::best`]; plain IEEE arithmetic, no fused multiply-add, so every set gives the
/// same bits), the rest one by one. From [`PARALLEL_MIN_INTERACTIONS`](crate::forces::scratch::PARALLEL_MIN_INTERACTIONS) waters on, in a pool
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
    let lengths = pbc.map_or([0.0; 3], |b| b.lengths);
    let changes = scratch.computed(waters.len(), |first, out| {
        let waters = &waters[first..first + out.len()];
        let q_new = &*q_new;
        isa.run(
            #[inline(always)]
            || match pbc {
                Some(_) => position_changes::<true>(waters, lengths, q_old, q_new, out),
                None => position_changes::<false>(waters, lengths, q_old, q_new, out),
            },
        )
    });
    let inverse_dt = 1.0 / dt;
    apply_changes(waters, &changes[..waters.len()], |water, delta| {
        apply_positions(water, delta, inverse_dt, q_new, p)
    })
}

/// [`positions_all`] on the instruction set `isa` (available on this processor), on this
/// thread.
fn positions_on(
    isa: Isa,
    waters: &[Settle],
    pbc: Option<&PeriodicBox>,
    q_old: &[f64],
    q_new: &mut [f64],
    p: &mut [f64],
    dt: f64,
) -> Result<(), ConstraintFailure> {
    isa.run(
        #[inline(always)]
        || match pbc {
            Some(b) => positions_lanes::<true>(waters, b.lengths, q_old, q_new, p, dt),
            None => positions_lanes::<false>(waters, [0.0; 3], q_old, q_new, p, dt),
        },
    )
}

/// The position pass on this thread: [`LANES`] waters' changes at a time, then added.
#[inline(always)]
fn positions_lanes<const PERIODIC: bool>(
    waters: &[Settle],
    lengths: V3,
    q_old: &[f64],
    q_new: &mut [f64],
    p: &mut [f64],
    dt: f64,
) -> Result<(), ConstraintFailure> {
    let inverse_dt = 1.0 / dt;
    for chunk in waters.chunks(LANES) {
        let mut changes = [NO_CHANGE; LANES];
        let changes = &mut changes[..chunk.len()];
        position_changes::<PERIODIC>(chunk, lengths, q_old, q_new, changes);
        apply_changes(chunk, changes, |water, delta| {
            apply_positions(water, delta, inverse_dt, q_new, p)
        })?;
    }
    Ok(())
}

/// The position step ([`position_step`]) of every water of `waters` into `out`: [`LANES`]
/// at a time, their coordinates read into arrays first so that the lane loop vectorises,
/// the rest one by one.
// The lane loop indexes its fixed arrays by `l`: a counted loop the vectoriser takes.
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn position_changes<const PERIODIC: bool>(
    waters: &[Settle],
    lengths: V3,
    q_old: &[f64],
    q_new: &[f64],
    out: &mut [Change],
) {
    let mut chunks = waters.chunks_exact(LANES);
    let mut outs = out.chunks_exact_mut(LANES);
    for (chunk, out) in (&mut chunks).zip(&mut outs) {
        let old: [[V3; 3]; LANES] = std::array::from_fn(|l| three(&chunk[l], q_old));
        let new: [[V3; 3]; LANES] = std::array::from_fn(|l| three(&chunk[l], q_new));
        for l in 0..LANES {
            out[l] = position_step::<PERIODIC>(&chunk[l], lengths, old[l], new[l]);
        }
    }
    for (water, out) in chunks.remainder().iter().zip(outs.into_remainder()) {
        let (old, new) = (three(water, q_old), three(water, q_new));
        *out = position_step::<PERIODIC>(water, lengths, old, new);
    }
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

/// The canonical triangle (oxygen at `(0, r_a, 0)`, hydrogens at `(∓r_c, −r_b, 0)` about the
/// centre of mass) tilted by φ about x and ψ about y so that its out-of-plane coordinates
/// are `z = [z_O, z_H₁, z_H₂]` (MK92 (A1)–(A3)), and [`OK`] or why it cannot be.
#[inline(always)]
fn tilted_triangle(water: &Settle, z: [f64; 3]) -> ([V3; 3], u8) {
    let (ra, rb, rc) = (water.ra, water.rb, water.rc);
    let sin_phi = z[0] / ra;
    let cos_phi = (1.0 - sin_phi * sin_phi).sqrt();
    let sin_psi = (z[1] - z[2]) / (2.0 * rc * cos_phi);
    let cos_psi = (1.0 - sin_psi * sin_psi).sqrt();
    let code = if sin_phi.abs() >= 1.0 {
        OXYGEN_OUT
    } else if sin_psi.abs() >= 1.0 {
        HYDROGENS_OUT
    } else {
        OK
    };
    let triangle = [
        [0.0, ra * cos_phi, ra * sin_phi],
        [
            -rc * cos_psi,
            -rb * cos_phi - rc * sin_psi * sin_phi,
            -rb * sin_phi + rc * sin_psi * cos_phi,
        ],
        [
            rc * cos_psi,
            -rb * cos_phi + rc * sin_psi * sin_phi,
            -rb * sin_phi - rc * sin_psi * cos_phi,
        ],
    ];
    (triangle, code)
}

/// `(sin θ, cos θ)` of the in-plane turn: zero torque of the in-plane constraint
/// displacements about the old positions, `α sin θ + β cos θ = γ` (MK92 (A8)–(A10)), the
/// root near `θ = 0`, and [`OK`] or [`TURNED`] when there is none. `old` are the old
/// hydrogens relative to the old oxygen, `new` the new ones and `tilted` the tilted
/// triangle's, relative to the new centre of mass.
#[inline(always)]
fn in_plane_turn([b0, c0]: [V3; 2], [b1, c1]: [V3; 2], [b2, c2]: [V3; 2]) -> (f64, f64, u8) {
    let alpha = b2[0] * (b0[0] - c0[0]) + b0[1] * b2[1] + c0[1] * c2[1];
    let beta = b2[0] * (c0[1] - b0[1]) + b0[0] * b2[1] + c0[0] * c2[1];
    let gamma = b0[0] * b1[1] - b1[0] * b0[1] + c0[0] * c1[1] - c1[0] * c0[1];
    let norm2 = alpha * alpha + beta * beta;
    let discriminant = norm2 - gamma * gamma;
    let code = if discriminant >= 0.0 && norm2 > 0.0 {
        OK
    } else {
        TURNED
    };
    let sin_theta = (alpha * gamma - beta * discriminant.sqrt()) / norm2;
    (sin_theta, (1.0 - sin_theta * sin_theta).sqrt(), code)
}

/// The velocity step of one water at rigid positions `q` (oxygen, hydrogens) with momenta
/// `p`, branch-free: the momentum changes of its three atoms, and [`OK`] or [`SINGULAR`].
/// ~100 flops, one division.
#[inline(always)]
fn velocity_step<const PERIODIC: bool>(
    water: &Settle,
    lengths: V3,
    q: [V3; 3],
    p: [V3; 3],
) -> ([V3; 3], u8) {
    let (wa, wh) = (water.w_o, water.w_h);
    let rab = image_of::<PERIODIC>(lengths, q[0], q[1]);
    let rac = image_of::<PERIODIC>(lengths, q[0], q[2]);
    // q_H₁ − q_H₂ of the same (unwrapped) water.
    let rbc = sub(rac, rab);
    let (va, vb, vc) = (scale(p[0], wa), scale(p[1], wh), scale(p[2], wh));
    // Impulses: a += λ₁ r_ab + λ₂ r_ac, b += −λ₁ r_ab + λ₃ r_bc, c += −λ₂ r_ac − λ₃ r_bc.
    // The conditions are M λ = r with M symmetric; solved by its adjugate (~50 flops).
    let (m11, m12, m13) = (
        (wa + wh) * dot(rab, rab),
        wa * dot(rab, rac),
        -wh * dot(rab, rbc),
    );
    let (m22, m23, m33) = (
        (wa + wh) * dot(rac, rac),
        wh * dot(rac, rbc),
        2.0 * wh * dot(rbc, rbc),
    );
    let rhs = [
        -dot(rab, sub(va, vb)),
        -dot(rac, sub(va, vc)),
        -dot(rbc, sub(vb, vc)),
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
    // A collinear water makes M singular: det vanishes against the product of its diagonal.
    let singular = det.abs() <= 1e-12 * (m11 * m22 * m33).abs() || !det.is_finite();
    let inverse_det = 1.0 / det;
    let l1 = (c11 * rhs[0] + c12 * rhs[1] + c13 * rhs[2]) * inverse_det;
    let l2 = (c12 * rhs[0] + c22 * rhs[1] + c23 * rhs[2]) * inverse_det;
    let l3 = (c13 * rhs[0] + c23 * rhs[1] + c33 * rhs[2]) * inverse_det;
    let dp = [
        add(scale(rab, l1), scale(rac, l2)),
        sub(scale(rbc, l3), scale(rab, l1)),
        scale(add(scale(rac, l2), scale(rbc, l3)), -1.0),
    ];
    (dp, if singular { SINGULAR } else { OK })
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
/// reference of [`velocities_all`]'s lanes in the tests).
#[cfg(test)]
fn velocities(
    water: &Settle,
    pbc: Option<&PeriodicBox>,
    q: &[f64],
    p: &mut [f64],
) -> Result<(), ConstraintFailure> {
    let (qw, pw) = (three(water, q), three(water, p));
    let (dp, code) = match pbc {
        Some(b) => velocity_step::<true>(water, b.lengths, qw, pw),
        None => velocity_step::<false>(water, [0.0; 3], qw, pw),
    };
    if code != OK {
        return Err(failure(water, code));
    }
    apply_momenta(water, dp, p);
    Ok(())
}

/// Project every water's momenta ([`velocities`] for each, the same bits), [`LANES`] at a
/// time and from [`PARALLEL_MIN_INTERACTIONS`](crate::forces::scratch::PARALLEL_MIN_INTERACTIONS) waters on in parallel, as
/// [`positions_all`]. Allocates nothing.
pub(super) fn velocities_all(
    waters: &[Settle],
    pbc: Option<&PeriodicBox>,
    q: &[f64],
    p: &mut [f64],
    scratch: &Scratch<Change>,
) -> Result<(), ConstraintFailure> {
    let isa = Isa::best();
    if !parallel(waters.len()) {
        return velocities_on(isa, waters, pbc, q, p);
    }
    let lengths = pbc.map_or([0.0; 3], |b| b.lengths);
    let changes = scratch.computed(waters.len(), |first, out| {
        let waters = &waters[first..first + out.len()];
        let p = &*p;
        isa.run(
            #[inline(always)]
            || match pbc {
                Some(_) => velocity_changes::<true>(waters, lengths, q, p, out),
                None => velocity_changes::<false>(waters, lengths, q, p, out),
            },
        )
    });
    apply_changes(waters, &changes[..waters.len()], |water, dp| {
        apply_momenta(water, dp, p)
    })
}

/// [`velocities_all`] on the instruction set `isa` (available on this processor), on this
/// thread.
fn velocities_on(
    isa: Isa,
    waters: &[Settle],
    pbc: Option<&PeriodicBox>,
    q: &[f64],
    p: &mut [f64],
) -> Result<(), ConstraintFailure> {
    isa.run(
        #[inline(always)]
        || match pbc {
            Some(b) => velocities_lanes::<true>(waters, b.lengths, q, p),
            None => velocities_lanes::<false>(waters, [0.0; 3], q, p),
        },
    )
}

/// The velocity pass on this thread: [`LANES`] waters' changes at a time, then added.
#[inline(always)]
fn velocities_lanes<const PERIODIC: bool>(
    waters: &[Settle],
    lengths: V3,
    q: &[f64],
    p: &mut [f64],
) -> Result<(), ConstraintFailure> {
    for chunk in waters.chunks(LANES) {
        let mut changes = [NO_CHANGE; LANES];
        let changes = &mut changes[..chunk.len()];
        velocity_changes::<PERIODIC>(chunk, lengths, q, p, changes);
        apply_changes(chunk, changes, |water, dp| apply_momenta(water, dp, p))?;
    }
    Ok(())
}

/// The velocity step ([`velocity_step`]) of every water of `waters` into `out`, [`LANES`]
/// at a time as [`position_changes`].
// The lane loop indexes its fixed arrays by `l`: a counted loop the vectoriser takes.
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn velocity_changes<const PERIODIC: bool>(
    waters: &[Settle],
    lengths: V3,
    q: &[f64],
    p: &[f64],
    out: &mut [Change],
) {
    let mut chunks = waters.chunks_exact(LANES);
    let mut outs = out.chunks_exact_mut(LANES);
    for (chunk, out) in (&mut chunks).zip(&mut outs) {
        let qw: [[V3; 3]; LANES] = std::array::from_fn(|l| three(&chunk[l], q));
        let pw: [[V3; 3]; LANES] = std::array::from_fn(|l| three(&chunk[l], p));
        for l in 0..LANES {
            out[l] = velocity_step::<PERIODIC>(&chunk[l], lengths, qw[l], pw[l]);
        }
    }
    for (water, out) in chunks.remainder().iter().zip(outs.into_remainder()) {
        *out = velocity_step::<PERIODIC>(water, lengths, three(water, q), three(water, p));
    }
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
            let (mut q_one, mut p_one) = (q_new.clone(), p.clone());
            for w in &waters {
                positions(w, pbc, &q_old, &mut q_one, &mut p_one, 2.0).unwrap();
            }
            let mut p_vel = p_one.clone();
            for w in &waters {
                velocities(w, pbc, &q_one, &mut p_vel).unwrap();
            }
            for isa in Isa::available() {
                let (mut q_lanes, mut p_lanes) = (q_new.clone(), p.clone());
                positions_on(isa, &waters, pbc, &q_old, &mut q_lanes, &mut p_lanes, 2.0).unwrap();
                assert_eq!(bits(&q_lanes), bits(&q_one), "{isa:?} n {n}");
                assert_eq!(bits(&p_lanes), bits(&p_one), "{isa:?} n {n}");
                velocities_on(isa, &waters, pbc, &q_lanes, &mut p_lanes).unwrap();
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
