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
