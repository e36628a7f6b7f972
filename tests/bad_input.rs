//! Bad input gets a clear message naming what and where, a non-zero exit, and no panic.
//! Every scene in tests/input/bad/ states the message it must produce in `# expect:` lines.

mod common;
use common::run_cli as run;
use common::{argv, scratch_dir, words};

use std::path::Path;

#[test]
fn every_bad_scene_fails_with_its_message() {
    let mut checked = 0;
    let mut entries: Vec<_> = std::fs::read_dir("tests/input/bad")
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    entries.sort();
    for path in entries {
        let text = std::fs::read_to_string(&path).unwrap();
        let expected: Vec<&str> = text
            .lines()
            .filter_map(|l| l.strip_prefix("# expect: "))
            .collect();
        assert!(
            !expected.is_empty(),
            "{} states no expected message",
            path.display()
        );
        let out = scratch_dir(&format!(
            "bad-{}",
            path.file_stem().unwrap().to_string_lossy()
        ));
        let (code, _, stderr) = run(&argv(
            "run {} --h 0.01 --t-end 0.1 --out {}",
            &[path.to_str().unwrap(), out.to_str().unwrap()],
        ));
        assert_eq!(
            code,
            1,
            "{}: exit code {code}, stderr: {stderr}",
            path.display()
        );
        assert!(
            stderr.starts_with("error: "),
            "{}: {stderr}",
            path.display()
        );
        assert!(!stderr.contains("panicked"), "{}: {stderr}", path.display());
        for fragment in expected {
            assert!(
                stderr.contains(fragment),
                "{}: message lacks \"{fragment}\":\n{stderr}",
                path.display()
            );
        }
        checked += 1;
    }
    assert!(checked >= 20, "only {checked} bad scenes checked");
}

#[test]
fn a_scene_error_names_the_line() {
    // The error must point at the offending key's line, or at the particle table it is in.
    for (file, needle) in [
        ("unknown-key", "mas = 1.0"),
        ("negative-mass", "[[particles]]"),
    ] {
        let path = format!("tests/input/bad/{file}.toml");
        let text = std::fs::read_to_string(&path).unwrap();
        let line = text.lines().position(|l| l == needle).unwrap() + 1;
        let (_, _, stderr) = run(&["check", &path]);
        assert!(stderr.contains(&format!("{file}.toml:{line}:")), "{stderr}");
    }
}

#[test]
fn bad_command_line_values_are_refused() {
    let scene = "systems/three-spring.toml";
    let cases: &[(&[&str], i32, &str)] = &[
        (
            &["--h", "0"],
            1,
            "outer step h must be positive and finite, got 0",
        ),
        (
            &["--h", "-0.1"],
            1,
            "outer step h must be positive and finite, got -0.1",
        ),
        (&["--h", "nan"], 1, "outer step h is not finite"),
        (&["--h", "inf"], 1, "outer step h is not finite"),
        (&["--t-end", "0"], 1, "end time t_end must be positive"),
        (
            &["--dt", "0.03"],
            1,
            "inner step dt = 0.03 does not divide the outer step h = 0.05",
        ),
        (&["--inner", "0"], 1, "inner steps must be at least 1"),
        (
            &["--inner", "4", "--dt", "0.01"],
            1,
            "either as inner steps (--inner) or as dt",
        ),
        (
            &["--set", "omega3=1"],
            1,
            "has no parameter \"omega3\" (it has: angle, omega1, omega2, p0)",
        ),
        (&["--set", "omega1"], 1, "--set expects name=value"),
        (
            &["--set", "omega1=sqrt(-1)"],
            1,
            "parameter \"omega1\" is not finite",
        ),
        (
            &["--method", "leapfrog"],
            1,
            "unknown method \"leapfrog\"; known methods: verlet",
        ),
        (
            &["--energy-every", "0"],
            1,
            "--energy-every must be at least 1",
        ),
        (&["--blowup", "-1"], 1, "blow-up factor must be positive"),
        (&["--h", "abc"], 1, "outer step h: unknown parameter 'abc'"),
        (&["--inner", "x"], 2, "invalid value 'x' for '--inner <K>'"),
    ];
    let out = scratch_dir("bad-cli");
    for (extra, expected_code, fragment) in cases {
        let mut args = vec!["run", scene, "--out", out.to_str().unwrap()];
        if !extra.contains(&"--t-end") {
            args.extend(["--t-end", "1"]);
        }
        args.extend_from_slice(extra);
        let (code, _, stderr) = run(&args);
        assert_eq!(code, *expected_code, "{extra:?}: {stderr}");
        assert!(
            stderr.contains(fragment),
            "{extra:?}: message lacks \"{fragment}\":\n{stderr}"
        );
        assert!(!stderr.contains("panicked"), "{extra:?}: {stderr}");
    }
    let (code, _, stderr) = run(&["run", "systems/no-such-scene.toml"]);
    assert_eq!(code, 1);
    assert!(
        stderr.contains("systems/no-such-scene.toml: No such file"),
        "{stderr}"
    );
}

#[test]
fn a_blow_up_says_when_and_which_method_and_keeps_the_output() {
    // hΩ2 = 7 is far beyond Verlet's stability limit hω < 2.
    let out = scratch_dir("blow-up");
    let (code, stdout, stderr) = run(&argv(
        "run systems/three-spring.toml --h 0.5 --t-end 1000 --json --out {}",
        &[out.to_str().unwrap()],
    ));
    assert_eq!(code, 3, "{stderr}");
    let summary: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(summary["status"], "unstable");
    let at = summary["unstable_at"].as_f64().unwrap();
    assert!(at > 0.0 && at < 1000.0);
    let message = summary["message"].as_str().unwrap();
    assert!(message.starts_with("verlet stopped: "), "{message}");
    assert!(
        stderr.contains(&format!("unstable at t = {at}")),
        "{stderr}"
    );

    // energy.csv is complete up to the blow-up: a header, then full rows to t = `at`.
    let csv = std::fs::read_to_string(out.join("energy.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    let columns = rows[0].split(',').count();
    assert!(rows.len() > 2);
    for row in &rows[1..] {
        assert_eq!(row.split(',').count(), columns, "incomplete row {row}");
    }
    let last_t: f64 = rows
        .last()
        .unwrap()
        .split(',')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert_eq!(last_t, at);
}

#[test]
fn no_argument_prints_help() {
    let (code, stdout, stderr) = run(&[]);
    assert_ne!(code, 0);
    let text = stdout + &stderr;
    assert!(text.contains("Usage: longstep <COMMAND>"), "{text}");
    assert!(Path::new(env!("CARGO_BIN_EXE_longstep")).exists());
}

/// Run `longstep check` on scene text written to a scratch file.
fn check_text(name: &str, text: &str) -> (i32, String) {
    let dir = scratch_dir(name);
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).unwrap();
    let (code, _, stderr) = run(&["check", path.to_str().unwrap()]);
    (code, stderr)
}

#[test]
fn deep_nesting_is_an_error_not_a_stack_overflow() {
    let tail = "[[particles]]\nmass = \"a\"\nposition = [0]\n[[particles]]\nmass = 1\n\
                position = [1]\n[[terms]]\ntype = \"spring\"\nbetween = [0, 1]\nstiffness = 1\n";
    // 100 000 nested parentheses: the recursive parser would overflow the main stack.
    let deep = format!("{}1{}", "(".repeat(100_000), ")".repeat(100_000));
    let scene =
        format!("version = 1\nname = \"deep\"\ndim = 1\n[parameters]\na = \"{deep}\"\n{tail}");
    let (code, stderr) = check_text("deep-parentheses", &scene);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("nests deeper than 200 levels"), "{stderr}");
    // So do 100 000 signs.
    let signs = format!("{}1", "-".repeat(100_000));
    let scene =
        format!("version = 1\nname = \"deep\"\ndim = 1\n[parameters]\na = \"{signs}\"\n{tail}");
    let (code, stderr) = check_text("deep-signs", &scene);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("nests deeper than 200 levels"), "{stderr}");
    // A chain of 100 000 parameters, each referring to the next.
    let mut chain = String::from("a = \"p1\"\n");
    for k in 1..100_000 {
        chain += &format!("p{k} = \"p{} + 1\"\n", k + 1);
    }
    chain += "p100000 = 1\n";
    let scene = format!("version = 1\nname = \"deep\"\ndim = 1\n[parameters]\n{chain}{tail}");
    let (code, stderr) = check_text("deep-chain", &scene);
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("chain of more than 1000 parameters"),
        "{stderr}"
    );
}

/// `check` validates the scene's `[run]` table (item 9), with the file and the table's line;
/// `run` blames the table for what the table alone gives.
#[test]
fn check_validates_the_run_table_with_file_and_line() {
    let base = "version = 1\nname = \"r\"\ndim = 1\n[[particles]]\nmass = 1\nposition = [0]\n\
                [[particles]]\nmass = 1\nposition = [1]\n[[terms]]\ntype = \"spring\"\n\
                between = [0, 1]\nstiffness = 1\n[run]\n";
    let cases = [
        ("method = \"nope\"", "unknown method \"nope\""),
        ("h = 0", "outer step h must be positive"),
        ("t_end = -5", "end time t_end must be positive"),
        ("inner_steps = 0", "inner steps must be at least 1"),
    ];
    for (k, (line, message)) in cases.iter().enumerate() {
        let (code, stderr) = check_text(&format!("run-table-{k}"), &format!("{base}{line}\n"));
        assert_eq!(code, 1, "{line}: {stderr}");
        assert!(
            stderr.contains("scene.toml:14: in [run]: ") && stderr.contains(message),
            "{line}: {stderr}"
        );
    }
    // The command line's own bad value is not blamed on the table.
    let dir = scratch_dir("run-table-cli");
    let path = dir.join("scene.toml");
    std::fs::write(&path, format!("{base}t_end = 1\n")).unwrap();
    let (code, _, stderr) = run(&argv(
        "run {} --h 0 --out {}",
        &[path.to_str().unwrap(), dir.join("out").to_str().unwrap()],
    ));
    assert_eq!(code, 1, "{stderr}");
    assert!(
        !stderr.contains("[run]") && stderr.contains("outer step h must be positive"),
        "{stderr}"
    );
    // The table's bad value with the command line silent is blamed on the table.
    std::fs::write(&path, format!("{base}t_end = -1\n")).unwrap();
    let (code, _, stderr) = run(&argv(
        "run {} --h 0.1 --out {}",
        &[path.to_str().unwrap(), dir.join("out").to_str().unwrap()],
    ));
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("scene.toml:14: in [run]: end time t_end"),
        "{stderr}"
    );
}

/// A negative number reaches the flag it was given to, which refuses it by name (issue 30
/// item 8: `--inner -3` was "unexpected argument '-3'").
#[test]
fn negative_values_are_refused_by_their_flag() {
    let cases: [&[&str]; 3] = [
        &words("run systems/three-spring.toml --h 0.1 --inner -3"),
        &words("run systems/three-spring.toml --h 0.1 --energy-every -1"),
        &words("analyze systems/water-box/scene.toml out/none --skip -1ps"),
    ];
    for args in cases {
        let (code, _, stderr) = common::run_cli(args);
        assert_ne!(code, 0, "{args:?}");
        let flag = args[args.len() - 2];
        assert!(stderr.contains(flag), "{args:?}: {stderr}");
        assert!(
            !stderr.contains("unexpected argument"),
            "{args:?}: {stderr}"
        );
        // A count says what it takes, not Rust's "invalid digit found in string".
        assert!(!stderr.contains("invalid digit"), "{args:?}: {stderr}");
    }
}

/// A copy of the butane scene in a scratch folder, its structure and scene edited by
/// `edit_xyz` and `edit_toml`; the scene's path.
fn edited_butane(
    name: &str,
    edit_xyz: fn(String) -> String,
    edit_toml: fn(String) -> String,
) -> String {
    let dir = scratch_dir(name);
    let from = Path::new(env!("CARGO_MANIFEST_DIR")).join("systems/molecules");
    let xyz = std::fs::read_to_string(from.join("butane.xyz")).unwrap();
    let toml = std::fs::read_to_string(from.join("butane.toml")).unwrap();
    std::fs::write(dir.join("butane.xyz"), edit_xyz(xyz)).unwrap();
    std::fs::write(dir.join("butane.toml"), edit_toml(toml)).unwrap();
    dir.join("butane.toml").display().to_string()
}

/// Issue 30 item 10: what was silently accepted.
#[test]
fn a_coordinate_far_out_is_refused_with_its_atom() {
    let far = edited_butane(
        "bad-input-far-coordinate",
        |xyz| xyz.replacen("-1.5806700261", "1e300", 1),
        |toml| toml,
    );
    let (code, _, stderr) = run(&["check", &far]);
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("atom 0") && stderr.contains("butane.xyz"),
        "{stderr}"
    );
}

#[test]
fn charges_with_coulomb_none_get_a_notice() {
    let none = edited_butane(
        "bad-input-coulomb-none",
        |xyz| xyz,
        |toml| toml.replace("coulomb = \"plain\"", "coulomb = \"none\""),
    );
    let (code, stdout, stderr) = run(&["check", &none]);
    assert_eq!(code, 0, "{stderr}");
    let printed = stdout + &stderr;
    assert!(printed.contains("charges are ignored"), "{printed}");
}

#[test]
fn forces_at_another_molecules_positions_are_refused() {
    let (code, _, stderr) = run(&words(
        "forces systems/alanine-dipeptide-amber/ala2.prmtop \
         --positions systems/molecules/butane.xyz",
    ));
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("--positions: has 14 atoms"), "{stderr}");
}

#[test]
fn zero_weights_and_empty_labels_are_refused() {
    let (code, _, stderr) = run(&argv(
        "chart work-precision systems/three-spring.toml --methods impulse --h-list 0.1 \
         --t-end 1 --inner 4 --weights 0,0,0 --out {}",
        &[&scratch_dir("bad-input-weights").display().to_string()],
    ));
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("--weights 0,0,0"), "{stderr}");
    let (code, _, stderr) = run(&argv(
        "analyze systems/water-box/scene.toml out/none --labels {}",
        &[""],
    ));
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("--labels"), "{stderr}");
}

/// Issue 30 item 11: a reversed range says so; a trajectory format chemfiles cannot write
/// fails before the run writes anything.
#[test]
fn a_reversed_range_and_a_bad_trajectory_format_are_said_before_any_run() {
    let out = scratch_dir("bad-input-reversed");
    let (code, _, stderr) = run(&argv(
        "scan steps systems/three-spring.toml --methods impulse --h 0.7:0.1:0.01 \
         --inner 4 --t-end 1 --out {}",
        &[&out.display().to_string()],
    ));
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("reversed") && stderr.contains("0.1:0.7:0.01"),
        "{stderr}"
    );

    let dir = scratch_dir("bad-input-trajectory-format");
    let scene = std::fs::read_to_string("systems/three-spring.toml").unwrap()
        + "\n[output]\ntrajectory = \"t.abc\"\n";
    std::fs::write(dir.join("scene.toml"), scene).unwrap();
    let out = dir.join("out");
    let (code, _, stderr) = run(&argv(
        "run {} --method verlet --h 0.1 --t-end 1 --trajectory-every 1 --out {}",
        &[
            &dir.join("scene.toml").display().to_string(),
            &out.display().to_string(),
        ],
    ));
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("t.abc"), "{stderr}");
    assert!(
        !out.join("energy.csv").exists(),
        "energy.csv written before the failure"
    );
}

/// A flag with an optional value (`--rigid-water`) does not take the next flag as its
/// value now that option values may start with `-`.
#[test]
fn a_flag_with_an_optional_value_leaves_the_next_flag_alone() {
    let (code, stdout, stderr) = run(&words(
        "check systems/water-box/scene.toml --rigid-water --method verlet --h 2fs",
    ));
    assert_eq!(code, 0, "{stderr}");
    assert!((stdout + &stderr).contains("SETTLE"), "{stderr}");
}

/// Issue 30 item 9: the size guard counts innermost steps (`--inner 1000000000` ran
/// silently).
#[test]
fn the_size_guard_counts_innermost_steps() {
    let (code, _, stderr) = run(&words(
        "run systems/three-spring.toml --method impulse --h 0.5 --inner 1000000000 \
         --t-end 100",
    ));
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("innermost steps"), "{stderr}");
}
