//! The non-bonded term split by distance (`forces::distance_split`): the short-range part
//! against a brute-force double loop of `S · V` over all pairs, the two parts adding up to
//! the full term, gradients and Hessian-vector products against central finite
//! differences (both switch modes, periodic and open), the switch's continuity at `r_in`
//! and `r_out`, the gradient cache, and the same bits at 1 and 2 threads.
//!
//! Tolerances. Brute force against the term: the same formulas summed in another order;
//! ≲ 10⁴ pair terms of size ≲ 10² in double precision differ by ≲ 10⁴·10²·1e-16 = 1e-10 of
//! the absolute sum, so 1e-9·Σ|V| bounds it. Sum against full: one subtraction and one
//! addition of numbers of size |V_full| and |V_short|, so a few ulps of their size:
//! 1e-12·(|V_full| + |V_short|) (gradients likewise per component). Finite differences as
//! in `molecule_terms.rs`: ε = 1e-5 gives truncation ≤ ε²/6·|f‴| and round-off ≈ 2u|V|/ε,
//! both ≲ 1e-7 here (atoms ≥ 0.9 apart only within a molecule, whose pairs are excluded
//! or carry |Q| ≤ 60 at ≥ 1.5; the switch's derivatives are ≤ 60/w³), so 1e-5·max(1, |exact|)
//! bounds them while a missing chain-rule term is off by O(1).

mod common;

use common::{TestRng, max_abs, max_abs_difference};
use longstep::forces::distance_split::{
    NonbondedShort, ShortCoulomb, SplitSpec, Switch, SwitchBy, molecules_from_bonds,
    reference_atoms, split_nonbonded,
};
use longstep::forces::nonbonded::{Electrostatics, LjPair, Nonbonded, NonbondedSpec};
use longstep::forces::{ForceTerm, Precision};

const K_E: f64 = 332.06371;
const EPSILON: f64 = 1e-5;
const FD_TOLERANCE: f64 = 1e-5;

/// Waters on a jittered cubic grid (spacing 3.1 Å), randomly oriented, O–H 1.0 Å,
/// H–O–H 109.5°, every atom ≥ 1.5 Å from the atoms of other molecules (minimum image in the
/// grid's box): positions, O–H bonds and the box length. `side` sites per axis.
fn waters(side: usize, count: usize, rng: &mut TestRng) -> (Vec<f64>, Vec<[usize; 2]>, f64) {
    let spacing = 3.1;
    let length = side as f64 * spacing;
    let mut q: Vec<f64> = Vec::with_capacity(9 * count);
    let mut bonds = Vec::new();
    for w in 0..count {
        let site = [w / (side * side), (w / side) % side, w % side];
        let molecule = loop {
            let candidate = water(site.map(|s| (s as f64 + 0.5) * spacing), rng);
            let clear = candidate.chunks_exact(3).all(|x| {
                q.chunks_exact(3).all(|y| {
                    let r2: f64 = (0..3)
                        .map(|a| {
                            let d = x[a] - y[a];
                            let d = d - length * (d / length).round();
                            d * d
                        })
                        .sum();
                    r2 >= 1.5 * 1.5
                })
            });
            if clear {
                break candidate;
            }
        };
        q.extend(molecule);
        bonds.push([3 * w, 3 * w + 1]);
        bonds.push([3 * w, 3 * w + 2]);
    }
    (q, bonds, length)
}

/// One water near `centre`, randomly oriented: O, H, H.
fn water(centre: [f64; 3], rng: &mut TestRng) -> Vec<f64> {
    let o: [f64; 3] = centre.map(|c| c + rng.uniform(-0.3, 0.3));
    let unit = |x: [f64; 3]| {
        let norm = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
        x.map(|c| c / norm)
    };
    let u = unit([
        rng.uniform(-1.0, 1.0),
        rng.uniform(-1.0, 1.0),
        rng.uniform(-1.0, 1.0),
    ]);
    let t = [
        rng.uniform(-1.0, 1.0),
        rng.uniform(-1.0, 1.0),
        rng.uniform(-1.0, 1.0),
    ];
    let v = unit([
        u[1] * t[2] - u[2] * t[1],
        u[2] * t[0] - u[0] * t[2],
        u[0] * t[1] - u[1] * t[0],
    ]);
    let half = 0.5 * 109.5_f64.to_radians();
    let mut atoms = o.to_vec();
    for sign in [1.0, -1.0] {
        atoms.extend((0..3).map(|a| o[a] + half.cos() * u[a] + sign * half.sin() * v[a]));
    }
    atoms
}

/// SPC/Fw-like parameters: O with LJ and −0.82, H charge only; exclusions O–H always and
/// H–H when `exclude_hh` (else the H–H pair is an intramolecular non-bonded pair).
fn water_spec(
    n: usize,
    cutoff: f64,
    electrostatics: Electrostatics,
    box_lengths: Option<[f64; 3]>,
    exclude_hh: bool,
) -> NonbondedSpec {
    let types: Vec<u32> = (0..n).map(|i| (i % 3 != 0) as u32).collect();
    let charges = (0..n)
        .map(|i| if i % 3 == 0 { -0.82 } else { 0.41 })
        .collect();
    let lj = vec![
        LjPair::new(0.1554253, 3.165492, cutoff, true),
        LjPair::default(),
        LjPair::default(),
        LjPair::default(),
    ];
    let mut excluded = Vec::new();
    for w in 0..n / 3 {
        excluded.push((3 * w, 3 * w + 1));
        excluded.push((3 * w, 3 * w + 2));
        if exclude_hh {
            excluded.push((3 * w + 1, 3 * w + 2));
        }
    }
    NonbondedSpec {
        cutoff,
        skin: 1.0,
        inner_buffer: None,
        electrostatics,
        coulomb_constant: K_E,
        box_lengths,
        types,
        lj,
        charges,
        excluded,
    }
}

fn split_spec(by: SwitchBy, r_in: f64, r_out: f64, n: usize, bonds: &[[usize; 2]]) -> SplitSpec {
    let molecule_of = molecules_from_bonds(n, bonds);
    let masses: Vec<f64> = (0..n)
        .map(|i| if i % 3 == 0 { 15.9994 } else { 1.008 })
        .collect();
    SplitSpec {
        r_in,
        r_out,
        by,
        short_coulomb: ShortCoulomb::Model,
        reference_atoms: reference_atoms(&molecule_of, &masses, None).unwrap(),
        molecule_of,
    }
}

/// The pair energy of the test model (LJ energy-shifted at `r_c`, DSF α = 0 Coulomb).
fn pair_energy(spec: &NonbondedSpec, i: usize, j: usize, r: f64) -> f64 {
    let rc = spec.cutoff;
    let mut v = 0.0;
    if i.is_multiple_of(3) && j.is_multiple_of(3) {
        let p = spec.lj[0];
        v += p.c12 / r.powi(12) - p.c6 / r.powi(6) - p.shift;
    }
    let qq = K_E * spec.charges[i] * spec.charges[j];
    v + qq * (1.0 / r - 2.0 / rc + r / (rc * rc))
}

/// Brute force: (Σ S·V, Σ V, Σ |V|) over every non-excluded pair inside the cutoff.
fn brute_force(spec: &NonbondedSpec, split: &SplitSpec, q: &[f64]) -> (f64, f64, f64) {
    let n = spec.types.len();
    let switch = Switch::new(split.r_in, split.r_out).unwrap();
    let distance = |i: usize, j: usize| -> f64 {
        (0..3)
            .map(|a| {
                let mut d = q[3 * j + a] - q[3 * i + a];
                if let Some(l) = spec.box_lengths {
                    d -= l[a] * (d / l[a]).round();
                }
                d * d
            })
            .sum::<f64>()
            .sqrt()
    };
    let (mut short, mut full, mut scale) = (0.0, 0.0, 0.0);
    for i in 0..n {
        for j in i + 1..n {
            if spec.excluded.contains(&(i, j)) {
                continue;
            }
            let r = distance(i, j);
            if r >= spec.cutoff {
                continue;
            }
            let v = pair_energy(spec, i, j, r);
            let (mi, mj) = (split.molecule_of[i], split.molecule_of[j]);
            let switch_distance = if split.by == SwitchBy::Molecule && mi != mj {
                distance(
                    split.reference_atoms[mi as usize],
                    split.reference_atoms[mj as usize],
                )
            } else {
                r
            };
            short += switch.value_slope(switch_distance).0 * v;
            full += v;
            scale += v.abs();
        }
    }
    (short, full, scale)
}

fn gradient(term: &dyn ForceTerm, q: &[f64]) -> Vec<f64> {
    let mut g = vec![0.0; q.len()];
    term.add_gradient(q, &mut g);
    g
}

fn check_finite_differences(term: &dyn ForceTerm, q: &[f64], rng: &mut TestRng, label: &str) {
    let g = gradient(term, q);
    let fd = common::finite_difference_gradient(term, q, EPSILON);
    let error = max_abs_difference(&g, &fd);
    let scale = max_abs(&g).max(1.0);
    assert!(
        error <= FD_TOLERANCE * scale,
        "{label}: gradient differs from finite differences by {error:e} (scale {scale:e})"
    );
    assert!(max_abs(&g) > 1e-3, "{label}: gradient is zero");
    for _ in 0..2 {
        let v = rng.vector(q.len(), -1.0, 1.0);
        let mut hv = vec![0.0; q.len()];
        term.add_hessian_vector(q, &v, &mut hv);
        let fd = common::finite_difference_hessian_vector(term, q, &v, EPSILON);
        let error = max_abs_difference(&hv, &fd);
        let scale = max_abs(&hv).max(1.0);
        assert!(
            error <= FD_TOLERANCE * scale,
            "{label}: Hessian-vector product differs from finite differences by {error:e} \
             (scale {scale:e})"
        );
    }
}

/// (label, mode, periodic, exclude H–H)
const CASES: [(&str, SwitchBy, bool, bool); 4] = [
    ("by molecule, periodic", SwitchBy::Molecule, true, true),
    ("by atom pair, periodic", SwitchBy::AtomPair, true, true),
    (
        "by molecule, open, H–H pairs",
        SwitchBy::Molecule,
        false,
        false,
    ),
    (
        "by atom pair, open, H–H pairs",
        SwitchBy::AtomPair,
        false,
        false,
    ),
];

#[test]
fn short_part_is_the_switched_brute_force_sum_and_parts_add_up() {
    let mut rng = TestRng::new(12);
    // 4³ sites: a 12.4 Å box, so a 6 Å cutoff is under half of it.
    let (q, bonds, length) = waters(4, 60, &mut rng);
    let n = q.len() / 3;
    // With O–H = 1 Å, r_out + 2 Å < L − r_c = 6.4 Å takes the whole-molecule loop by
    // molecule (r_out = 3.5), else the loop with a minimum image per atom pair (5.0).
    for ((label, by, periodic, exclude_hh), (r_in, r_out)) in CASES
        .into_iter()
        .flat_map(|case| [(case, (2.5, 3.5)), (case, (3.5, 5.0))])
    {
        let label = format!("{label}, r_out {r_out}");
        let lengths = periodic.then_some([length; 3]);
        let spec = water_spec(
            n,
            6.0,
            Electrostatics::DampedShiftedForce { alpha: 0.0 },
            lengths,
            exclude_hh,
        );
        let split = split_spec(by, r_in, r_out, n, &bonds);
        let (short, rest) = split_nonbonded(spec.clone(), &split, &q).unwrap();
        let full = Nonbonded::new(spec.clone(), &q).unwrap();
        let (expected_short, expected_full, scale) = brute_force(&spec, &split, &q);
        let e_short = short.energy(&q);
        assert!(
            (e_short - expected_short).abs() <= 1e-9 * scale,
            "{label}: short part {e_short} against brute force {expected_short}"
        );
        // Each part at least 10⁴ times the energy tolerance above, so that a split that
        // moved pairs between the parts could not pass within it.
        let trivial = 1e4 * 1e-9 * scale;
        assert!(
            e_short.abs() > trivial && (expected_full - expected_short).abs() > trivial,
            "{label}: both parts must be non-trivial: short {e_short}, full {expected_full}, \
             scale {scale}"
        );
        let (e_rest, e_full) = (rest.energy(&q), full.energy(&q));
        assert!(
            (e_rest + e_short - e_full).abs() <= 1e-12 * (e_full.abs() + e_short.abs()),
            "{label}: parts {e_short} + {e_rest} against full {e_full}"
        );
        let (g_short, g_rest, g_full) = (
            gradient(&short, &q),
            gradient(&rest, &q),
            gradient(&full, &q),
        );
        let bound = 1e-12 * (max_abs(&g_full) + max_abs(&g_short));
        for k in 0..q.len() {
            assert!(
                (g_short[k] + g_rest[k] - g_full[k]).abs() <= bound,
                "{label}: gradient component {k}: parts {} + {} against full {}",
                g_short[k],
                g_rest[k],
                g_full[k]
            );
        }
    }
}

/// Waters of one kind take the SIMD molecule blocks; waters of two kinds (one molecule's
/// charges moved) the row loop compiled for three atoms; one O–H bond left out makes a
/// one-atom molecule, so the same box takes the row loop for any sizes: each must be the
/// switched brute-force sum, with gradients that match finite differences.
#[test]
fn molecules_of_one_kind_of_two_and_of_mixed_sizes_give_the_switched_sum() {
    let mut rng = TestRng::new(21);
    let (q, bonds, length) = waters(4, 60, &mut rng);
    let n = q.len() / 3;
    // r_out + 2 Å < L − r_c: the whole-molecule loops.
    let cases = [
        ("one kind", None, false, "molecule blocks"),
        ("two kinds", None, true, "molecule rows"),
        ("mixed sizes", Some(1), false, "molecule rows"),
    ];
    for (label, skipped, two_kinds, pair_loop) in cases {
        let mut spec = water_spec(
            n,
            6.0,
            Electrostatics::DampedShiftedForce { alpha: 0.0 },
            Some([length; 3]),
            true,
        );
        if two_kinds {
            // The last water becomes another neutral kind.
            spec.charges[n - 3] *= 0.9;
            spec.charges[n - 2] *= 0.9;
            spec.charges[n - 1] *= 0.9;
        }
        // Exclusions stay inside molecules: the lone H (atom 2) interacts with its old water.
        if skipped.is_some() {
            spec.excluded.retain(|&(i, j)| i != 2 && j != 2);
        }
        let kept: Vec<[usize; 2]> = bonds
            .iter()
            .enumerate()
            .filter(|&(k, _)| Some(k) != skipped)
            .map(|(_, &b)| b)
            .collect();
        let split = split_spec(SwitchBy::Molecule, 2.5, 3.5, n, &kept);
        let (short, _) = split_nonbonded(spec.clone(), &split, &q).unwrap();
        assert_eq!(short.short_range().pair_loop(), pair_loop, "{label}");
        let (expected, _, scale) = brute_force(&spec, &split, &q);
        let energy = short.energy(&q);
        assert!(
            (energy - expected).abs() <= 1e-9 * scale,
            "{label}: short part {energy} against brute force {expected}"
        );
        check_finite_differences(&short, &q, &mut rng, label);
    }
}

/// The SIMD molecule blocks give the portable lanes' bits on every instruction set here
/// (energy and gradient; `1/r` by integer seed and Newton steps, sums in a fixed lane order).
#[test]
fn molecule_blocks_give_the_same_bits_on_every_instruction_set() {
    let mut rng = TestRng::new(23);
    let (q, bonds, length) = waters(4, 60, &mut rng);
    let n = q.len() / 3;
    for electrostatics in [
        Electrostatics::DampedShiftedForce { alpha: 0.0 },
        Electrostatics::DampedShiftedForce { alpha: 0.2 },
        Electrostatics::ReactionField { dielectric: 78.0 },
        Electrostatics::Ewald { alpha: 0.35 },
    ] {
        let spec = water_spec(n, 6.0, electrostatics, Some([length; 3]), true);
        // r_in 2.5 < R < r_out 3.5 puts many pairs on the switch's slope.
        let split = split_spec(SwitchBy::Molecule, 2.5, 3.5, n, &bonds);
        let (short, _) = split_nonbonded(spec, &split, &q).unwrap();
        assert_eq!(short.short_range().pair_loop(), "molecule blocks");
        assert_same_bits_on_every_isa(&short, &q, &format!("{electrostatics:?}"));
    }
}

/// The short part's energy and gradient at `q` have the same bits on every instruction set
/// here as on the first (the portable lanes).
fn assert_same_bits_on_every_isa(short: &NonbondedShort, q: &[f64], label: &str) {
    let mut results = Vec::new();
    for isa in longstep::forces::simd::Isa::available() {
        short.short_range().set_isa(isa);
        let g = gradient(short, q);
        results.push((
            isa,
            short.energy(q).to_bits(),
            g.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
        ));
    }
    let (_, e0, g0) = &results[0];
    for (isa, e, g) in &results[1..] {
        assert_eq!(e, e0, "{label}: energy on {isa:?} against portable");
        assert!(g == g0, "{label}: gradient on {isa:?} against portable");
    }
}

/// By atom pair the short part is the cluster-pair kernel with the switch in its lanes: the
/// portable lanes' bits on every instruction set here, in both precisions.
#[test]
fn the_switched_cluster_kernel_gives_the_same_bits_on_every_instruction_set() {
    let mut rng = TestRng::new(29);
    let (q, bonds, length) = waters(4, 60, &mut rng);
    let n = q.len() / 3;
    for electrostatics in [
        Electrostatics::DampedShiftedForce { alpha: 0.0 },
        Electrostatics::Ewald { alpha: 0.35 },
    ] {
        for precision in [Precision::Double, Precision::Mixed] {
            let spec = water_spec(n, 6.0, electrostatics, Some([length; 3]), true);
            let split = split_spec(SwitchBy::AtomPair, 2.5, 3.5, n, &bonds);
            let (short, _) = split_nonbonded(spec, &split, &q).unwrap();
            assert_eq!(short.short_range().pair_loop(), "cluster pairs");
            assert!(short.set_precision(precision));
            assert_same_bits_on_every_isa(
                &short,
                &q,
                &format!("{electrostatics:?}, {precision:?}"),
            );
        }
    }
}

#[test]
fn both_parts_match_finite_differences_in_both_modes() {
    let mut rng = TestRng::new(7);
    let (q, bonds, length) = waters(4, 40, &mut rng);
    let n = q.len() / 3;
    for (label, by, periodic, exclude_hh) in CASES {
        // The whole-molecule loop (r_out + 2 Å < L − r_c) and the per-pair image (5.5).
        for (electrostatics, r_in, r_out) in [
            (Electrostatics::DampedShiftedForce { alpha: 0.2 }, 2.5, 4.0),
            (Electrostatics::ReactionField { dielectric: 78.3 }, 3.0, 5.5),
        ] {
            let lengths = periodic.then_some([length; 3]);
            let spec = water_spec(n, 6.0, electrostatics, lengths, exclude_hh);
            let split = split_spec(by, r_in, r_out, n, &bonds);
            let (short, rest) = split_nonbonded(spec, &split, &q).unwrap();
            check_finite_differences(&short, &q, &mut rng, &format!("{label}, short"));
            check_finite_differences(&rest, &q, &mut rng, &format!("{label}, remainder"));
        }
    }
}

#[test]
fn switch_is_continuous_to_second_order_at_both_ends() {
    let switch = Switch::new(6.0, 7.0).unwrap();
    let w: f64 = 1.0;
    for delta in [1e-3, 1e-6] {
        for (edge, value) in [(6.0, 1.0), (7.0, 0.0)] {
            for side in [-1.0, 1.0] {
                let (s, s1, s2) = switch.derivatives(edge + side * delta);
                // Taylor bounds of the quintic at an end: |S − S(end)| ≤ 10(δ/w)³,
                // |S′| ≤ 30(δ/w)²/w, |S″| ≤ 60(δ/w)/w²; S near 1 carries a few ulps of 1.
                let t = delta / w;
                let round_off = 4.0 * f64::EPSILON * value;
                assert!(
                    (s - value).abs() <= 10.0 * t.powi(3) * (1.0 + 1e-9) + round_off,
                    "S at {edge}±{delta}: {s}"
                );
                assert!(
                    s1.abs() <= 30.0 * t * t / w * (1.0 + 1e-9),
                    "S′ at {edge}±{delta}"
                );
                assert!(
                    s2.abs() <= 60.0 * t / (w * w) * (1.0 + 1e-9),
                    "S″ at {edge}±{delta}"
                );
            }
        }
    }
    // Inside: S′ and S″ are the derivatives of S and S′ (central differences, h = 1e-5:
    // truncation ≤ h²/6·max|S‴| = 1e-10·60/6, round-off ≈ 1e-16/1e-5).
    for r in [6.1, 6.37, 6.5, 6.81, 6.99] {
        let h = 1e-5;
        let (_, s1, s2) = switch.derivatives(r);
        let (sp, s1p) = switch.value_slope(r + h);
        let (sm, s1m) = switch.value_slope(r - h);
        assert!(((sp - sm) / (2.0 * h) - s1).abs() < 1e-8, "S′ at {r}");
        assert!(((s1p - s1m) / (2.0 * h) - s2).abs() < 1e-8, "S″ at {r}");
    }
    assert_eq!(
        switch.value_slope(6.5).0,
        0.5,
        "the quintic is symmetric about the middle"
    );
}

#[test]
fn bad_switch_ranges_are_refused_with_the_reason() {
    let mut rng = TestRng::new(3);
    let (q, bonds, length) = waters(4, 8, &mut rng);
    let n = q.len() / 3;
    let spec = water_spec(
        n,
        6.0,
        Electrostatics::DampedShiftedForce { alpha: 0.0 },
        Some([length; 3]),
        true,
    );
    for (r_in, r_out, expected) in [
        (5.0, 5.0, "must be smaller than r_out"),
        (5.5, 4.0, "must be smaller than r_out"),
        (0.0, 4.0, "must be positive"),
        (4.0, 6.5, "beyond the non-bonded cutoff 6"),
    ] {
        let split = split_spec(SwitchBy::Molecule, r_in, r_out, n, &bonds);
        let error = split_nonbonded(spec.clone(), &split, &q)
            .err()
            .expect("refused");
        assert!(
            error.contains(expected),
            "r_in {r_in}, r_out {r_out}: {error}"
        );
    }
    let molecule_of = molecules_from_bonds(n, &bonds);
    let masses = vec![1.0; n];
    let error = reference_atoms(&molecule_of, &masses, Some(&|_| false)).unwrap_err();
    assert!(error.contains("molecule 0"), "{error}");
}

#[test]
fn the_gradient_cache_serves_the_remainder_only_at_the_same_positions() {
    let mut rng = TestRng::new(5);
    let (q, bonds, length) = waters(4, 60, &mut rng);
    let n = q.len() / 3;
    let spec = water_spec(
        n,
        6.0,
        Electrostatics::DampedShiftedForce { alpha: 0.0 },
        Some([length; 3]),
        true,
    );
    let split = split_spec(SwitchBy::Molecule, 3.5, 5.0, n, &bonds);
    let (short, rest) = split_nonbonded(spec.clone(), &split, &q).unwrap();
    let (_, fresh) = split_nonbonded(spec, &split, &q).unwrap();
    // The remainder after the short part at the same q (cache hit) is bit-for-bit the
    // remainder alone (cache miss).
    gradient(&short, &q);
    assert_eq!(gradient(&rest, &q), gradient(&fresh, &q));
    // At other positions the cache must not be used. Both full terms are built at `q`: a
    // buffered pair list depends on where it was built (its summation order does), so
    // only terms with the same list history give the same bits.
    let moved: Vec<f64> = q.iter().map(|x| x + rng.uniform(-0.05, 0.05)).collect();
    gradient(&short, &q);
    let (_, fresh) = split_nonbonded(
        water_spec(
            n,
            6.0,
            Electrostatics::DampedShiftedForce { alpha: 0.0 },
            Some([length; 3]),
            true,
        ),
        &split,
        &q,
    )
    .unwrap();
    assert_eq!(gradient(&rest, &moved), gradient(&fresh, &moved));
}

#[test]
fn same_bits_at_one_and_two_threads() {
    // 700 waters (2100 atoms): the short part's list is split into 4 chunks.
    let mut rng = TestRng::new(9);
    let (q, bonds, length) = waters(9, 700, &mut rng);
    let n = q.len() / 3;
    let v = rng.vector(q.len(), -1.0, 1.0);
    let mut results = Vec::new();
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        results.push(pool.install(|| {
            let mut out = Vec::new();
            for by in [SwitchBy::Molecule, SwitchBy::AtomPair] {
                let spec = water_spec(
                    n,
                    9.0,
                    Electrostatics::DampedShiftedForce { alpha: 0.0 },
                    Some([length; 3]),
                    true,
                );
                let split = split_spec(by, 6.0, 7.0, n, &bonds);
                let (short, rest) = split_nonbonded(spec, &split, &q).unwrap();
                for term in [&short as &dyn ForceTerm, &rest] {
                    out.push(vec![term.energy(&q)]);
                    out.push(gradient(term, &q));
                    let mut hv = vec![0.0; q.len()];
                    term.add_hessian_vector(&q, &v, &mut hv);
                    out.push(hv);
                }
            }
            out
        }));
    }
    assert!(
        results[0] == results[1],
        "results differ between 1 and 2 threads"
    );
}

/// `∇V_level` of a scene's level at `q`.
fn level_gradient(scene: &mut longstep::io::scene::Scene, level: usize, q: &[f64]) -> Vec<f64> {
    let mut g = vec![0.0; q.len()];
    scene.system.forces.gradient(level, q, &mut g);
    g
}

#[test]
fn the_water_box_split_adds_up_to_the_unsplit_model() {
    let mut plain = common::scene_file("systems/water-box/scene.toml", &[]);
    let mut split = common::scene_file("systems/water-box/three-level.toml", &[]);
    assert_eq!(split.system.forces.n_levels(), 3);
    let mut rng = TestRng::new(216);
    let start = plain.system.state.q.clone();
    // At the file's positions and at positions moved up to 0.4 Å per coordinate (past the
    // skin/2 of both lists: both are rebuilt).
    let moved: Vec<f64> = start.iter().map(|x| x + rng.uniform(-0.4, 0.4)).collect();
    for q in [start, moved] {
        let unsplit = plain.system.forces.energy(1, &q);
        let (short, rest) = (
            split.system.forces.energy(1, &q),
            split.system.forces.energy(2, &q),
        );
        // Round-off of full − short + short: a few ulps of |full| + |short|.
        let bound = 1e-12 * (unsplit.abs() + short.abs());
        assert!(
            (short + rest - unsplit).abs() <= bound,
            "energy: {short} + {rest} against {unsplit}"
        );
        assert_eq!(
            plain.system.forces.energy(0, &q),
            split.system.forces.energy(0, &q),
            "bonded level"
        );
        let g = level_gradient(&mut plain, 1, &q);
        let (g1, g2) = (
            level_gradient(&mut split, 1, &q),
            level_gradient(&mut split, 2, &q),
        );
        let bound = 1e-12 * (max_abs(&g) + max_abs(&g1));
        let error = (0..q.len())
            .map(|k| (g1[k] + g2[k] - g[k]).abs())
            .fold(0.0, f64::max);
        assert!(
            error <= bound,
            "gradient: parts differ from the model by {error:e}"
        );
        // The split is not trivial: the remainder is a small part of the force.
        assert!(
            max_abs(&g2) < 0.5 * max_abs(&g),
            "remainder as large as the force"
        );
    }
}

#[test]
fn the_level_table_shows_both_parts_with_their_range() {
    let output = common::longstep()
        .args(["check", "systems/water-box/three-level.toml"])
        .output()
        .unwrap();
    assert!(output.status.success());
    let text = String::from_utf8_lossy(&output.stdout).into_owned()
        + &String::from_utf8_lossy(&output.stderr);
    for expected in [
        "1 (level 1) = nonbonded-short \"short-range: switched off from r_in = 6 to r_out = 7 by molecule (O)\"",
        "2 (slow) = nonbonded-remainder \"remainder: nonbonded − short-range\"",
        "0 (fast) = bond \"bonds\"",
        // One kind of water: the SIMD molecule blocks.
        "computed as molecule blocks",
    ] {
        assert!(
            text.contains(expected),
            "level table lacks {expected}:\n{text}"
        );
    }
}

#[test]
fn impulse_on_three_levels_gives_the_same_bits_at_one_and_two_threads() {
    let mut finals = Vec::new();
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        finals.push(pool.install(|| {
            let mut scene = common::scene_file("systems/water-box/three-level.toml", &[]);
            let mut settings = longstep::settings::MethodSettings::new("impulse", 2.0);
            settings.level_steps = Some(vec![2, 2]);
            let mut integrator = longstep::integrators::build(&settings, &mut Vec::new()).unwrap();
            common::integrate(&mut scene, integrator.as_mut(), 10)
        }));
    }
    assert!(
        finals[0] == finals[1],
        "positions or momenta differ between 1 and 2 threads"
    );
}

/// Impulse on the three-level water box for `span` fs at outer step `h` (level steps 2, 2):
/// the largest |E(t) − E(0)| over the outer steps.
fn impulse_energy_error(h: f64, span: f64) -> f64 {
    let mut scene = common::scene_file("systems/water-box/three-level.toml", &[]);
    let mut settings = longstep::settings::MethodSettings::new("impulse", h);
    settings.level_steps = Some(vec![2, 2]);
    let mut integrator = longstep::integrators::build(&settings, &mut Vec::new()).unwrap();
    integrator.setup(&mut scene.system).unwrap();
    let start = scene.system.total_energy();
    let mut error: f64 = 0.0;
    for _ in 0..(span / h).round() as usize {
        integrator.step(&mut scene.system).unwrap();
        error = error.max((scene.system.total_energy() - start).abs());
    }
    error
}

#[test]
fn impulse_on_three_levels_conserves_energy_to_second_order() {
    // Impulse is symplectic, so on a split whose forces are the gradients of its energies
    // the energy error stays O(h²) (a modified Hamiltonian): halving every step (outer,
    // middle, inner together) divides it by 4. A split force that is not the gradient of
    // its energy (a missing switch term) gives an error that grows with time and does not
    // shrink as h². Accepted: a ratio nearer 4 than 2 or 8 on a log scale, [2√2, 4√2].
    // 60 fs, past the first remainder-list rebuild; h = 2 fs is stable (inner 0.5 fs).
    let (coarse, fine) = (
        impulse_energy_error(2.0, 60.0),
        impulse_energy_error(1.0, 60.0),
    );
    let ratio = coarse / fine;
    assert!(
        (2.0 * 2f64.sqrt()..=4.0 * 2f64.sqrt()).contains(&ratio),
        "energy error {coarse:e} at h = 2 fs, {fine:e} at 1 fs: ratio {ratio}, not ≈ 4"
    );
}

#[test]
fn langevin_respa_without_friction_is_impulse_on_three_levels() {
    // langevin-respa uses the same three-level recursion as impulse: with γ = 1e-300 its O
    // step is the identity below half an ulp, and only the drift taken as two halves
    // differs, by ≤ 1 ulp u = ε max|q| of q per inner step (as in tests/thermostats.rs).
    // Velocities then differ only through forces at positions that differ: per inner step
    // δv dt ≤ (ω dt)² δq with ω dt ≈ 0.35 for the O–H stretch (period ≈ 9 fs) at
    // dt = 0.5 fs, so over n = 12 inner steps δv dt ≤ (ω dt)² n² u/2 ≈ 9 u and
    // δq ≤ n u + Σ δv dt: both stay below 10 n u.
    let (h, steps, dt) = (2.0, 3, 0.5);
    let mut finals = Vec::new();
    let mut inverse_mass = Vec::new();
    for method in ["impulse", "langevin-respa"] {
        let mut scene = common::scene_file("systems/water-box/three-level.toml", &[]);
        inverse_mass = scene.system.inverse_mass.clone();
        let mut settings = longstep::settings::MethodSettings::new(method, h);
        settings.level_steps = Some(vec![2, 2]);
        settings.units = longstep::units::Units::Real;
        settings.temperature = Some(300.0);
        settings.friction = Some(1e-300);
        let mut integrator = longstep::integrators::build(&settings, &mut Vec::new()).unwrap();
        finals.push(common::integrate(&mut scene, integrator.as_mut(), steps));
    }
    let ((q1, p1), (q2, p2)) = (&finals[0], &finals[1]);
    let n = (h / dt) as usize * steps;
    let bound = 10.0 * n as f64 * f64::EPSILON * max_abs(q1);
    let dq = max_abs_difference(q1, q2);
    let dv_dt = (0..p1.len())
        .map(|i| (p1[i] - p2[i]).abs() * inverse_mass[i] * dt)
        .fold(0.0, f64::max);
    assert!(dq <= bound, "positions differ by {dq:e} > {bound:e}");
    assert!(
        dv_dt <= bound,
        "velocities × dt differ by {dv_dt:e} > {bound:e}"
    );
}

/// The energy block of `longstep forces --json` on the PME water box on three levels.
fn pme_three_level_energy(extra: &[&str]) -> serde_json::Value {
    let mut args = vec![
        "forces",
        "systems/water-box/three-level.toml",
        "--coulomb",
        "pme",
        "--json",
    ];
    args.extend_from_slice(extra);
    let (code, stdout, stderr) = common::run_cli(&args);
    assert_eq!(code, 0, "{stderr}");
    let value: serde_json::Value = serde_json::from_str(&stdout).expect("json");
    value["energy"].clone()
}

/// The Coulomb energy of the short part in a `forces --json` energy block.
fn short_coulomb_energy(energy: &serde_json::Value) -> f64 {
    let terms = energy["terms"].as_object().expect("terms");
    let (_, value) = terms
        .iter()
        .find(|(name, _)| name.starts_with("short-range") && name.ends_with("/coulomb"))
        .expect("short-range coulomb");
    value.as_f64().expect("number")
}

#[test]
fn with_pme_the_short_part_takes_the_bare_coulomb_and_the_parts_add_up() {
    let default = pme_three_level_energy(&[]);
    let bare =
        pme_three_level_energy(&["--split", "r_in=6,r_out=7,reference=O,short_coulomb=bare"]);
    let model =
        pme_three_level_energy(&["--split", "r_in=6,r_out=7,reference=O,short_coulomb=model"]);
    // Bare is the default with PME: the same numbers as asking for it.
    assert_eq!(default, bare);
    // Either way the levels add up to the same model: round-off of sums of terms of
    // magnitude ~1e4 (the exclusion and self corrections), a few ulps of 1e4.
    let total = |e: &serde_json::Value| e["total"].as_f64().expect("total");
    assert!(
        (total(&bare) - total(&model)).abs() <= 1e-10 * 1e4,
        "{} against {}",
        total(&bare),
        total(&model)
    );
    // The bare short part holds the near field's erf(αr)/r too, which the screened one
    // leaves to the reciprocal sum on the slow level: at α = 0.347/Å it is ~170 kcal/mol
    // of attraction on this box (erf(0.347 · 3 Å) ≈ 0.86 of the H-bond pairs' Coulomb).
    let (short_bare, short_model) = (short_coulomb_energy(&bare), short_coulomb_energy(&model));
    assert!(
        short_bare < short_model - 100.0,
        "short Coulomb bare {short_bare} against screened {short_model}"
    );
    let slow = |e: &serde_json::Value| e["slow"].as_f64().expect("slow");
    assert!(
        (slow(&bare) - slow(&model) - (short_model - short_bare)).abs() < 1e-6,
        "the slow level gives back what the short level takes"
    );
    let (code, _, stderr) = common::run_cli(&[
        "forces",
        "systems/water-box/three-level.toml",
        "--coulomb",
        "pme",
        "--split",
        "r_in=6,r_out=7,short_coulomb=screened",
    ]);
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("short_coulomb = \"screened\"") && stderr.contains("\"bare\""),
        "{stderr}"
    );
}

/// A checkpoint's state of the short part's molecule list ([`ForceTerm::list_state`]: the
/// reference atoms' positions at its build) makes the same list in a term built elsewhere
/// ([`ForceTerm::restore_lists`]): the restored term then gives the bits of the term the
/// state came from, and a state of the wrong size or without its array is refused by name.
#[test]
fn the_molecule_list_state_restores_the_same_list() {
    let mut rng = TestRng::new(13);
    let (q, bonds, length) = waters(4, 60, &mut rng);
    let n = q.len() / 3;
    let split = split_spec(SwitchBy::Molecule, 3.5, 5.0, n, &bonds);
    let make = |at: &[f64]| {
        let electrostatics = Electrostatics::DampedShiftedForce { alpha: 0.0 };
        let spec = water_spec(n, 6.0, electrostatics, Some([length; 3]), true);
        split_nonbonded(spec, &split, at).unwrap()
    };
    let (short, _) = make(&q);
    let state = short.list_state().expect("the list is built with the term");
    // Built up to 0.6 Å per axis away (more than half the 1 Å skin): another list
    // (`couplings`: the listed molecule pairs' atoms in list order).
    let far: Vec<f64> = q.iter().map(|x| x + rng.uniform(-0.6, 0.6)).collect();
    let (restored, _) = make(&far);
    assert_ne!(restored.couplings(), short.couplings());
    restored.restore_lists(&state).unwrap();
    assert_eq!(restored.couplings(), short.couplings());
    assert_eq!(restored.list_state(), Some(state.clone()));
    // Near q (within half the skin) neither term rebuilds: the same pairs in the same order.
    let near: Vec<f64> = q.iter().map(|x| x + rng.uniform(-0.05, 0.05)).collect();
    assert_eq!(gradient(&restored, &near), gradient(&short, &near));
    assert_eq!(
        restored.energy(&near).to_bits(),
        short.energy(&near).to_bits()
    );
    let wrong_size = serde_json::json!({ "molecule_list_built_at": [1.0, 2.0, 3.0] });
    for (bad, expected) in [
        (wrong_size, "has 3 numbers, this split has 60 molecules"),
        (serde_json::json!({}), "no array \"molecule_list_built_at\""),
    ] {
        let error = restored.restore_lists(&bad).unwrap_err().to_string();
        assert!(error.contains(expected), "{error}");
    }
}
