//! Run, study and merge errors carry where and what as fields (issue 25 item 7): the
//! setting or flag as the user writes it (`block`, `--t-end`), the value expected and
//! the value got, and for a study table its file and line. These tests read the fields;
//! where they also read the text, it is to check that a value the message already names
//! is not printed twice.

mod common;

use std::path::Path;

use common::{argv, run_cli, scratch_dir};
use longstep::error::{Error, Problem};
use longstep::integrators::adaptive_verlet::Control;
use longstep::io::study_csv::{Located, merge_located};
use longstep::settings::MethodSettings;
use longstep::system::constraints::Constraints;

/// The problem an error carries; a failure names the error that has none.
fn problem(error: &Error) -> &Problem {
    error
        .problem()
        .unwrap_or_else(|| panic!("no fields in {error:?}"))
}

/// The error of building `settings`'s integrator (it must fail).
fn build_error(settings: &MethodSettings) -> Error {
    match longstep::integrators::build(settings, &mut Vec::new()) {
        Ok(_) => panic!("{} built", settings.method),
        Err(e) => e,
    }
}

#[test]
fn an_unknown_method_names_the_key_the_choices_and_the_value_once() {
    let error = build_error(&MethodSettings::new("leapfrog", 0.1));
    let p = problem(&error);
    assert_eq!(p.location.key.as_deref(), Some("method"));
    assert_eq!(p.got.as_deref(), Some("leapfrog"));
    assert!(p.expected.as_deref().unwrap().contains("verlet"), "{p:?}");
    // The message names the method already: it is not printed again after it.
    assert_eq!(error.to_string().matches("leapfrog").count(), 1, "{error}");
}

#[test]
fn a_block_size_beyond_the_structural_schemes_gives_block_and_its_value() {
    let mut settings = MethodSettings::new("structural-zd", 0.1);
    settings.block = Some(40);
    let error = build_error(&settings);
    let p = problem(&error);
    assert_eq!(p.location.key.as_deref(), Some("block"));
    assert_eq!(p.got.as_deref(), Some("40"));
    assert_eq!(p.expected.as_deref(), Some("1 to 16"));
    assert!(error.to_string().ends_with(", got 40"), "{error}");
}

#[test]
fn a_multiple_time_step_method_without_its_inner_step_names_inner_steps() {
    let error = build_error(&MethodSettings::new("impulse", 0.1));
    let p = problem(&error);
    assert_eq!(p.location.key.as_deref(), Some("inner_steps"));
    assert_eq!(p.expected.as_deref(), Some("--inner K or --dt"));
    assert_eq!(p.got, None);
}

#[test]
fn a_constraint_tolerance_outside_zero_to_one_gives_key_and_value() {
    let constraints = Constraints::new(1, 2, Vec::new(), Vec::new(), None).unwrap();
    let error = constraints.with_tolerance(1.5).unwrap_err();
    let p = problem(&error);
    assert_eq!(p.location.key.as_deref(), Some("constraint_tolerance"));
    assert_eq!(p.expected.as_deref(), Some("a number in (0, 1)"));
    assert_eq!(p.got.as_deref(), Some("1.5"));
}

#[test]
fn a_step_control_of_the_wrong_form_gives_control_and_the_text() {
    let error = Control::parse("min-distance=-2").unwrap_err();
    let p = problem(&error);
    assert_eq!(p.location.key.as_deref(), Some("control"));
    assert_eq!(p.got.as_deref(), Some("-2"));
    let error = Control::parse("steady").unwrap_err();
    let p = problem(&error);
    assert_eq!(p.location.key.as_deref(), Some("control"));
    assert_eq!(p.got.as_deref(), Some("\"steady\""));
    assert_eq!(error.to_string().matches("steady").count(), 1, "{error}");
}

#[test]
fn a_stiffness_run_length_that_is_no_whole_number_of_steps_names_t_end() {
    let error = longstep::analysis::stiffness::outer_steps(1.0, 0.3).unwrap_err();
    let p = problem(&error);
    assert_eq!(p.location.key.as_deref(), Some("--t-end"));
    assert_eq!(p.got.as_deref(), Some("1"));
    // Through the command line: the same refusal, exit status 1, the flags named.
    let dir = scratch_dir("fields-stiffness-t-end");
    let out = dir.join("stiffness.csv");
    let (code, _, stderr) = run_cli(&argv(
        "scan stiffness systems/two-spring.toml --method impulse --param omega1 --range 0:32 \
         --n 2 --h 0.3 --t-end 1 --inner 10 --out {}",
        &[out.to_str().unwrap()],
    ));
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("--t-end 1 is not a whole number of outer steps --h 0.3"),
        "{stderr}"
    );
}

#[test]
fn a_stability_map_range_and_shard_give_their_flag_and_text() {
    use longstep::analysis::stability::map::{Axis, Shard};
    let error = Axis::parse("6.5", 4, "--gamma1").unwrap_err();
    let p = problem(&error);
    assert_eq!(p.location.key.as_deref(), Some("--gamma1"));
    assert_eq!(p.got.as_deref(), Some("\"6.5\""));
    let error = Axis::parse("3:1", 4, "--gamma2").unwrap_err();
    assert_eq!(problem(&error).location.key.as_deref(), Some("--gamma2"));
    assert_eq!(problem(&error).got.as_deref(), Some("3:1"));
    let error = Shard::parse("3/2").unwrap_err();
    let p = problem(&error);
    assert_eq!(p.location.key.as_deref(), Some("--shard"));
    assert_eq!(p.got.as_deref(), Some("\"3/2\""));
}

/// A shard table of the `demo` study with the given point indices: its first line, its
/// header, then a row a line.
fn write_shard(dir: &Path, name: &str, points: usize, indices: &[usize]) -> std::path::PathBuf {
    let path = dir.join(name);
    let mut text = format!("# longstep demo, points = {points}\nindex,x\n");
    for i in indices {
        text.push_str(&format!("{i},{}\n", i * i));
    }
    std::fs::write(&path, text).unwrap();
    path
}

/// The error of merging two shards, a.csv and b.csv, each of (points, indices), read
/// from files; and b.csv's path.
fn merge_error(
    name: &str,
    a: (usize, &[usize]),
    b: (usize, &[usize]),
) -> (Error, std::path::PathBuf) {
    let dir = scratch_dir(name);
    let first = write_shard(&dir, "a.csv", a.0, a.1);
    let second = write_shard(&dir, "b.csv", b.0, b.1);
    let shards = vec![
        Located::read(&first).unwrap(),
        Located::read(&second).unwrap(),
    ];
    match merge_located(shards) {
        Ok(_) => panic!("{name}: the shards merged"),
        Err(e) => (e, second),
    }
}

#[test]
fn a_short_row_of_a_study_table_gives_its_file_and_line() {
    let dir = scratch_dir("fields-study-short-row");
    let path = dir.join("scan.csv");
    std::fs::write(&path, "# longstep demo, points = 3\nindex,x\n0,0\n1\n2,4\n").unwrap();
    let error = Located::read(&path).unwrap_err();
    let p = problem(&error);
    assert_eq!(p.location.file.as_deref(), Some(path.as_path()));
    // Line 4: the first line, the header, row 0, then the short row.
    assert_eq!(p.location.line, Some(4));
    assert_eq!(p.expected.as_deref(), Some("2 fields"));
    assert_eq!(p.got.as_deref(), Some("1"));
    // The command line prints it as `file:line: message`.
    let (code, _, stderr) = run_cli(&[
        "merge",
        path.to_str().unwrap(),
        "--out",
        dir.join("merged").to_str().unwrap(),
    ]);
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains(&format!("{}:4: row 2 has 1 fields", path.display())),
        "{stderr}"
    );
}

#[test]
fn a_point_two_shards_both_hold_gives_the_file_and_line_of_the_second() {
    let (error, second) = merge_error("fields-study-twice", (3, &[0, 1]), (3, &[1, 2]));
    let p = problem(&error);
    // Point 1 is b.csv's first row, line 3 (after the first line and the header).
    assert_eq!(p.location.file.as_deref(), Some(second.as_path()));
    assert_eq!(p.location.line, Some(3));
    assert_eq!(p.location.key.as_deref(), Some("index"));
    assert_eq!(p.got.as_deref(), Some("1"));
    assert!(
        error.to_string().contains("point 1 appears twice"),
        "{error}"
    );
}

#[test]
fn shards_of_different_settings_give_the_setting_and_both_values() {
    let (error, second) = merge_error("fields-study-settings", (2, &[0]), (3, &[1]));
    let p = problem(&error);
    assert_eq!(p.location.file.as_deref(), Some(second.as_path()));
    assert_eq!(p.location.line, Some(1));
    assert_eq!(p.location.key.as_deref(), Some("points"));
    assert_eq!(p.expected.as_deref(), Some("2"));
    assert_eq!(p.got.as_deref(), Some("3"));
}

#[test]
fn an_error_in_context_keeps_its_fields_and_its_text() {
    let error = build_error(&MethodSettings::new("leapfrog", 0.1));
    let text = format!("leapfrog at h = 0.1: {error}");
    let error = error.context("leapfrog at h = 0.1");
    assert_eq!(error.to_string(), text);
    assert_eq!(problem(&error).location.key.as_deref(), Some("method"));
    assert_eq!(problem(&error).got.as_deref(), Some("leapfrog"));
}

#[test]
fn a_picture_of_an_unknown_format_names_its_file() {
    let path = Path::new("chart.jpg");
    let error = longstep::plot::Format::of(path).unwrap_err();
    let p = problem(&error);
    assert_eq!(p.location.file.as_deref(), Some(path));
    assert_eq!(p.expected.as_deref(), Some(".png or .svg"));
    assert_eq!(
        error.to_string(),
        "chart.jpg: a picture must end in .png or .svg"
    );
}
