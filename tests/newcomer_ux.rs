//! What a newcomer with their own system was misled by (issue 43, items 12–19): messages
//! that name the wrong thing or nothing, a drift judged two ways, progress, sizes and
//! outputs. The messages are read through their `Problem` fields (DEVELOPERS.md), the
//! commands through their exit codes, tables and JSON.

mod common;

use std::path::{Path, PathBuf};

use common::{argv, run_cli, scratch_dir};
use longstep::error::{Error, Problem};
use longstep::io::scene::{load_scene, load_scene_with_coordinates, read_topology_file};
use longstep::units::Units;

const ALA2: &str = "systems/alanine-dipeptide-amber";

/// The problem an error carries; a failure names the error that has none.
fn problem(error: &Error) -> &Problem {
    error
        .problem()
        .unwrap_or_else(|| panic!("no fields in {error:?}"))
}

/// The 1-based number of the first line of `text` that contains `needle`.
fn line_with(text: &str, needle: &str) -> usize {
    text.lines()
        .position(|l| l.contains(needle))
        .unwrap_or_else(|| panic!("no line with {needle:?}"))
        + 1
}

/// A copy of `ALA2/name` with `edit` applied, in the scratch folder `dir`: its path and text.
fn edited(dir: &Path, name: &str, edit: impl Fn(&str) -> String) -> (PathBuf, String) {
    let text = std::fs::read_to_string(Path::new(ALA2).join(name)).unwrap();
    let changed = edit(&text);
    assert_ne!(changed, text, "{name}: the edit changed nothing");
    let path = dir.join(name);
    std::fs::write(&path, &changed).unwrap();
    (path, changed)
}

/// The error of loading the topology `top` with the coordinates `gro` (it must fail).
fn top_gro_error(top: &Path, gro: &Path) -> Error {
    match load_scene_with_coordinates(top, Some(gro), &[]) {
        Ok(_) => panic!("{} with {} loaded", top.display(), gro.display()),
        Err(e) => e,
    }
}

// Item 12: messages that mislead.

#[test]
fn a_nan_coordinate_in_a_gro_names_its_file_and_line() {
    let dir = scratch_dir("ux-gro-nan");
    // Atom 5's x (line 7), "nan" in the 8-wide column: Rust's parser reads it as NaN.
    let (gro, text) = edited(&dir, "ala2.gro", |t| {
        t.replacen("  -0.154   0.087  -0.026", "     nan   0.087  -0.026", 1)
    });
    let error = top_gro_error(&Path::new(ALA2).join("ala2.top"), &gro);
    let p = problem(&error);
    assert_eq!(p.location.file.as_deref(), Some(gro.as_path()), "{error}");
    assert_eq!(p.location.line, Some(line_with(&text, "nan")), "{error}");
    assert_eq!(p.got.as_deref(), Some("nan"), "{error}");
}

#[test]
fn a_nan_charge_in_a_top_names_its_file_line_and_directive() {
    let dir = scratch_dir("ux-top-nan");
    let (top, text) = edited(&dir, "ala2.top", |t| {
        t.replacen("0.11230000   1.007947", "nan   1.007947", 1)
    });
    let error = read_topology_file(&top, &[]).unwrap_err();
    let p = problem(&error);
    assert_eq!(p.location.file.as_deref(), Some(top.as_path()), "{error}");
    assert_eq!(p.location.line, Some(line_with(&text, "nan")), "{error}");
    assert_eq!(p.location.key.as_deref(), Some("atoms"), "{error}");
    assert_eq!(p.got.as_deref(), Some("nan"), "{error}");
}

#[test]
fn overlapping_atoms_are_named() {
    let dir = scratch_dir("ux-overlap");
    // Atom 22 (a hydrogen of NME) put on atom 1 (a hydrogen of ACE): not bonded, so their
    // Coulomb and Lennard-Jones energies are infinite.
    let (gro, _) = edited(&dir, "ala2.gro", |t| {
        t.replacen("   0.279   0.246   0.014", "  -0.211   0.115  -0.230", 1)
    });
    let error = top_gro_error(&Path::new(ALA2).join("ala2.top"), &gro);
    let p = problem(&error);
    // The pair, numbered from 1 as the structure file numbers its atoms.
    let got = p
        .got
        .as_deref()
        .unwrap_or_else(|| panic!("no pair in {error}"));
    assert!(got.contains("atoms 1 and 22"), "{error}");
}

#[test]
fn a_gro_atom_count_one_short_blames_the_count() {
    let dir = scratch_dir("ux-gro-count");
    let (gro, _) = edited(&dir, "ala2.gro", |t| {
        t.replacen("\n   22\n", "\n   21\n", 1)
    });
    let error = top_gro_error(&Path::new(ALA2).join("ala2.top"), &gro);
    let p = problem(&error);
    assert_eq!(p.location.file.as_deref(), Some(gro.as_path()), "{error}");
    assert_eq!(p.location.line, Some(2), "{error}");
    assert_eq!(p.got.as_deref(), Some("21"), "{error}");
}

#[test]
fn a_missing_moleculetype_header_is_named() {
    let dir = scratch_dir("ux-moleculetype");
    let (top, text) = edited(&dir, "ala2.top", |t| {
        t.replacen("[ moleculetype ]\n", "", 1)
    });
    let error = read_topology_file(&top, &[]).unwrap_err();
    let p = problem(&error);
    assert_eq!(p.location.key.as_deref(), Some("moleculetype"), "{error}");
    assert_eq!(
        p.location.line,
        Some(line_with(&text, "system1          3"))
    );
}

#[test]
fn a_negative_molecule_count_says_negative() {
    let dir = scratch_dir("ux-molecules");
    let (top, _) = edited(&dir, "ala2.top", |t| {
        t.replacen("system1              1", "system1              -1", 1)
    });
    let error = read_topology_file(&top, &[]).unwrap_err();
    let p = problem(&error);
    assert_eq!(p.location.key.as_deref(), Some("molecules"), "{error}");
    assert_eq!(p.got.as_deref(), Some("-1"), "{error}");
    assert_eq!(p.expected.as_deref(), Some("a whole number, 0 or more"));
}

#[test]
fn a_folder_given_as_the_topology_says_folder() {
    let dir = Path::new(ALA2);
    let error = match load_scene_with_coordinates(dir, Some(&dir.join("ala2.inpcrd")), &[]) {
        Ok(_) => panic!("a folder loaded"),
        Err(e) => e,
    };
    let p = problem(&error);
    assert_eq!(p.location.file.as_deref(), Some(dir), "{error}");
    assert_eq!(
        p.expected.as_deref(),
        Some("a scene (.toml) or a topology (.prmtop, .top) file"),
        "{error}"
    );
}

#[test]
fn a_scene_with_topology_and_forcefield_names_both() {
    let dir = scratch_dir("ux-topology-forcefield");
    let prmtop = Path::new(env!("CARGO_MANIFEST_DIR")).join(ALA2);
    let text = format!(
        "version = 1\nname = \"both\"\ndim = 3\nunits = \"real\"\n[topology]\n\
         file = \"{0}/ala2.prmtop\"\ncoordinates = \"{0}/ala2.inpcrd\"\n\
         [forcefield]\ncoulomb = \"plain\"\n",
        prmtop.display()
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, &text).unwrap();
    let error = match load_scene(&path, &[]) {
        Ok(_) => panic!("the scene loaded"),
        Err(e) => e,
    };
    let p = problem(&error);
    assert_eq!(p.location.key.as_deref(), Some("forcefield"), "{error}");
    assert_eq!(p.location.line, Some(line_with(&text, "[forcefield]")));
    // dim is 3: the message must not blame it.
    assert!(!error.to_string().contains("dim"), "{error}");
}

#[test]
fn a_hydrogen_mass_too_large_says_the_largest_allowed() {
    let load = || load_scene(&Path::new(ALA2).join("ala2.toml"), &[]).unwrap();
    let mut scene = load();
    let bonded = scene.bonded.clone().expect("a molecular scene");
    let error = scene
        .system
        .repartition_hydrogen_mass(&bonded, 20.0, Units::Real)
        .unwrap_err();
    let p = problem(&error);
    assert_eq!(p.location.key.as_deref(), Some("hydrogen_mass"), "{error}");
    assert_eq!(p.got.as_deref(), Some("20 amu"), "{error}");
    let expected = p.expected.as_deref().unwrap();
    let largest: f64 = expected
        .strip_prefix("below ")
        .and_then(|rest| rest.strip_suffix(" amu"))
        .and_then(|number| number.parse().ok())
        .unwrap_or_else(|| panic!("no largest mass in {expected:?}"));
    // The bound is sharp: a tenth of a percent below it repartitions, above it does not
    // (the bound is printed to 6 significant digits, far finer than 0.1 %).
    let mut below = load();
    assert!(
        below
            .system
            .repartition_hydrogen_mass(&bonded, largest * 0.999, Units::Real)
            .is_ok(),
        "{largest}"
    );
    let mut above = load();
    assert!(
        above
            .system
            .repartition_hydrogen_mass(&bonded, largest * 1.001, Units::Real)
            .is_err(),
        "{largest}"
    );
}

#[test]
fn a_folder_as_a_csv_out_is_refused_by_name() {
    let out = scratch_dir("ux-stiffness-out");
    let (code, _, stderr) = run_cli(&argv(
        "scan stiffness systems/three-spring.toml --methods impulse --h 0.1 --param omega1 \
         --range 10:20 --n 2 --t-end 1 --out {}",
        &[out.to_str().unwrap()],
    ));
    assert_ne!(code, 0, "{stderr}");
    assert!(!stderr.contains("os error"), "{stderr}");
    assert!(stderr.contains("--out"), "{stderr}");
}

#[test]
fn every_out_flag_says_file_or_folder() {
    for command in [
        "run",
        "analyze",
        "forces",
        "merge",
        "scan steps",
        "scan growth",
        "scan stiffness",
        "chart work-precision",
        "stability-map",
        "async-stability-map",
    ] {
        let mut args: Vec<&str> = command.split(' ').collect();
        args.push("--help");
        let (code, stdout, stderr) = run_cli(&args);
        assert_eq!(code, 0, "{command}: {stderr}");
        let line = stdout
            .lines()
            .find(|l| l.trim_start().starts_with("--out "))
            .unwrap_or_else(|| panic!("{command}: no --out in {stdout}"));
        assert!(
            line.contains("--out <FILE>") || line.contains("--out <DIR>"),
            "{command}: {line}"
        );
    }
}

/// The JSON summary of a `run` that succeeds.
fn run_json(args: &[&str]) -> serde_json::Value {
    let (code, stdout, stderr) = run_cli(args);
    assert_eq!(code, 0, "{stderr}");
    serde_json::from_str(&stdout).unwrap_or_else(|e| panic!("{e}: {stdout}"))
}

// Item 13: no drift verdict without a temperature.

#[test]
fn a_run_at_rest_has_no_drift_verdict_and_says_why() {
    let out = scratch_dir("ux-at-rest");
    // ala2.inpcrd is minimised in ff14SB and has no velocities: without --temperature the
    // molecule stays at rest (millikelvins from its residual forces).
    let summary = run_json(&argv(
        "run systems/alanine-dipeptide-amber/ala2.toml --method verlet --h 1fs --t-end 0.2ps \
         --json --quiet --out {}",
        &[out.to_str().unwrap()],
    ));
    let drift = &summary["drift"];
    assert_eq!(drift["verdict"], "none", "{drift}");
    let text = drift["verdict_text"].as_str().unwrap();
    assert!(text.starts_with("no verdict: the run is at rest"), "{text}");
    // At 300 K the same molecule is judged.
    let warm = run_json(&argv(
        "run systems/alanine-dipeptide-amber/ala2.toml --method verlet --h 1fs --t-end 0.2ps \
         --temperature 300K --json --quiet --out {} --force",
        &[out.to_str().unwrap()],
    ));
    let verdict = warm["drift"]["verdict"].as_str().unwrap();
    assert!(["pass", "fail", "undecided"].contains(&verdict), "{warm}");
}

// Item 14: one drift criterion for `run` and `scan steps`.

#[test]
fn run_and_scan_steps_judge_a_dimensionless_run_alike() {
    let out = scratch_dir("ux-one-criterion");
    let run_out = out.join("run");
    let summary = run_json(&argv(
        "run systems/three-spring.toml --method impulse --h 0.45 --inner 10 --json --quiet \
         --out {}",
        &[run_out.to_str().unwrap()],
    ));
    let scan_out = out.join("scan");
    let (code, _, stderr) = run_cli(&argv(
        "scan steps systems/three-spring.toml --methods impulse --h 0.45 --inner 10 \
         --repeats 0 --quiet --out {}",
        &[scan_out.to_str().unwrap()],
    ));
    assert_eq!(code, 0, "{stderr}");
    let (header, rows) = common::study_table(&scan_out.join("scan.csv"));
    let column = |name: &str| {
        let k = header.iter().position(|h| h == name).unwrap();
        rows[0][k].clone()
    };
    let first_line = std::fs::read_to_string(scan_out.join("scan.csv")).unwrap();
    let first_line = first_line.lines().next().unwrap().to_string();
    let drift = &summary["drift"];
    // The same verdict, the same numbers (the same fit, the same conversion: equal to the
    // bit), the same unit and bound.
    assert_eq!(
        drift["verdict"].as_str().unwrap(),
        column("status"),
        "{drift}"
    );
    let number = |text: String| text.parse::<f64>().unwrap();
    assert_eq!(drift["value"].as_f64().unwrap(), number(column("drift")));
    assert_eq!(
        drift["error"].as_f64().unwrap(),
        number(column("drift_error"))
    );
    let unit = drift["unit"].as_str().unwrap();
    assert!(
        first_line.contains(&format!("drift_unit = {unit},")),
        "{unit} vs {first_line}"
    );
    let bound = drift["bound"].as_f64().unwrap();
    assert!(
        first_line.contains(&format!("drift_bound = {bound},")),
        "{bound} vs {first_line}"
    );
}

// Item 16: progress on a terminal, and only there.

/// The bytes a terminal shows while `longstep args` runs under a pseudo-terminal
/// (util-linux `script`), and its exit code.
fn on_a_terminal(args: &str) -> (i32, String) {
    let binary = std::env::var("LONGSTEP_BIN")
        .unwrap_or_else(|_| env!("CARGO_BIN_EXE_longstep").to_string());
    let output = std::process::Command::new("script")
        .args(["-q", "-e", "-c", &format!("{binary} {args}"), "/dev/null"])
        .env("TERM", "xterm")
        .output()
        .expect("util-linux `script` runs (it gives the command a terminal)");
    (
        output.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&output.stdout).into_owned(),
    )
}

#[test]
fn progress_shows_on_a_terminal_and_nowhere_else() {
    let out = scratch_dir("ux-progress");
    let dir = out.to_str().unwrap();
    // 2 000 outer steps: far below the 1e5 a bar once needed.
    let run = format!("run systems/three-spring.toml --h 0.05 --t-end 100 --out {dir}/run --force");
    let (code, terminal) = on_a_terminal(&run);
    assert_eq!(code, 0, "{terminal}");
    assert!(terminal.contains("outer steps"), "{terminal}");
    assert!(terminal.contains("left"), "no time left shown: {terminal}");
    let (code, terminal) = on_a_terminal(&format!("{run} --quiet"));
    assert_eq!(code, 0, "{terminal}");
    assert!(!terminal.contains("outer steps"), "{terminal}");
    // Captured output (no terminal) holds no progress.
    let (code, _, stderr) = run_cli(&common::words(&run));
    assert_eq!(code, 0, "{stderr}");
    assert!(!stderr.contains("outer steps"), "{stderr}");
    // The asynchronous map counts its points.
    let map = format!(
        "async-stability-map systems/wave-inhomogeneous.toml --set n=20 --param h-slow \
         --range 0.02:0.05 --n 4 --ratio 5 --out {dir}/map.csv"
    );
    let (code, terminal) = on_a_terminal(&map);
    assert_eq!(code, 0, "{terminal}");
    assert!(terminal.contains("4/4 runs"), "{terminal}");
    let (code, terminal) = on_a_terminal(&format!("{map} --quiet"));
    assert_eq!(code, 0, "{terminal}");
    assert!(!terminal.contains("runs,"), "{terminal}");
}

/// Item 16 for the other long commands: `modes` (dense Hessian columns, or Lanczos
/// iterations) and `analyze` (the share of the run analysed) show a bar with the time left
/// on a terminal, none under `--quiet`, and nothing on a captured stderr; `scan growth`
/// and `scan stiffness` count their runs.
#[test]
fn modes_analyze_and_scans_show_progress_on_a_terminal_only() {
    let out = scratch_dir("ux-progress-more");
    let dir = out.to_str().unwrap();
    let top = format!("{ALA2}/ala2.top");
    let cases = [
        (format!("modes {top}"), "Hessian columns"),
        (
            format!("modes {top} --lanczos 30"),
            "Lanczos iterations (at most)",
        ),
    ];
    let run = format!("run {top} --t-end 100fs --trajectory-every 2 --quiet --out {dir}/run");
    let (code, _, stderr) = run_cli(&common::words(&run));
    assert_eq!(code, 0, "{stderr}");
    let analyze = format!("analyze {top} {dir}/run --blocks 2 --out {dir}/analysis");
    let growth = format!(
        "scan growth systems/three-spring.toml --method impulse --h 0.5,0.4 --inner 10 \
         --t-end 20 --out {dir}/growth"
    );
    let stiffness = format!(
        "scan stiffness systems/two-spring.toml --method impulse --param omega1 --range 0:8 \
         --n 3 --h 0.5 --t-end 4 --out {dir}/stiffness.csv"
    );
    let more = [
        (analyze, "% of its time span"),
        (growth, "2/2 runs"),
        (stiffness, "3/3 runs"),
    ];
    for (command, shown) in cases.iter().chain(&more) {
        let (code, terminal) = on_a_terminal(command);
        assert_eq!(code, 0, "{command}: {terminal}");
        assert!(terminal.contains(shown), "{command}: {terminal}");
        assert!(
            terminal.contains("left"),
            "{command}: no time left: {terminal}"
        );
        let (code, terminal) = on_a_terminal(&format!("{command} --quiet"));
        assert_eq!(code, 0, "{command} --quiet: {terminal}");
        assert!(!terminal.contains(shown), "{command} --quiet: {terminal}");
        let (code, _, stderr) = run_cli(&common::words(command));
        assert_eq!(code, 0, "{command}: {stderr}");
        assert!(
            !stderr.contains(shown),
            "{command}, not a terminal: {stderr}"
        );
    }
}

/// Item 4: a topology's run writes no trajectory unless asked, and `analyze` of it says
/// so and which flag writes one, naming the run directory.
#[test]
fn analyze_of_a_run_without_frames_says_which_flag_writes_them() {
    let out = scratch_dir("ux-no-frames");
    let dir = out.to_str().unwrap();
    let top = format!("{ALA2}/ala2.top");
    let run = format!("run {top} --t-end 20fs --quiet --out {dir}/run");
    let (code, _, stderr) = run_cli(&common::words(&run));
    assert_eq!(code, 0, "{stderr}");
    assert!(!out.join("run/trajectory.xyz").exists());
    let analyze = format!("analyze {top} {dir}/run");
    let (code, _, stderr) = run_cli(&common::words(&analyze));
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains(&format!("{dir}/run")), "{stderr}");
    assert!(
        stderr.contains("the run wrote no frames")
            && stderr.contains("rerun it with --trajectory-every"),
        "{stderr}"
    );
}

// Item 17: guards that stop at sizes a user would not expect.

/// `longstep args`: its exit code and stderr, or `None` when it is still running after
/// `seconds` (it is killed then).
fn run_within(args: &[&str], seconds: u64) -> Option<(i32, String)> {
    let mut child = common::longstep()
        .args(args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    while start.elapsed().as_secs() < seconds {
        if let Some(status) = child.try_wait().unwrap() {
            let mut stderr = String::new();
            use std::io::Read;
            child
                .stderr
                .take()
                .unwrap()
                .read_to_string(&mut stderr)
                .unwrap();
            return Some((status.code().unwrap_or(-1), stderr));
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    None
}

#[test]
fn a_mistyped_inner_step_count_is_refused_before_it_runs() {
    let out = scratch_dir("ux-huge-inner");
    // 5 outer steps of 1e9 inner steps each on 648 atoms: 3.2e12 atom-steps.
    let (code, stderr) = run_within(
        &argv(
            "run systems/water-box/scene.toml --method impulse --h 2fs --inner 1000000000 \
             --t-end 10fs --out {}",
            &[out.join("run").to_str().unwrap()],
        ),
        60,
    )
    .expect("the run was not refused: it was still running after 60 s");
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("--allow-large"), "{stderr}");
}

#[test]
fn a_map_of_a_few_hundred_megabytes_is_refused_before_it_writes() {
    let out = scratch_dir("ux-big-map").join("map.csv");
    // 3000² rows at the estimate's 40 bytes a row: 360 MB, beyond the 100 MB limit.
    let (code, stderr) = run_within(
        &argv(
            "stability-map --method impulse --h 0.5 --n 3000 --quiet --out {}",
            &[out.to_str().unwrap()],
        ),
        60,
    )
    .expect("the map was not refused: it was still running after 60 s");
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("--allow-large"), "{stderr}");
    assert!(!out.exists(), "the refused map wrote {}", out.display());
}

// Item 18: outputs under out/.

#[test]
fn the_async_map_writes_under_out_by_default() {
    let dir = scratch_dir("ux-async-default");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("systems/wave-inhomogeneous.toml");
    let output = common::longstep()
        .current_dir(&dir)
        .args(argv(
            "async-stability-map {} --set n=20 --param h-slow --range 0.02:0.05 --n 4 \
             --ratio 5",
            &[scene.to_str().unwrap()],
        ))
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(dir.join("out/async-stability-map.csv").is_file());
    assert!(!dir.join("async-stability-map.csv").exists());
}

// Item 19: docs quote verdicts as the program prints them.

/// The `drift` and `warning` lines `longstep args` prints.
fn drift_lines(args: &[&str]) -> Vec<String> {
    let (code, stdout, stderr) = run_cli(args);
    assert!(code == 0, "{stderr}");
    let lines: Vec<String> = stdout
        .lines()
        .filter(|l| l.starts_with("drift ") || l.starts_with("warning "))
        .map(str::to_string)
        .collect();
    assert!(
        lines.iter().any(|l| l.starts_with("drift ")),
        "no drift line in {stdout}"
    );
    lines
}

/// Item 19: the verdicts README.md and docs/molecules.md quote (the water box at 2 and 4 fs,
/// the dipeptide under LongAverage, each run as the docs show it) are the lines the program
/// prints, warning included, character for character.
#[test]
fn readme_and_molecules_quote_the_verdicts_as_printed() {
    let out = scratch_dir("ux-docs-drift");
    let readme = std::fs::read_to_string("README.md").unwrap();
    let molecules = std::fs::read_to_string("docs/molecules.md").unwrap();
    let water = "run systems/water-box/scene.toml --method impulse --t-end 10ps";
    let dipeptide = "run systems/molecules/alanine-dipeptide.toml --method long-average --h 3fs \
                     --inner 6 --t-end 10ps --temperature 300K";
    let cases = [
        (water, "--h 2fs --inner 4", true),
        (water, "--h 4fs --inner 8", true),
        (dipeptide, "", false),
    ];
    for (k, (command, steps, in_readme)) in cases.into_iter().enumerate() {
        let dir = out.join(k.to_string());
        let mut args = common::words(command);
        args.extend(common::words(steps));
        args.extend(["--quiet", "--out", dir.to_str().unwrap()]);
        for line in drift_lines(&args) {
            assert!(
                !in_readme || readme.contains(&line),
                "README.md does not quote {line:?}"
            );
            assert!(
                molecules.contains(&line),
                "docs/molecules.md does not quote {line:?}"
            );
        }
    }
}

// Item 15: no notice about a setting the user did not give.

#[test]
fn verlet_on_a_topology_scene_notices_only_the_settings_given() {
    let out = scratch_dir("ux-verlet-notice");
    // A topology's scene gives impulse its inner steps; --method verlet replaces impulse.
    let run = "run systems/alanine-dipeptide-amber/ala2.prmtop --method verlet --h 1fs \
               --t-end 10fs --force --out";
    let mut args = common::words(run);
    args.push(out.to_str().unwrap());
    let (code, stdout, stderr) = run_cli(&args);
    assert_eq!(code, 0, "{stderr}");
    assert!(
        !format!("{stdout}{stderr}").contains("inner_steps"),
        "{stdout}{stderr}"
    );
    // Given on the command line, it is noticed.
    args.extend(["--inner", "4"]);
    let (code, stdout, stderr) = run_cli(&args);
    assert_eq!(code, 0, "{stderr}");
    assert!(
        format!("{stdout}{stderr}").contains("verlet does not use the setting inner_steps"),
        "{stdout}{stderr}"
    );
}
