//! `stability-map --method async-pseudo-energy SCENE …` is the asynchronous map of MEMM18
//! (issue 5), with the same result as `async-stability-map`.

mod common;

use std::path::Path;

use longstep::analysis::async_stability::{Scheme, amplification_matrix, dense_spectral_radius};
use longstep::integrators::AsyncPseudoEnergy;
use longstep::integrators::quadrature::Quadrature;
use longstep::io::scene::load_scene;

#[test]
fn stability_map_with_the_async_method_maps_the_async_scheme() {
    let dir = common::scratch_dir("async-routing");
    let args = |command: &str, out: &str| -> Vec<String> {
        let mut a = vec![command.to_string()];
        if command == "stability-map" {
            a.extend(["--method".into(), "async-pseudo-energy".into()]);
        }
        a.extend(
            [
                "systems/wave-inhomogeneous.toml",
                "--set",
                "n=20",
                "--param",
                "h-slow",
                "--range",
                "0.02:0.05",
                "--n",
                "4",
                "--ratio",
                "5",
                "--out",
            ]
            .map(String::from),
        );
        a.push(dir.join(out).display().to_string());
        a
    };
    for (command, out) in [("stability-map", "a.csv"), ("async-stability-map", "b.csv")] {
        let output = common::longstep()
            .args(args(command, out))
            .output()
            .unwrap();
        assert!(
            output.status.success(),
            "{command}: {}",
            String::from_utf8_lossy(&output.stderr)
        );
    }
    let (a, b) = (
        std::fs::read_to_string(dir.join("a.csv")).unwrap(),
        std::fs::read_to_string(dir.join("b.csv")).unwrap(),
    );
    assert!(a.starts_with("h_slow,h_fast,ratio"), "{a}");
    assert_eq!(a, b);
}

/// ρ of one coarse step of `async-pseudo-energy` at `h_slow`, `K = 10`, on the n = 50 wave
/// (the scheme the command line builds: midpoint quadrature).
fn coarse_step_radius(h_slow: f64) -> f64 {
    let mut system = load_scene(
        Path::new("systems/wave-inhomogeneous.toml"),
        &["n=50".into()],
    )
    .expect("scene")
    .system;
    let scheme = AsyncPseudoEnergy::new(h_slow, 10, Quadrature::by_name("midpoint").unwrap())
        .unwrap()
        .with_monitor(false);
    let mut scheme = Scheme::Asynchronous(Box::new(scheme));
    let matrix = amplification_matrix(&mut system, &mut scheme).expect("the wave is linear");
    dense_spectral_radius(&matrix)
}

/// n = 50, K = 10: the step of largest ρ in a scan of h_S over [0.0140, 0.0150] (a band
/// of MEMM18's scheme lies there, ~0.0002 wide) is warned about before the run, and the
/// run blows up (exit 3); a step of the scan with ρ = 1 (to 1e-8, the warning's
/// threshold) gets no warning and runs to the end.
///
/// The run length is derived: rounding seeds the growing mode with at least ε of the state
/// each step, so its amplitude reaches the blow-up test (|ΔE| > 10 E-scale, an amplitude
/// factor √10) after at most n₁ = ln(√10/ε)/ln ρ coarse steps; we run 2n₁, which also
/// covers a seed as small as ε².
#[test]
fn an_asynchronous_run_inside_an_instability_band_is_warned_before_it_starts() {
    let scan: Vec<(f64, f64)> = (0..=100)
        .map(|i| {
            let h = 0.0140 + 1e-5 * i as f64;
            (h, coarse_step_radius(h))
        })
        .collect();
    let (h_in, rho) = scan
        .iter()
        .copied()
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap();
    let (h_out, _) = scan
        .iter()
        .copied()
        .find(|&(_, rho)| rho <= 1.0 + 1e-8)
        .expect("a stable step in the scan");
    assert!(
        rho > 1.0 + 1e-3,
        "no band in the scan: largest ρ = {rho} at {h_in}"
    );
    let steps = 2.0 * (10f64.sqrt() / f64::EPSILON).ln() / rho.ln();
    let t_end = format!("{}", (steps * h_in).ceil());
    eprintln!("band: ρ = {rho:.6} at h_S = {h_in}; run to t = {t_end}; stable at h_S = {h_out}");
    let run = |h: f64| {
        let h = format!("{h}");
        common::longstep()
            .args(["run", "systems/wave-inhomogeneous.toml", "--set", "n=50"])
            .args(["--method", "async-pseudo-energy", "--ratio", "10"])
            .args(["--t-end", &t_end, "--h", &h, "--out"])
            .arg(common::scratch_dir(&format!("async-warning-{h}")))
            .output()
            .unwrap()
    };
    let inside = run(h_in);
    let stderr = String::from_utf8_lossy(&inside.stderr);
    assert!(stderr.contains("lies in an instability band"), "{stderr}");
    assert_eq!(
        inside.status.code(),
        Some(3),
        "the run inside the band blows up"
    );
    let outside = run(h_out);
    let stderr = String::from_utf8_lossy(&outside.stderr);
    assert!(!stderr.contains("instability band"), "{stderr}");
    assert!(outside.status.success(), "{stderr}");
}
