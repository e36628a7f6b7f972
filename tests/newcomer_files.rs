//! What a newcomer with their own files lost or had accepted unchecked (issue 43, items 3
//! and 5–11): rows lost on a crash, restarts refused for defaults spelled out and accepted
//! from an edited checkpoint, a refused or killed run's manifest, nonsense accepted, the
//! momentum with PME, and what `check --help`, `minimize` and `analyze` say.

mod common;
use common::{argv, longstep, scratch_dir};

use std::path::Path;
use std::time::{Duration, Instant, SystemTime};

/// Run longstep on one thread: exit code, stdout, stderr.
fn run(args: &[&str]) -> (i32, String, String) {
    let output = longstep()
        .args(args)
        .env("RAYON_NUM_THREADS", "1")
        .output()
        .expect("longstep runs");
    (
        output.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&output.stdout).into_owned(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

fn modified(path: &Path) -> Option<SystemTime> {
    std::fs::metadata(path).and_then(|m| m.modified()).ok()
}

/// Item 6: a run killed (SIGKILL) just after a checkpoint leaves every energy row before
/// the checkpoint on disk, so a restart from it continues the table without a gap. The
/// solvated dipeptide takes milliseconds a step, so energy.csv's buffer (8 KiB, flushed
/// every 0.5 s otherwise) holds tens of rows when the kill comes, right after the second
/// checkpoint appears: without a flush before each checkpoint they are lost.
#[test]
fn a_killed_run_keeps_every_row_before_its_checkpoint() {
    let dir = scratch_dir("newcomer-killed-run");
    let out = dir.join("run");
    let checkpoint = out.join("checkpoint.json");
    let mut child = longstep()
        .args(argv(
            "run systems/alanine-dipeptide-amber/ala2-solvated.toml --method verlet --h 1fs \
             --t-end 100ps --checkpoint-every 25fs --energy-every 1 --quiet --allow-large \
             --out {}",
            &[out.to_str().unwrap()],
        ))
        .env("RAYON_NUM_THREADS", "1")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("longstep starts");
    let started = Instant::now();
    let mut first = None;
    loop {
        assert!(
            started.elapsed() < Duration::from_secs(120),
            "no second checkpoint within two minutes"
        );
        if let Some(at) = modified(&checkpoint) {
            match first {
                None => first = Some(at),
                Some(f) if at != f => break,
                Some(_) => {}
            }
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    child.kill().expect("kill");
    child.wait().expect("reaped");
    let saved: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&checkpoint).unwrap()).unwrap();
    let step = saved["step"].as_u64().expect("step");
    let text = std::fs::read_to_string(out.join("energy.csv")).unwrap();
    // Only whole lines count: the buffer may have been written up to any byte.
    let complete = &text[..text.rfind('\n').map_or(0, |k| k + 1)];
    let rows = complete.lines().count().saturating_sub(1) as u64;
    // Rows at steps 0 … step − 1 are due before the checkpoint at `step` (one a step);
    // the row at `step` itself is the continued run's first.
    assert!(
        rows >= step,
        "checkpoint at step {step}, but only {rows} energy rows on disk"
    );
}

/// A chain run under langevin with a checkpoint, for the restart tests.
fn langevin_checkpoint(dir: &Path, extra: &[&str]) -> std::path::PathBuf {
    let out = dir.join("origin");
    let mut args = argv(
        "run systems/chain/scene.toml --method langevin-respa --h 0.01 --inner 2 --t-end 0.1 \
         --temperature 1 --friction 1 --checkpoint-every 0.05 --quiet --out {}",
        &[out.to_str().unwrap()],
    );
    args.extend(extra);
    let (code, _, stderr) = run(&args);
    assert_eq!(code, 0, "{stderr}");
    out.join("checkpoint.json")
}

/// Item 7: a restart that spells out the default it ran with (`--seed 2013`, or a real
/// scene's `--friction 1/ps`) is the same run and continues; a real difference is named
/// with its value, without Rust's `Some(…)`.
#[test]
fn a_restart_with_the_defaults_spelled_out_continues() {
    let dir = scratch_dir("newcomer-restart-defaults");
    let checkpoint = langevin_checkpoint(&dir, &[]);
    let out = dir.join("seed");
    let (code, _, stderr) = run(&argv(
        "run systems/chain/scene.toml --method langevin-respa --h 0.01 --inner 2 --t-end 0.2 --temperature 1 \
         --friction 1 --seed 2013 --quiet --out {} --restart {}",
        &[out.to_str().unwrap(), checkpoint.to_str().unwrap()],
    ));
    assert_eq!(code, 0, "--seed 2013 (the default) refused:\n{stderr}");

    let out = dir.join("other-seed");
    let (code, _, stderr) = run(&argv(
        "run systems/chain/scene.toml --method langevin-respa --h 0.01 --inner 2 --t-end 0.2 --temperature 1 \
         --friction 1 --seed 7 --quiet --out {} --restart {}",
        &[out.to_str().unwrap(), checkpoint.to_str().unwrap()],
    ));
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("seed: 2013 in the checkpoint, 7 now"),
        "{stderr}"
    );
    assert!(!stderr.contains("Some("), "Debug text in: {stderr}");

    // A real scene: friction 1/ps is langevin's default there.
    let water = dir.join("water");
    let (code, _, stderr) = run(&argv(
        "run systems/alanine-dipeptide-amber/ala2.prmtop --method langevin-respa --h 1fs \
         --t-end 4fs --temperature 300K --checkpoint-every 2fs --quiet --out {}",
        &[water.to_str().unwrap()],
    ));
    assert_eq!(code, 0, "{stderr}");
    let out = dir.join("water-friction");
    let (code, _, stderr) = run(&argv(
        "run systems/alanine-dipeptide-amber/ala2.prmtop --method langevin-respa --h 1fs \
         --t-end 6fs --temperature 300K --friction 1/ps --quiet --out {} --restart {}",
        &[
            out.to_str().unwrap(),
            water.join("checkpoint.json").to_str().unwrap(),
        ],
    ));
    assert_eq!(code, 0, "--friction 1/ps (the default) refused:\n{stderr}");
    let out = dir.join("water-cutoff");
    let (code, _, stderr) = run(&argv(
        "run systems/alanine-dipeptide-amber/ala2.prmtop --method langevin-respa --h 1fs \
         --t-end 6fs --temperature 300K --friction 2/ps --cutoff 8 --quiet --out {} \
         --restart {}",
        &[
            out.to_str().unwrap(),
            water.join("checkpoint.json").to_str().unwrap(),
        ],
    ));
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("friction: 0.001 /fs in the checkpoint, 0.002 /fs now"),
        "{stderr}"
    );
    assert!(stderr.contains("cutoff = 8"), "{stderr}");
    assert!(
        !stderr.contains("Some(") && !stderr.contains("SceneFlags"),
        "{stderr}"
    );
}

/// Item 8: a checkpoint with one coordinate edited (still valid JSON) is refused, naming
/// the checksum; the refused restart leaves no manifest behind, so the same command runs
/// once the checkpoint is good; and a killed run's manifest is called interrupted.
#[test]
fn an_edited_checkpoint_is_refused_and_leaves_nothing_behind() {
    let dir = scratch_dir("newcomer-edited-checkpoint");
    let checkpoint = langevin_checkpoint(&dir, &[]);
    let text = std::fs::read_to_string(&checkpoint).unwrap();
    let mut value: serde_json::Value = serde_json::from_str(&text).unwrap();
    let q0 = value["q"][0].as_f64().unwrap();
    value["q"][0] = serde_json::Value::from(q0 + 0.5);
    let edited = dir.join("edited.json");
    std::fs::write(&edited, value.to_string()).unwrap();
    let out = dir.join("continued");
    let args = |file: &Path| -> Vec<String> {
        common::argv_owned(
            "run systems/chain/scene.toml --method langevin-respa --h 0.01 --inner 2 --t-end 0.2 \
             --temperature 1 --friction 1 --quiet --out {} --restart {}",
            &[out.to_str().unwrap(), file.to_str().unwrap()],
        )
    };
    let run_owned = |args: Vec<String>| run(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let (code, _, stderr) = run_owned(args(&edited));
    assert_eq!(code, 1, "an edited checkpoint was accepted:\n{stderr}");
    assert!(stderr.contains("checksum"), "{stderr}");
    assert!(stderr.contains(edited.to_str().unwrap()), "{stderr}");
    assert!(
        !out.join("manifest.json").exists(),
        "a refused restart left a manifest"
    );
    let (code, _, stderr) = run_owned(args(&checkpoint));
    assert_eq!(code, 0, "the retry with the good checkpoint: {stderr}");

    // A run that never finished (its manifest has no end time) is called interrupted.
    let killed = dir.join("killed");
    std::fs::create_dir_all(&killed).unwrap();
    let manifest = serde_json::json!({
        "longstep": "0", "run_id": "0123456789abcdef", "command": ["longstep", "run"],
        "started": "2026-01-01T00:00:00Z", "files": [{"name": "energy.csv"}]
    });
    std::fs::write(killed.join("manifest.json"), manifest.to_string()).unwrap();
    std::fs::write(killed.join("energy.csv"), "t\n0\n").unwrap();
    let (code, _, stderr) = run(&argv(
        "run systems/chain/scene.toml --method verlet --h 0.01 --t-end 0.02 --quiet --out {}",
        &[killed.to_str().unwrap()],
    ));
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("interrupted"), "{stderr}");
    assert!(!stderr.contains("an earlier run"), "{stderr}");
}

/// `systems/alanine-dipeptide-amber/ala2.top` with `from` replaced by `to`, written into
/// `dir` beside a copy of its .gro; the path of the copy.
fn spoiled_top(dir: &Path, name: &str, from: &str, to: &str) -> std::path::PathBuf {
    let systems = Path::new(env!("CARGO_MANIFEST_DIR")).join("systems/alanine-dipeptide-amber");
    let text = std::fs::read_to_string(systems.join("ala2.top")).unwrap();
    assert!(text.contains(from), "{from} not in ala2.top");
    let top = dir.join(format!("{name}.top"));
    std::fs::write(&top, text.replacen(from, to, 1)).unwrap();
    std::fs::copy(systems.join("ala2.gro"), dir.join(format!("{name}.gro"))).unwrap();
    top
}

/// `check` on `args`: exit code and everything it printed.
fn check(args: &[&str]) -> (i32, String) {
    let mut all = vec!["check"];
    all.extend(args);
    let (code, stdout, stderr) = run(&all);
    (code, format!("{stdout}{stderr}"))
}

/// Item 10: nonsense that was accepted silently is refused, or warned about.
#[test]
fn nonsense_in_a_topology_or_its_flags_is_refused_or_warned_about() {
    let dir = scratch_dir("newcomer-nonsense");
    // A charge off by half an electron: a warning naming the total.
    let top = spoiled_top(
        &dir,
        "charge",
        " 0.11230000   1.007947",
        " 0.61230000   1.007947",
    );
    let (code, said) = check(&[top.to_str().unwrap()]);
    assert_eq!(code, 0, "{said}");
    assert!(said.contains("not a whole number"), "{said}");
    // The same in a prmtop: the first hydrogen's charge (in units of e/18.2223) raised by
    // half an electron, 9.11115 units.
    let systems = Path::new(env!("CARGO_MANIFEST_DIR")).join("systems/alanine-dipeptide-amber");
    let prmtop = std::fs::read_to_string(systems.join("ala2.prmtop")).unwrap();
    let spoiled = prmtop.replacen(
        "  2.04636429E+00 -6.67300626E+00",
        "  1.11575143E+01 -6.67300626E+00",
        1,
    );
    assert_ne!(spoiled, prmtop);
    std::fs::write(dir.join("charge.prmtop"), spoiled).unwrap();
    std::fs::copy(systems.join("ala2.inpcrd"), dir.join("charge.inpcrd")).unwrap();
    let (code, said) = check(&[dir.join("charge.prmtop").to_str().unwrap()]);
    assert_eq!(code, 0, "{said}");
    assert!(
        said.contains("total charge is 0.500000 e, not a whole number"),
        "{said}"
    );
    // Refused, naming the file: a negative bond force constant, a negative mass, a
    // [ moleculetype ] defined twice.
    let refused = [
        (
            "bond",
            "0.15220 265265.600000",
            "0.15220 -265265.600000",
            "negative",
        ),
        (
            "mass",
            "0.11230000   1.007947",
            "0.11230000   -1.007947",
            "mass",
        ),
        (
            "twice",
            "[ system ]",
            "[ moleculetype ]\nsystem1 3\n\n[ atoms ]\n1 H1 1 ACE H1 1 0.0 1.008\n\n[ system ]",
            "defined twice",
        ),
    ];
    for (name, from, to, what) in refused {
        let top = spoiled_top(&dir, name, from, to);
        let (code, said) = check(&[top.to_str().unwrap()]);
        assert_eq!(code, 1, "{name}: {said}");
        assert!(
            said.contains(what) && said.contains(top.to_str().unwrap()),
            "{name}: {said}"
        );
    }
    // Flags out of any sense.
    let vacuum = systems.join("ala2.prmtop");
    let solvated = systems.join("ala2-solvated.prmtop");
    for (scene, flags, what) in [
        (&solvated, &["--epsilon-rf", "0.5"][..], "epsilon_rf"),
        (&vacuum, &["--hydrogen-mass", "0.5amu"][..], "lighter than"),
        (&vacuum, &["--temperature", "1e30K"][..], "temperature"),
    ] {
        let mut args = vec![scene.to_str().unwrap()];
        args.extend(flags);
        let (code, said) = check(&args);
        assert_eq!(code, 1, "{flags:?}: {said}");
        assert!(said.contains(what), "{flags:?}: {said}");
    }
    // A solvated top whose .gro box is 0 0 0 is read in vacuum: a warning says so.
    let systems_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("systems/alanine-dipeptide-amber");
    std::fs::copy(
        systems_dir.join("ala2-solvated.top"),
        dir.join("no-box.top"),
    )
    .unwrap();
    let gro = std::fs::read_to_string(systems_dir.join("ala2-solvated.gro")).unwrap();
    let mut lines: Vec<&str> = gro.lines().collect();
    let last = lines.len() - 1;
    lines[last] = "   0.00000   0.00000   0.00000";
    std::fs::write(dir.join("no-box.gro"), lines.join("\n") + "\n").unwrap();
    let (code, said) = check(&[dir.join("no-box.top").to_str().unwrap()]);
    assert_eq!(code, 0, "{said}");
    assert!(
        said.contains("warning:") && said.contains("gives no box"),
        "{said}"
    );
    // With PME, a charged box says so (docs/molecules.md).
    let solvated_top = systems.join("ala2-solvated.top");
    let text = std::fs::read_to_string(&solvated_top).unwrap();
    let charged = dir.join("charged-box.top");
    std::fs::write(&charged, text.replacen(" 0.11230000 ", " 1.11230000 ", 1)).unwrap();
    std::fs::copy(
        systems.join("ala2-solvated.gro"),
        dir.join("charged-box.gro"),
    )
    .unwrap();
    let (code, said) = check(&[charged.to_str().unwrap(), "--coulomb", "pme"]);
    assert_eq!(code, 0, "{said}");
    assert!(said.contains("net charge of 1.000000 e"), "{said}");
}

/// Item 11: with PME the solvated dipeptide still conserves its momentum (the Ewald sum is
/// translation invariant; only its mesh interpolation leaves a net force ~1e-3 of the
/// forces): the start removes the centre-of-mass momentum and the temperature counts
/// 3N − 3 = 3870 degrees of freedom, as with the reaction field.
#[test]
fn with_pme_the_centre_of_mass_momentum_is_removed() {
    let dir = scratch_dir("newcomer-pme-momentum");
    let (code, stdout, stderr) = run(&argv(
        "run systems/alanine-dipeptide-amber/ala2-solvated-pme.toml --temperature 300K \
         --t-end 2fs --out {}",
        &[dir.to_str().unwrap()],
    ));
    assert_eq!(code, 0, "{stderr}");
    let said = format!("{stdout}{stderr}");
    assert!(
        said.contains("3870 degrees of freedom (3·1291 − 3: centre-of-mass momentum removed)"),
        "{said}"
    );
}

/// Item 9: `analyze` of a run directory without manifest.json says it cannot check that
/// its files come from one run.
#[test]
fn analyze_without_a_manifest_says_nothing_is_checked() {
    let dir = scratch_dir("newcomer-analyze-no-manifest");
    let out = dir.join("run");
    let (code, _, stderr) = run(&argv(
        "run systems/chain/scene.toml --method verlet --h 0.01 --t-end 0.2 \
         --trajectory-every 2 --quiet --out {}",
        &[out.to_str().unwrap()],
    ));
    assert_eq!(code, 0, "{stderr}");
    std::fs::remove_file(out.join("manifest.json")).unwrap();
    let (_, _, stderr) = run(&["analyze", "systems/chain/scene.toml", out.to_str().unwrap()]);
    assert!(
        stderr.contains("no manifest.json") && stderr.contains("without a check"),
        "{stderr}"
    );
}

/// Item 3: `check --help` says a topology is accepted in place of a scene, and the box of
/// a topology read in nm prints as the number it is (45.981, not 45.980999999999995).
#[test]
fn check_help_names_topologies_and_boxes_print_short() {
    let (code, stdout, _) = run(&["check", "--help"]);
    assert_eq!(code, 0);
    assert!(stdout.contains("or a topology in its place"), "{stdout}");
    let dir = scratch_dir("newcomer-box-digits");
    let systems = Path::new(env!("CARGO_MANIFEST_DIR")).join("systems/alanine-dipeptide-amber");
    let gro = std::fs::read_to_string(systems.join("ala2-solvated.gro")).unwrap();
    let mut lines: Vec<&str> = gro.lines().collect();
    let last = lines.len() - 1;
    lines[last] = "   4.59810   4.59810   4.59810";
    std::fs::write(dir.join("box.gro"), lines.join("\n") + "\n").unwrap();
    std::fs::copy(systems.join("ala2-solvated.top"), dir.join("box.top")).unwrap();
    let (code, said) = check(&[dir.join("box.top").to_str().unwrap()]);
    assert_eq!(code, 0, "{said}");
    assert!(said.contains("box 45.981 × 45.981 × 45.981 Å"), "{said}");
}

/// Item 3, the rest: `check` gives the Ewald splitting α in 1/Å, the unit of every real
/// scene and of a topology (GROMACS's nm are read as Å), where it printed `1/length` with 16
/// digits on one line and 6 on the next; the lengths of the non-bonded term carry their
/// unit; no float noise (`-0.000000 e`, `× 0.8333333333333334`). Three ways to PME: an
/// AMBER prmtop scene, a GROMACS top/gro with `--coulomb pme`, a force-field scene. The
/// help names the coordinates' formats too.
#[test]
fn check_gives_alpha_and_lengths_in_the_scenes_units() {
    let (code, stdout, _) = run(&["check", "--help"]);
    assert_eq!(code, 0);
    for format in [".prmtop", ".top", ".inpcrd", ".gro"] {
        assert!(stdout.contains(format), "{format}: {stdout}");
    }
    let cases: [&[&str]; 3] = [
        &["systems/protein-amber/trpcage-pme.toml"],
        &[
            "systems/alanine-dipeptide-amber/ala2-solvated.top",
            "--coulomb",
            "pme",
        ],
        &["systems/water-box/pme.toml"],
    ];
    for args in cases {
        let (code, said) = check(args);
        assert_eq!(code, 0, "{said}");
        for noise in ["1/length", "-0.000000", "0.8333333333333334"] {
            assert!(!said.contains(noise), "{args:?}: {noise} in {said}");
        }
        let alphas: Vec<f64> = said
            .match_indices("alpha = ")
            .map(|(at, key)| {
                let rest = &said[at + key.len()..];
                let (number, unit) = rest.split_once(' ').unwrap();
                assert!(unit.starts_with("1/Å"), "{args:?}: {rest}");
                let digits = number.chars().filter(char::is_ascii_digit).count();
                assert!(digits <= 11, "{args:?}: {number}");
                number.trim_end_matches(',').parse().unwrap()
            })
            .collect();
        // The real-space line and the reciprocal line give the same α.
        assert_eq!(alphas.len(), 2, "{args:?}: {said}");
        assert_eq!(alphas[0], alphas[1], "{args:?}");
        // GROMACS's ewald-rtol 1e-5 at the 9 Å cutoff: LAMMPS reports 0.34704592/Å for it,
        // GROMACS and OpenMM 0.347046 (docs/data/sittings/head-to-head-pme-2026-11-26.txt);
        // 10 digits shown keep it within 5e-9 of LAMMPS's 8.
        assert!(
            (alphas[0] - 0.34704592).abs() < 1e-8,
            "{args:?}: {}",
            alphas[0]
        );
        assert!(said.contains("cutoff 9 Å, skin "), "{args:?}: {said}");
    }
}

/// Item 5: `minimize --save` to a format that rounds positions (PDB: 0.001 Å) warns that
/// the minimum is lost; `minimize --json` prints its report as JSON.
#[test]
fn minimize_warns_of_a_rounding_format_and_takes_json() {
    let dir = scratch_dir("newcomer-minimize");
    let pdb = dir.join("min.pdb");
    let (code, stdout, stderr) = run(&[
        "minimize",
        "systems/alanine-dipeptide-amber/ala2.prmtop",
        "--max-iterations",
        "20",
        "--json",
        "--save",
        pdb.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{stderr}");
    assert!(
        stderr.contains("warning") && stderr.contains("0.001 Å"),
        "{stderr}"
    );
    let json = &stdout[..stdout.rfind('}').map_or(0, |k| k + 1)];
    let report: serde_json::Value = serde_json::from_str(json).expect("a JSON report");
    assert_eq!(report["iterations"], 20, "{stdout}");
}

/// A reader that stops early (`longstep check SCENE | head -1`) ends the command as it ends
/// any Unix tool: no panic message about a broken pipe. The read end is closed before the
/// program writes its first line, so every write after start-up meets a closed pipe.
#[test]
fn a_closed_pipe_ends_the_command_without_a_panic() {
    use std::process::Stdio;
    let mut child = longstep()
        .args(["check", "systems/three-spring.toml"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("longstep runs");
    drop(child.stdout.take());
    let output = child.wait_with_output().expect("longstep ends");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_ne!(output.status.code(), Some(101), "{stderr}");
}
