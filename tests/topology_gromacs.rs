//! GROMACS top/gro topologies: the shipped alanine dipeptide systems as ParmEd wrote them
//! from the prmtop (`scripts/make_gromacs_topologies.py`) term by term against OpenMM's
//! own GROMACS reader (`scripts/openmm_topology_reference.py` wrote
//! `tests/data/openmm-ala2*-gromacs.json`), the top against the prmtop it was written
//! from, the preprocessor, and the reader's errors on bad input.
//!
//! Groups as `tests/topology_prmtop.rs` (OpenMM force groups vs longstep's terms by name).
//! Tolerance 1e-6 relative against OpenMM (issue 27's requirement): both evaluate the same
//! parameters (the top's printed values) at the same .gro coordinates in double
//! precision; what separates them is OpenMM's Coulomb constant (9e-9 relative to
//! longstep's) and unit conversions exact to round-off.

mod common;
use common::{
    OPENMM_GROUPS as GROUPS, assert_forces_match, flat, group_energy, openmm_json as json, rms,
};

use std::path::{Path, PathBuf};

use longstep::io::topology::gro::{parse_gro, read_gro_for};
use longstep::io::topology::gromacs::read_gromacs_top;
use longstep::io::topology::inpcrd::read_inpcrd;
use longstep::io::topology::prmtop::read_prmtop;
use longstep::io::topology::{BuiltTopology, NonbondedOptions, Topology, build_terms};

const TOLERANCE: f64 = 1e-6;

fn system_path(file: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("systems/alanine-dipeptide-amber")
        .join(file)
}

fn flexible() -> Vec<String> {
    vec!["FLEXIBLE".into()]
}

fn build(topology: &Topology, q: &[f64]) -> BuiltTopology {
    build_terms(topology, q, &NonbondedOptions::default()).expect("terms build")
}

/// The top and its .gro coordinates (with the .gro's box, as the scene loader takes it).
fn load_top(stem: &str) -> (Topology, Vec<f64>) {
    let mut topology =
        read_gromacs_top(&system_path(&format!("{stem}.top")), &flexible()).expect("top reads");
    let gro = read_gro_for(&system_path(&format!("{stem}.gro")), &topology).expect("gro reads");
    topology.periodic_box = gro.box_lengths;
    (topology, gro.positions)
}

/// Per-group energies, then the bonded, non-bonded and total forces (the total against
/// the non-bonded part's RMS, as in tests/topology_prmtop.rs: at a minimised structure it
/// is a small difference of the two parts).
fn compare_with_openmm(stem: &str) {
    let (topology, q) = load_top(stem);
    compare_topology_with_openmm(stem, &topology, &q, &format!("{stem}-gromacs"));
}

fn compare_topology_with_openmm(stem: &str, topology: &Topology, q: &[f64], reference: &str) {
    let built = build(topology, q);
    let q = q.to_vec();
    let reference = json(reference);
    for group in GROUPS {
        let expected = reference["energy"][group].as_f64().expect("energy");
        let got = group_energy(&built, &q, group);
        let error = (got - expected).abs() / expected.abs();
        eprintln!("{stem} {group}: {got:.9} kcal/mol, OpenMM {expected:.9}, relative {error:.1e}");
        assert!(
            error <= TOLERANCE,
            "{stem} {group}: {got} vs OpenMM {expected}"
        );
    }
    let expected = |part: &str| flat(&reference["forces"][part]);
    assert_forces_match(stem, &built, &q, &expected, TOLERANCE);
}

#[test]
fn vacuum_dipeptide_top_matches_openmm_term_by_term() {
    compare_with_openmm("ala2");
}

#[test]
fn solvated_dipeptide_top_matches_openmm_term_by_term() {
    compare_with_openmm("ala2-solvated");
}

/// Explicit 1-4 Lennard-Jones as ParmEd writes a Structure made from an OpenMM System
/// (and acpype writes): `gen-pairs no`, `fudgeLJ 1`, each pair's own σ/ε, inline
/// (`-inline`) or in `[ pairtypes ]` (`-types`), and `gen-pairs yes` with `fudgeLJ 0.5`
/// and half the `[ pairtypes ]` lines gone, those pairs generated from the atom types
/// (`-genpairs`): term by term against OpenMM's GromacsTopFile of the same files
/// (`scripts/make_gromacs_topologies.py --only-explicit-pairs`, then
/// `scripts/openmm_topology_reference.py --only-explicit-pairs`). Tolerance as above.
#[test]
fn explicit_1_4_parameters_match_openmm_term_by_term() {
    let data = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    for variant in ["inline", "types", "genpairs"] {
        let stem = format!("gromacs-pairs-{variant}");
        let topology = read_gromacs_top(&data.join(format!("{stem}.top")), &[]).expect("top reads");
        let gro = read_gro_for(&data.join("gromacs-pairs.gro"), &topology).expect("gro reads");
        assert_eq!(topology.pairs_14.len(), 41, "{stem}");
        compare_topology_with_openmm(&stem, &topology, &gro.positions, &stem);
    }
}

/// The top and the prmtop it was written from, at the same (inpcrd) coordinates. The top
/// prints charges to 8 decimals (≤ 5e-9 e, ≤ 1e-7 of the smallest charge, 0.0337 e),
/// σ to 8 significant digits, ε to 7 (0.0656888 kJ/mol: ≤ 7.6e-7 relative), force
/// constants to 6 decimals of kJ/mol/nm² (≤ 2e-9 relative), angles to 7 decimals of a
/// degree, dihedral constants to 7 decimals of kJ/mol, bond lengths to 5 decimals of nm
/// (ff14SB's lengths have 4 decimals of Å: exact). A group's energy is a sum of terms each
/// off by at most these relative amounts (LJ: 12 × 5e-8 from σ¹² plus 7.6e-7 from ε,
/// ≤ 1.4e-6), so each group is compared to 2e-6 relative. (A group whose terms cancel
/// could be off by more relative to its sum; none does here: the largest difference seen
/// is 1.6e-7, vacuum LJ.)
#[test]
fn the_top_and_its_prmtop_give_the_same_energies() {
    for stem in ["ala2", "ala2-solvated"] {
        let prmtop = read_prmtop(&system_path(&format!("{stem}.prmtop"))).expect("reads");
        let inpcrd = read_inpcrd(&system_path(&format!("{stem}.inpcrd"))).expect("reads");
        let top =
            read_gromacs_top(&system_path(&format!("{stem}.top")), &flexible()).expect("reads");
        let mut top = top;
        top.periodic_box = prmtop.periodic_box;
        let q = &inpcrd.positions;
        let (a, b) = (build(&prmtop, q), build(&top, q));
        for group in GROUPS {
            let (ea, eb) = (group_energy(&a, q, group), group_energy(&b, q, group));
            let error = (ea - eb).abs() / ea.abs();
            eprintln!("{stem} {group}: prmtop {ea:.9}, top {eb:.9}, relative {error:.1e}");
            assert!(error <= 2e-6, "{stem} {group}: prmtop {ea}, top {eb}");
        }
    }
}

#[test]
fn the_reader_counts_what_parmed_wrote() {
    let (topology, _) = load_top("ala2-solvated");
    let prmtop = read_prmtop(&system_path("ala2-solvated.prmtop")).expect("reads");
    assert_eq!(topology.atoms.len(), prmtop.atoms.len());
    assert_eq!(topology.bonds.len(), prmtop.bonds.len());
    assert_eq!(topology.angles.len(), prmtop.angles.len());
    assert_eq!(topology.pairs_14.len(), prmtop.pairs_14.len());
    assert_eq!(topology.exclusions, prmtop.exclusions);
    assert_eq!(topology.residues.len(), prmtop.residues.len());
    assert_eq!(topology.periodic_box, Some([24.0, 24.0, 24.0]));
    for (a, b) in topology.atoms.iter().zip(&prmtop.atoms) {
        assert_eq!((&a.name, &a.element), (&b.name, &b.element));
    }
}

// --- The preprocessor and bad input ----------------------------------------------------

/// A small topology over files in a scratch folder: `main.top` plus `extra` files.
fn write_files(dir: &str, main: &str, extra: &[(&str, &str)]) -> PathBuf {
    let dir = common::scratch_dir(dir);
    for (name, text) in extra {
        std::fs::write(dir.join(name), text).expect("writes");
    }
    let path = dir.join("main.top");
    std::fs::write(&path, main).expect("writes");
    path
}

const HEAD: &str = "[ defaults ]\n1 2 yes 0.5 0.8333\n";

const TYPES: &str = "[ atomtypes ]\n\
    CT 6 12.01 0.0 A 0.34 0.45\n\
    HC 1 1.008 0.0 A 0.26 0.065\n\
    [ bondtypes ]\nCT HC 1 0.109 284512.0\nCT CT 1 0.1526 259408.0\n\
    [ angletypes ]\nHC CT CT 1 110.7 313.8\nHC CT HC 1 107.8 276.144\nCT CT CT 1 109.5 300.0\n\
    [ dihedraltypes ]\nX CT CT X 9 0.0 0.6276 3\nHC CT CT HC 9 0.0 0.5 3\nHC CT CT HC 9 180.0 0.1 1\n";

/// Ethane-like: C1 C2 with hydrogens on each, parameters from the type tables.
const ETHANE: &str = "[ moleculetype ]\nETH 3\n[ atoms ]\n\
    1 CT 1 ETH C1 1 -0.3 12.01\n2 CT 1 ETH C2 2 -0.3 12.01\n\
    3 HC 1 ETH H1 3 0.1\n4 HC 1 ETH H2 4 0.1\n5 HC 1 ETH H3 5 0.1\n\
    6 HC 1 ETH H4 6 0.1\n7 HC 1 ETH H5 7 0.1\n8 HC 1 ETH H6 8 0.1\n\
    [ bonds ]\n1 2 1\n1 3 1\n1 4 1\n1 5 1\n2 6 1\n2 7 1\n2 8 1\n\
    [ angles ]\n3 1 2 1\n4 1 2 1\n5 1 2 1\n6 2 1 1\n7 2 1 1\n8 2 1 1\n3 1 4 1\n";

const TAIL: &str = "[ system ]\nethane\n[ molecules ]\nETH 2\n";

#[test]
fn includes_defines_and_conditionals_are_followed() {
    let main = format!(
        "{HEAD}#include \"types.itp\"\n#define KB 300000.0\n{ETHANE}\
         [ dihedrals ]\n3 1 2 6 9\n#ifdef NOPE\n4 1 2 7 9 0.0 KB 2\n#else\n\
         4 1 2 7 9 0.0 \\\n 4.184 2\n#endif\n#ifndef NOPE\n[ bonds ]\n3 6 1 0.2 KB\n#endif\n{TAIL}"
    );
    let path = write_files("gromacs_pre", &main, &[("types.itp", TYPES)]);
    let t = read_gromacs_top(&path, &[]).expect("reads");
    assert_eq!(t.atoms.len(), 16);
    assert_eq!(t.atoms[2].mass, 1.008, "mass from the type");
    // 7 bonds from bondtypes + the one under #ifndef, ×2 molecules.
    assert_eq!(t.bonds.len(), 16);
    let defined = t.bonds[7];
    assert_eq!(defined.atoms, [2, 5]);
    assert!(
        (defined.k - 300000.0 / 418.4).abs() < 1e-9,
        "KB macro, kJ/nm² → kcal/Å²"
    );
    assert!((defined.r0 - 2.0).abs() < 1e-12);
    let cc = t.bonds[0];
    assert!((cc.r0 - 1.526).abs() < 1e-12 && (cc.k - 259408.0 / 418.4).abs() < 1e-9);
    // H-C-C-H from its own two lines (more specific than X CT CT X); the #else line.
    let first: Vec<_> = t
        .dihedrals
        .iter()
        .filter(|d| d.atoms == [2, 0, 1, 5])
        .collect();
    assert_eq!(first.len(), 2);
    assert!((first[1].k - 0.1 / 4.184).abs() < 1e-12);
    assert!((first[1].phase - std::f64::consts::PI).abs() < 1e-12);
    let continued: Vec<_> = t
        .dihedrals
        .iter()
        .filter(|d| d.atoms == [3, 0, 1, 6])
        .collect();
    assert_eq!(continued.len(), 1);
    assert!((continued[0].k - 1.0).abs() < 1e-12 && continued[0].periodicity == 2.0);
    // nrexcl 3 over the bond graph plus the #ifndef bond: every pair of a molecule.
    assert_eq!(t.exclusions.len(), 2 * 28);
    let t = read_gromacs_top(&path, &["NOPE".into()]).expect("reads");
    let defined: Vec<_> = t
        .dihedrals
        .iter()
        .filter(|d| d.atoms == [3, 0, 1, 6])
        .collect();
    assert!(
        (defined[0].k - 300000.0 / 4.184).abs() < 1e-6,
        "#ifdef branch with -DNOPE"
    );
    assert_eq!(t.bonds.len(), 14);
}

#[test]
fn a_wildcard_dihedral_type_is_used_when_nothing_closer_matches() {
    let types = TYPES.replace(
        "HC CT CT HC 9 0.0 0.5 3\nHC CT CT HC 9 180.0 0.1 1\n",
        "HC CT CT CT 9 0.0 0.5 3\n",
    );
    let main = format!("{HEAD}{types}{ETHANE}[ dihedrals ]\n3 1 2 6 9\n{TAIL}");
    let path = write_files("gromacs_wild", &main, &[]);
    let t = read_gromacs_top(&path, &[]).expect("reads");
    let d = &t.dihedrals[0];
    assert!((d.k - 0.6276 / 4.184).abs() < 1e-12 && d.periodicity == 3.0);
    assert_eq!(t.dihedrals.len(), 2);
}

fn read_error(dir: &str, main: &str) -> (String, PathBuf) {
    let path = write_files(dir, main, &[]);
    let e = read_gromacs_top(&path, &[]).expect_err("refused");
    (e.to_string(), path)
}

#[test]
fn a_missing_include_names_file_and_line() {
    let (e, path) = read_error(
        "gromacs_missing",
        &format!("{HEAD}\n#include \"nowhere.itp\"\n"),
    );
    let at = format!("{}:4", path.display());
    assert!(e.contains(&at) && e.contains("nowhere.itp"), "{e}");
}

#[test]
fn an_unknown_directive_names_file_and_line() {
    let main = format!("{HEAD}{TYPES}{ETHANE}[ cmap ]\n1 2 3 4 5 1\n{TAIL}");
    let (e, path) = read_error("gromacs_unknown", &main);
    let line = main
        .lines()
        .position(|l| l.contains("cmap"))
        .expect("there")
        + 1;
    assert!(e.contains(&format!("{}:{line}", path.display())), "{e}");
    assert!(e.contains("[ cmap ]"), "{e}");
}

#[test]
fn unmodelled_function_types_are_refused_by_line() {
    for (text, what) in [
        (
            "[ dihedrals ]\n1 2 3 4 5 1 2 3 4\n",
            "[ dihedrals ] function 5",
        ),
        (
            "[ dihedrals ]\n1 2 3 4 8 1 1.0\n",
            "[ dihedrals ] function 8",
        ),
        ("[ bonds ]\n1 2 2 0.1 1000.0\n", "[ bonds ] function 2"),
        (
            "[ dihedrals ]\n1 2 3 4 3 1 2 3 4 5\n",
            "function 3: needs 6 parameters",
        ),
    ] {
        let main = format!("{HEAD}{TYPES}{ETHANE}{text}{TAIL}");
        let (e, path) = read_error("gromacs_function", &main);
        let line = main.lines().count() - TAIL.lines().count();
        assert!(e.contains(&format!("{}:{line}", path.display())), "{e}");
        assert!(e.contains(what), "{e}");
    }
}

#[test]
fn urey_bradley_is_an_angle_and_a_1_3_bond() {
    let main = format!("{HEAD}{TYPES}{ETHANE}[ angles ]\n3 1 5 5 108.0 300.0 0.18 20000.0\n{TAIL}");
    let path = write_files("gromacs_ub", &main, &[]);
    let t = read_gromacs_top(&path, &[]).expect("reads");
    let ub = t
        .bonds
        .iter()
        .find(|b| b.atoms == [2, 4])
        .expect("the 1-3 bond");
    assert!((ub.r0 - 1.8).abs() < 1e-12 && (ub.k - 20000.0 / 418.4).abs() < 1e-9);
    assert_eq!(t.angles.len(), 2 * 8);
}

#[test]
fn a_gro_of_another_atom_count_or_names_is_refused() {
    let (topology, _) = load_top("ala2");
    let other = system_path("ala2-solvated.gro");
    let e = read_gro_for(&other, &topology)
        .expect_err("refused")
        .to_string();
    assert!(
        e.contains("ala2-solvated.gro:2") && e.contains("1291 atoms"),
        "{e}"
    );
    let text = std::fs::read_to_string(system_path("ala2.gro")).expect("reads");
    let renamed = text.replacen("    1ACE     H1", "    1ACE     XX", 1);
    let dir = common::scratch_dir("gromacs_gro");
    let path = dir.join("renamed.gro");
    std::fs::write(&path, renamed).expect("writes");
    let e = read_gro_for(&path, &topology)
        .expect_err("refused")
        .to_string();
    assert!(e.contains("renamed.gro:3") && e.contains("XX"), "{e}");
    let (c, _) = parse_gro(&text, Path::new("ala2.gro")).expect("parses");
    assert_eq!(c.box_lengths, None, "a zero box is no box");
}

#[test]
fn check_reads_a_top_and_its_settles_as_rigid_water() {
    let top = system_path("ala2.top");
    let (code, stdout, stderr) = common::run_cli(&["check", top.to_str().expect("path")]);
    assert_eq!(code, 0, "{stderr}");
    assert!(
        stdout.contains("(GROMACS top), 22 atoms") || stderr.contains("(GROMACS top), 22 atoms")
    );
    // Without FLEXIBLE the water is [ settles ]: rigid water by default, as GROMACS.
    let solvated = system_path("ala2-solvated.top");
    let (code, stdout, stderr) = common::run_cli(&["check", solvated.to_str().expect("path")]);
    assert_eq!(code, 0, "{stderr}");
    let said = format!("{stdout}{stderr}");
    assert!(
        said.contains("rigid waters: 423 ([ settles ])")
            && said.contains("+ rigid water (the topology's [ settles ])")
            && said.contains("423 rigid waters by SETTLE: 1269 scalar constraints"),
        "{said}"
    );
    // Asked to run it flexible, it says how.
    let (code, _, stderr) = common::run_cli(&[
        "check",
        solvated.to_str().expect("path"),
        "--rigid-water",
        "false",
    ]);
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("[ settles ]") && stderr.contains("FLEXIBLE"),
        "{stderr}"
    );
    let scene = system_path("ala2-solvated-gromacs.toml");
    let (code, _, stderr) = common::run_cli(&["check", scene.to_str().expect("path")]);
    assert_eq!(code, 0, "{stderr}");
}

/// `--define FLEXIBLE` on the command line (issue 43 item 2) reads the top as a scene's
/// `defines = ["FLEXIBLE"]` does: flexible water, and the potential energy of OpenMM's
/// GromacsTopFile with FLEXIBLE (tests/data/openmm-ala2-solvated-gromacs.json, the same
/// reaction field at 9 Å that a topology with a box gets by default) to the tolerance above;
/// without it the water is rigid. `forces` prints the total it checks here; a define on a
/// prmtop is refused.
#[test]
fn a_define_on_the_command_line_reads_the_water_flexible() {
    let solvated = system_path("ala2-solvated.top");
    let solvated = solvated.to_str().expect("path");
    let flags = longstep::io::scene::SceneFlags {
        defines: vec!["FLEXIBLE".into()],
        ..Default::default()
    };
    let scene = longstep::io::scene::load_scene_with(Path::new(solvated), &flags, &[])
        .expect("the top reads with --define FLEXIBLE");
    let total: f64 = scene.system.potential_energies().iter().sum();
    let expected = json("ala2-solvated-gromacs")["energy"]["total"]
        .as_f64()
        .expect("total");
    let error = (total - expected).abs() / expected.abs();
    eprintln!("--define FLEXIBLE: {total:.9} kcal/mol, OpenMM {expected:.9}, relative {error:.1e}");
    assert!(error <= TOLERANCE, "{total} vs OpenMM {expected}");
    let (code, stdout, stderr) = common::run_cli(&[
        "check",
        solvated,
        "--define",
        "FLEXIBLE",
        "--rigid-water",
        "false",
    ]);
    assert_eq!(code, 0, "{stderr}");
    let said = format!("{stdout}{stderr}");
    assert!(!said.contains("SETTLE"), "{said}");
    let prmtop = system_path("ala2.prmtop");
    let (code, _, stderr) = common::run_cli(&[
        "check",
        prmtop.to_str().expect("path"),
        "--define",
        "FLEXIBLE",
    ]);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("--define"), "{stderr}");
}

/// The solvated top without FLEXIBLE: the peptide's terms, no water bonds or angle, one
/// SETTLE per water at the top's d_OH, d_HH, and the same exclusions as the flexible read
/// (the water's three pairs).
#[test]
fn settles_read_as_rigid_waters_with_their_exclusions() {
    let path = system_path("ala2-solvated.top");
    let rigid = read_gromacs_top(&path, &[]).expect("reads");
    let flexible = read_gromacs_top(&path, &flexible()).expect("reads");
    assert_eq!(rigid.settles.len(), 423);
    assert!(flexible.settles.is_empty());
    assert_eq!((rigid.bonds.len(), rigid.angles.len()), (21, 36));
    assert_eq!(rigid.exclusions, flexible.exclusions);
    let first = rigid.settles[0];
    assert_eq!(first.atoms, [22, 23, 24]);
    assert!((first.oh - 0.9572).abs() < 1e-12 && (first.hh - 1.5139007).abs() < 1e-12);
}

/// A top with one water molecule type whose `[ settles ]` line is `settles`.
fn water_top(settles: &str) -> String {
    format!(
        "{HEAD}[ atomtypes ]\nOW 8 15.999 0.0 A 0.315 0.636\nHW 1 1.008 0.0 A 0.0 0.0\n\
         [ moleculetype ]\nSOL 2\n[ atoms ]\n1 OW 1 SOL OW 1 -0.834\n2 HW 1 SOL HW1 1 0.417\n\
         3 HW 1 SOL HW2 1 0.417\n[ settles ]\n{settles}\n[ system ]\nw\n[ molecules ]\nSOL 2\n"
    )
}

#[test]
fn bad_settles_are_refused_by_file_and_line() {
    let good = read_gromacs_top(
        &write_files(
            "gromacs_settles_good",
            &water_top("1 1 0.09572 0.15139"),
            &[],
        ),
        &[],
    )
    .expect("reads");
    assert_eq!(good.settles.len(), 2);
    assert_eq!(good.settles[1].atoms, [3, 4, 5]);
    for (settles, what) in [
        ("2 1 0.09572 0.15139", "SETTLE needs atoms 2, 3, 4"),
        ("1 1 0.09572", "two distances"),
        ("1 1 0.09572 0.2", "not the sides of a water triangle"),
        ("1 2 0.09572 0.15139", "[ settles ] function 2"),
        (
            "1 1 0.09572 0.15139\n1 1 0.09572 0.15139",
            "a second line in molecule SOL",
        ),
    ] {
        let main = water_top(settles);
        let (e, path) = read_error("gromacs_settles_bad", &main);
        let lines: Vec<&str> = main.lines().collect();
        let last = lines
            .iter()
            .rposition(|l| l.starts_with(settles.lines().last().expect("line")))
            .expect("there")
            + 1;
        assert!(e.contains(&format!("{}:{last}", path.display())), "{e}");
        assert!(e.contains(what), "{settles}: {e}");
    }
    // Atoms that are not O, H, H (ethane's carbons and a hydrogen).
    let main = format!("{HEAD}{TYPES}{ETHANE}[ settles ]\n1 1 0.1 0.16\n{TAIL}");
    let (e, _) = read_error("gromacs_settles_carbon", &main);
    assert!(e.contains("atoms 1-3 are C, C, H"), "{e}");
}

/// Dihedral functions 2 (harmonic improper, one of them more than 180° from its ξ₀, so
/// the difference wraps) and 3 (Ryckaert–Bellemans, one from [ dihedraltypes ], one
/// inline) of a hand-made top against OpenMM's GromacsTopFile (its CustomTorsionForce and
/// RBTorsionForce). Tolerance 1e-6 relative as above: both read the same printed numbers
/// at the same .gro positions in double precision; the cosine-series form of the RB terms
/// differs from the power form by round-off (~1e-15).
#[test]
fn dihedral_functions_2_and_3_match_openmm() {
    let data = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    let topology = read_gromacs_top(&data.join("gromacs-dihedral-types.top"), &[]).expect("reads");
    assert_eq!(topology.harmonic_dihedrals.len(), 2);
    assert!(
        topology
            .notes
            .iter()
            .any(|n| n.starts_with("Ryckaert-Bellemans dihedrals (function 3): 2,")),
        "{:?}",
        topology.notes
    );
    let gro = read_gro_for(&data.join("gromacs-dihedral-types.gro"), &topology).expect("gro");
    let q = gro.positions;
    let built = build(&topology, &q);
    let reference = json("gromacs-dihedral-types");
    let term = |name: &str| {
        built
            .terms
            .iter()
            .find(|(n, _, _)| n == name)
            .map(|(_, t, _)| t.as_ref())
            .expect("term")
    };
    for (group, name) in [
        ("ryckaert_bellemans", "torsions"),
        ("harmonic_dihedrals", "harmonic-impropers"),
    ] {
        let expected = reference["energy"][group].as_f64().expect("energy");
        let got = term(name).energy(&q);
        let error = (got - expected).abs() / expected.abs();
        eprintln!("{group}: {got:.12} kcal/mol, OpenMM {expected:.12}, relative {error:.1e}");
        assert!(error <= TOLERANCE, "{group}: {got} vs OpenMM {expected}");
        let mut gradient = vec![0.0; q.len()];
        term(name).add_gradient(&q, &mut gradient);
        let expected = flat(&reference["forces"][group]);
        let difference = rms(gradient.iter().zip(&expected).map(|(g, f)| -g - f));
        let scale = rms(expected.iter().copied());
        eprintln!(
            "{group} forces: RMS difference / scale {:.1e}",
            difference / scale
        );
        assert!(difference <= TOLERANCE * scale, "{group}: {difference:e}");
    }
    let total: f64 = built.terms.iter().map(|(_, t, _)| t.energy(&q)).sum();
    let expected = reference["energy"]["total"].as_f64().expect("total");
    assert!(
        (total - expected).abs() <= TOLERANCE * expected.abs(),
        "{total} vs {expected}"
    );
}
