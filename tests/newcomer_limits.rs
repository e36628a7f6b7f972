//! What a newcomer tripped over (issue 14): sizes a user can ask for are bounded before any
//! work or output (item 3), the state that blew up is in the trajectory (item 5), failed
//! validation leaves no output directory (item 6), huge and tiny numbers print in exponent
//! form (item 7), and `stability-map` names the flag that is wrong (item 11).

mod common;
use common::run_cli as run;
use common::{argv, scratch_dir, words};

#[test]
fn a_run_too_long_or_too_large_is_refused_before_it_writes() {
    let dir = scratch_dir("huge-run");
    for (flag, value) in [("--h", "1e-300"), ("--t-end", "1e300")] {
        let out = dir.join(flag.trim_start_matches('-'));
        let (code, _, stderr) = run(&[
            "run",
            "systems/two-spring.toml",
            flag,
            value,
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(code, 1, "{flag} {value}: {stderr}");
        assert!(
            stderr.contains("outer steps") && stderr.contains("--allow-large"),
            "{stderr}"
        );
        assert!(!out.exists(), "{flag} {value} created {}", out.display());
    }
}

/// Issue 30 item 9: a map whose CSV would be larger than 2 GB is refused before it writes
/// (`--n 20000` wrote 340 MB in 5 s, ~16 GB projected); a shard of it that fits runs.
#[test]
fn a_map_too_large_to_write_is_refused_before_it_writes() {
    let dir = scratch_dir("huge-map");
    let out = dir.join("map.csv");
    let (code, _, stderr) = run(&argv(
        "stability-map --method impulse --h 0.5 --n 20000 --out {} --quiet",
        &[out.to_str().unwrap()],
    ));
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("400000000 rows") && stderr.contains("--allow-large"),
        "{stderr}"
    );
    assert!(!out.exists(), "the refused map wrote {}", out.display());
}

#[test]
fn tiny_and_huge_numbers_print_in_exponent_form() {
    let out = scratch_dir("tiny-step");
    let (code, stdout, stderr) = run(&argv(
        "run systems/two-spring.toml --h 1e-300 --t-end 1e-298 --out {}",
        &[out.to_str().unwrap()],
    ));
    assert_eq!(code, 0, "{stderr}");
    assert!(stdout.contains("h = 1e-300"), "{stdout}");
    assert!(
        stdout.contains("to t = 1") && stdout.contains("e-298\n"),
        "{stdout}"
    );
    let csv = std::fs::read_to_string(out.join("energy.csv")).unwrap();
    for field in csv.lines().flat_map(|l| l.split(',')) {
        assert!(field.len() <= 25, "long field {field}");
    }
    // Round trip: the times read back exactly.
    let last_t: f64 = csv
        .lines()
        .last()
        .and_then(|l| l.split(',').next())
        .and_then(|t| t.parse().ok())
        .unwrap();
    assert!((last_t / 1e-298 - 1.0).abs() < 1e-12, "{last_t}");
}

/// hΩ2 = 7 blows Verlet up within a few steps, long before the 1000th step at which the
/// trajectory is next written: the last frame is the state at the stop.
#[test]
fn the_trajectory_keeps_the_state_that_blew_up() {
    let out = scratch_dir("blow-up-frame");
    let (code, stdout, stderr) = run(&argv(
        "run systems/three-spring.toml --h 0.5 --t-end 1000 --trajectory-every 1000 \
         --json --out {}",
        &[out.to_str().unwrap()],
    ));
    assert_eq!(code, 3, "{stderr}");
    let summary: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let at = summary["unstable_at"].as_f64().unwrap();
    let steps = summary["steps"].as_u64().unwrap();
    assert!(steps < 1000, "blew up only after {steps} steps");
    let trajectory = std::fs::read_to_string(out.join("trajectory.xyz")).unwrap();
    let comments: Vec<&str> = trajectory.lines().filter(|l| l.contains("time=")).collect();
    assert_eq!(comments.len(), 2, "{trajectory}");
    assert!(
        comments[1].contains(&format!("time={at}")),
        "last frame {} is not the stop at step {steps}, t = {at}",
        comments[1]
    );
}

#[test]
fn stability_map_names_the_flag_and_the_path() {
    let dir = scratch_dir("map-limits");
    let csv = dir.join("m.csv");
    let base = ["stability-map", "--method", "impulse", "--h", "1", "--out"];
    let mut args: Vec<&str> = base.to_vec();
    args.extend([csv.to_str().unwrap(), "--n", "0"]);
    let (code, _, stderr) = run(&args);
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("--n") && !stderr.contains("--gamma1"),
        "{stderr}"
    );
    let mut args: Vec<&str> = base.to_vec();
    args.extend([csv.to_str().unwrap(), "--n", "100000000"]);
    let (code, _, stderr) = run(&args);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("--n 100000000"), "{stderr}");
    let missing = dir.join("no-such-dir").join("map.png");
    let mut args: Vec<&str> = base.to_vec();
    args.extend([
        csv.to_str().unwrap(),
        "--n",
        "4",
        "--png",
        missing.to_str().unwrap(),
    ]);
    let (code, _, stderr) = run(&args);
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("does not exist") && !stderr.contains("backend"),
        "{stderr}"
    );
    assert!(
        !csv.exists(),
        "the map ran before the picture's path was checked"
    );
}

/// Item 16: after `--minimize` the hint to minimise is not repeated; the warning says why a
/// minimum of all forces can leave negative fast curvature.
#[test]
fn modes_after_minimize_do_not_ask_to_minimize() {
    let (code, stdout, stderr) = run(&[
        "modes",
        "systems/molecules/alanine-dipeptide.toml",
        "--minimize",
    ]);
    assert_eq!(code, 0, "{stderr}");
    assert!(stdout.contains("minimised"), "{stdout}");
    assert!(!stdout.contains("try --minimize"), "{stdout}");
}

/// Item 15: a molecule without a torsion table says that its dihedrals get no term, and
/// `check` prints the force-field report (as docs/molecules.md promises).
#[test]
fn check_reports_missing_torsions_and_default_charges() {
    let dir = scratch_dir("no-torsions");
    std::fs::copy("systems/molecules/butane.xyz", dir.join("butane.xyz")).unwrap();
    let scene = std::fs::read_to_string("systems/molecules/butane.toml").unwrap();
    let without: String = scene
        .lines()
        .filter(|l| !l.starts_with("\"X-C-") && !l.starts_with("[forcefield.torsions]"))
        .filter(|l| !l.starts_with("charges =") && !l.starts_with("coulomb ="))
        .map(|l| format!("{l}\n"))
        .collect();
    let path = dir.join("butane.toml");
    std::fs::write(&path, without).unwrap();
    let (code, stdout, stderr) = run(&["check", path.to_str().unwrap()]);
    assert_eq!(code, 0, "{stderr}");
    assert!(
        stdout.contains("torsions: none — the 27 proper dihedrals get no torsion term"),
        "{stdout}"
    );
    assert!(stdout.contains("charge 0 (default 0)"), "{stdout}");
}

/// Item 14: `minimize --save` writes the minimised structure and `run --start` starts from
/// it, at the minimised energy; a structure of other atoms is refused.
#[test]
fn minimize_saves_and_run_starts_from_it() {
    let dir = scratch_dir("minimize-save");
    let saved = dir.join("min.xyz");
    let (code, stdout, stderr) = run(&[
        "minimize",
        "systems/molecules/butane.toml",
        "--save",
        saved.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{stderr}");
    // "N iterations, E before kcal/mol -> after kcal/mol, …": the minimised energy (to 10
    // significant digits: 1e-9 relative, far inside the 1e-6 below).
    let after: f64 = stdout
        .split("-> ")
        .nth(1)
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|e| e.parse().ok())
        .expect("the minimised energy in the report");
    let (code, stdout, stderr) = run(&argv(
        "run systems/molecules/butane.toml --start {} --t-end 10fs --json --out {}",
        &[saved.to_str().unwrap(), dir.join("run").to_str().unwrap()],
    ));
    assert_eq!(code, 0, "{stderr}");
    let summary: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let e0 = summary["energy"]["initial"].as_f64().unwrap();
    // The file keeps positions to the 1e-6 Å or so chemfiles writes; at a minimum the
    // energy changes to second order in that.
    assert!(
        (e0 - after).abs() < 1e-6,
        "E0 {e0} against the minimum {after}"
    );
    let (code, _, stderr) = run(&argv(
        "run systems/molecules/hexane.toml --start {} --t-end 10fs --out {}",
        &[saved.to_str().unwrap(), dir.join("other").to_str().unwrap()],
    ));
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("has 14 atoms, the scene 20"), "{stderr}");
}

/// Item 12: a long run's energy picture (2000 rows of a fast oscillation) keeps every drawn
/// pixel of its series inside the plotting area: none over the title or the tick labels.
/// The layout (src/plot/mod.rs, 900 × 600): a 14 px margin and the 22 px title above the plot,
/// the 48 px x-label area and the margin below it, the 72 px y-label area left of it.
#[test]
fn a_long_runs_picture_stays_inside_its_axes() {
    let out = scratch_dir("long-plot");
    let (code, _, stderr) = run(&argv(
        "run systems/three-spring.toml --method impulse --h 0.05 --inner 10 --t-end 100 \
         --plot --out {}",
        &[out.to_str().unwrap()],
    ));
    assert_eq!(code, 0, "{stderr}");
    let decoder = png::Decoder::new(std::fs::File::open(out.join("energy.png")).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let mut pixels = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut pixels).unwrap();
    let channels = info.color_type.samples();
    let (width, height) = (info.width as usize, info.height as usize);
    let (top, bottom, left) = (14 + 22, height - 14 - 48, 14 + 72);
    let mut coloured = 0;
    for y in 0..height {
        for x in 0..width {
            let at = (y * width + x) * channels;
            let rgb = &pixels[at..at + 3];
            // Series colours are saturated; text, grid and axes are grey.
            let saturated = rgb.iter().max().unwrap() - rgb.iter().min().unwrap() > 60;
            if saturated {
                coloured += 1;
                assert!(
                    (top..=bottom).contains(&y) && x >= left,
                    "a series pixel at ({x}, {y}) lies outside the plotting area"
                );
            }
        }
    }
    assert!(
        coloured > 10_000,
        "only {coloured} series pixels: nothing drawn?"
    );
}

/// Item 13: an unstable point is drawn in its method's colour under its method's name, not
/// as an anonymous red cross. Verlet blows up at h = 0.5 on the three-spring system (hΩ2 =
/// 7 > 2); impulse with 10 inner steps does not.
#[test]
fn unstable_points_carry_their_method() {
    let out = scratch_dir("scan-unstable-method");
    let (code, _, stderr) = run(&argv(
        "scan steps systems/three-spring.toml --methods verlet,impulse --h 0.1,0.5 \
         --inner 10 --t-end 20 --repeats 0 --quiet --out {}",
        &[out.to_str().unwrap()],
    ));
    assert_eq!(code, 0, "{stderr}");
    let svg = std::fs::read_to_string(out.join("scan.svg")).unwrap();
    assert!(svg.contains("verlet unstable"), "no verlet legend entry");
    assert!(
        // plotters writes a text's content on a line of its own.
        !svg.lines().any(|l| l.trim() == "unstable"),
        "an anonymous unstable legend entry"
    );
}

/// Item 17: every option of `minimize` has a help text (its `--set` had none), on the same
/// line or, in clap's wide layout, on the next, deeper-indented line.
#[test]
fn minimize_options_all_have_help() {
    let (code, stdout, _) = run(&["minimize", "-h"]);
    assert_eq!(code, 0);
    let lines: Vec<&str> = stdout.lines().collect();
    let indent = |l: &str| l.len() - l.trim_start().len();
    for (k, line) in lines.iter().enumerate() {
        if !line.trim_start().starts_with('-') {
            continue;
        }
        let words: Vec<&str> = line.split_whitespace().collect();
        let flag_words = 1
            + words
                .iter()
                .skip(1)
                .take_while(|w| w.starts_with('<'))
                .count()
            + usize::from(words.first() == Some(&"-h,"));
        let same_line = words.len() > flag_words;
        let next_line = lines.get(k + 1).is_some_and(|next| {
            !next.trim().is_empty()
                && !next.trim_start().starts_with('-')
                && indent(next) > indent(line)
        });
        assert!(same_line || next_line, "no help text: {line}");
    }
}

/// Item 13: a map's axes in units of π carry π ticks, so their titles do not repeat
/// "(units of π)".
#[test]
fn map_axes_do_not_repeat_units_of_pi() {
    let dir = scratch_dir("map-pi-axes");
    let svg = dir.join("map.svg");
    let (code, _, stderr) = run(&argv(
        "stability-map --method impulse --h 1 --n 8 --out {} --svg {}",
        &[dir.join("map.csv").to_str().unwrap(), svg.to_str().unwrap()],
    ));
    assert_eq!(code, 0, "{stderr}");
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(text.contains('π'), "no π ticks");
    assert!(
        !text.contains("units of π"),
        "the axis title repeats the π ticks' unit"
    );
}

/// Item 7 in the study tables too: `{}` wrote Verlet's errors of 1e34–1e140 in this
/// stiffness scan as 35–141-digit decimals (and its tiny reference errors as 0.000000…).
/// Every field is now short: the shortest round-trip form is at most 24 characters
/// (17 digits, sign, point, exponent).
#[test]
fn study_tables_write_huge_and_tiny_numbers_in_exponent_form() {
    let (csv, _) = common::verlet_blowup_stiffness_scan(&scratch_dir("stiffness-exponent-form"));
    let text = std::fs::read_to_string(&csv).unwrap();
    let huge = text
        .lines()
        .skip(2)
        .filter_map(|l| l.split(',').nth(4)?.parse::<f64>().ok())
        .fold(0.0, f64::max);
    assert!(
        huge > 1e100,
        "the run no longer blows up far enough: {huge}"
    );
    for line in text.lines().skip(2) {
        for field in line.split(',') {
            assert!(field.len() <= 24, "a long field: {field}");
        }
    }
}

/// Items 18 and 19: what docs/studies.md says about shards is what the commands do — the
/// commands it lists as taking `--shard k/n` have the flag, the two it says do not (it
/// once claimed every scan and chart had one, `scan growth` included) have none.
#[test]
fn the_docs_list_of_sharded_commands_matches_the_commands() {
    let docs = std::fs::read_to_string("docs/studies.md").unwrap();
    let claim = "`scan steps`, `scan stiffness`, `chart work-precision` and `stability-map` take\n`--shard k/n` (`scan growth` and `async-stability-map` do not";
    assert!(
        docs.contains(claim),
        "docs/studies.md no longer says which commands shard"
    );
    let sharded: [&[&str]; 4] = [
        &["scan", "steps"],
        &["scan", "stiffness"],
        &["chart", "work-precision"],
        &["stability-map"],
    ];
    let unsharded: [&[&str]; 2] = [&["scan", "growth"], &["async-stability-map"]];
    for (commands, has) in [(&sharded[..], true), (&unsharded[..], false)] {
        for command in commands {
            let (code, stdout, stderr) = run(&[*command, &["--help"]].concat());
            assert_eq!(code, 0, "{command:?}: {stderr}");
            assert_eq!(stdout.contains("--shard"), has, "{command:?} --help");
        }
    }
}

/// Issue 30 item 17: the README's command list names every command and every `scan` and
/// `chart` study the program has (it lacked minimize, spectral-radius, async-stability-map
/// and scan stiffness/growth), and no doc embeds a picture the repository does not hold.
#[test]
fn the_readme_lists_every_command_and_no_doc_embeds_a_missing_picture() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    let help = |args: &[&str]| -> Vec<String> {
        let (code, stdout, stderr) = common::run_cli(args);
        assert_eq!(code, 0, "{stderr}");
        let listing = stdout.split("Commands:").nth(1).unwrap_or("").to_string();
        let listing = listing.split("Options:").next().unwrap_or("").to_string();
        listing
            .lines()
            .filter_map(|l| l.split_whitespace().next().map(String::from))
            .filter(|c| c != "help")
            .collect()
    };
    let mut commands: Vec<String> = help(&["--help"])
        .into_iter()
        .filter(|c| c != "scan" && c != "chart")
        .map(|c| format!("longstep {c} "))
        .collect();
    for group in ["scan", "chart"] {
        commands.extend(
            help(&[group, "--help"])
                .into_iter()
                .map(|c| format!("longstep {group} {c} ")),
        );
    }
    assert!(commands.len() > 10, "{commands:?}");
    for command in commands {
        assert!(readme.contains(&command), "README lacks `{command}`");
    }
    let docs = std::fs::read_dir(root.join("docs")).unwrap();
    for entry in docs.flatten().map(|e| e.path()) {
        if entry.extension().is_none_or(|e| e != "md") {
            continue;
        }
        let text = std::fs::read_to_string(&entry).unwrap();
        for embed in text.split("](").skip(1).filter(|_| text.contains("![")) {
            let target = embed.split(')').next().unwrap_or("");
            if target.ends_with(".png") || target.ends_with(".svg") {
                assert!(
                    root.join("docs").join(target).exists(),
                    "{} embeds {target}, which is not in the repository",
                    entry.display()
                );
            }
        }
    }
}

/// Issue 30 item 12: `check` gives E0 and the box with their units and ten significant
/// digits (it printed E0 = -1554.6365394244694 and the box as a 17-digit list).
#[test]
fn check_prints_energies_and_box_with_units_and_ten_digits() {
    let (code, stdout, stderr) = common::run_cli(&["check", "systems/water-box/scene.toml"]);
    assert_eq!(code, 0, "{stderr}");
    let line = |start: &str| -> String {
        stdout
            .lines()
            .find(|l| l.starts_with(start))
            .unwrap_or_else(|| panic!("no {start} line in {stdout}"))
            .to_string()
    };
    let energy = line("energy");
    assert!(
        energy.contains("E0 = ") && energy.contains(" kcal/mol"),
        "{energy}"
    );
    let particles = line("particles");
    assert!(particles.contains(" Å"), "{particles}");
    for text in [energy, particles] {
        let digits = text
            .split(|c: char| !(c.is_ascii_digit() || c == '.'))
            .map(|n| n.chars().filter(char::is_ascii_digit).count())
            .max()
            .unwrap_or(0);
        assert!(digits <= 11, "{text}");
    }
}

/// Issue 30 item 12: `modes` on a real scene gives ω in rad/fs, periods in fs, wavenumbers
/// in cm⁻¹ and the resonant steps in fs (it printed bare numbers).
#[test]
fn modes_of_a_real_scene_carry_their_units() {
    let (code, stdout, stderr) = common::run_cli(&words(
        "modes systems/water-box/scene.toml --h-range 4fs:10fs --top 1",
    ));
    assert_eq!(code, 0, "{stderr}");
    assert!(
        stdout.contains("omega (rad/fs)") && stdout.contains("period (fs)"),
        "{stdout}"
    );
    assert!(stdout.contains("cm^-1"), "{stdout}");
    assert!(stdout.contains("in [4, 10] fs:"), "{stdout}");
    // The fastest mode is an O–H stretch: its wavenumber between 3000 and 4000 cm⁻¹.
    let first = stdout
        .lines()
        .find(|l| l.trim_start().starts_with("1 "))
        .unwrap_or_else(|| panic!("{stdout}"));
    let wavenumber: f64 = first.split_whitespace().nth(3).unwrap().parse().unwrap();
    assert!((3000.0..4000.0).contains(&wavenumber), "{first}");
}
