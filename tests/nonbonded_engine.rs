//! The cluster-pair non-bonded engine (`forces::clusters`, `forces::nonbonded`):
//!
//! * every instruction set this processor has gives the bits of the portable lanes, in
//!   double and in mixed precision, with tabulated and with factored Lennard-Jones;
//! * double precision is the brute-force sum (round-off apart) and mixed precision is
//!   within its round-off bound, derived pair by pair below;
//! * through a run of the water box the buffered, pruned list holds every pair within the
//!   cutoff at every outer step, across list rebuilds and prunings (no pair missed);
//! * the same bits at one and two threads on the 1728-water box, in both precisions;
//! * the kernel's left-out groups (no pair within the cutoff, hydrogens' Lennard-Jones
//!   lanes) are exact zeros: computing every group gives the same bits.
//!
//! Brute force against the list in double precision: the same formulas summed in another
//! order, so they agree to round-off: sums of ≲ 10³ terms of size ≲ 10³ differ by
//! ≲ 10³·10³·1e-16 = 1e-10; we allow 1e-9·max(1, scale), as `molecule_terms.rs` does.

mod common;

use std::path::Path;

use common::{TestRng, max_abs, max_abs_difference};
use longstep::forces::nonbonded::{Electrostatics, LjPair, Nonbonded, NonbondedSpec};
#[cfg(target_arch = "x86_64")]
use longstep::forces::simd::{Avx2F32, Avx2F64, Avx512F32, Avx512F64};
use longstep::forces::simd::{
    ERFC_X_MAX, EWALD_Z_MAX, EwaldForce, Isa, Portable, Real, Simd, erfc_exp, ewald_force,
};
use longstep::forces::{ForceTerm, Precision};
use longstep::io::scene::{Scene, load_scene};

const FORMS: [Electrostatics; 5] = [
    Electrostatics::DampedShiftedForce { alpha: 0.0 },
    Electrostatics::DampedShiftedForce { alpha: 0.2 },
    Electrostatics::ReactionField { dielectric: 78.3 },
    Electrostatics::Ewald { alpha: 0.45 },
    Electrostatics::None,
];
const CUTOFF: f64 = 5.0;
const KE: f64 = 332.06371;

/// `n` atoms in a periodic cube of side `side`, at least 1.6 apart (minimum image).
fn atoms(n: usize, side: f64, rng: &mut TestRng) -> Vec<f64> {
    let mut q: Vec<f64> = Vec::with_capacity(3 * n);
    while q.len() < 3 * n {
        let x = [0, 1, 2].map(|_| rng.uniform(0.0, side));
        let far = q.chunks_exact(3).all(|y| {
            let r2: f64 = (0..3)
                .map(|a| {
                    let d = x[a] - y[a];
                    let d = d - side * (d / side).round();
                    d * d
                })
                .sum();
            r2 >= 1.6 * 1.6
        });
        if far {
            q.extend(x);
        }
    }
    q
}

/// Three types; `factored` gives geometric coefficients (the kernel's per-atom factors),
/// else a table that does not factor (the kernel's gathered table).
fn spec(
    n: usize,
    side: f64,
    form: Electrostatics,
    factored: bool,
    rng: &mut TestRng,
) -> NonbondedSpec {
    let eps: [f64; 3] = [0.25, 0.1, 0.0];
    let sigma: [f64; 3] = [3.0, 2.5, 1.0];
    let lj = (0..9)
        .map(|k| {
            let (a, b) = (k / 3, k % 3);
            let epsilon = if factored || a == b {
                (eps[a] * eps[b]).sqrt()
            } else {
                0.5 * (eps[a] + eps[b])
            };
            let sigma = if factored {
                (sigma[a] * sigma[b]).sqrt()
            } else {
                0.5 * (sigma[a] + sigma[b])
            };
            LjPair::new(epsilon, sigma, CUTOFF, true)
        })
        .collect();
    NonbondedSpec {
        cutoff: CUTOFF,
        skin: 1.0,
        inner_buffer: None,
        electrostatics: form,
        coulomb_constant: KE,
        box_lengths: Some([side; 3]),
        types: (0..n).map(|i| (i % 3) as u32).collect(),
        lj,
        charges: (0..n)
            .map(|i| {
                if i % 5 == 4 {
                    0.0
                } else {
                    rng.uniform(-0.8, 0.8)
                }
            })
            .collect(),
        excluded: (0..n / 4).map(|k| (4 * k, 4 * k + 1)).collect(),
    }
}

fn gradient_and_energy(term: &Nonbonded, q: &[f64]) -> (Vec<f64>, f64) {
    let mut g = vec![0.0; q.len()];
    term.add_gradient(q, &mut g);
    (g, term.energy(q))
}

fn bits(x: &[f64]) -> Vec<u64> {
    x.iter().map(|v| v.to_bits()).collect()
}

#[test]
fn every_instruction_set_gives_the_bits_of_the_portable_lanes() {
    let mut rng = TestRng::new(71);
    let available = Isa::available();
    eprintln!("instruction sets here: {available:?}");
    for precision in [Precision::Double, Precision::Mixed] {
        for factored in [true, false] {
            for form in FORMS {
                let side = 14.0;
                let q = atoms(150, side, &mut rng);
                let term = Nonbonded::new(spec(150, side, form, factored, &mut rng), &q).unwrap();
                term.set_precision(precision);
                term.set_isa(Isa::Portable);
                let (g0, e0) = gradient_and_energy(&term, &q);
                for &isa in &available {
                    term.set_isa(isa);
                    let (g, e) = gradient_and_energy(&term, &q);
                    let label = format!("{isa:?} {precision:?} {form:?} factored {factored}");
                    assert_eq!(bits(&g), bits(&g0), "{label}: gradient");
                    assert_eq!(e.to_bits(), e0.to_bits(), "{label}: energy");
                }
            }
        }
    }
}

/// The brute-force sum of `spec` at `q` and, per atom, the round-off bound of mixed
/// precision on its gradient.
///
/// Mixed precision rounds positions to f32 (ε = 2⁻²⁴ relative): a displacement `d` from
/// two coordinates of size ≤ 2L (wrapped position plus image shift) is off by
/// `δ ≤ √3·2εL + ε r` in length. A pair force `φ(r) d` whose pieces fall at most like
/// `r⁻¹⁴` (Lennard-Jones repulsion) then moves by at most `P·(15 δ/r + 32ε)` with `P` the
/// sum of the pieces' magnitudes (so that cancellation between pieces cannot hide error):
/// `14 δ/r` from `φ`, `δ/r` from the direction, and 32ε for the ≈ 30 rounded operations
/// and the Newton `1/√r²`. A pair within `δ` of the cutoff may fall on the other side in
/// f32: its whole `P` counts.
fn brute_force_with_bound(spec: &NonbondedSpec, q: &[f64]) -> (f64, Vec<f64>, Vec<f64>) {
    let n = spec.types.len();
    let side = spec.box_lengths.unwrap()[0];
    let eps = f32::EPSILON as f64 / 2.0;
    let mut energy = 0.0;
    let mut gradient = vec![0.0; q.len()];
    let mut bound = vec![0.0; n];
    for i in 0..n {
        for j in i + 1..n {
            if spec.excluded.contains(&(i, j)) {
                continue;
            }
            let d: [f64; 3] = std::array::from_fn(|a| {
                let d = q[3 * j + a] - q[3 * i + a];
                d - side * (d / side).round()
            });
            let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let delta = 3f64.sqrt() * 2.0 * eps * 2.0 * side + eps * r;
            if r >= CUTOFF + delta {
                continue;
            }
            let p = spec.lj[spec.types[i] as usize * 3 + spec.types[j] as usize];
            let qq = KE * spec.charges[i] * spec.charges[j];
            let (e, de, pieces) = pair(spec.electrostatics, p, qq, r);
            let size = if r > CUTOFF - delta {
                pieces
            } else {
                pieces * (15.0 * delta / r + 32.0 * eps)
            };
            bound[i] += size;
            bound[j] += size;
            if r >= CUTOFF {
                continue;
            }
            energy += e;
            for a in 0..3 {
                gradient[3 * j + a] += de * d[a] / r;
                gradient[3 * i + a] -= de * d[a] / r;
            }
        }
    }
    (energy, gradient, bound)
}

/// `(V, V′, Σ|force pieces|)` of one pair at distance `r`, straight from the formulas.
fn pair(form: Electrostatics, p: LjPair, qq: f64, r: f64) -> (f64, f64, f64) {
    let rc = CUTOFF;
    let mut e = p.c12 / r.powi(12) - p.c6 / r.powi(6) - p.shift;
    let mut de = -12.0 * p.c12 / r.powi(13) + 6.0 * p.c6 / r.powi(7);
    let mut pieces = 12.0 * p.c12 / r.powi(13) + 6.0 * p.c6 / r.powi(7);
    match form {
        Electrostatics::DampedShiftedForce { alpha } => {
            let erfc = libm::erfc;
            let g = 2.0 * alpha / std::f64::consts::PI.sqrt();
            let fshift = erfc(alpha * rc) / (rc * rc) + g * (-alpha * alpha * rc * rc).exp() / rc;
            e += qq * (erfc(alpha * r) / r - erfc(alpha * rc) / rc + (r - rc) * fshift);
            let near = erfc(alpha * r) / (r * r) + g * (-alpha * alpha * r * r).exp() / r;
            de += qq * (fshift - near);
            pieces += qq.abs() * (near + fshift);
        }
        Electrostatics::ReactionField { dielectric } => {
            let k = (dielectric - 1.0) / ((2.0 * dielectric + 1.0) * rc.powi(3));
            e += qq * (1.0 / r + k * r * r - (1.0 / rc + k * rc * rc));
            de += qq * (-1.0 / (r * r) + 2.0 * k * r);
            pieces += qq.abs() * (1.0 / (r * r) + 2.0 * k * r);
        }
        Electrostatics::Ewald { alpha } => {
            let g = 2.0 * alpha / std::f64::consts::PI.sqrt();
            e += qq * libm::erfc(alpha * r) / r;
            let near = libm::erfc(alpha * r) / (r * r) + g * (-alpha * alpha * r * r).exp() / r;
            de -= qq * near;
            // Mixed precision takes the force as `Q/r² − Q r α³F(α²r²)` (`ewald_force`):
            // two pieces of sizes 1/r² and 1/r² − near (near r² ≤ 1).
            pieces += qq.abs() * (2.0 / (r * r) - near);
        }
        Electrostatics::Plain => {
            e += qq / r;
            de -= qq / (r * r);
            pieces += qq.abs() / (r * r);
        }
        Electrostatics::None => {}
    }
    (e, de, pieces)
}

#[test]
fn double_is_the_brute_force_sum_and_mixed_is_within_its_round_off() {
    let mut rng = TestRng::new(72);
    for factored in [true, false] {
        for form in FORMS {
            let side = 14.0;
            let q = atoms(150, side, &mut rng);
            let spec = spec(150, side, form, factored, &mut rng);
            let (energy, gradient, bound) = brute_force_with_bound(&spec, &q);
            let term = Nonbonded::new(spec, &q).unwrap();
            let label = format!("{form:?} factored {factored}");
            let (g, e) = gradient_and_energy(&term, &q);
            let scale = max_abs(&gradient).max(1.0);
            let error = max_abs_difference(&g, &gradient);
            assert!(error <= 1e-9 * scale, "{label}: double off by {error:e}");
            assert!(
                (e - energy).abs() <= 1e-9 * energy.abs().max(1.0),
                "{label}: {e} vs {energy}"
            );
            // The term's own brute force (used by the run test below) is the same sum.
            let own = term.brute_force(&q);
            assert!(
                max_abs_difference(&own.gradient, &gradient) <= 1e-9 * scale,
                "{label}"
            );
            term.set_precision(Precision::Mixed);
            let (g, _) = gradient_and_energy(&term, &q);
            for (atom, b) in bound.iter().enumerate() {
                for a in 0..3 {
                    let k = 3 * atom + a;
                    let off = (g[k] - gradient[k]).abs();
                    assert!(
                        off <= *b,
                        "{label}: mixed atom {atom} off by {off:e} > {b:e}"
                    );
                }
            }
            // Mixed differs from double (else this test checks nothing about f32 lanes).
            assert_ne!(
                bits(&g),
                bits(&gradient),
                "{label}: mixed gave double's bits"
            );
        }
    }
}

fn nonbonded(scene: &Scene) -> &Nonbonded {
    scene
        .system
        .forces
        .find::<Nonbonded>()
        .expect("the scene has a non-bonded term")
}

/// At every outer step of an impulse run (the steps at which the slow forces are taken),
/// the term's gradient is the brute-force sum and its pruned list holds exactly the pairs
/// within the cutoff. Smaller list buffers than the scene's (outer 1 Å, inner 0.3 Å) make
/// rebuilds and prunings frequent, so the run crosses many of each.
#[test]
fn the_buffered_list_misses_no_pair_at_any_step_of_a_run() {
    let mut scene = load_scene(Path::new("systems/water-box/scene.toml"), &[]).unwrap();
    nonbonded(&scene).set_list_buffers(1.0, 0.3);
    let mut integrator = common::method("impulse", 3.0, Some(6));
    integrator.setup(&mut scene.system).unwrap();
    for step in 0..120 {
        integrator.step(&mut scene.system).unwrap();
        let q = scene.system.state.q.clone();
        let term = nonbonded(&scene);
        let mut g = vec![0.0; q.len()];
        term.add_gradient(&q, &mut g);
        let reference = term.brute_force(&q);
        assert_eq!(
            term.listed_pairs_within_cutoff(),
            reference.pairs,
            "step {step}: pairs within the cutoff"
        );
        let error = max_abs_difference(&g, &reference.gradient);
        let scale = max_abs(&reference.gradient).max(1.0);
        assert!(
            error <= 1e-9 * scale,
            "step {step}: gradient off by {error:e}"
        );
    }
    let counts = nonbonded(&scene).list_counts();
    assert!(
        counts.builds >= 4 && counts.prunes >= counts.builds + 10,
        "too few rebuilds or prunings to test them: {counts:?}"
    );
}

/// Gradient at the start and state after 10 impulse steps of the 1728-water box (5184
/// atoms: 8 chunks, parallel search, kernel and reduction).
fn water1728(threads: usize, precision: Precision) -> (Vec<u64>, Vec<u64>) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let mut scene = load_scene(Path::new("systems/water-box-1728/scene.toml"), &[]).unwrap();
        assert_eq!(scene.system.forces.set_precision(precision), 1);
        let q = scene.system.state.q.clone();
        let mut g = vec![0.0; q.len()];
        scene.system.forces.gradient(1, &q, &mut g);
        let mut integrator = common::method("impulse", 4.0, Some(8));
        integrator.setup(&mut scene.system).unwrap();
        for _ in 0..10 {
            integrator.step(&mut scene.system).unwrap();
        }
        (bits(&g), bits(&scene.system.state.q))
    })
}

/// On the water box a third of the register groups have no pair within the cutoff and
/// half have only hydrogens (no Lennard-Jones parameters) as i-atoms: the kernel skips
/// both. Along a run (list rebuilt and pruned), on every instruction set and in both
/// precisions, computing every group must give the same gradient and energy bits.
#[test]
fn skipping_dead_groups_and_hydrogen_lennard_jones_changes_no_bit() {
    let mut scene = load_scene(Path::new("systems/water-box/scene.toml"), &[]).unwrap();
    let mut integrator = common::method("impulse", 4.0, Some(8));
    integrator.setup(&mut scene.system).unwrap();
    for step in 0..30 {
        integrator.step(&mut scene.system).unwrap();
        if step % 10 != 9 {
            continue;
        }
        let q = scene.system.state.q.clone();
        let term = nonbonded(&scene);
        for precision in [Precision::Double, Precision::Mixed] {
            term.set_precision(precision);
            for isa in Isa::available() {
                term.set_isa(isa);
                let label = format!("step {step}, {isa:?} {precision:?}");
                term.set_every_group(true);
                let (g_all, e_all) = gradient_and_energy(term, &q);
                term.set_every_group(false);
                let (g, e) = gradient_and_energy(term, &q);
                assert!(max_abs(&g) > 0.0, "{label}: no forces");
                let first = (0..g.len()).find(|&k| g[k].to_bits() != g_all[k].to_bits());
                assert!(
                    first.is_none(),
                    "{label}: gradient differs from {first:?} on"
                );
                assert_eq!(e.to_bits(), e_all.to_bits(), "{label}: energy");
            }
        }
        term.set_precision(Precision::Double);
        term.set_isa(Isa::best());
    }
}

#[test]
fn the_1728_water_box_gives_the_same_bits_on_one_and_two_threads() {
    for precision in [Precision::Double, Precision::Mixed] {
        let one = water1728(1, precision);
        let two = water1728(2, precision);
        assert!(one.0 == two.0, "{precision:?}: forces differ");
        assert!(
            one.1 == two.1,
            "{precision:?}: positions after 10 steps differ"
        );
    }
}

/// `(erfc, e^{−x²})` of [`erfc_exp`] in the lanes of `s` at every `x` (as `S::R`), in f64.
fn erfc_lanes<S: Simd>(s: S, xs: &[f64]) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(xs.len());
    for chunk in xs.chunks(S::WIDTH) {
        let mut lanes = [S::R::default(); 16];
        for (k, &x) in chunk.iter().enumerate() {
            lanes[k] = S::R::of(x);
        }
        let (erfc, gauss) = erfc_exp(s, s.load(&lanes));
        let (mut e, mut g) = ([S::R::default(); 16], [S::R::default(); 16]);
        s.store(erfc, &mut e);
        s.store(gauss, &mut g);
        out.extend((0..chunk.len()).map(|k| (e[k].to_f64(), g[k].to_f64())));
    }
    out
}

/// [`erfc_lanes`] on the instruction set `isa` in precision `R`.
fn erfc_on<R: Real>(isa: Isa, xs: &[f64]) -> Vec<(f64, f64)>
where
    Portable<R>: Simd<R = R>,
{
    let wide = std::mem::size_of::<R>() == 8;
    match isa {
        #[cfg(target_arch = "x86_64")]
        // SAFETY (all four): `Isa::run` asserts the instruction set is available.
        Isa::Avx2 if wide => isa.run(|| erfc_lanes(unsafe { Avx2F64::new_unchecked() }, xs)),
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 => isa.run(|| erfc_lanes(unsafe { Avx2F32::new_unchecked() }, xs)),
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 if wide => isa.run(|| erfc_lanes(unsafe { Avx512F64::new_unchecked() }, xs)),
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => isa.run(|| erfc_lanes(unsafe { Avx512F32::new_unchecked() }, xs)),
        _ => erfc_lanes(Portable::<R>::new(), xs),
    }
}

/// A dense grid of `x` over the fit's range, `[0, ERFC_X_MAX]` in steps of 1e-5, and a
/// little beyond (clamped there).
fn erfc_grid() -> Vec<f64> {
    let n = (ERFC_X_MAX * 1e5).round() as usize;
    (0..=n + 1000).map(|k| k as f64 * 1e-5).collect()
}

/// The lanes' erfc and Gaussian against libm over the dense grid, relative error.
///
/// Bounds, from the operations of `erfc_exp` (unit round-off `u`, 2⁻⁵³ or 2⁻²⁴): the
/// fit's own error (1.4e-17 in double, 2.0e-9 in single: `scripts/fit_erfc.py`), Horner
/// in fused multiply-adds on non-negative coefficients at `x ≥ 0` (`m u` for degree `m`:
/// 8 + 9 u in double, 4 + 5 u in single), the division and the product with the
/// Gaussian (2 u); the Gaussian: the reduction (2 u), the Taylor polynomial's Horner,
/// its terms falling by ≥ 2.9× (2 u), its remainder (4.4e-18 and 5e-9), the scaling
/// and the `x²` correction (2 u); libm's erfc and exp, at most 1 ulp (2 u). In all
/// ≤ 27 u + fit: 3.0e-15 in double and 1.7e-6 + 7e-9 in single (`u = 6e-8`; 1.8e-6).
/// Beyond the range the lanes hold the value at `ERFC_X_MAX` (not checked: the kernel
/// computes in lanes only where `α r_c ≤ ERFC_X_MAX`).
#[test]
fn the_lanes_erfc_is_libm_s_within_its_bound() {
    let xs = erfc_grid();
    let inside = |x: f64| x <= ERFC_X_MAX;
    for (wide, bound) in [(true, 3.0e-15), (false, 1.8e-6)] {
        let lanes = if wide {
            erfc_on::<f64>(Isa::Portable, &xs)
        } else {
            erfc_on::<f32>(Isa::Portable, &xs)
        };
        let (mut worst_erfc, mut worst_gauss) = (0.0f64, 0.0f64);
        for (&x, &(erfc, gauss)) in xs.iter().zip(&lanes) {
            if !inside(x) {
                continue;
            }
            // The lanes' own argument (rounded to f32 in single), and e^{−x²} at it:
            // e^{−t}(1 − δ) with t = x² rounded, δ its exact rounding error.
            let x = if wide { x } else { x as f32 as f64 };
            let t = x * x;
            let delta = x.mul_add(x, -t);
            let exact_gauss = libm::exp(-t) * (1.0 - delta);
            worst_erfc = worst_erfc.max((erfc / libm::erfc(x) - 1.0).abs());
            worst_gauss = worst_gauss.max((gauss / exact_gauss - 1.0).abs());
        }
        eprintln!("wide {wide}: max relative error erfc {worst_erfc:e}, exp {worst_gauss:e}");
        assert!(
            worst_erfc <= bound,
            "wide {wide}: erfc off by {worst_erfc:e}"
        );
        assert!(
            worst_gauss <= bound,
            "wide {wide}: exp off by {worst_gauss:e}"
        );
    }
}

/// Every instruction set gives the portable lanes' bits of erfc and the Gaussian, in both
/// precisions, over the dense grid and beyond the fit's range.
#[test]
fn the_lanes_erfc_is_the_same_bits_on_every_instruction_set() {
    let xs = erfc_grid();
    let bits = |v: &[(f64, f64)]| -> Vec<[u64; 2]> {
        v.iter().map(|(a, b)| [a.to_bits(), b.to_bits()]).collect()
    };
    let (double, single) = (
        bits(&erfc_on::<f64>(Isa::Portable, &xs)),
        bits(&erfc_on::<f32>(Isa::Portable, &xs)),
    );
    for isa in Isa::available() {
        assert_eq!(bits(&erfc_on::<f64>(isa, &xs)), double, "{isa:?} double");
        assert_eq!(bits(&erfc_on::<f32>(isa, &xs)), single, "{isa:?} single");
    }
}

/// `[α r_c, r_c]` of the rational Ewald force's checks: the engine test's, Trp-cage's
/// (α from `erfc(α r_c) = 1e-5` at 9 Å, GROMACS's `ewald-rtol`) and the fit's edge.
const EWALD_CASES: [[f64; 2]; 3] = [[0.45 * 5.0, 5.0], [3.123_413, 9.0], [4.0, 9.0]];

/// `(r², r³(1/r³ − α³F), exact r³ (−V′/(Q r)))` of [`ewald_force`] in single-precision
/// portable lanes over `r ∈ [0.5, r_c]` (each `r²` an f32, the exact value at it).
fn ewald_force_grid(alpha: f64, cutoff: f64) -> Vec<(f64, f64, f64)> {
    let s = Portable::<f32>::new();
    let fit = EwaldForce::new(alpha);
    // 200 000 points: four lanes each, r_c the last.
    let n = 199_999;
    let r2s: Vec<f32> = (0..=n)
        .map(|k| {
            let r = 0.5 + (cutoff - 0.5) * k as f64 / n as f64;
            (r * r) as f32
        })
        .collect();
    let mut out = Vec::with_capacity(r2s.len());
    for chunk in r2s.chunks_exact(4) {
        let r2 = s.load4(chunk.try_into().expect("four lanes"));
        let rinv = s.rsqrt(r2);
        let f = ewald_force(s, &fit, r2, rinv, s.mul(rinv, rinv));
        let mut lanes = [0f32; 16];
        s.store(f, &mut lanes);
        for (&r2, &f) in chunk.iter().zip(&lanes) {
            let r = (r2 as f64).sqrt();
            let x = alpha * r;
            let g = 2.0 / std::f64::consts::PI.sqrt() * x * (-x * x).exp();
            out.push((r2 as f64, f as f64 * r.powi(3), libm::erfc(x) + g));
        }
    }
    out
}

/// The rational Ewald force of mixed precision against the f64 erfc form, over `r ≤ r_c`.
///
/// Its error, in units of `1/r³` (so of the plain Coulomb force `Q/r²`; `u = 2⁻²⁴`): the
/// fit `P/Q` of `F` (7.59e-8 relative, `scripts/fit_ewald_force.py`); the coefficients
/// rounded to f32 (`u Σ|c_k| z^k`: 1.68 u in P, 1.0 u in Q by the script's conditions);
/// Horner's fused steps (one rounding each: 6 · 1.68 u and 5 · 1.0 u); the division (u):
/// `α³F` within 7.59e-8 + 18.8 u of itself, and `α³F r³ = erf(x) − 2x e^{−x²}/√π < 1`.
/// `1/r` from Newton (its last step `y (3/2 − (x/2) y y)`: ≤ 2.5 u from three roundings;
/// 3 u allowed), `1/r²` (2 · 3 + 1 = 7 u), `1/r³` (3 + 7 + 1 = 11 u), the subtraction
/// (u): 12 u. In all ≤ 30.8 u + 7.59e-8 = 1.91e-6 of `1/r³`. Near the cutoff the force
/// itself is small (`erfc(x) + 2x e^{−x²}/√π`, 2.2e-4 at `x = 3.12`), so the relative
/// error there is larger (printed); it is the error GROMACS's mixed kernels accept, and
/// ~1e-2 of the real-space truncation the cutoff already makes.
#[test]
fn the_rational_ewald_force_is_erfc_s_within_its_bound() {
    let u = f32::EPSILON as f64 / 2.0;
    let bound = 30.8 * u + 7.59e-8;
    for [x_c, cutoff] in EWALD_CASES {
        let alpha = x_c / cutoff;
        assert!(
            x_c * x_c <= EWALD_Z_MAX - 0.5,
            "the kernel takes the rational here"
        );
        let (mut worst, mut worst_relative) = (0.0f64, 0.0f64);
        for (_, lanes, exact) in ewald_force_grid(alpha, cutoff) {
            worst = worst.max((lanes - exact).abs());
            worst_relative = worst_relative.max((lanes / exact - 1.0).abs());
        }
        eprintln!(
            "alpha r_c {x_c}: max error {worst:e} of 1/r^3 ({:.1} u), relative {worst_relative:e}",
            worst / u
        );
        assert!(worst <= bound, "alpha r_c {x_c}: {worst:e} > {bound:e}");
        // The error is the rational's, not zero (else this checks nothing).
        assert!(worst > u, "alpha r_c {x_c}");
    }
}
