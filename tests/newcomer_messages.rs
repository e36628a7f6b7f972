//! What a newcomer was misled by (issue 30): the SIN(R) default τ is the one the docs show
//! sampling correctly (item 5); messages say what is wrong in the user's terms (item 11);
//! real-unit numbers carry their units and at most 10 significant digits (item 12).

mod common;
use common::run_cli as run;
use common::{argv, scratch_dir};

const WATER: &str = "systems/water-box/scene.toml";
const BUTANE: &str = "systems/molecules/butane.toml";

/// The `method` line of a run's summary.
fn method_line(stdout: &str) -> &str {
    stdout
        .lines()
        .find(|l| l.starts_with("method "))
        .unwrap_or_else(|| panic!("no method line in {stdout}"))
}

#[test]
fn sinr_default_tau_is_the_documented_one_with_units() {
    let out = scratch_dir("messages-sinr-tau");
    // Two outer steps: the run's header reports the settings it used.
    let (code, stdout, stderr) = run(&argv(
        "run {} --method sinr --h 2fs --temperature 300K --t-end 4fs --out {}",
        &[WATER, out.to_str().unwrap()],
    ));
    assert_eq!(code, 0, "{stderr}");
    let line = method_line(&stdout);
    // docs/thermostats.md: τ = 3 fs with L = 1 is the configuration shown sampling the
    // 15 Å water box correctly (PE and peak pass at 48 and 96 fs); 10 fs samples the 9 Å
    // box 0.33 kcal/mol high.
    let docs = std::fs::read_to_string("docs/thermostats.md").unwrap();
    assert!(
        docs.contains("| `--tau` | 3 fs (real scenes)")
            && docs.contains("| `--thermostats L` | 1 |"),
        "docs/thermostats.md's settings table must state the default τ and L"
    );
    assert!(
        line.contains("tau = 3 fs") && line.contains("L = 1,"),
        "{line}"
    );
    // friction defaults to 1/τ, printed in full (shortest round-trip decimal); kT = k_B ·
    // 300 K in kcal/mol (k_B = 0.0019872 kcal/mol/K), printed to 6 significant digits.
    let friction: f64 = line
        .split("friction = ")
        .nth(1)
        .and_then(|rest| rest.split(' ').next())
        .and_then(|number| number.parse().ok())
        .unwrap_or_else(|| panic!("no friction in {line}"));
    assert_eq!(friction, 1.0 / 3.0, "{line}");
    assert!(line.contains("1/fs (on v2)"), "{line}");
    assert!(line.contains("kT = 0.596161 kcal/mol"), "{line}");
    let report = stdout
        .lines()
        .find(|l| l.starts_with("sinr "))
        .unwrap_or_else(|| panic!("{stdout}"));
    assert!(
        report.contains("kcal/mol") && report.contains("1/fs"),
        "{report}"
    );
}

#[test]
fn a_run_past_t_end_says_so_and_fit_from_has_units() {
    let out = scratch_dir("messages-past-end");
    let args = |t_end: &'static str| {
        vec![
            "run",
            BUTANE,
            "--method",
            "verlet",
            "--h",
            "2fs",
            "--t-end",
            t_end,
            "--out",
            out.to_str().unwrap(),
            // Each run replaces the one before it in the folder.
            "--force",
        ]
    };
    // 21 fs in steps of 2 fs ends at 22 fs.
    let (code, stdout, stderr) = run(&args("21fs"));
    assert_eq!(code, 0, "{stderr}");
    assert!(
        stdout.contains("11 to t = 22 fs (past --t-end 21 fs"),
        "{stdout}"
    );
    // A whole number of steps ends where asked, and says nothing more.
    let (code, stdout, stderr) = run(&args("20fs"));
    assert_eq!(code, 0, "{stderr}");
    assert!(stdout.contains("10 to t = 20 fs\n"), "{stdout}");

    let mut bad = args("20fs");
    bad.extend(["--fit-from", "5ps"]);
    let (code, _, stderr) = run(&bad);
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("--fit-from 5 ps is outside the run [0, 20 fs)"),
        "{stderr}"
    );
}

#[test]
fn minimize_prints_energies_with_units_and_ten_digits() {
    let (code, stdout, stderr) = run(&["minimize", BUTANE]);
    assert_eq!(code, 0, "{stderr}");
    let line = stdout.lines().next().unwrap();
    // "N iterations, E a kcal/mol -> b kcal/mol, max force f kcal/mol/Å"
    let (_, energies) = line.split_once(", E ").unwrap_or_else(|| panic!("{line}"));
    let (before, rest) = energies.split_once(" kcal/mol -> ").unwrap();
    let (after, rest) = rest.split_once(" kcal/mol, max force ").unwrap();
    assert!(rest.ends_with(" kcal/mol/Å"), "{line}");
    for number in [before, after] {
        let mantissa = number.split('e').next().unwrap();
        let digits = mantissa.chars().filter(char::is_ascii_digit).count();
        assert!(digits <= 10, "{number} has {digits} significant digits");
        assert!(number.parse::<f64>().is_ok(), "{number}");
    }
}

#[test]
fn integrator_map_on_a_scene_without_frequencies_names_the_scene() {
    let out = scratch_dir("messages-map");
    let (code, _, stderr) = run(&argv(
        "stability-map --mode integrator --scene {} --method verlet --h 1 --out {}",
        &[BUTANE, out.join("map.csv").to_str().unwrap()],
    ));
    assert_eq!(code, 1, "{stderr}");
    // The user typed --scene, never --set omega1.
    assert!(!stderr.contains("--set"), "{stderr}");
    assert!(
        stderr.contains(&format!("--scene {BUTANE}")) && stderr.contains("omega1 and omega2"),
        "{stderr}"
    );
}

#[test]
fn an_xyz_count_line_that_disagrees_with_the_atom_lines_is_named() {
    let dir = scratch_dir("messages-xyz-count");
    let xyz = std::fs::read_to_string("systems/molecules/butane.xyz").unwrap();
    let scene = std::fs::read_to_string(BUTANE).unwrap();
    let atoms = xyz.lines().next().unwrap().trim().parse::<usize>().unwrap();
    let body: String = xyz.lines().skip(1).map(|l| format!("{l}\n")).collect();
    // Fewer than the atom lines: the first extra atom line (line atoms + 1) is named.
    // More: the count line itself.
    for (name, count, line, words) in [
        ("short", atoms - 2, atoms - 2 + 3, "another atom line"),
        ("long", atoms + 2, 1, &format!("{atoms} atom lines") as &str),
    ] {
        let file = format!("{name}.xyz");
        std::fs::write(dir.join(&file), format!("{count}\n{body}")).unwrap();
        let toml = scene.replace("butane.xyz", &file);
        std::fs::write(dir.join(format!("{name}.toml")), toml).unwrap();
        let (code, _, stderr) = run(&["check", dir.join(format!("{name}.toml")).to_str().unwrap()]);
        assert_eq!(code, 1, "{name}: {stderr}");
        assert!(
            stderr.contains(&format!("{file}:{line}: ")) && stderr.contains(words),
            "{name}: {stderr}"
        );
    }
}

/// A step scan of butane with verlet at 1 and 2 fs, `--shard k/2` when given.
fn scan(out: &std::path::Path, shard: Option<&str>) -> (i32, String, String) {
    let mut args = argv(
        "scan steps {} --methods verlet --h 1fs,2fs --t-end 100fs --repeats 0 --quiet \
         --out {}",
        &[BUTANE, out.to_str().unwrap()],
    );
    if let Some(s) = shard {
        args.extend(["--shard", s]);
    }
    run(&args)
}

#[test]
fn merge_prints_the_safe_step_table_and_scan_headers_carry_units() {
    let dir = scratch_dir("messages-merge");
    let (whole, one, two, merged) = (
        dir.join("whole"),
        dir.join("one"),
        dir.join("two"),
        dir.join("merged"),
    );
    let (code, whole_out, stderr) = scan(&whole, None);
    assert_eq!(code, 0, "{stderr}");
    for (out, shard) in [(&one, "1/2"), (&two, "2/2")] {
        let (code, _, stderr) = scan(out, Some(shard));
        assert_eq!(code, 0, "{stderr}");
    }
    let (code, merged_out, stderr) = run(&[
        "merge",
        one.to_str().unwrap(),
        two.to_str().unwrap(),
        "--out",
        merged.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{stderr}");
    // The merged table is the unsharded scan's (no timings: --repeats 0).
    let table = |text: &str| -> Vec<String> {
        text.lines()
            .skip_while(|l| !l.contains("safe up to"))
            .take_while(|l| !l.contains(" runs, "))
            .map(String::from)
            .collect()
    };
    assert!(!table(&whole_out).is_empty(), "{whole_out}");
    assert_eq!(table(&merged_out), table(&whole_out), "{merged_out}");

    // The header carries units as energy.csv's does.
    let csv = std::fs::read_to_string(whole.join("scan.csv")).unwrap();
    let header = csv.lines().nth(1).unwrap();
    for column in [
        "h[fs]",
        "drift[kT/ns/dof]",
        "blowup_time[fs]",
        "decide_at[fs]",
    ] {
        assert!(header.split(',').any(|c| c == column), "{column}: {header}");
    }
    // Merging tables with units works (the merge above read them), and the merged file
    // keeps them.
    let merged_csv = std::fs::read_to_string(merged.join("scan.csv")).unwrap();
    assert_eq!(merged_csv.lines().nth(1), Some(header));
}

#[test]
fn work_precision_headers_carry_units_in_a_real_scene() {
    let out = scratch_dir("messages-work-precision");
    let (code, _, stderr) = run(&argv(
        "chart work-precision {} --methods impulse --h-list 2fs --inner 2 --t-end 20fs \
         --quiet --out {}",
        &[BUTANE, out.to_str().unwrap()],
    ));
    assert_eq!(code, 0, "{stderr}");
    let csv = std::fs::read_to_string(out.join("work-precision.csv")).unwrap();
    let header = csv.lines().nth(1).unwrap();
    for column in ["h[fs]", "max_position_error[Å]"] {
        assert!(header.split(',').any(|c| c == column), "{column}: {header}");
    }
}

/// Item 11: a box too small for the cutoff is named as such, not as overlapping atoms.
#[test]
fn a_box_too_small_for_the_cutoff_is_named() {
    let dir = scratch_dir("messages-small-box");
    let scene = std::fs::read_to_string("systems/water-box/scene.toml").unwrap();
    let start = scene
        .find("box = [")
        .expect("the water box scene gives its box");
    let end = start + scene[start..].find('\n').unwrap();
    let small = format!("{}box = [17, 17, 17]{}", &scene[..start], &scene[end..]).replace(
        "file = \"water216.xyz\"",
        &format!(
            "file = \"{}\"",
            std::fs::canonicalize("systems/water-box/water216.xyz")
                .unwrap()
                .display()
        ),
    );
    let path = dir.join("small-box.toml");
    std::fs::write(&path, small).unwrap();
    let (code, _, stderr) = common::run_cli(&["check", path.to_str().unwrap()]);
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("too small for [forcefield] cutoff = 9") && !stderr.contains("overlap"),
        "{stderr}"
    );
}
