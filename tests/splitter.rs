//! The splitter: default and explicit levels, the level table, particle classes,
//! fast components and evaluation counts.

use std::path::Path;

use longstep::io::scene::{build_scene, load_scene};
use longstep::split::ParticleClass;

fn scene(terms: &str) -> longstep::io::scene::Scene {
    let text = format!(
        r#"
version = 1
name = "split"
dim = 2
[[particles]]
count = 5
mass = 1.0
position = ["1.5*i", "0.1*i^2"]
{terms}
"#
    );
    build_scene(&text, Path::new("split.toml"), &[]).unwrap()
}

#[test]
fn bonded_terms_are_fast_and_nonbonded_slow_by_default() {
    let scene = scene(
        r#"
[[terms]]
type = "chain"
name = "backbone"
stiffness = 100.0
[[terms]]
type = "angle"
name = "bend"
triples = [[0, 1, 2]]
stiffness = 10.0
[[terms]]
type = "lennard-jones"
name = "vdw"
epsilon = 0.1
sigma = 1.0
cutoff = 3.0
"#,
    );
    let forces = &scene.system.forces;
    assert_eq!(forces.n_levels(), 2);
    let levels: Vec<(String, usize)> = forces
        .terms()
        .iter()
        .map(|t| (t.name.clone(), t.level))
        .collect();
    assert_eq!(
        levels,
        vec![
            ("backbone".into(), 0),
            ("bend".into(), 0),
            ("vdw".into(), 1)
        ]
    );
    let table = forces.level_table();
    assert!(
        table
            .starts_with("levels: 0 (fast) = spring \"backbone\" (4 interactions), angle \"bend\""),
        "{table}"
    );
    assert!(
        table.contains("| 1 (slow) = lennard-jones \"vdw\""),
        "{table}"
    );
}

#[test]
fn groups_and_levels_override_the_default() {
    let scene = scene(
        r#"
[[terms]]
type = "spring"
name = "soft"
between = [0, 1]
stiffness = 1.0
group = "slow"
[[terms]]
type = "lennard-jones"
name = "close"
epsilon = 0.1
sigma = 1.0
group = "fast"
[[terms]]
type = "spring"
name = "middle"
between = [1, 2]
stiffness = 5.0
level = 1
[[terms]]
type = "spring"
name = "outer"
between = [3, 4]
stiffness = 0.1
level = 2
"#,
    );
    let forces = &scene.system.forces;
    assert_eq!(forces.n_levels(), 3);
    let level_of = |name: &str| {
        forces
            .terms()
            .iter()
            .find(|t| t.name == name)
            .unwrap()
            .level
    };
    assert_eq!(level_of("soft"), 2, "slow is the outermost level");
    assert_eq!(level_of("close"), 0);
    assert_eq!(level_of("middle"), 1);
    assert_eq!(level_of("outer"), 2);
    assert!(
        forces
            .level_table()
            .contains("1 (level 1) = spring \"middle\"")
    );
}

#[test]
fn particle_classes_of_the_slow_fast_fpu_chain() {
    // MEMM18 4.3.1 with m = 3: particles 1..m-1 fast, m mixed, m+1..2m slow.
    let scene = load_scene(Path::new("systems/fpu-slow-fast.toml"), &[]).unwrap();
    let classes = scene.system.forces.classify_particles(6);
    use ParticleClass::*;
    assert_eq!(classes, vec![Fast, Fast, Mixed, Slow, Slow, Slow]);
}

#[test]
fn fast_components_follow_the_fast_bonds() {
    let scene = scene(
        r#"
[[terms]]
type = "spring"
name = "a"
pairs = [[0, 1], [3, 4]]
stiffness = 10.0
[[terms]]
type = "spring"
name = "soft"
between = [1, 3]
stiffness = 1.0
group = "slow"
"#,
    );
    let components = scene.system.forces.fast_components(5);
    assert_eq!(components, vec![vec![0, 1], vec![2], vec![3, 4]]);
}

#[test]
fn evaluations_are_counted_per_level() {
    let mut scene = scene(
        r#"
[[terms]]
type = "chain"
name = "backbone"
stiffness = 100.0
[[terms]]
type = "lennard-jones"
name = "vdw"
epsilon = 0.1
sigma = 1.0
"#,
    );
    let system = &mut scene.system;
    let q = system.state.q.clone();
    let mut gradient = vec![0.0; q.len()];
    system.forces.gradient(0, &q, &mut gradient);
    system.forces.gradient(0, &q, &mut gradient);
    system.forces.total_gradient(&q, &mut gradient);
    let v = vec![1.0; q.len()];
    let mut out = vec![0.0; q.len()];
    system.forces.hessian_vector(0, &q, &v, &mut out);
    let counts = system.forces.counts();
    assert_eq!(counts.gradient, vec![3, 1]);
    assert_eq!(counts.hessian_vector, vec![1, 0]);
    // 4 springs × 4 evaluations + 10 pairs × 1.
    assert_eq!(counts.interactions, 4 * 4 + 10);
}
