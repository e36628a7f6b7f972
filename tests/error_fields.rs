//! Scene, topology and command-line errors carry where and what as fields (issue 25 item
//! 7): the file, the line, the key (a scene key, a prmtop `%FLAG`, a command-line flag),
//! and the value expected and got. These tests read the fields, not the message text.

mod common;

use std::path::Path;

use common::scratch_dir;
use longstep::error::{Error, Problem};
use longstep::io::scene::{load_scene, read_topology_file};
use longstep::units::Units;

/// The problem an error carries; a failure names the error that has none.
fn problem(error: &Error) -> &Problem {
    error
        .problem()
        .unwrap_or_else(|| panic!("no fields in {error:?}"))
}

/// The 1-based number of the first line of `text` that is `needle`.
fn line_of(text: &str, needle: &str) -> usize {
    text.lines()
        .position(|l| l == needle)
        .unwrap_or_else(|| panic!("no line {needle:?}"))
        + 1
}

/// The scene error of `text` written to a scratch file: the error and the file's path.
fn scene_error(name: &str, text: &str) -> (Error, std::path::PathBuf) {
    let path = scratch_dir(name).join("scene.toml");
    std::fs::write(&path, text).unwrap();
    match load_scene(&path, &[]) {
        Ok(_) => panic!("{name}: the scene loaded"),
        Err(e) => (e, path),
    }
}

const SPRING: &str = "[[terms]]\ntype = \"spring\"\nbetween = [0, 1]\nstiffness = 1\n";

#[test]
fn an_unknown_scene_key_gives_file_line_and_key() {
    let text = format!(
        "version = 1\nname = \"k\"\ndim = 1\n[[particles]]\nmass = 1\nposition = [0]\n\
         [[particles]]\nmas = 1.0\nposition = [1]\n{SPRING}"
    );
    let (error, path) = scene_error("fields-unknown-key", &text);
    assert!(matches!(error, Error::Scene(_)), "{error:?}");
    let p = problem(&error);
    assert_eq!(p.location.file.as_deref(), Some(path.as_path()));
    assert_eq!(p.location.line, Some(line_of(&text, "mas = 1.0")));
    assert_eq!(p.location.key.as_deref(), Some("mas"));
}

#[test]
fn a_scene_value_of_the_wrong_type_gives_expected_and_got() {
    let text = format!(
        "version = 1\nname = \"t\"\ndim = \"two\"\n[[particles]]\nmass = 1\nposition = [0]\n\
         [[particles]]\nmass = 1\nposition = [1]\n{SPRING}"
    );
    let (error, _) = scene_error("fields-wrong-type", &text);
    let p = problem(&error);
    assert_eq!(p.location.line, Some(line_of(&text, "dim = \"two\"")));
    assert_eq!(p.location.key.as_deref(), Some("dim"));
    assert_eq!(p.expected.as_deref(), Some("a whole number (0, 1, 2, …)"));
    assert_eq!(p.got.as_deref(), Some("string \"two\""));
}

#[test]
fn a_non_positive_mass_gives_its_key_and_value() {
    let text = format!(
        "version = 1\nname = \"m\"\ndim = 1\n[[particles]]\nmass = -2\nposition = [0]\n\
         [[particles]]\nmass = 1\nposition = [1]\n{SPRING}"
    );
    let (error, path) = scene_error("fields-mass", &text);
    let p = problem(&error);
    assert_eq!(p.location.file.as_deref(), Some(path.as_path()));
    // A particle's error points at its table's header.
    assert_eq!(p.location.line, Some(line_of(&text, "[[particles]]")));
    assert_eq!(p.location.key.as_deref(), Some("mass"));
    assert_eq!(p.got.as_deref(), Some("-2"));
}

#[test]
fn a_negative_stiffness_gives_the_term_key() {
    let text = "version = 1\nname = \"s\"\ndim = 1\n[[particles]]\nmass = 1\nposition = [0]\n\
                [[particles]]\nmass = 1\nposition = [1]\n[[terms]]\ntype = \"spring\"\n\
                between = [0, 1]\nstiffness = -100\n";
    let (error, _) = scene_error("fields-stiffness", text);
    let p = problem(&error);
    assert_eq!(p.location.key.as_deref(), Some("stiffness"));
    assert_eq!(p.location.line, Some(line_of(text, "[[terms]]")));
    assert_eq!(p.got.as_deref(), Some("-100"));
}

/// A copy of the alanine-dipeptide prmtop with `edit` applied, in a scratch folder.
fn edited_prmtop(name: &str, edit: impl Fn(&str) -> String) -> (std::path::PathBuf, String) {
    let text = std::fs::read_to_string("systems/alanine-dipeptide-amber/ala2.prmtop").unwrap();
    let edited = edit(&text);
    assert_ne!(edited, text, "{name}: the edit changed nothing");
    let path = scratch_dir(name).join("ala2.prmtop");
    std::fs::write(&path, &edited).unwrap();
    (path, edited)
}

#[test]
fn a_bad_prmtop_value_gives_file_line_and_flag() {
    let first = "  2.04636429E+00 -6.67300626E+00";
    let (path, text) = edited_prmtop("fields-prmtop-value", |t| {
        t.replacen(first, "  2.04636429E+00 -6.67300626Q+00", 1)
    });
    let error = read_topology_file(&path, &[]).unwrap_err();
    assert!(matches!(error, Error::Topology(_)), "{error:?}");
    let p = problem(&error);
    assert_eq!(p.location.file.as_deref(), Some(path.as_path()));
    let bad_line = text.lines().position(|l| l.contains("Q+00")).unwrap() + 1;
    assert_eq!(p.location.line, Some(bad_line));
    assert_eq!(p.location.key.as_deref(), Some("CHARGE"));
}

#[test]
fn a_prmtop_section_without_format_gives_its_flag_line() {
    let (path, text) = edited_prmtop("fields-prmtop-format", |t| {
        t.replacen("%FLAG CHARGE\n%FORMAT(5E16.8)\n", "%FLAG CHARGE\n", 1)
    });
    let error = read_topology_file(&path, &[]).unwrap_err();
    let p = problem(&error);
    assert_eq!(p.location.line, Some(line_of(&text, "%FLAG CHARGE")));
    assert_eq!(p.location.key.as_deref(), Some("CHARGE"));
}

#[test]
fn a_bad_command_line_value_gives_the_flag() {
    let error = longstep::cli::parse_shard("3/2").unwrap_err();
    let p = problem(&error);
    assert_eq!(p.location.key.as_deref(), Some("--shard"));
    assert_eq!(p.location.file, None);
    assert_eq!(p.got.as_deref(), Some("\"3/2\""));

    let error = longstep::cli::parse_steps("0.1:0.2", Units::None).unwrap_err();
    let p = problem(&error);
    assert_eq!(p.location.key.as_deref(), Some("--h"));
    assert_eq!(p.expected.as_deref(), Some("LO:HI:STEP"));
}

#[test]
fn a_bad_setting_gives_its_key_and_value() {
    let mut run = longstep::settings::RunSpec {
        h: Some(longstep::settings::Value::Number(0.1)),
        ..Default::default()
    };
    run.t_end = Some(longstep::settings::Value::Number(-5.0));
    let error = run.resolve(&Default::default()).unwrap_err();
    let p = problem(&error);
    assert_eq!(p.location.key.as_deref(), Some("t_end"));
    assert_eq!(p.got.as_deref(), Some("-5"));
}

#[test]
fn a_setting_blamed_on_the_scene_keeps_its_key() {
    // `check` places a bad [run] value at the table's line (tests/bad_input.rs checks the
    // text); the library's error keeps the setting's key under the scene's location.
    let error = Error::setting("h", "outer step h must be positive and finite")
        .got("0")
        .in_scene(Path::new("scene.toml"), Some(14), "in [run]");
    let p = problem(&error);
    assert_eq!(p.location.line, Some(14));
    assert_eq!(p.location.key.as_deref(), Some("h"));
    assert_eq!(p.got.as_deref(), Some("0"));
}

#[test]
fn a_gromacs_error_gives_file_line_and_directive() {
    // A bond of an atom the molecule does not have, in a two-atom molecule.
    let text = "[ defaults ]\n1 2 yes 0.5 0.8333\n[ atomtypes ]\nCT 6 12.01 0.0 A 0.34 0.45\n\
                [ moleculetype ]\nM 3\n[ atoms ]\n1 CT 1 M C1 1 0.0 12.01\n\
                2 CT 1 M C2 2 0.0 12.01\n[ bonds ]\n1 2 1 0.15 1000.0\n1 x 1 0.15 1000.0\n\
                [ system ]\nm\n[ molecules ]\nM 1\n";
    let path = scratch_dir("fields-gromacs").join("main.top");
    std::fs::write(&path, text).unwrap();
    let error = read_topology_file(&path, &[]).unwrap_err();
    let p = problem(&error);
    assert_eq!(p.location.file.as_deref(), Some(path.as_path()));
    assert_eq!(p.location.line, Some(line_of(text, "1 x 1 0.15 1000.0")));
    assert_eq!(p.location.key.as_deref(), Some("bonds"));
}
