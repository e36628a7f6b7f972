//! `stability-map --method async-pseudo-energy SCENE …` is the asynchronous map of MEMM18
//! (issue 5), with the same result as `async-stability-map`.

mod common;

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

#[test]
fn an_asynchronous_run_inside_an_instability_band_is_warned_before_it_starts() {
    // n = 50, K = 10: the amplification matrix has ρ ≈ 1.036 at h_S = 0.0146 (a band of
    // width ~0.0002 found by the map) and ρ = 1 at 0.0138. The warning comes before the run,
    // and the run confirms it.
    let run = |h: &str| {
        common::longstep()
            .args(["run", "systems/wave-inhomogeneous.toml", "--set", "n=50"])
            .args([
                "--method",
                "async-pseudo-energy",
                "--ratio",
                "10",
                "--t-end",
                "20",
                "--h",
                h,
            ])
            .args(["--out"])
            .arg(common::scratch_dir(&format!("async-warning-{h}")))
            .output()
            .unwrap()
    };
    let inside = run("0.0146");
    let stderr = String::from_utf8_lossy(&inside.stderr);
    assert!(stderr.contains("lies in an instability band"), "{stderr}");
    assert_eq!(
        inside.status.code(),
        Some(3),
        "the run inside the band blows up"
    );
    let outside = run("0.0138");
    let stderr = String::from_utf8_lossy(&outside.stderr);
    assert!(!stderr.contains("instability band"), "{stderr}");
    assert!(outside.status.success(), "{stderr}");
}
