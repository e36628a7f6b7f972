//! The molecular force-field terms: torsions, the non-bonded term (Lennard-Jones with DSF,
//! shifted-force, reaction-field and plain Coulomb, periodic and open, over its neighbour
//! list) and the plain Coulomb 1-4 pair, against central finite differences; and the
//! neighbour-listed non-bonded term against a brute-force double loop over all pairs and
//! images, through list rebuilds and with positions far outside the box.
//!
//! Finite-difference tolerance as in `force_terms.rs`: step ε = 1e-5, truncation ≤ ε²/6·|f‴|
//! and round-off ≈ 2u|V|/ε. The configurations keep atoms ≥ 1.6 apart with ε_LJ ≤ 0.3,
//! σ ≤ 3 and charges ≤ 0.8 (k_e = 332), so |f‴| ≲ 1e3 and |V| ≲ 1e3: both errors are
//! ≲ 2e-7, and 1e-5·max(1, |exact|) bounds them with margin, while a wrong sign, factor or
//! missing Hessian piece is off by O(1).
//!
//! Brute force against the list: the same formulas summed in another order, so they agree
//! to round-off: sums of ≲ 10³ terms of size ≲ 10³ in double precision differ by
//! ≲ 10³·10³·1e-16 = 1e-10; we allow 1e-9·max(1, scale).

mod common;

use common::{FdCheck, TestRng, max_abs, max_abs_difference};
use longstep::forces::ForceTerm;
use longstep::forces::coulomb::Coulomb;
use longstep::forces::nonbonded::{Electrostatics, LjPair, Nonbonded, NonbondedSpec};
use longstep::forces::pair::{Pair, PairTerm};
use longstep::forces::torsion::{Cosine, Dihedral, Torsions};
use longstep::forces::{Site, TermClass};
use longstep::system::PeriodicBox;

const EPSILON: f64 = 1e-5;
const TOLERANCE: f64 = 1e-5;

/// Checks gradient and Hessian-vector product at `q` along several random directions.
fn check(term: &dyn ForceTerm, q: &[f64], rng: &mut TestRng, label: &str) {
    let fd = FdCheck {
        epsilon: EPSILON,
        tolerance: TOLERANCE,
        floor: 1e-6,
    };
    fd.check(term, q, rng, label);
}

/// `n` atoms uniformly in a cube of side `side`, at least `min_distance` apart (minimum
/// image when periodic).
fn atoms(n: usize, side: f64, min_distance: f64, periodic: bool, rng: &mut TestRng) -> Vec<f64> {
    let mut q: Vec<f64> = Vec::with_capacity(3 * n);
    while q.len() < 3 * n {
        let x = [
            rng.uniform(0.0, side),
            rng.uniform(0.0, side),
            rng.uniform(0.0, side),
        ];
        let far = q.chunks_exact(3).all(|y| {
            let r2: f64 = (0..3)
                .map(|a| {
                    let mut d = x[a] - y[a];
                    if periodic {
                        d -= side * (d / side).round();
                    }
                    d * d
                })
                .sum();
            r2 >= min_distance * min_distance
        });
        if far {
            q.extend(x);
        }
    }
    q
}

/// Two types: 0 with LJ and charge, 1 charge only (like water O and H), plus charge-free
/// LJ-only atoms when types alternate with zero charges.
fn spec(
    n: usize,
    cutoff: f64,
    electrostatics: Electrostatics,
    box_lengths: Option<[f64; 3]>,
    rng: &mut TestRng,
) -> NonbondedSpec {
    let types: Vec<u32> = (0..n).map(|i| (i % 3 == 0) as u32).collect();
    // Type 1 has no LJ; every fifth atom carries no charge (an LJ-only pair class).
    let charges: Vec<f64> = (0..n)
        .map(|i| {
            if i % 5 == 4 {
                0.0
            } else {
                rng.uniform(-0.8, 0.8)
            }
        })
        .collect();
    let shift = true;
    let lj = vec![
        LjPair::new(0.25, 3.0, cutoff, shift),
        LjPair::new(0.0, 1.0, cutoff, shift),
        LjPair::new(0.0, 1.0, cutoff, shift),
        LjPair::new(0.0, 1.0, cutoff, shift),
    ];
    let excluded = (0..n / 4).map(|k| (4 * k, 4 * k + 1)).collect();
    NonbondedSpec {
        cutoff,
        skin: 1.0,
        inner_buffer: None,
        electrostatics,
        coulomb_constant: 332.06371,
        box_lengths,
        types,
        lj,
        charges,
        excluded,
    }
}

const FORMS: [Electrostatics; 5] = [
    Electrostatics::DampedShiftedForce { alpha: 0.0 },
    Electrostatics::DampedShiftedForce { alpha: 0.2 },
    Electrostatics::ReactionField { dielectric: 78.3 },
    Electrostatics::Ewald { alpha: 0.35 },
    Electrostatics::None,
];

#[test]
fn nonbonded_matches_finite_differences() {
    let mut rng = TestRng::new(61);
    // A box shorter than 2(cutoff + skin): pairs are listed with two images.
    let side = 11.0;
    for form in FORMS {
        let q = atoms(24, side, 1.6, true, &mut rng);
        let spec = spec(24, 5.0, form, Some([side; 3]), &mut rng);
        let term = Nonbonded::new(spec, &q).unwrap();
        check(
            &term,
            &q,
            &mut rng,
            &format!("nonbonded {form:?}, periodic"),
        );
    }
    // In vacuum: no cutoff, plain Coulomb.
    let q = atoms(12, 8.0, 1.6, false, &mut rng);
    let spec = spec(12, f64::INFINITY, Electrostatics::Plain, None, &mut rng);
    let term = Nonbonded::new(spec, &q).unwrap();
    check(&term, &q, &mut rng, "nonbonded plain, vacuum");
}

/// The same energy and gradient by brute force: every pair not excluded, every image within
/// the cutoff (at most one, as cutoff < L/2), straight from the formulas.
fn brute_force(spec: &NonbondedSpec, q: &[f64]) -> (f64, Vec<f64>) {
    let n = spec.types.len();
    let rc = spec.cutoff;
    let ke = spec.coulomb_constant;
    let mut energy = 0.0;
    let mut gradient = vec![0.0; q.len()];
    for i in 0..n {
        for j in i + 1..n {
            if spec
                .excluded
                .iter()
                .any(|&(a, b)| (a, b) == (i, j) || (a, b) == (j, i))
            {
                continue;
            }
            let mut d = [0.0; 3];
            for a in 0..3 {
                d[a] = q[3 * j + a] - q[3 * i + a];
                if let Some(l) = spec.box_lengths {
                    d[a] -= l[a] * (d[a] / l[a]).round();
                }
            }
            let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            if r >= rc {
                continue;
            }
            let p = spec.lj[spec.types[i] as usize * 2 + spec.types[j] as usize];
            let qq = ke * spec.charges[i] * spec.charges[j];
            let mut e = p.c12 / r.powi(12) - p.c6 / r.powi(6) - p.shift;
            let mut de = -12.0 * p.c12 / r.powi(13) + 6.0 * p.c6 / r.powi(7);
            match spec.electrostatics {
                Electrostatics::DampedShiftedForce { alpha } => {
                    let erfc = |x: f64| libm::erfc(x);
                    let fshift = erfc(alpha * rc) / (rc * rc)
                        + 2.0 * alpha / std::f64::consts::PI.sqrt()
                            * (-alpha * alpha * rc * rc).exp()
                            / rc;
                    e += qq * (erfc(alpha * r) / r - erfc(alpha * rc) / rc + (r - rc) * fshift);
                    de += qq
                        * (-erfc(alpha * r) / (r * r)
                            - 2.0 * alpha / std::f64::consts::PI.sqrt()
                                * (-alpha * alpha * r * r).exp()
                                / r
                            + fshift);
                }
                Electrostatics::ReactionField { dielectric } => {
                    let k = (dielectric - 1.0) / ((2.0 * dielectric + 1.0) * rc.powi(3));
                    let c = 1.0 / rc + k * rc * rc;
                    e += qq * (1.0 / r + k * r * r - c);
                    de += qq * (-1.0 / (r * r) + 2.0 * k * r);
                }
                Electrostatics::Ewald { alpha } => {
                    let gauss =
                        2.0 * alpha / std::f64::consts::PI.sqrt() * (-alpha * alpha * r * r).exp();
                    e += qq * libm::erfc(alpha * r) / r;
                    de -= qq * (libm::erfc(alpha * r) / (r * r) + gauss / r);
                }
                Electrostatics::Plain => {
                    e += qq / r;
                    de -= qq / (r * r);
                }
                Electrostatics::None => {}
            }
            energy += e;
            for a in 0..3 {
                gradient[3 * j + a] += de * d[a] / r;
                gradient[3 * i + a] -= de * d[a] / r;
            }
        }
    }
    (energy, gradient)
}

#[test]
fn neighbour_list_gives_the_brute_force_sum_through_rebuilds() {
    let mut rng = TestRng::new(62);
    // (box side, atoms, periodic): an all-pairs list, a periodic cell list, an open one.
    for (side, n, periodic) in [(11.0, 60, true), (23.0, 250, true), (23.0, 250, false)] {
        for form in FORMS {
            let mut q = atoms(n, side, 1.6, periodic, &mut rng);
            let spec = spec(n, 5.0, form, periodic.then_some([side; 3]), &mut rng);
            let term = Nonbonded::new(spec.clone(), &q).unwrap();
            for round in 0..6 {
                let (energy, gradient) = brute_force(&spec, &q);
                let mut listed = vec![0.0; q.len()];
                term.add_gradient(&q, &mut listed);
                let listed_energy = term.energy(&q);
                let scale = max_abs(&gradient).max(1.0);
                assert!(
                    (listed_energy - energy).abs() <= 1e-9 * energy.abs().max(1.0),
                    "{form:?}, L = {side} ({periodic}), round {round}: energy {listed_energy} vs {energy}"
                );
                let error = max_abs_difference(&listed, &gradient);
                assert!(
                    error <= 1e-9 * scale,
                    "{form:?}, L = {side} ({periodic}), round {round}: gradient off by {error:e}"
                );
                // Move every atom by up to 0.3 (some rounds keep the list, others force a
                // rebuild), and shift a few by whole boxes: positions are never wrapped.
                for (k, x) in q.iter_mut().enumerate() {
                    *x += rng.uniform(-0.3, 0.3);
                    if periodic && round % 2 == 1 && k % 7 == 0 {
                        *x += side * (1.0 + (k % 3) as f64);
                    }
                }
            }
            // Moves of up to 0.3 per coordinate add up to more than the skin (1) within a
            // few rounds: the list must have been rebuilt on the way.
            let (_, _, builds) = term.list_statistics();
            assert!(builds >= 2, "the list was never rebuilt ({builds} builds)");
        }
    }
}

#[test]
fn torsions_match_finite_differences() {
    let mut rng = TestRng::new(63);
    // A zig-zag chain of six atoms with random offsets: three dihedrals, a cosine series.
    let mut q = Vec::new();
    for i in 0..6 {
        q.extend([
            1.3 * i as f64 + rng.uniform(-0.2, 0.2),
            if i % 2 == 0 { 0.0 } else { 0.9 } + rng.uniform(-0.2, 0.2),
            rng.uniform(-0.6, 0.6),
        ]);
    }
    let series = vec![
        Cosine {
            k: 1.4,
            periodicity: 3.0,
            phase: 0.0,
        },
        Cosine {
            k: 0.5,
            periodicity: 1.0,
            phase: 0.7,
        },
        Cosine {
            k: 2.5,
            periodicity: 2.0,
            phase: std::f64::consts::PI,
        },
    ];
    let dihedrals = (0..3)
        .map(|s| Dihedral {
            atoms: [s, s + 1, s + 2, s + 3],
            series: series.clone(),
        })
        .collect();
    check(&Torsions::new(dihedrals, None), &q, &mut rng, "torsions");
    // Across a periodic boundary: the same chain shifted so that it straddles the box.
    let side = 7.0;
    let shifted: Vec<f64> = q
        .iter()
        .enumerate()
        .map(|(k, x)| if k % 3 == 0 { x + 3.0 } else { *x })
        .collect();
    let dihedrals = vec![Dihedral {
        atoms: [2, 3, 4, 5],
        series,
    }];
    let term = Torsions::new(dihedrals, Some(PeriodicBox { lengths: [side; 3] }));
    check(&term, &shifted, &mut rng, "torsions, periodic");
}

/// From `PARALLEL_MIN_DIHEDRALS` (256) dihedrals on, in a pool of several threads, the
/// torsion gradient is computed in parallel and added in dihedral order: 600 random
/// dihedrals on 80 atoms (so every atom gets many additions, whose order the bits would
/// show) give the bits of one thread on two and three, and of the serial loop outside a pool.
#[test]
fn torsions_give_the_same_bits_on_one_two_and_three_threads() {
    let mut rng = TestRng::new(66);
    let n = 80;
    let q: Vec<f64> = (0..3 * n).map(|_| rng.uniform(0.0, 12.0)).collect();
    let dihedrals: Vec<Dihedral> = (0..600)
        .map(|_| {
            let mut atoms = [0; 4];
            for k in 0..4 {
                atoms[k] = loop {
                    let a = (rng.next_u64() % n as u64) as usize;
                    if !atoms[..k].contains(&a) {
                        break a;
                    }
                };
            }
            let series = vec![Cosine {
                k: rng.uniform(0.1, 2.0),
                periodicity: (1 + rng.next_u64() % 3) as f64,
                phase: rng.uniform(0.0, 3.0),
            }];
            Dihedral { atoms, series }
        })
        .collect();
    let term = Torsions::new(dihedrals, Some(PeriodicBox { lengths: [12.0; 3] }));
    let gradient = || {
        let mut g = vec![0.0; q.len()];
        term.add_gradient(&q, &mut g);
        g.iter().map(|x| x.to_bits()).collect::<Vec<u64>>()
    };
    let serial = gradient();
    for threads in [1, 2, 3] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        assert_eq!(pool.install(gradient), serial, "{threads} threads");
    }
}

#[test]
fn torsion_angle_follows_the_iupac_sign() {
    use longstep::forces::torsion::dihedral_angle;
    // trans: π; cis: 0; +90° when the far atom turns anticlockwise seen along j → k.
    let (i, j, k) = ([1.0, 1.0, 0.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0]);
    let trans = dihedral_angle(i, j, k, [0.0, -1.0, 0.0]);
    let cis = dihedral_angle([0.0, 1.0, 0.0], j, k, [1.0, 1.0, 0.0]);
    let plus = dihedral_angle([0.0, 1.0, 0.0], j, k, [1.0, 0.0, 1.0]);
    assert!(
        (trans.abs() - std::f64::consts::PI).abs() < 1e-12,
        "{trans}"
    );
    assert!(cis.abs() < 1e-12, "{cis}");
    assert!((plus - std::f64::consts::FRAC_PI_2).abs() < 1e-12, "{plus}");
}

#[test]
fn coulomb_pairs_match_finite_differences() {
    let mut rng = TestRng::new(64);
    let q = atoms(4, 5.0, 1.6, false, &mut rng);
    let pairs = vec![
        Pair {
            a: Site::Particle(0),
            b: Site::Particle(3),
            potential: Coulomb {
                charge_product: 40.0,
            },
        },
        Pair {
            a: Site::Particle(1),
            b: Site::Particle(2),
            potential: Coulomb {
                charge_product: -75.0,
            },
        },
    ];
    let term = PairTerm::new("coulomb-14", TermClass::Nonbonded, 3, pairs, None);
    check(&term, &q, &mut rng, "coulomb 1-4");
}
