//! Every force term's gradient and Hessian-vector product against central finite
//! differences, in 1, 2 and 3 dimensions (angles in 2 and 3: in 1-D every angle is 0 or π,
//! where θ is not differentiable, and scenes reject them).
//!
//! Tolerance: with step ε the central difference has truncation error ≤ ε²/6·|f‴| and
//! round-off ≈ 2u|f|/ε (u = 1.1e-16). With ε = 1e-5 and the O(1) configurations below
//! (|V|, |f‴| ≲ 1e3) that is ≲ 2e-8 + 2e-8, so 1e-6·max(1, |exact|) is a bound with margin,
//! yet a wrong term (a sign, a factor 2, a missing Hessian piece) is off by O(1).

mod common;

use common::{FdCheck, TestRng};
use longstep::forces::angle::{AngleBend, HarmonicAngles};
use longstep::forces::gravity::{CentralMass, gravity};
use longstep::forces::lennard_jones::{LennardJones, lennard_jones_pairs};
use longstep::forces::pendulum::Pendulum;
use longstep::forces::quartic::{QuarticBond, quartic_springs};
use longstep::forces::spring::{HarmonicBond, harmonic_springs};
use longstep::forces::{ForceTerm, Site};
use longstep::system::PeriodicBox;

const EPSILON: f64 = 1e-5;

/// Checks gradient and Hessian-vector product at `q` along several random directions.
fn check(term: &dyn ForceTerm, q: &[f64], rng: &mut TestRng, label: &str) {
    let fd = FdCheck {
        epsilon: EPSILON,
        tolerance: 1e-6,
        floor: 1e-8,
    };
    fd.check(term, q, rng, label);
}

/// `n` particles near a line with spacing ~1.2 and random offsets, in `dim` dimensions.
fn positions(n: usize, dim: usize, rng: &mut TestRng) -> Vec<f64> {
    let mut q = Vec::with_capacity(n * dim);
    for i in 0..n {
        for axis in 0..dim {
            let base = if axis == 0 { 1.2 * i as f64 } else { 0.0 };
            q.push(base + rng.uniform(-0.25, 0.25));
        }
    }
    q
}

fn anchor(dim: usize, x: f64) -> Site {
    let mut position = [0.0; 3];
    position[0] = x;
    if dim > 1 {
        position[1] = 0.3;
    }
    Site::Fixed(position)
}

#[test]
fn harmonic_springs_match_finite_differences() {
    let mut rng = TestRng::new(1);
    for dim in 1..=3 {
        let q = positions(4, dim, &mut rng);
        let spring = |k: f64, rest: f64| HarmonicBond {
            stiffness: k,
            rest_length: rest,
        };
        let term = harmonic_springs(
            dim,
            vec![
                (anchor(dim, -1.0), Site::Particle(0), spring(100.0, 1.0)),
                (Site::Particle(0), Site::Particle(1), spring(3.0, 0.9)),
                (Site::Particle(1), Site::Particle(2), spring(7.0, 0.0)),
                (Site::Particle(3), Site::Particle(2), spring(2.5, 1.5)),
                (Site::Particle(3), anchor(dim, 5.0), spring(0.5, 0.7)),
            ],
            None,
        );
        check(&term, &q, &mut rng, &format!("spring, dim {dim}"));
    }
}

#[test]
fn quartic_springs_match_finite_differences() {
    let mut rng = TestRng::new(2);
    for dim in 1..=3 {
        let q = positions(3, dim, &mut rng);
        let bond = |c: f64, rest: f64| QuarticBond {
            coefficient: c,
            rest_length: rest,
        };
        let term = quartic_springs(
            dim,
            vec![
                (anchor(dim, -0.5), Site::Particle(0), bond(1.0, 0.0)),
                (Site::Particle(0), Site::Particle(1), bond(2.0, 0.6)),
                (Site::Particle(1), Site::Particle(2), bond(0.5, 0.0)),
            ],
            None,
        );
        check(&term, &q, &mut rng, &format!("quartic spring, dim {dim}"));
    }
}

#[test]
fn angles_match_finite_differences() {
    let mut rng = TestRng::new(3);
    for dim in 2..=3 {
        // A zig-zag so no angle is near 0 or π.
        let mut q = positions(4, dim, &mut rng);
        for i in 0..4 {
            q[i * dim + 1] += if i % 2 == 0 { 0.8 } else { -0.8 };
        }
        let angles = vec![
            AngleBend {
                sites: [Site::Particle(0), Site::Particle(1), Site::Particle(2)],
                stiffness: 40.0,
                rest_angle: 1.9,
            },
            AngleBend {
                sites: [Site::Particle(1), Site::Particle(2), Site::Particle(3)],
                stiffness: 15.0,
                rest_angle: 1.2,
            },
            AngleBend {
                sites: [anchor(dim, -1.0), Site::Particle(0), Site::Particle(1)],
                stiffness: 5.0,
                rest_angle: 2.5,
            },
        ];
        let term = HarmonicAngles::new(dim, angles, None);
        check(&term, &q, &mut rng, &format!("angle, dim {dim}"));
    }
}

#[test]
fn lennard_jones_matches_finite_differences() {
    let mut rng = TestRng::new(4);
    for dim in 1..=3 {
        let n = 5;
        let q = positions(n, dim, &mut rng);
        let particles: Vec<usize> = (0..n).collect();
        let cutoff = 2.5;
        // Shifted energy: continuous at the cutoff, but the force jumps there, so no pair
        // may sit within the finite-difference reach of it.
        let term = lennard_jones_pairs(
            dim,
            &particles,
            &[(0, 4)],
            LennardJones::new(1.0, 1.0, cutoff, true),
            None,
        );
        for pair in term.pairs() {
            let (Site::Particle(a), Site::Particle(b)) = (pair.a, pair.b) else {
                unreachable!()
            };
            let r = (0..dim)
                .map(|k| (q[b * dim + k] - q[a * dim + k]).powi(2))
                .sum::<f64>()
                .sqrt();
            assert!(
                (r - cutoff).abs() > 1e-3,
                "pair ({a}, {b}) sits at the cutoff"
            );
        }
        assert_eq!(term.interaction_count(), n * (n - 1) / 2 - 1);
        check(&term, &q, &mut rng, &format!("Lennard-Jones, dim {dim}"));
    }
}

#[test]
fn lennard_jones_uses_the_minimum_image() {
    let mut rng = TestRng::new(5);
    let dim = 3;
    let box_lengths = PeriodicBox {
        lengths: [4.0, 4.0, 4.0],
    };
    // Two particles near opposite faces are close through the boundary.
    let q = vec![0.2, 0.1, 0.0, 3.5, 0.3, 0.1];
    let term = lennard_jones_pairs(
        dim,
        &[0, 1],
        &[],
        LennardJones::new(1.0, 1.0, 1.9, false),
        Some(box_lengths),
    );
    let r: f64 = ((0.2f64 + 4.0 - 3.5).powi(2) + 0.2f64.powi(2) + 0.1f64.powi(2)).sqrt();
    let expected = 4.0 * (r.powi(-12) - r.powi(-6));
    assert!((term.energy(&q) - expected).abs() < 1e-12 * expected.abs());
    check(&term, &q, &mut rng, "Lennard-Jones, periodic");
}

#[test]
fn gravity_matches_finite_differences() {
    let mut rng = TestRng::new(6);
    for dim in 1..=3 {
        let q = positions(3, dim, &mut rng);
        let masses = [1.0, 0.5, 2.0];
        let term = gravity(
            dim,
            1.3,
            &[0, 1, 2],
            &masses,
            Some(CentralMass {
                position: [-1.5, 0.4, 0.2],
                mass: 3.0,
            }),
        );
        check(&term, &q, &mut rng, &format!("gravity, dim {dim}"));
    }
}

#[test]
fn pendulum_matches_finite_differences() {
    let mut rng = TestRng::new(7);
    for dim in 1..=3 {
        let q = rng.vector(2 * dim, -2.0, 2.0);
        let coordinates = (0..2).map(|i| (i, dim - 1, 1.5 + i as f64)).collect();
        let term = Pendulum::new(dim, coordinates);
        check(&term, &q, &mut rng, &format!("pendulum, dim {dim}"));
    }
}

#[test]
fn couplings_name_the_particles_of_each_interaction() {
    let term = harmonic_springs(
        2,
        vec![
            (
                Site::Fixed([0.0; 3]),
                Site::Particle(0),
                HarmonicBond {
                    stiffness: 1.0,
                    rest_length: 1.0,
                },
            ),
            (
                Site::Particle(0),
                Site::Particle(1),
                HarmonicBond {
                    stiffness: 1.0,
                    rest_length: 1.0,
                },
            ),
        ],
        None,
    );
    assert_eq!(term.couplings(), vec![vec![0], vec![0, 1]]);
    let angles = HarmonicAngles::new(
        2,
        vec![AngleBend {
            sites: [Site::Particle(2), Site::Particle(0), Site::Fixed([1.0; 3])],
            stiffness: 1.0,
            rest_angle: 1.0,
        }],
        None,
    );
    assert_eq!(angles.couplings(), vec![vec![2, 0]]);
}
