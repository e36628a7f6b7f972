//! Scene files: every shipped scene loads, parameters and --set, expressions, generated
//! particles, and structures read through chemfiles.

use std::path::{Path, PathBuf};

use longstep::io::scene::{build_scene, load_scene};

fn shipped_scenes() -> Vec<PathBuf> {
    let mut scenes = Vec::new();
    let mut stack = vec![PathBuf::from("systems")];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "toml") {
                scenes.push(path);
            }
        }
    }
    scenes.sort();
    scenes
}

#[test]
fn every_shipped_scene_loads_with_finite_energy() {
    let scenes = shipped_scenes();
    assert!(scenes.len() >= 7, "{scenes:?}");
    for path in scenes {
        let scene = load_scene(&path, &[]).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let energy = scene.system.total_energy();
        assert!(energy.is_finite(), "{}: energy {energy}", path.display());
        assert!(scene.run.h.is_some(), "{}: no default h", path.display());
        assert!(
            scene.run.t_end.is_some(),
            "{}: no default t_end",
            path.display()
        );
    }
}

#[test]
fn three_spring_scene_is_gss98_section_3() {
    let scene = load_scene(Path::new("systems/three-spring.toml"), &[]).unwrap();
    let system = &scene.system;
    assert_eq!(system.dim, 2);
    assert_eq!(system.state.q, vec![1.0, 0.0, 2.0, 0.0]);
    assert_eq!(system.state.p, vec![0.5, 0.0, -0.5, 0.0]);
    // At rest lengths the potential is zero; E0 is the kinetic energy 2 · 0.5²/2.
    assert_eq!(system.total_energy(), 0.25);
    // Stretching m1 to the right by u changes the energies by Ω1²u²/2 (fast) and u²/4 (slow).
    let mut q = system.state.q.clone();
    q[0] += 0.01;
    let fast = system.forces.energy(0, &q);
    let slow = system.forces.energy(1, &q);
    assert!((fast - 100.0 * 1e-4 / 2.0).abs() < 1e-15);
    assert!((slow - 0.5 * 1e-4 / 2.0).abs() < 1e-15);
}

#[test]
fn set_overrides_a_parameter_and_expressions_follow_it() {
    let scene = load_scene(
        Path::new("systems/three-spring.toml"),
        &["omega1=12.3".into(), "angle=pi/12".into()],
    )
    .unwrap();
    assert_eq!(scene.parameters["omega1"], 12.3);
    let mut q = scene.system.state.q.clone();
    q[0] += 0.01;
    let fast = scene.system.forces.energy(0, &q);
    assert!((fast - 12.3f64.powi(2) * 1e-4 / 2.0).abs() < 1e-14);
    let angle = std::f64::consts::PI / 12.0;
    let p = &scene.system.state.p;
    assert!((p[0] - 0.5 * angle.cos()).abs() < 1e-15);
    assert!((p[1] - 0.5 * angle.sin()).abs() < 1e-15);
}

#[test]
fn fpu_initial_data_are_gni_in_q_p_form() {
    // x1 = (q2 + q1)/√2 = 1, x4 = (q2 − q1)/√2 = 1/ω, y1 = y4 = 1 (ERRATA.md, MEMM18 3.2).
    let scene = load_scene(Path::new("systems/fpu.toml"), &[]).unwrap();
    let (q, p) = (&scene.system.state.q, &scene.system.state.p);
    let s = std::f64::consts::SQRT_2;
    assert!(((q[1] + q[0]) / s - 1.0).abs() < 1e-15);
    assert!(((q[1] - q[0]) / s - 1.0 / 50.0).abs() < 1e-15);
    assert!(((p[1] + p[0]) / s - 1.0).abs() < 1e-15);
    assert!(((p[1] - p[0]) / s - 1.0).abs() < 1e-15);
    assert_eq!(q.len(), 6);
    assert!(q[2..].iter().all(|&x| x == 0.0));
}

#[test]
fn generated_particles_see_their_index() {
    let text = r#"
version = 1
name = "generated"
dim = 1
[parameters]
dx = 0.25
[[particles]]
count = 4
name = "bead{i}"
mass = "1 + i"
position = ["i*dx"]
velocity = ["-i"]
[[terms]]
type = "chain"
stiffness = "10*(i + 1)"
"#;
    let scene = build_scene(text, Path::new("generated.toml"), &[]).unwrap();
    let system = &scene.system;
    assert_eq!(
        system.particles.names,
        vec!["bead0", "bead1", "bead2", "bead3"]
    );
    assert_eq!(system.particles.masses, vec![1.0, 2.0, 3.0, 4.0]);
    assert_eq!(system.state.q, vec![0.0, 0.25, 0.5, 0.75]);
    assert_eq!(system.state.p, vec![0.0, -2.0, -6.0, -12.0]);
    // Rest lengths come from the geometry, so the chain starts unstretched; stretching
    // the last link by u costs (k₂/2)u² with k₂ = 30.
    let mut q = system.state.q.clone();
    assert_eq!(system.forces.energy(0, &q), 0.0);
    q[3] += 0.1;
    assert!((system.forces.energy(0, &q) - 15.0 * 0.01).abs() < 1e-13);
}

#[test]
fn chain_structure_is_read_through_chemfiles() {
    let scene = load_scene(Path::new("systems/chain/scene.toml"), &[]).unwrap();
    let system = &scene.system;
    assert_eq!(system.n_particles(), 100);
    assert_eq!(system.dim, 3);
    assert!(system.particles.names.iter().all(|n| n == "C"));
    // Masses from chemfiles' element table.
    assert!(
        system
            .particles
            .masses
            .iter()
            .all(|&m| (m - 12.011).abs() < 1e-3)
    );
    // Springs at the file's geometry: the backbone starts unstretched.
    assert!(system.forces.energy(0, &system.state.q).abs() < 1e-18);
    let components = system.forces.fast_components(100);
    assert_eq!(components.len(), 1, "one connected backbone");
}
