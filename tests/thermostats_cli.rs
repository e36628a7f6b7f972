//! langevin-respa and sinr through `longstep run` on the water box (short runs): the same
//! seed gives the same energy.csv at 1 and 2 threads, another seed differs; SIN(R) holds
//! its constraint to round-off (also with PME on three levels, at 48 fs) and stops with exit
//! 3 when a thermostat collapses; bad input exits 1 with the problem named.

mod common;
use common::{argv, longstep, scratch_dir, words};

const WATER: &str = "systems/water-box/scene.toml";

fn run(args: &[&str], threads: &str) -> (i32, String, String) {
    let output = longstep()
        .args(args)
        .env("RAYON_NUM_THREADS", threads)
        .output()
        .expect("longstep runs");
    (
        output.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&output.stdout).into_owned(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

/// A short water-box run of `method` with `extra` flags; returns (exit, summary JSON, energy.csv).
fn water(name: &str, method: &str, extra: &[&str], threads: &str) -> (i32, String, String) {
    let out = scratch_dir(name);
    let mut args = argv(
        "run {} --method {} --temperature 300K --energy-every 1 --json --quiet --out {}",
        &[WATER, method, out.to_str().unwrap()],
    );
    args.extend_from_slice(extra);
    let (code, stdout, stderr) = run(&args, threads);
    let csv = std::fs::read_to_string(out.join("energy.csv")).unwrap_or_default();
    assert!(code == 0 || code == 3, "{method}: exit {code}: {stderr}");
    (code, stdout, csv)
}

#[test]
fn same_seed_same_bits_at_one_and_two_threads() {
    for method in ["langevin-respa", "sinr"] {
        let flags = ["--h", "2fs", "--inner", "4", "--t-end", "0.1ps"];
        let with_seed = |seed: &str, threads: &str| {
            let mut f = flags.to_vec();
            f.extend(["--seed", seed]);
            let name = format!("thermo-{method}-{seed}-{threads}");
            water(&name, method, &f, threads).2
        };
        let one = with_seed("5", "1");
        let two = with_seed("5", "2");
        assert!(
            one.lines().count() == 52,
            "{method}: {} rows",
            one.lines().count()
        );
        assert_eq!(
            one, two,
            "{method}: energy.csv differs between 1 and 2 threads"
        );
        assert_ne!(one, with_seed("6", "2"), "{method}: seeds 5 and 6 agree");
    }
}

#[test]
fn sinr_holds_its_constraint_on_the_water_box() {
    // Two levels (bonded 0.5 fs, non-bonded 2 fs), L = 2: the largest violation of
    // m v² + L/(L+1) Σ Q1 v1² = L kT over every coordinate after every step.
    let flags = words("--h 2fs --inner 4 --t-end 0.1ps --thermostats 2");
    let (code, json, _) = water("thermo-sinr-constraint", "sinr", &flags, "2");
    assert_eq!(code, 0);
    let summary: serde_json::Value = serde_json::from_str(&json).unwrap();
    let violation = summary["sinr"]["constraint_max_violation"]
        .as_f64()
        .unwrap();
    assert!(violation <= 1e-10, "constraint violated by {violation}");
    assert_eq!(summary["sinr"]["kinetic_temperature_factor"], 2.0 / 3.0);
}

#[test]
fn sinr_with_pme_on_three_levels_holds_its_constraint_and_bits() {
    // The PME water box on three levels, as docs/thermostats.md runs it at long steps:
    // bonded 1 fs / short part 3 fs / 48 fs, the slow level holding (a) the remainder of the
    // O–O split (6–7 Å, the short part's Coulomb bare) with the reciprocal sum, (b) the
    // reciprocal sum alone (the whole real space at 3 fs). Three outer steps: 145, 49 and 4
    // evaluations per level. The slow kick of 48 fs is several thermal momenta, so an
    // isokinetic operator not solved exactly (or a slow force applied as a plain kick)
    // breaks m v² + L/(L+1) Σ Q1 v1² = L kT at O(1); solved exactly, each operator keeps it
    // to round-off (~1e-16 per update, ~1e-15 after these 145 steps), so 1e-10 is the
    // existing test's bound with room. The same bits at 1 and 2 threads: PME's spreading
    // and the split's short part reduce in a fixed order.
    let split = ["systems/water-box/three-level.toml", "--coulomb", "pme"];
    let recip = [
        "systems/water-box/pme.toml",
        "--nonbonded-level",
        "1",
        "--pme-level",
        "2",
    ];
    for (name, scene) in [("split", &split[..]), ("recip", &recip[..])] {
        let go = |threads: &str| {
            let out = scratch_dir(&format!("thermo-sinr-pme-{name}-{threads}"));
            let mut args = scene.to_vec();
            args.insert(0, "run");
            args.extend(argv(
                "--method sinr --temperature 300K --h 48fs --level-steps 16,3 --t-end 0.144ps \
                 --seed 5 --energy-every 1 --json --quiet --out {}",
                &[out.to_str().unwrap()],
            ));
            let (code, json, stderr) = run(&args, threads);
            assert_eq!(code, 0, "{name}: {stderr}");
            let csv = std::fs::read_to_string(out.join("energy.csv")).unwrap();
            (json, csv)
        };
        let (json, one) = go("1");
        let summary: serde_json::Value = serde_json::from_str(&json).unwrap();
        assert_eq!(
            summary["force_evaluations"]["levels"],
            serde_json::json!([145, 49, 4]),
            "{name}"
        );
        let violation = summary["sinr"]["constraint_max_violation"]
            .as_f64()
            .unwrap();
        assert!(
            violation <= 1e-10,
            "{name}: constraint violated by {violation}"
        );
        assert_eq!(one.lines().count(), 5, "{name}: {one}");
        assert_eq!(
            one,
            go("2").1,
            "{name}: energy.csv differs at 1 and 2 threads"
        );
    }
}

#[test]
fn sinr_stops_when_a_thermostat_collapses() {
    // All non-bonded forces as one 50 fs impulse: the first kicks pin velocities at their
    // bound and drive v1 to zero (the prototype blew up here). Exit 3, with the method,
    // the time and the reason, and nothing non-finite in energy.csv. L = 4 and τ = 5 fs
    // (Tinker's L with a light thermostat) collapse here; the defaults (L = 1, τ = 3 fs)
    // hold on, badly biased.
    let out = scratch_dir("thermo-sinr-collapse");
    let (code, stdout, stderr) = run(
        &argv(
            "run {} --method sinr --temperature 300K --h 50fs --dt 0.5fs --t-end 1ps \
             --thermostats 4 --tau 5fs --quiet --out {}",
            &[WATER, out.to_str().unwrap()],
        ),
        "2",
    );
    assert_eq!(code, 3, "{stdout}{stderr}");
    assert!(stdout.contains("FAILED at t = "), "{stdout}");
    assert!(
        stdout.contains("sinr stopped: the SIN(R) thermostat of coordinate"),
        "{stdout}"
    );
    assert!(stdout.contains("collapsed"), "{stdout}");
    let csv = std::fs::read_to_string(out.join("energy.csv")).unwrap();
    assert!(!csv.contains("NaN") && !csv.contains("inf"), "{csv}");
}

#[test]
fn thermostatted_runs_refuse_bad_input() {
    let out = scratch_dir("thermo-bad");
    let out = out.to_str().unwrap();
    let base = [
        "run", WATER, "--h", "2fs", "--inner", "4", "--t-end", "0.01ps", "--out", out,
    ];
    let cases: &[(&[&str], &str)] = &[
        (&["--method", "langevin-respa"], "needs a temperature"),
        (&["--method", "sinr"], "needs a temperature"),
        (
            &words("--method sinr --temperature 300K --thermostats 0"),
            "thermostats",
        ),
        (
            &["--method", "sinr", "--temperature", "0K"],
            "temperature must be positive",
        ),
        (
            &["--method", "langevin-respa", "--temperature", "-5K"],
            "temperature must be positive",
        ),
        (
            &words("--method langevin-respa --temperature 300K --friction 0"),
            "friction must be positive",
        ),
        (
            &words("--method sinr --temperature 300K --friction -1/ps"),
            "friction must be positive",
        ),
        (
            &["--method", "sinr", "--temperature", "300K", "--tau", "0fs"],
            "tau must be positive",
        ),
    ];
    for (flags, message) in cases {
        let mut args = base.to_vec();
        args.extend_from_slice(flags);
        let (code, _, stderr) = run(&args, "1");
        assert_eq!(code, 1, "{flags:?}: exit {code}, {stderr}");
        assert!(stderr.contains(message), "{flags:?}: {stderr}");
    }
    // A dimensionless scene: no temperature, and no default τ.
    let scene = "systems/mass-spring.toml";
    let (code, _, stderr) = run(
        &[
            "run", scene, "--method", "sinr", "--inner", "2", "--out", out,
        ],
        "1",
    );
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("k_B T with k_B = 1"), "{stderr}");
    let (code, _, stderr) = run(
        &argv(
            "run {} --method sinr --inner 2 --temperature 1 --out {}",
            &[scene, out],
        ),
        "1",
    );
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("--tau"), "{stderr}");
}
