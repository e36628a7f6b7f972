//! AMBER prmtop topologies: the shipped alanine dipeptide systems (vacuum and solvated in
//! flexible TIP3P) term by term against OpenMM's own AMBER reader
//! (`scripts/openmm_topology_reference.py` wrote `tests/data/openmm-ala2*.json`), and the
//! reader's errors on bad input.
//!
//! Groups compared (OpenMM's forces split by `force group`, longstep's terms by name):
//! bonds = HarmonicBondForce vs "bonds"; angles = HarmonicAngleForce vs "angles";
//! torsions = PeriodicTorsionForce (propers and impropers) vs "torsions" + "impropers";
//! lj and coulomb = the NonbondedForce's pairs (exceptions zeroed) vs the Lennard-Jones and
//! Coulomb parts of "nonbonded"; lj_14 and coulomb_14 = the NonbondedForce's exceptions vs
//! "lj-14" and "coulomb-14". Forces: the sum of all terms.
//!
//! Tolerance 1e-6 relative (issue 27's requirement). What separates the two codes is far
//! below it: both evaluate at the same inpcrd coordinates in double precision; OpenMM's
//! Coulomb constant (138.935456 kJ/mol·nm) is 332.063707 kcal/mol·Å against longstep's
//! 332.06371 (9e-9 relative); OpenMM mixes the per-atom σ, ε (from the diagonal A, B
//! printed to 9 digits) where longstep reads the A, B of each type pair (≲ 1e-8 relative
//! for a Lorentz–Berthelot force field); kJ/kcal and nm/Å conversions are exact to
//! round-off. A wrong factor 2 in a constant, a missed 1-4 pair or a wrong scale is off by
//! ≥ 1e-3.

mod common;
use common::{OPENMM_GROUPS, assert_forces_match, flat, group_energy};

use std::path::{Path, PathBuf};

use longstep::forces::ewald::EwaldRequest;
use longstep::io::forcefield::ElectrostaticsOverrides;
use longstep::io::scene::{
    Scene, SceneFlags, load_scene, load_scene_with, load_scene_with_coordinates,
};
use longstep::io::topology::build_terms;
use longstep::io::topology::inpcrd::read_inpcrd;
use longstep::io::topology::prmtop::{parse_prmtop, read_prmtop};
use longstep::io::topology::{BuiltTopology, Coulomb, NonbondedOptions};

const TOLERANCE: f64 = 1e-6;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn system_path(file: &str) -> PathBuf {
    root().join("systems/alanine-dipeptide-amber").join(file)
}

struct Reference {
    energy: serde_json::Map<String, serde_json::Value>,
    /// Per-atom forces (flat `n × 3`) of "bonded", "nonbonded" and "total".
    forces: serde_json::Map<String, serde_json::Value>,
}

fn reference(name: &str) -> Reference {
    let path = root().join(format!("tests/data/openmm-{name}.json"));
    let text = std::fs::read_to_string(&path).expect("reference JSON");
    let json: serde_json::Value = serde_json::from_str(&text).expect("valid JSON");
    let energy = json["energy"].as_object().expect("energy table").clone();
    let forces = json["forces"].as_object().expect("force table").clone();
    Reference { energy, forces }
}

fn load(name: &str, options: &NonbondedOptions) -> (BuiltTopology, Vec<f64>) {
    let topology = read_prmtop(&system_path(&format!("{name}.prmtop"))).expect("prmtop reads");
    let coordinates = read_inpcrd(&system_path(&format!("{name}.inpcrd"))).expect("inpcrd reads");
    assert_eq!(coordinates.n_atoms(), topology.atoms.len());
    let built = build_terms(&topology, &coordinates.positions, options).expect("terms build");
    (built, coordinates.positions)
}

fn compare_with_openmm(name: &str) {
    compare_with_openmm_as(name, name, &NonbondedOptions::default());
}

/// The system `file` built with `options` against the reference `name`.
fn compare_with_openmm_as(name: &str, file: &str, options: &NonbondedOptions) {
    let (built, q) = load(file, options);
    let reference = reference(name);
    let mut total = 0.0;
    for group in OPENMM_GROUPS {
        let expected = reference.energy[group].as_f64().expect("energy");
        let got = group_energy(&built, &q, group);
        total += got;
        let error = (got - expected).abs() / expected.abs();
        eprintln!("{name} {group}: {got:.9} kcal/mol, OpenMM {expected:.9}, relative {error:.1e}");
        assert!(
            error <= TOLERANCE,
            "{name} {group}: longstep {got} kcal/mol, OpenMM {expected}, relative {error:e}"
        );
    }
    let expected_total = reference.energy["total"].as_f64().expect("total");
    assert!((total - expected_total).abs() <= TOLERANCE * expected_total.abs());
    compare_forces(name, &built, &q, &reference);
}

/// Forces of the bonded terms, of the non-bonded ones, and in total. At a minimised
/// structure the total is a small difference of the two parts (its RMS is ~1e-3 of theirs
/// in the vacuum dipeptide), so the total's difference is measured against the RMS of the
/// non-bonded part, the larger one: a relative error of the parts of 1e-6 moves the total
/// by at most about that much.
fn compare_forces(name: &str, built: &BuiltTopology, q: &[f64], reference: &Reference) {
    let expected = |part: &str| flat(&reference.forces[part]);
    assert_forces_match(name, built, q, &expected, TOLERANCE);
}

#[test]
fn vacuum_dipeptide_matches_openmm_term_by_term() {
    compare_with_openmm("ala2");
}

#[test]
fn solvated_dipeptide_matches_openmm_term_by_term() {
    compare_with_openmm("ala2-solvated");
}

/// PME with OpenMM's parameters given explicitly (α = 0.35 Å⁻¹, 24³ grid, order 5, 9 Å):
/// the Ewald real space, the mesh, the excluded-pair correction (1-4 pairs included, whose
/// scaled Coulomb stays in coulomb-14) and the self energy, term by term.
#[test]
fn solvated_dipeptide_with_pme_matches_openmm_term_by_term() {
    let options = NonbondedOptions {
        coulomb: Some(Coulomb::Pme),
        ewald: EwaldRequest {
            alpha: Some(0.35),
            grid: Some([24; 3]),
            order: Some(5),
            ..EwaldRequest::default()
        },
        ..NonbondedOptions::default()
    };
    compare_with_openmm_as("ala2-solvated-pme", "ala2-solvated", &options);
}

/// A prmtop of another tool chain: openmmtools' alanine dipeptide, made by tleap in 2009
/// (ff96-era parameters), copied unchanged by `openmm_topology_reference.py --other`. It
/// has no SCEE/SCNB and no ATOMIC_NUMBER sections, so the defaults (1.2, 2.0) and elements
/// by mass are used, as OpenMM does.
#[test]
fn a_tleap_prmtop_matches_openmm_term_by_term() {
    compare_with_openmm("ala2-tleap");
    let topology = read_prmtop(&system_path("ala2-tleap.prmtop")).expect("reads");
    assert!(
        topology
            .notes
            .iter()
            .any(|n| n.contains("no SCEE_SCALE_FACTOR section, 1.2")),
        "{:?}",
        topology.notes
    );
    assert_eq!(topology.atoms[1].element, "C");
}

#[test]
fn the_reader_counts_what_parmed_wrote() {
    let topology = read_prmtop(&system_path("ala2-solvated.prmtop")).expect("reads");
    let waters = topology.residues.iter().filter(|r| r.name == "HOH").count();
    assert_eq!(topology.residues.len(), 3 + waters);
    assert_eq!(topology.atoms.len(), 22 + 3 * waters);
    // Flexible water: two O-H bonds and one H-O-H angle per water, no H-H bond.
    let (bonds_peptide, angles_peptide) = (21, 36);
    assert_eq!(topology.bonds.len(), bonds_peptide + 2 * waters);
    assert_eq!(topology.angles.len(), angles_peptide + waters);
    assert!(topology.total_charge().abs() < 1e-4, "neutral system");
    assert!(topology.dihedrals.iter().any(|d| d.improper));
    assert_eq!(topology.periodic_box, Some([24.0, 24.0, 24.0]));
}

// --- Bad input -------------------------------------------------------------------------

fn text(name: &str) -> String {
    std::fs::read_to_string(system_path(name)).expect("shipped file")
}

fn parse_error(text: &str) -> String {
    parse_prmtop(text, Path::new("bad.prmtop"))
        .expect_err("the reader refuses it")
        .to_string()
}

/// The 1-based line of `%FLAG name` in `text`.
fn flag_line(text: &str, name: &str) -> usize {
    text.lines()
        .position(|l| l.trim_end() == format!("%FLAG {name}"))
        .expect("flag present")
        + 1
}

#[test]
fn a_truncated_file_is_an_error_naming_file_and_section() {
    let full = text("ala2.prmtop");
    let cut = &full[..full.find("%FLAG EXCLUDED_ATOMS_LIST").expect("section") + 40];
    let e = parse_error(cut);
    assert!(e.starts_with("bad.prmtop:"), "{e}");
    assert!(e.contains("EXCLUDED_ATOMS_LIST"), "{e}");
}

#[test]
fn a_section_of_the_wrong_length_names_its_flag_line() {
    let full = text("ala2.prmtop");
    // Drop the last line of MASS: 22 masses become 20.
    let start = full.find("%FLAG MASS").expect("MASS");
    let next = start + full[start..].find("%FLAG ATOM_TYPE_INDEX").expect("next");
    let last_line = full[..next - 1].rfind('\n').expect("line") + 1;
    let broken = format!("{}{}", &full[..last_line], &full[next..]);
    let e = parse_error(&broken);
    let line = flag_line(&broken, "MASS");
    assert!(
        e.starts_with(&format!("bad.prmtop:{line}: %FLAG MASS")),
        "{e}"
    );
    assert!(e.contains("has 20 values, POINTERS says 22"), "{e}");
}

#[test]
fn cmap_is_refused_by_name() {
    let full = text("ala2.prmtop");
    let with_cmap = format!("{full}%FLAG CMAP_COUNT\n%FORMAT(2I8)\n       1       1\n");
    let e = parse_error(&with_cmap);
    assert!(e.contains("%FLAG CMAP_COUNT"), "{e}");
    assert!(e.contains("CMAP"), "{e}");
    assert!(e.contains("does not model"), "{e}");
}

#[test]
fn hydrogen_bond_terms_and_octahedra_are_refused() {
    let full = text("ala2.prmtop");
    // A truncated octahedron: IFBOX (the 28th pointer) = 2.
    let start = full.find("%FLAG POINTERS").expect("pointers");
    let third_row = start + full[start..].match_indices('\n').nth(3).expect("row").0 + 1;
    let mut row: Vec<char> = full[third_row..third_row + 80].chars().collect();
    row[7 * 8 + 7] = '2';
    let octahedron = format!(
        "{}{}{}",
        &full[..third_row],
        row.into_iter().collect::<String>(),
        &full[third_row + 80..]
    );
    let e = parse_error(&octahedron);
    assert!(e.contains("IFBOX = 2"), "{e}");
}

#[test]
fn coordinates_with_another_atom_count_are_refused() {
    let topology = read_prmtop(&system_path("ala2.prmtop")).expect("reads");
    let other = read_inpcrd(&system_path("ala2-solvated.inpcrd")).expect("reads");
    let e = build_terms(&topology, &other.positions, &NonbondedOptions::default())
        .err()
        .expect("refused");
    assert!(
        e.contains("22 atoms in the topology, 1291 in the coordinates"),
        "{e}"
    );
}

#[test]
fn garbage_is_not_a_prmtop() {
    let e = parse_error("hello\nworld\n");
    assert!(e.starts_with("bad.prmtop:1:"), "{e}");
    let e = parse_error("%FLAG POINTERS\n%FORMAT(10I8)\n      2x\n");
    assert!(e.starts_with("bad.prmtop:3:"), "{e}");
}

// --- Scenes and the command line -------------------------------------------------------

/// Energy of every term of a scene's system at its start, by name.
fn term_energies(scene: &Scene) -> Vec<(String, f64)> {
    let q = &scene.system.state.q;
    scene
        .system
        .forces
        .terms()
        .iter()
        .map(|t| (t.name.clone(), t.term.energy(q)))
        .collect()
}

#[test]
fn a_scene_and_the_bare_topology_build_the_same_terms() {
    for name in ["ala2", "ala2-solvated"] {
        let from_scene = load_scene(&system_path(&format!("{name}.toml")), &[]).expect("scene");
        let from_file = load_scene_with_coordinates(
            &system_path(&format!("{name}.prmtop")),
            Some(&system_path(&format!("{name}.inpcrd"))),
            &[],
        )
        .expect("topology");
        // Same file, same options (the scenes spell out the defaults): the same terms in
        // the same order, so the same bits.
        assert_eq!(
            term_energies(&from_scene),
            term_energies(&from_file),
            "{name}"
        );
        assert_eq!(
            from_scene.system.periodic_box,
            from_file.system.periodic_box
        );
        assert_eq!(
            from_scene.system.particles.masses,
            from_file.system.particles.masses
        );
    }
}

#[test]
fn a_scene_cannot_mix_a_topology_with_a_structure() {
    let dir = common::scratch_dir("topology_mixed_scene");
    let scene = dir.join("mixed.toml");
    let prmtop = system_path("ala2.prmtop");
    let text = format!(
        "version = 1\nname = \"x\"\ndim = 3\nunits = \"real\"\n[structure]\nfile = \"a.xyz\"\n\
         [topology]\nfile = \"{}\"\n",
        prmtop.display()
    );
    std::fs::write(&scene, text).expect("write");
    let e = load_scene(&scene, &[]).err().expect("refused").to_string();
    assert!(e.contains("leave out [structure]"), "{e}");
}

fn run_check(args: &[&std::ffi::OsStr]) -> (i32, String) {
    let output = common::longstep()
        .arg("check")
        .args(args)
        .output()
        .expect("runs");
    (
        output.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&output.stderr).to_string(),
    )
}

#[test]
fn check_refuses_coordinates_of_another_system_with_exit_1() {
    let prmtop = system_path("ala2.prmtop");
    let inpcrd = system_path("ala2-solvated.inpcrd");
    let (code, stderr) = run_check(&[
        prmtop.as_os_str(),
        "--coordinates".as_ref(),
        inpcrd.as_os_str(),
    ]);
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("ala2-solvated.inpcrd:2: has 1291 atoms"),
        "{stderr}"
    );
    assert!(stderr.contains("has 22"), "{stderr}");
}

#[test]
fn check_refuses_a_cmap_topology_with_exit_1() {
    let dir = common::scratch_dir("topology_cmap");
    let prmtop = dir.join("cmap.prmtop");
    let text = format!(
        "{}%FLAG CMAP_COUNT\n%FORMAT(2I8)\n       1       1\n",
        text("ala2.prmtop")
    );
    std::fs::write(&prmtop, text).expect("write");
    std::fs::copy(system_path("ala2.inpcrd"), dir.join("cmap.inpcrd")).expect("copy");
    let (code, stderr) = run_check(&[prmtop.as_os_str()]);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("cmap.prmtop:"), "{stderr}");
    assert!(stderr.contains("%FLAG CMAP_COUNT"), "{stderr}");
}

#[test]
fn flags_choose_the_electrostatics_of_a_bare_topology() {
    let prmtop = system_path("ala2.prmtop");
    let coulomb = |form: &str| ElectrostaticsOverrides {
        coulomb: Some(form.into()),
        ..ElectrostaticsOverrides::default()
    };
    let flags = SceneFlags {
        cutoff: Some(8.0),
        epsilon_rf: Some(50.0),
        electrostatics: coulomb("reaction-field"),
        ..SceneFlags::default()
    };
    let scene = load_scene_with(&prmtop, &flags, &[]).expect("builds");
    assert!(
        scene
            .forcefield_report
            .iter()
            .any(|l| l.contains("cutoff 8 Å") && l.contains("eps_rf = 50")),
        "{:?}",
        scene.forcefield_report
    );
    // Plain Coulomb has no cutoff; a scene file takes no topology flags.
    let plain_with_cutoff = SceneFlags {
        cutoff: Some(8.0),
        electrostatics: coulomb("none"),
        ..SceneFlags::default()
    };
    let e = load_scene_with(&prmtop, &plain_with_cutoff, &[])
        .err()
        .expect("refused")
        .to_string();
    assert!(e.contains("has no cutoff"), "{e}");
    let e = load_scene_with(&system_path("ala2.toml"), &flags, &[])
        .err()
        .expect("refused")
        .to_string();
    assert!(e.contains("are for a topology file"), "{e}");
    let unknown = SceneFlags {
        electrostatics: coulomb("ewald-sum"),
        ..SceneFlags::default()
    };
    let e = load_scene_with(&prmtop, &unknown, &[])
        .err()
        .expect("refused")
        .to_string();
    assert!(e.contains("coulomb \"ewald-sum\" is not one of"), "{e}");
    // PME needs the periodic box the vacuum dipeptide has not.
    let pme = SceneFlags {
        electrostatics: coulomb("pme"),
        ..SceneFlags::default()
    };
    let e = load_scene_with(&prmtop, &pme, &[])
        .err()
        .expect("refused")
        .to_string();
    assert!(e.contains("needs a periodic box"), "{e}");
}
