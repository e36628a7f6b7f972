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

use super::{ConstraintFailure, PeriodicBox, RigidWater};

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

/// `v / |v|`, `None` for a zero vector.
#[inline(always)]
fn unit(v: V3) -> Option<V3> {
    let norm = dot(v, v).sqrt();
    (norm > 0.0).then(|| scale(v, 1.0 / norm))
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

/// `qᵢ − qⱼ`, the minimum image in a periodic box.
#[inline(always)]
fn image(pbc: Option<&PeriodicBox>, q: &[f64], i: usize, j: usize) -> V3 {
    let r = sub(at(q, i), at(q, j));
    match pbc {
        Some(b) => [b.wrap(0, r[0]), b.wrap(1, r[1]), b.wrap(2, r[2])],
        None => r,
    }
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
    let o = water.oxygen;
    let [h1, h2] = water.hydrogens;
    // Old bond vectors, and the new positions relative to the new oxygen (unwrapped).
    let b0 = image(pbc, q_old, h1, o);
    let c0 = image(pbc, q_old, h2, o);
    let b1 = image(pbc, q_new, h1, o);
    let c1 = image(pbc, q_new, h2, o);
    // Relative to the new centre of mass.
    let com = scale(add(b1, c1), water.h_share);
    let (a1, b1, c1) = (scale(com, -1.0), sub(b1, com), sub(c1, com));
    // The frame: z normal to the old plane, x ⟂ (a1, z), y = z × x.
    let z = cross(b0, c0);
    let x = cross(a1, z);
    let y = cross(z, x);
    let (Some(x), Some(y), Some(z)) = (unit(x), unit(y), unit(z)) else {
        return Err(failure(
            water,
            "is collinear or its oxygen sits at its centre of mass",
        ));
    };
    let frame = |v: V3| [dot(v, x), dot(v, y), dot(v, z)];
    let (b0, c0) = (frame(b0), frame(c0));
    let (a1, b1, c1) = (frame(a1), frame(b1), frame(c1));
    let [a2, b2, c2] = tilted_triangle(water, [a1[2], b1[2], c1[2]])?;
    let (sin_theta, cos_theta) = in_plane_turn(water, [b0, c0], [b1, c1], [b2, c2])?;
    // Displacements of the three atoms (turned in the plane, back in the lab frame): `q`
    // and `p` take `Δq` and `m Δq / dt`.
    let inverse_dt = 1.0 / dt;
    let mut apply = |atom: usize, now: V3, moved: V3, m: f64| {
        let turned = [
            moved[0] * cos_theta - moved[1] * sin_theta,
            moved[0] * sin_theta + moved[1] * cos_theta,
            moved[2],
        ];
        let d = sub(turned, now);
        let delta = add(add(scale(x, d[0]), scale(y, d[1])), scale(z, d[2]));
        add_to(q_new, atom, delta);
        add_to(p, atom, scale(delta, m * inverse_dt));
    };
    apply(o, a1, a2, water.m_o);
    apply(h1, b1, b2, water.m_h);
    apply(h2, c1, c2, water.m_h);
    Ok(())
}

/// The canonical triangle (oxygen at `(0, r_a, 0)`, hydrogens at `(∓r_c, −r_b, 0)` about the
/// centre of mass) tilted by φ about x and ψ about y so that its out-of-plane coordinates
/// are `z = [z_O, z_H₁, z_H₂]` (MK92 (A1)–(A3)).
#[inline(always)]
fn tilted_triangle(water: &Settle, z: [f64; 3]) -> Result<[V3; 3], ConstraintFailure> {
    let (ra, rb, rc) = (water.ra, water.rb, water.rc);
    let sin_phi = z[0] / ra;
    if sin_phi.abs() >= 1.0 {
        return Err(failure(water, "oxygen moved out of the plane beyond reach"));
    }
    let cos_phi = (1.0 - sin_phi * sin_phi).sqrt();
    let sin_psi = (z[1] - z[2]) / (2.0 * rc * cos_phi);
    if sin_psi.abs() >= 1.0 {
        return Err(failure(
            water,
            "hydrogens moved out of the plane beyond reach",
        ));
    }
    let cos_psi = (1.0 - sin_psi * sin_psi).sqrt();
    Ok([
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
    ])
}

/// `(sin θ, cos θ)` of the in-plane turn: zero torque of the in-plane constraint
/// displacements about the old positions, `α sin θ + β cos θ = γ` (MK92 (A8)–(A10)), the
/// root near `θ = 0`. `old` are the old hydrogens relative to the old oxygen, `new` the
/// new ones and `tilted` the tilted triangle's, relative to the new centre of mass.
#[inline(always)]
fn in_plane_turn(
    water: &Settle,
    [b0, c0]: [V3; 2],
    [b1, c1]: [V3; 2],
    [b2, c2]: [V3; 2],
) -> Result<(f64, f64), ConstraintFailure> {
    let alpha = b2[0] * (b0[0] - c0[0]) + b0[1] * b2[1] + c0[1] * c2[1];
    let beta = b2[0] * (c0[1] - b0[1]) + b0[0] * b2[1] + c0[0] * c2[1];
    let gamma = b0[0] * b1[1] - b1[0] * b0[1] + c0[0] * c1[1] - c1[0] * c0[1];
    let norm2 = alpha * alpha + beta * beta;
    let discriminant = norm2 - gamma * gamma;
    if !(discriminant >= 0.0 && norm2 > 0.0) {
        return Err(failure(water, "turned in its plane beyond reach"));
    }
    let sin_theta = (alpha * gamma - beta * discriminant.sqrt()) / norm2;
    Ok((sin_theta, (1.0 - sin_theta * sin_theta).sqrt()))
}

/// Project one water's momenta at rigid positions `q` so no distance in it changes.
pub(super) fn velocities(
    water: &Settle,
    pbc: Option<&PeriodicBox>,
    q: &[f64],
    p: &mut [f64],
) -> Result<(), ConstraintFailure> {
    let o = water.oxygen;
    let [h1, h2] = water.hydrogens;
    let (wa, wh) = (water.w_o, water.w_h);
    let rab = image(pbc, q, o, h1);
    let rac = image(pbc, q, o, h2);
    // q_H₁ − q_H₂ of the same (unwrapped) water.
    let rbc = sub(rac, rab);
    let (va, vb, vc) = (
        scale(at(p, o), wa),
        scale(at(p, h1), wh),
        scale(at(p, h2), wh),
    );
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
    if det.abs() <= 1e-12 * (m11 * m22 * m33).abs() || !det.is_finite() {
        return Err(failure(
            water,
            "is collinear: its velocity constraints are singular",
        ));
    }
    let inverse_det = 1.0 / det;
    let l1 = (c11 * rhs[0] + c12 * rhs[1] + c13 * rhs[2]) * inverse_det;
    let l2 = (c12 * rhs[0] + c22 * rhs[1] + c23 * rhs[2]) * inverse_det;
    let l3 = (c13 * rhs[0] + c23 * rhs[1] + c33 * rhs[2]) * inverse_det;
    add_to(p, o, add(scale(rab, l1), scale(rac, l2)));
    add_to(p, h1, sub(scale(rbc, l3), scale(rab, l1)));
    add_to(p, h2, scale(add(scale(rac, l2), scale(rbc, l3)), -1.0));
    Ok(())
}

fn failure(water: &Settle, what: &str) -> ConstraintFailure {
    let [h1, h2] = water.hydrogens;
    ConstraintFailure(format!(
        "SETTLE: water {}-{h1}-{h2} {what}; the step is too long",
        water.oxygen
    ))
}
