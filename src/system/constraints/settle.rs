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
//! Cost: ~200 flops per water for positions, ~100 for velocities; to round-off.

use nalgebra::Vector3;

use super::{ConstraintFailure, PeriodicBox, RigidWater, separation};

type V3 = Vector3<f64>;

fn at(q: &[f64], i: usize) -> V3 {
    V3::new(q[3 * i], q[3 * i + 1], q[3 * i + 2])
}

fn image(pbc: Option<PeriodicBox>, q: &[f64], i: usize, j: usize) -> V3 {
    let r = separation(3, pbc, q, i, j);
    V3::new(r[0], r[1], r[2])
}

/// SETTLE one water's positions (`q_old` rigid, `q_new` after a drift of `dt`) and its
/// momenta.
pub(super) fn positions(
    water: &RigidWater,
    pbc: Option<PeriodicBox>,
    q_old: &[f64],
    q_new: &mut [f64],
    p: &mut [f64],
    inverse_mass: &[f64],
    dt: f64,
) -> Result<(), ConstraintFailure> {
    let o = water.oxygen;
    let [h1, h2] = water.hydrogens;
    let (m_o, m_h) = (1.0 / inverse_mass[3 * o], 1.0 / inverse_mass[3 * h1]);
    let total = m_o + 2.0 * m_h;
    // Old bond vectors, and the new positions relative to the new oxygen (unwrapped).
    let b0 = image(pbc, q_old, h1, o);
    let c0 = image(pbc, q_old, h2, o);
    let b1 = image(pbc, q_new, h1, o);
    let c1 = image(pbc, q_new, h2, o);
    // Relative to the new centre of mass.
    let com = (b1 + c1) * (m_h / total);
    let (a1, b1, c1) = (-com, b1 - com, c1 - com);
    // The frame: z normal to the old plane, x ⟂ (a1, z), y = z × x.
    let z = b0.cross(&c0);
    let x = a1.cross(&z);
    let y = z.cross(&x);
    let (Some(x), Some(y), Some(z)) = (
        x.try_normalize(0.0),
        y.try_normalize(0.0),
        z.try_normalize(0.0),
    ) else {
        return Err(failure(
            water,
            "is collinear or its oxygen sits at its centre of mass",
        ));
    };
    let frame = |v: &V3| V3::new(v.dot(&x), v.dot(&y), v.dot(&z));
    let (b0, c0) = (frame(&b0), frame(&c0));
    let (a1, b1, c1) = (frame(&a1), frame(&b1), frame(&c1));
    let [a2, b2, c2] = tilted_triangle(water, m_o, m_h, [a1.z, b1.z, c1.z])?;
    let (sin_theta, cos_theta) = in_plane_turn(water, [b0, c0], [b1, c1], [b2, c2])?;
    let turn = |v: V3| {
        V3::new(
            v.x * cos_theta - v.y * sin_theta,
            v.x * sin_theta + v.y * cos_theta,
            v.z,
        )
    };
    let back = |v: V3| x * v.x + y * v.y + z * v.z;
    // Displacements of the three atoms, in the lab frame.
    for (atom, now, moved) in [(o, a1, a2), (h1, b1, b2), (h2, c1, c2)] {
        let delta = back(turn(moved) - now);
        let w = inverse_mass[3 * atom];
        for a in 0..3 {
            q_new[3 * atom + a] += delta[a];
            p[3 * atom + a] += delta[a] / (w * dt);
        }
    }
    Ok(())
}

/// The canonical triangle (oxygen at `(0, r_a, 0)`, hydrogens at `(∓r_c, −r_b, 0)` about the
/// centre of mass) tilted by φ about x and ψ about y so that its out-of-plane coordinates
/// are `z = [z_O, z_H₁, z_H₂]` (MK92 (A1)–(A3)).
fn tilted_triangle(
    water: &RigidWater,
    m_o: f64,
    m_h: f64,
    z: [f64; 3],
) -> Result<[V3; 3], ConstraintFailure> {
    let rc = 0.5 * water.hh;
    let height = (water.oh * water.oh - rc * rc).sqrt();
    let ra = 2.0 * m_h * height / (m_o + 2.0 * m_h);
    let rb = height - ra;
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
        V3::new(0.0, ra * cos_phi, ra * sin_phi),
        V3::new(
            -rc * cos_psi,
            -rb * cos_phi - rc * sin_psi * sin_phi,
            -rb * sin_phi + rc * sin_psi * cos_phi,
        ),
        V3::new(
            rc * cos_psi,
            -rb * cos_phi + rc * sin_psi * sin_phi,
            -rb * sin_phi - rc * sin_psi * cos_phi,
        ),
    ])
}

/// `(sin θ, cos θ)` of the in-plane turn: zero torque of the in-plane constraint
/// displacements about the old positions, `α sin θ + β cos θ = γ` (MK92 (A8)–(A10)), the
/// root near `θ = 0`. `old` are the old hydrogens relative to the old oxygen, `new` the
/// new ones and `tilted` the tilted triangle's, relative to the new centre of mass.
fn in_plane_turn(
    water: &RigidWater,
    [b0, c0]: [V3; 2],
    [b1, c1]: [V3; 2],
    [b2, c2]: [V3; 2],
) -> Result<(f64, f64), ConstraintFailure> {
    let alpha = b2.x * (b0.x - c0.x) + b0.y * b2.y + c0.y * c2.y;
    let beta = b2.x * (c0.y - b0.y) + b0.x * b2.y + c0.x * c2.y;
    let gamma = b0.x * b1.y - b1.x * b0.y + c0.x * c1.y - c1.x * c0.y;
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
    water: &RigidWater,
    pbc: Option<PeriodicBox>,
    q: &[f64],
    p: &mut [f64],
    inverse_mass: &[f64],
) -> Result<(), ConstraintFailure> {
    let o = water.oxygen;
    let [h1, h2] = water.hydrogens;
    let (wa, wb, wc) = (
        inverse_mass[3 * o],
        inverse_mass[3 * h1],
        inverse_mass[3 * h2],
    );
    let (rab, rac, rbc) = (
        image(pbc, q, o, h1),
        image(pbc, q, o, h2),
        image(pbc, q, h1, h2),
    );
    let (va, vb, vc) = (at(p, o) * wa, at(p, h1) * wb, at(p, h2) * wc);
    // Impulses: a += λ₁ r_ab + λ₂ r_ac, b += −λ₁ r_ab + λ₃ r_bc, c += −λ₂ r_ac − λ₃ r_bc.
    // The conditions are M λ = r with M symmetric; solved by its adjugate (~50 flops).
    let (m11, m12, m13) = (
        (wa + wb) * rab.norm_squared(),
        wa * rab.dot(&rac),
        -wb * rab.dot(&rbc),
    );
    let (m22, m23, m33) = (
        (wa + wc) * rac.norm_squared(),
        wc * rac.dot(&rbc),
        (wb + wc) * rbc.norm_squared(),
    );
    let rhs = -V3::new(
        rab.dot(&(va - vb)),
        rac.dot(&(va - vc)),
        rbc.dot(&(vb - vc)),
    );
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
    let lambda = V3::new(
        c11 * rhs.x + c12 * rhs.y + c13 * rhs.z,
        c12 * rhs.x + c22 * rhs.y + c23 * rhs.z,
        c13 * rhs.x + c23 * rhs.y + c33 * rhs.z,
    ) / det;
    let impulses = [
        (o, rab * lambda.x + rac * lambda.y),
        (h1, -rab * lambda.x + rbc * lambda.z),
        (h2, -rac * lambda.y - rbc * lambda.z),
    ];
    for (atom, impulse) in impulses {
        for a in 0..3 {
            p[3 * atom + a] += impulse[a];
        }
    }
    Ok(())
}

fn failure(water: &RigidWater, what: &str) -> ConstraintFailure {
    let [h1, h2] = water.hydrogens;
    ConstraintFailure(format!(
        "SETTLE: water {}-{h1}-{h2} {what}; the step is too long",
        water.oxygen
    ))
}
