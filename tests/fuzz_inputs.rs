//! A bounded, seeded mutation fuzz of what a user hands longstep besides scenes: structure
//! files (XYZ), command-line flags (issue 14), topologies (AMBER prmtop, GROMACS .top) and
//! checkpoint files (issue 30). Every case must end with exit 0, 1, 2
//! or 3 — never a panic (101), a signal or a hang — and a refusal must start with
//! "error:" (or clap's usage message). The same seed gives the same cases on every run.

mod common;
use common::{TestRng, argv_owned, scratch_dir, words};

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Longest a single case may take before it counts as a hang (generous: the machine is
/// shared; every case is a check or a run of at most a few thousand steps of 3 particles).
const HANG: Duration = Duration::from_secs(60);

struct Outcome {
    code: Option<i32>,
    stderr: String,
}

/// Run longstep with `args`, killing it after [`HANG`]; its stderr goes to `err_path`.
fn run_bounded(args: &[String], err_path: &std::path::Path) -> Outcome {
    let err_file = std::fs::File::create(err_path).unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_longstep"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(err_file)
        .spawn()
        .expect("longstep starts");
    let started = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break Some(status);
        }
        if started.elapsed() > HANG {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let stderr = std::fs::read(err_path)
        .map(|b| String::from_utf8_lossy(&b).into_owned())
        .unwrap_or_default();
    Outcome {
        code: status.and_then(|s| s.code()),
        stderr,
    }
}

fn judge(case: &str, outcome: &Outcome) {
    let Some(code) = outcome.code else {
        panic!(
            "{case}: no exit code (a signal or a hang)\n{}",
            outcome.stderr
        );
    };
    assert!(
        matches!(code, 0..=3),
        "{case}: exit {code} (a panic is 101)\n{}",
        outcome.stderr
    );
    if code == 1 {
        assert!(
            outcome.stderr.contains("error:"),
            "{case}: exit 1 without an error line\n{}",
            outcome.stderr
        );
    }
}

/// One mutation of a text file's bytes: a byte changed, inserted or deleted, a line
/// duplicated or dropped, a number replaced by something hostile.
fn mutate(bytes: &[u8], rng: &mut TestRng) -> Vec<u8> {
    const HOSTILE: &[&str] = &[
        "nan",
        "inf",
        "-inf",
        "1e309",
        "-1e308",
        "abc",
        "",
        "0x10",
        "1,5",
        "99999999999999999999",
        "\u{00e9}",
        "-0",
    ];
    let mut out = bytes.to_vec();
    let pick = |rng: &mut TestRng, n: usize| (rng.next_u64() % n.max(1) as u64) as usize;
    match pick(rng, 6) {
        0 if !out.is_empty() => {
            let i = pick(rng, out.len());
            out[i] = (rng.next_u64() & 0xff) as u8;
        }
        1 => {
            let i = pick(rng, out.len() + 1);
            out.insert(i, (rng.next_u64() & 0xff) as u8);
        }
        2 if !out.is_empty() => {
            let i = pick(rng, out.len());
            out.remove(i);
        }
        3 | 4 => {
            let text = String::from_utf8_lossy(&out).into_owned();
            let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
            if lines.is_empty() {
                return out;
            }
            let i = pick(rng, lines.len());
            if pick(rng, 2) == 0 {
                let line = lines[i].clone();
                lines.insert(i, line);
            } else {
                lines.remove(i);
            }
            out = (lines.join("\n") + "\n").into_bytes();
        }
        _ => {
            let text = String::from_utf8_lossy(&out).into_owned();
            let mut words: Vec<String> = text.split(' ').map(str::to_string).collect();
            let i = pick(rng, words.len());
            words[i] = HOSTILE[pick(rng, HOSTILE.len())].to_string();
            out = words.join(" ").into_bytes();
        }
    }
    out
}

/// 150 mutated copies of butane's structure (1–3 mutations each), read by butane's scene
/// through `check` (which builds the whole force field from the structure).
#[test]
fn mutated_structure_files_never_panic() {
    let dir = scratch_dir("fuzz-xyz");
    let original = std::fs::read("systems/molecules/butane.xyz").unwrap();
    let scene = std::fs::read_to_string("systems/molecules/butane.toml").unwrap();
    let scene_path = dir.join("butane.toml");
    std::fs::write(&scene_path, scene).unwrap();
    let mut rng = TestRng::new(2026);
    let mut refused = 0;
    for case in 0..150 {
        let mut bytes = original.clone();
        for _ in 0..1 + rng.next_u64() % 3 {
            bytes = mutate(&bytes, &mut rng);
        }
        std::fs::write(dir.join("butane.xyz"), &bytes).unwrap();
        let outcome = run_bounded(
            &["check".into(), scene_path.display().to_string()],
            &dir.join("stderr"),
        );
        judge(&format!("xyz case {case}"), &outcome);
        refused += usize::from(outcome.code != Some(0));
    }
    // The mutations are hostile enough that many are refused (else the fuzz tests nothing).
    assert!(
        refused > 20,
        "only {refused} of 150 mutated files were refused"
    );
}

/// 200 command lines: a valid run of a three-particle scene with flags dropped, values
/// replaced by hostile ones and flags of other commands added.
#[test]
fn mutated_command_lines_never_panic() {
    const VALUES: &[&str] = &[
        "-1",
        "0",
        "nan",
        "inf",
        "1e300",
        "1e-300",
        "abc",
        "",
        "1fs",
        "3K",
        "1/ps",
        "--",
        "18446744073709551616",
        "0.5",
        "2",
        "4,2",
        "impulse",
        "sinr",
        "-5K",
        "1e9",
    ];
    const FLAGS: &[&str] = &[
        "--h",
        "--t-end",
        "--inner",
        "--dt",
        "--method",
        "--level-steps",
        "--temperature",
        "--seed",
        "--friction",
        "--thermostats",
        "--tau",
        "--energy-every",
        "--trajectory-every",
        "--blowup",
        "--mollifier",
        "--molly-constraints",
        "--quadrature",
        "--jacobian",
        "--drift-bound",
        "--fit-from",
        "--set",
        "--ratio",
        "--adaptive",
    ];
    let dir = scratch_dir("fuzz-cli");
    let mut rng = TestRng::new(14);
    let pick = |rng: &mut TestRng, n: usize| (rng.next_u64() % n as u64) as usize;
    let mut failures_seen = 0;
    for case in 0..200 {
        let out = dir.join(format!("out-{case}"));
        let mut args: Vec<String> =
            words("run systems/two-spring.toml --h 0.1 --t-end 5 --method impulse --inner 4")
                .iter()
                .map(|s| s.to_string())
                .collect();
        for _ in 0..1 + rng.next_u64() % 3 {
            match pick(&mut rng, 3) {
                0 => {
                    let i = 2 + pick(&mut rng, args.len() - 2);
                    args[i] = VALUES[pick(&mut rng, VALUES.len())].to_string();
                }
                1 => {
                    args.push(FLAGS[pick(&mut rng, FLAGS.len())].to_string());
                    args.push(VALUES[pick(&mut rng, VALUES.len())].to_string());
                }
                _ => {
                    let i = 2 + pick(&mut rng, args.len() - 2);
                    args.remove(i);
                }
            }
        }
        args.extend([
            "--out".to_string(),
            out.display().to_string(),
            "--quiet".into(),
        ]);
        let outcome = run_bounded(&args, &dir.join("stderr"));
        judge(&format!("command line {args:?}"), &outcome);
        failures_seen += usize::from(outcome.code != Some(0));
    }
    assert!(
        failures_seen > 20,
        "only {failures_seen} of 200 command lines were refused"
    );
}

/// `cases` mutated copies (1–3 mutations each) of the file `name` in `dir`, each handed to
/// longstep as `args` (which name the file); returns how many were refused.
fn fuzz_file(
    dir: &std::path::Path,
    name: &str,
    original: &[u8],
    args: &[String],
    seed: u64,
    cases: usize,
) -> usize {
    let mut rng = TestRng::new(seed);
    let mut refused = 0;
    for case in 0..cases {
        let mut bytes = original.to_vec();
        for _ in 0..1 + rng.next_u64() % 3 {
            bytes = mutate(&bytes, &mut rng);
        }
        std::fs::write(dir.join(name), &bytes).unwrap();
        let outcome = run_bounded(args, &dir.join("stderr"));
        judge(&format!("{name} case {case}"), &outcome);
        refused += usize::from(outcome.code != Some(0));
    }
    refused
}

/// 120 mutated copies each of alanine dipeptide's AMBER prmtop, GROMACS .top and the .gro
/// beside it, read by `check` (which builds the whole force field from them).
#[test]
fn mutated_topologies_never_panic() {
    let dir = scratch_dir("fuzz-topologies");
    for file in ["ala2.prmtop", "ala2.inpcrd", "ala2.top", "ala2.gro"] {
        std::fs::copy(
            format!("systems/alanine-dipeptide-amber/{file}"),
            dir.join(file),
        )
        .unwrap();
    }
    for (name, seed) in [("ala2.prmtop", 30), ("ala2.top", 31)] {
        let original = std::fs::read(dir.join(name)).unwrap();
        let args = ["check".to_string(), dir.join(name).display().to_string()];
        let refused = fuzz_file(&dir, name, &original, &args, seed, 120);
        // Hostile mutations of a topology are mostly refused (else the fuzz tests nothing).
        assert!(
            refused > 20,
            "only {refused} of 120 mutated {name} were refused"
        );
        // Put the file back, so the next one is fuzzed beside intact files.
        std::fs::write(dir.join(name), &original).unwrap();
    }
    // The .gro the .top reads its coordinates and box from (issue 43), read through `check`
    // on the intact .top. A mutated coordinate often still parses, so fewer are refused.
    let original = std::fs::read(dir.join("ala2.gro")).unwrap();
    let args = [
        "check".to_string(),
        dir.join("ala2.top").display().to_string(),
    ];
    let refused = fuzz_file(&dir, "ala2.gro", &original, &args, 32, 120);
    assert!(
        refused > 10,
        "only {refused} of 120 mutated ala2.gro were refused"
    );
}

/// 150 mutated checkpoints (pretty-printed first, so line and word mutations bite) of a
/// langevin-respa run, each continued with `run --restart`: a clear refusal or a valid run.
#[test]
fn mutated_checkpoints_never_panic() {
    let dir = scratch_dir("fuzz-checkpoints");
    let origin = dir.join("origin");
    let base = |t_end: &str, out: &std::path::Path| -> Vec<String> {
        argv_owned(
            "run systems/two-spring.toml --method langevin-respa --h 0.1 --inner 4 \
             --temperature 0.1 --friction 1 --t-end {} --quiet --out {}",
            &[t_end, &out.display().to_string()],
        )
    };
    let mut first = base("1", &origin);
    first.extend(["--checkpoint-every".to_string(), "1".to_string()]);
    let outcome = run_bounded(&first, &dir.join("stderr"));
    assert_eq!(outcome.code, Some(0), "{}", outcome.stderr);
    let text = std::fs::read_to_string(origin.join("checkpoint.json")).unwrap();
    let value: serde_json::Value = serde_json::from_str(&text).unwrap();
    let pretty = serde_json::to_string_pretty(&value).unwrap();
    let mut args = base("2", &dir.join("continued"));
    args.extend([
        "--force".to_string(),
        "--restart".to_string(),
        dir.join("mutated.json").display().to_string(),
    ]);
    // The pretty form reads back as the checkpoint itself.
    std::fs::write(dir.join("mutated.json"), &pretty).unwrap();
    let outcome = run_bounded(&args, &dir.join("stderr"));
    assert_eq!(outcome.code, Some(0), "{}", outcome.stderr);
    let refused = fuzz_file(&dir, "mutated.json", pretty.as_bytes(), &args, 32, 150);
    assert!(
        refused > 20,
        "only {refused} of 150 mutated checkpoints were refused"
    );
}
