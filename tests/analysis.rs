//! The configurational analysis (`longstep analyze`): g(r), block averages, the
//! configurational temperature, and its command line. Tolerances are statistical: each is
//! derived from the estimator's variance, said where it is used.

mod common;
use common::run_cli as run;
use common::{TestRng, argv, scratch_dir};

use longstep::analysis::block_average::{
    Estimate, blocks_long_enough, flyvbjerg_petersen, from_block_means, ratio_of_means,
};
use longstep::analysis::configurational::ConfigurationalProbe;
use longstep::analysis::rdf::{PairSelection, RdfGrid, first_peak};
use longstep::forces::pair::{Pair, PairTerm};
use longstep::forces::spring::{HarmonicBond, harmonic_springs};
use longstep::forces::{Site, TermClass};
use longstep::split::{Assignment, ForceSplit, LabelledTerm};

#[test]
fn ideal_gas_rdf_is_one_within_its_binomial_error() {
    // N uniform points in a periodic box: each pair lands in shell k with probability
    // p_k = shell_k/V, independently of every other pair (given one point, the other's
    // position is uniform; two pairs sharing a point are independent for the same reason).
    // So the count over M frames and P pairs has variance M P p (1 − p), and
    // σ(g_k) = √((1 − p)/(M P p)). Every bin within 5σ (all 50 bins: chance of a false
    // failure ~3e-5), and χ² = Σ ((g − 1)/σ)² over 50 bins within 50 ± 4·√100.
    let (n, length, frames) = (200usize, 10.0, 50usize);
    let elements = vec!["Ar".to_string(); n];
    let selection = PairSelection::new(&elements, "Ar", "Ar", None).unwrap();
    assert_eq!(selection.pairs(), (n * (n - 1) / 2) as f64);
    let grid = RdfGrid::new(5.0, 0.1).unwrap();
    let mut rng = TestRng::new(11);
    let mut counts = vec![0u64; grid.bins];
    for _ in 0..frames {
        let q = rng.vector(3 * n, 0.0, length);
        selection.histogram(&q, [length; 3], &grid, &mut counts);
    }
    let volume = length * length * length;
    let mut g = vec![0.0; grid.bins];
    selection.normalise(&counts, volume, &grid, &mut g);
    let mut chi2 = 0.0;
    for (k, &g) in g.iter().enumerate().skip(1) {
        let g = g / frames as f64;
        let p = grid.shell_volume(k) / volume;
        let sigma = ((1.0 - p) / (frames as f64 * selection.pairs() * p)).sqrt();
        assert!(
            (g - 1.0).abs() < 5.0 * sigma,
            "bin {k}: g = {g}, σ = {sigma}"
        );
        chi2 += ((g - 1.0) / sigma).powi(2);
    }
    // Bin 0 (r < 0.1) expects 0.4 pairs per frame: left out of χ², checked above only
    // through the loop's start at 1.
    let bins = (grid.bins - 1) as f64;
    assert!(
        (chi2 - bins).abs() < 4.0 * (2.0 * bins).sqrt(),
        "χ² = {chi2} over {bins} bins"
    );
}

#[test]
fn simple_cubic_lattice_peaks_at_its_shells_with_their_coordination_numbers() {
    // 6³ sites of spacing a = 1 in a periodic box of 6, each displaced by a seeded normal
    // of σ = 0.01 per axis: pair distances stay within ~0.1 of a, √2 a, √3 a, 2a (7σ of the
    // distance's √2 σ spread). Counting pairs within ±0.1 of each shell gives the exact
    // coordination numbers 6, 12, 8, 6 per atom; the first peak is at a.
    let (side, a, sigma) = (6usize, 1.0, 0.01);
    let n = side * side * side;
    let mut rng = TestRng::new(3);
    let mut q = Vec::with_capacity(3 * n);
    for i in 0..n {
        let site = [i % side, (i / side) % side, i / (side * side)];
        for s in site {
            q.push(s as f64 * a + sigma * rng.normal());
        }
    }
    let elements = vec!["Ar".to_string(); n];
    let selection = PairSelection::new(&elements, "Ar", "Ar", None).unwrap();
    let grid = RdfGrid::new(3.0, 0.01).unwrap();
    let mut counts = vec![0u64; grid.bins];
    selection.histogram(&q, [side as f64 * a; 3], &grid, &mut counts);
    for (shell, expected) in [
        (1.0f64, 6u64),
        (2f64.sqrt(), 12),
        (3f64.sqrt(), 8),
        (2.0, 6),
    ] {
        let lo = ((shell - 0.1) / grid.bin_width) as usize;
        let hi = ((shell + 0.1) / grid.bin_width) as usize;
        let pairs: u64 = counts[lo..=hi].iter().sum();
        // Each unordered pair counted once: neighbours per atom = 2 pairs / N.
        assert_eq!(2 * pairs, expected * n as u64, "shell at {shell}");
    }
    let mut g = vec![0.0; grid.bins];
    selection.normalise(&counts, (side as f64 * a).powi(3), &grid, &mut g);
    let peak = first_peak(&grid, &g, 0.25, 0.03).unwrap();
    assert!((peak.position - a).abs() < 0.02, "{peak:?}");
}

#[test]
fn intramolecular_pairs_are_left_out_of_counts_and_normalisation() {
    // Two "molecules" O-H-H; O-H pairs between molecules: 2 × 2 = 4 of the 2 × 4 = 8.
    let elements: Vec<String> = ["O", "H", "H", "O", "H", "H"].map(String::from).into();
    let molecule_of = [0, 0, 0, 1, 1, 1];
    let inter = PairSelection::new(&elements, "O", "H", Some(&molecule_of)).unwrap();
    assert_eq!(inter.pairs(), 4.0);
    let hh = PairSelection::new(&elements, "H", "H", Some(&molecule_of)).unwrap();
    assert_eq!(hh.pairs(), 4.0); // 6 H-H pairs, 2 within a molecule
    let missing = PairSelection::new(&elements, "O", "N", None).unwrap_err();
    assert!(missing.contains("\"N\""), "{missing}");
}

/// `x_t = φ x_{t−1} + √(1 − φ²) ε_t`, stationary with unit variance.
fn ar1(rng: &mut TestRng, phi: f64, n: usize) -> Vec<f64> {
    let mut x = rng.normal();
    let scale = (1.0 - phi * phi).sqrt();
    (0..n)
        .map(|_| {
            let value = x;
            x = phi * x + scale * rng.normal();
            value
        })
        .collect()
}

/// Variance of the mean of `n` consecutive AR(1) values of unit variance:
/// `(1/n)(1 + 2 Σ_{k<n} (1 − k/n) φ^k)`.
fn ar1_variance_of_mean(phi: f64, n: usize) -> f64 {
    let sum: f64 = (1..n)
        .map(|k| (1.0 - k as f64 / n as f64) * phi.powi(k as i32))
        .sum();
    (1.0 + 2.0 * sum) / n as f64
}

#[test]
fn block_averages_of_an_ar1_series_give_the_variance_of_its_mean() {
    // φ = 0.8 (integrated correlation time (1 + φ)/(1 − φ) = 9 samples), N = 4096 in 16
    // blocks of 256. For equal blocks E[sem²] = (Var(B) − Var(X̄))/(n − 1) exactly, from the
    // AR(1) autocovariance; it lies 1.7 % below Var(X̄) (blocks 28 correlation times long).
    // Over M = 400 independent series the mean of sem² must match E[sem²] within 4 standard
    // errors of that mean (its spread measured over the series).
    let (phi, n, blocks, series) = (0.8, 4096usize, 16usize, 400usize);
    let block = n / blocks;
    let expected =
        (ar1_variance_of_mean(phi, block) - ar1_variance_of_mean(phi, n)) / (blocks - 1) as f64;
    let truth = ar1_variance_of_mean(phi, n);
    assert!(
        (expected / truth - 1.0).abs() < 0.05,
        "E[sem²] = {expected}, Var = {truth}"
    );
    let mut rng = TestRng::new(7);
    let mut squares = Vec::with_capacity(series);
    let (mut plateau_blocks, mut plateau_naive) = (0, 0);
    for _ in 0..series {
        let x = ar1(&mut rng, phi, n);
        let means: Vec<f64> = x
            .chunks(block)
            .map(|c| c.iter().sum::<f64>() / block as f64)
            .collect();
        let estimate = from_block_means(&means);
        squares.push(estimate.error * estimate.error);
        let levels = flyvbjerg_petersen(&x);
        plateau_blocks += usize::from(blocks_long_enough(&levels, estimate.error, blocks));
        plateau_naive += usize::from(blocks_long_enough(&levels, levels[0].error, n));
    }
    let mean = squares.iter().sum::<f64>() / series as f64;
    let spread =
        (squares.iter().map(|s| (s - mean).powi(2)).sum::<f64>() / (series - 1) as f64).sqrt();
    let standard_error = spread / (series as f64).sqrt();
    assert!(
        (mean - expected).abs() < 4.0 * standard_error,
        "mean sem² {mean} vs {expected} ± {standard_error}"
    );
    // The Flyvbjerg–Petersen check: the naive error (a third of the truth here) is never on
    // the plateau. The 16-block error is, except by chance: each trusted level on the
    // plateau (block sizes 32–512: five levels) fails the one-sided 2σ test with
    // probability ≤ 2.3 %, so at most 11.5 % of the series fail (union bound); allow three
    // binomial standard deviations over 400 series on top (√(0.115 · 0.885/400) = 1.6 %).
    assert_eq!(plateau_naive, 0);
    let failed = (series - plateau_blocks) as f64 / series as f64;
    assert!(
        failed <= 0.115 + 3.0 * 0.016,
        "{plateau_blocks} of {series} pass"
    );
}

/// A harmonic network: every particle tied to the origin (bonded) plus springs between
/// random pairs (bonded) and weak springs between all pairs (non-bonded), all with rest
/// length 0, so the Hessian K is constant.
fn harmonic_network(n: usize, rng: &mut TestRng) -> ForceSplit {
    let spring = |k: f64| HarmonicBond {
        stiffness: k,
        rest_length: 0.0,
    };
    let mut bonded = Vec::new();
    for i in 0..n {
        bonded.push((
            Site::Particle(i),
            Site::Fixed([0.0; 3]),
            spring(rng.uniform(1.0, 3.0)),
        ));
        let j = (i + 1 + (rng.uniform(0.0, (n - 1) as f64) as usize)) % n;
        bonded.push((
            Site::Particle(i),
            Site::Particle(j),
            spring(rng.uniform(5.0, 20.0)),
        ));
    }
    let mut weak = Vec::new();
    for i in 0..n {
        for j in i + 1..n {
            weak.push(Pair {
                a: Site::Particle(i),
                b: Site::Particle(j),
                potential: spring(rng.uniform(0.1, 0.5)),
            });
        }
    }
    let nonbonded = PairTerm::new("spring", TermClass::Nonbonded, 3, weak, None);
    ForceSplit::new(vec![
        (
            "bonds".into(),
            Box::new(harmonic_springs(3, bonded, None)),
            Assignment::Default,
        ),
        ("pairs".into(), Box::new(nonbonded), Assignment::Default),
    ])
    .unwrap()
}

/// The Hessian of all terms, column by column from Hessian-vector products.
fn hessian(terms: &[LabelledTerm], dofs: usize) -> nalgebra::DMatrix<f64> {
    let q = vec![0.0; dofs];
    let mut k = nalgebra::DMatrix::zeros(dofs, dofs);
    for c in 0..dofs {
        let mut e = vec![0.0; dofs];
        e[c] = 1.0;
        let mut column = vec![0.0; dofs];
        for t in terms {
            t.term.add_hessian_vector(&q, &e, &mut column);
        }
        for r in 0..dofs {
            k[(r, c)] = column[r];
        }
    }
    k
}

#[test]
fn configurational_temperature_of_an_exactly_sampled_harmonic_network_is_t() {
    // U = ½ qᵀKq sampled exactly from exp(−U/kT): q = √kT L⁻ᵀ ξ with K = L Lᵀ. Then
    // ⟨|∇U|²⟩ = kT tr K = kT ⟨∇²U⟩. With the bonded Laplacian exact and the non-bonded one
    // from Hutchinson probes, T_conf (20 blocks of 100 samples, jackknife error) must be kT
    // within 4σ; the exact part alone must be tr K_bonded to round-off; and the Hutchinson
    // Laplacian must average to tr K within 4 standard errors (K is constant, so its spread
    // over samples is the estimator's own).
    let (n, kt, samples) = (8usize, 2.5f64, 2000usize);
    let dofs = 3 * n;
    let mut rng = TestRng::new(21);
    let split = harmonic_network(n, &mut rng);
    let terms = split.terms();
    let k = hessian(terms, dofs);
    let trace = k.trace();
    let cholesky = nalgebra::Cholesky::new(k.clone()).expect("K is positive definite");

    let mut bonded_only = ConfigurationalProbe::new(&terms[..1], n, 3, 1, 5, true);
    let bonded_trace = hessian(&terms[..1], dofs).trace();
    for exact_bonded in [true, false] {
        let mut probe = ConfigurationalProbe::new(terms, n, 3, 2, 9, exact_bonded);
        let (mut g2, mut lap) = (Vec::new(), Vec::new());
        for m in 0..samples {
            let xi = nalgebra::DVector::from_fn(dofs, |_, _| rng.normal());
            let q = cholesky
                .l()
                .transpose()
                .solve_upper_triangular(&xi)
                .unwrap()
                * kt.sqrt();
            let sample = probe.sample(terms, q.as_slice(), m as u64);
            g2.push(sample.gradient_squared);
            lap.push(sample.laplacian);
            if exact_bonded && m < 3 {
                let exact = bonded_only
                    .sample(&terms[..1], q.as_slice(), m as u64)
                    .laplacian;
                assert!(
                    (exact - bonded_trace).abs() < 1e-12 * bonded_trace,
                    "{exact} vs {bonded_trace}"
                );
            }
        }
        let block = |x: &[f64]| -> Vec<f64> {
            x.chunks(100)
                .map(|c| c.iter().sum::<f64>() / 100.0)
                .collect()
        };
        let t_conf: Estimate = ratio_of_means(&block(&g2), &block(&lap));
        assert!(
            (t_conf.mean - kt).abs() < 4.0 * t_conf.error,
            "exact bonded {exact_bonded}: {t_conf:?}"
        );
        let mean = lap.iter().sum::<f64>() / samples as f64;
        let spread =
            (lap.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / (samples - 1) as f64).sqrt();
        assert!(
            (mean - trace).abs() <= 4.0 * spread / (samples as f64).sqrt() + 1e-12 * trace,
            "Laplacian {mean} vs tr K {trace} (spread {spread})"
        );
    }
}

/// A 20 fs water-box run with an energy row and a frame every step (10 steps).
fn water_run(name: &str) -> std::path::PathBuf {
    let out = scratch_dir(name);
    common::water_run(&out, "20fs");
    out
}

#[test]
fn analyze_reports_the_energy_table_means_and_writes_its_tables() {
    let dir = water_run("analyze-water");
    let (code, stdout, stderr) = run(&argv(
        "analyze systems/water-box/scene.toml {} --pairs O-O,O-H --blocks 2 --json",
        &[dir.to_str().unwrap()],
    ));
    assert_eq!(code, 0, "{stderr}");
    let summary: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let run = &summary[0];
    assert_eq!(run["molecules"], 216);
    assert_eq!(run["frames"], 11);
    // The mean potential energy per molecule is the energy rows' mean over 216 molecules.
    let text = std::fs::read_to_string(dir.join("energy.csv")).unwrap();
    let column = text
        .lines()
        .next()
        .unwrap()
        .split(',')
        .position(|c| longstep::io::energy_table::column_matches(c, "potential"))
        .unwrap();
    let rows: Vec<f64> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(column).unwrap().parse().unwrap())
        .collect();
    let mean = rows.iter().sum::<f64>() / rows.len() as f64 / 216.0;
    let reported = run["potential_energy_per_molecule"]["mean"]
        .as_f64()
        .unwrap();
    assert!(
        (reported - mean).abs() < 1e-12 * mean.abs(),
        "{reported} vs {mean}"
    );
    assert!(
        run["rdf"]["O-O"]["first_peak"]["height"]["mean"]
            .as_f64()
            .unwrap()
            > 1.0
    );
    for table in [
        "rdf.csv",
        "blocks.csv",
        "blocking.csv",
        "geometry.csv",
        "summary.json",
    ] {
        assert!(dir.join("analysis").join(table).is_file(), "{table}");
    }
}

#[test]
fn analyze_rejects_missing_elements_files_and_mismatched_scenes() {
    let dir = water_run("analyze-bad");
    let dir = dir.to_str().unwrap();
    let water = "systems/water-box/scene.toml";
    let (code, _, stderr) = run(&["analyze", water, dir, "--pairs", "O-N", "--blocks", "2"]);
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("no atom of element \"N\"") && stderr.contains("O-N"),
        "{stderr}"
    );

    let empty = scratch_dir("analyze-empty");
    std::fs::copy(format!("{dir}/energy.csv"), empty.join("energy.csv")).unwrap();
    let (code, _, stderr) = run(&["analyze", water, empty.to_str().unwrap(), "--blocks", "2"]);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("has no trajectory.xyz"), "{stderr}");

    let (code, _, stderr) = run(&["analyze", water, "no/such/run", "--blocks", "2"]);
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("no/such/run: is not a run directory"),
        "{stderr}"
    );

    let melt = "systems/polymer-melt/scene.toml";
    let (code, _, stderr) = run(&["analyze", melt, dir, "--pairs", "none", "--blocks", "2"]);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("has 648 atoms, but the scene"), "{stderr}");

    let (code, _, stderr) = run(&["analyze", water, dir, "--blocks", "6"]);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("too few for 6 blocks"), "{stderr}");
}

/// A molecule in vacuum has no density for g(r): analyze leaves g(r) out unless pairs are
/// asked for (it used to default to O–O and fail), and still reports the rest.
#[test]
fn analyze_in_vacuum_skips_the_default_pair_distribution() {
    let out = scratch_dir("analyze-vacuum");
    let out_arg = out.to_str().unwrap();
    let (code, _, stderr) = run(&argv(
        "run systems/molecules/butane.toml --method verlet --h 0.5fs --t-end 50fs \
         --energy-every 1 --trajectory-every 1 --quiet --out {}",
        &[out_arg],
    ));
    assert_eq!(code, 0, "{stderr}");
    let (code, stdout, stderr) = run(&argv(
        "analyze systems/molecules/butane.toml {} --blocks 4 --json",
        &[out_arg],
    ));
    assert_eq!(code, 0, "{stderr}");
    let json: serde_json::Value = serde_json::from_str(&stdout).expect("JSON");
    let runs = json.as_array().map_or(&json, |a| &a[0]);
    let rdf = &runs["rdf"];
    assert!(
        rdf.as_object().is_none_or(|m| m.is_empty()),
        "no g(r) without a box: {rdf}"
    );
    // Asked for explicitly, it is an error naming the missing box.
    let (code, _, stderr) = run(&argv(
        "analyze systems/molecules/butane.toml {} --pairs C-C",
        &[out_arg],
    ));
    assert_ne!(code, 0, "g(r) without a box must be refused");
    assert!(stderr.contains("box"), "{stderr}");
}

/// A 20 fs Langevin run of the water box with rigid water (SETTLE), a row and a frame
/// every 2 fs step.
fn rigid_water_run(name: &str) -> std::path::PathBuf {
    let dir = scratch_dir(name);
    let (code, _, stderr) = run(&argv(
        "run systems/water-box/scene.toml --method langevin-respa --inner 1 --h 2fs \
         --rigid-water --temperature 300K --friction 1/ps --t-end 20fs --energy-every 1 \
         --trajectory-every 1 --quiet --out {}",
        &[dir.to_str().unwrap()],
    ));
    assert_eq!(code, 0, "{stderr}");
    dir
}

#[test]
fn the_kinetic_temperature_counts_the_degrees_of_freedom_as_the_run_did() {
    // A rigid-water run: 648 atoms, 216 SETTLE waters (648 constraints), the centre-of-mass
    // momentum removed, so the run counts 3·648 − 648 − 3 = 1293 and writes its temperature
    // column over them. analyze recovers the count from the run's manifest; its mean kinetic
    // temperature then equals the mean of that column (both over the same 11 rows, to
    // round-off), where 3N would read 1293/1944 of it.
    let dir = rigid_water_run("analyze-rigid-dof");
    let out = dir.to_str().unwrap();
    let analyze = |extra: &str| {
        let line = format!(
            "analyze systems/water-box/scene.toml {{}} --blocks 2 --no-configurational --json \
             --quiet{extra}"
        );
        let (code, stdout, stderr) = run(&argv(&line, &[out]));
        assert_eq!(code, 0, "{stderr}");
        let summary: serde_json::Value = serde_json::from_str(&stdout).unwrap();
        let t = &summary[0]["kinetic_temperature"];
        (t["dof"].as_f64().unwrap(), t["mean"].as_f64().unwrap())
    };
    let text = std::fs::read_to_string(dir.join("energy.csv")).unwrap();
    let column: Vec<f64> = text
        .lines()
        .skip(1)
        .map(|l| l.rsplit(',').next().unwrap().parse().unwrap())
        .collect();
    let column_mean = column.iter().sum::<f64>() / column.len() as f64;
    let (dof, mean) = analyze("");
    assert_eq!(dof, 1293.0);
    assert!(
        (mean - column_mean).abs() < 1e-9 * column_mean,
        "{mean} vs the run's {column_mean}"
    );
    // --dof overrides the manifest's count.
    assert_eq!(analyze(" --dof 1944").0, 1944.0);
    // The run wrote the count into its manifest; a manifest from before that field is
    // counted again from its command line, to the same number.
    let path = dir.join("manifest.json");
    let mut manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    assert_eq!(manifest["degrees_of_freedom"], 1293);
    manifest
        .as_object_mut()
        .unwrap()
        .remove("degrees_of_freedom");
    std::fs::write(&path, serde_json::to_string(&manifest).unwrap()).unwrap();
    assert_eq!(analyze("").0, 1293.0);
    // Without a manifest (a peer's directory) nothing says how the run counted: 3N.
    std::fs::remove_file(dir.join("manifest.json")).unwrap();
    assert_eq!(analyze("").0, 1944.0);
}

#[test]
fn the_configurational_temperature_of_a_constrained_run_is_judged_relative_to_the_reference() {
    // Under SETTLE the unconstrained estimator ⟨|∇U|²⟩/⟨∇²U⟩ is biased: the water's bond and
    // angle terms stay in the model at their rest values, their curvature in ∇²U, their
    // forces gone from |∇U|², so it reads far below the 300 K the run is at. The criterion
    // then holds the run to the relative tolerance ΔT/T of the reference's reading: bound
    // 3 K × T_conf,ref/300 K, and its note says the estimator is biased.
    let dir = rigid_water_run("analyze-rigid-tconf");
    let out = dir.to_str().unwrap();
    let (code, stdout, stderr) = run(&argv(
        "analyze systems/water-box/scene.toml {} --reference {} --temperature 300K --blocks 2 \
         --probes 1 --json --quiet --out {}",
        &[out, out, dir.join("analysis").to_str().unwrap()],
    ));
    assert_eq!(code, 0, "{stderr}");
    let summary: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let criterion = summary[0]["criteria"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["kind"] == "configurational_temperature")
        .unwrap()
        .clone();
    let reading = criterion["reference"].as_f64().unwrap();
    assert!(reading < 0.95 * 300.0, "estimator reads {reading} K");
    let bound = criterion["bound"].as_f64().unwrap();
    assert!(
        (bound - 3.0 * reading / 300.0).abs() < 1e-12 * bound,
        "bound {bound} for a reading of {reading}"
    );
    let note = criterion["note"].as_str().unwrap();
    assert!(note.contains("biased under constraints"), "{note}");
    // The run against itself: difference zero, so it passes (or is undecided) but never fails.
    assert_ne!(criterion["verdict"], "fail");
}
