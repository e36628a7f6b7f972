//! Helpers shared by the integration tests.
#![allow(dead_code)]

/// Seeded test numbers from the `rand` crate (Xoshiro256++), so every run sees the same
/// numbers.
pub struct TestRng(rand::rngs::Xoshiro256PlusPlus);

impl TestRng {
    pub fn new(seed: u64) -> Self {
        use rand::SeedableRng;
        TestRng(rand::rngs::Xoshiro256PlusPlus::seed_from_u64(seed))
    }

    pub fn next_u64(&mut self) -> u64 {
        use rand::Rng;
        self.0.next_u64()
    }

    /// Uniform in [lo, hi).
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        use rand::RngExt;
        lo + (hi - lo) * self.0.random::<f64>()
    }

    pub fn vector(&mut self, n: usize, lo: f64, hi: f64) -> Vec<f64> {
        (0..n).map(|_| self.uniform(lo, hi)).collect()
    }

    /// A standard normal deviate (Box–Muller).
    pub fn normal(&mut self) -> f64 {
        let u = self.uniform(f64::MIN_POSITIVE, 1.0);
        let v = self.uniform(0.0, 1.0);
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

/// A block-average estimate of `mean` and `error` (over 10 blocks).
pub fn estimate(mean: f64, error: f64) -> longstep::analysis::block_average::Estimate {
    longstep::analysis::block_average::Estimate {
        mean,
        error,
        blocks: 10,
    }
}

pub fn max_abs(x: &[f64]) -> f64 {
    x.iter().fold(0.0, |m, v| m.max(v.abs()))
}

pub fn max_abs_difference(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).fold(0.0, |m, (x, y)| m.max((x - y).abs()))
}

/// Path of the built `longstep` binary; `LONGSTEP_BIN` runs the command-line tests against
/// another build (for example an older one, to see a new test fail before its fix).
pub fn longstep() -> std::process::Command {
    let binary =
        std::env::var_os("LONGSTEP_BIN").unwrap_or_else(|| env!("CARGO_BIN_EXE_longstep").into());
    std::process::Command::new(binary)
}

/// Run `longstep` with `args`: its exit code (-1 when killed), stdout and stderr.
pub fn run_cli(args: &[&str]) -> (i32, String, String) {
    run_cli_threads(args, None)
}

/// [`run_cli`] with `threads` rayon threads (`RAYON_NUM_THREADS`) when given.
pub fn run_cli_threads(args: &[&str], threads: Option<usize>) -> (i32, String, String) {
    let mut command = longstep();
    command.args(args);
    if let Some(n) = threads {
        command.env("RAYON_NUM_THREADS", n.to_string());
    }
    let output = command.output().expect("longstep runs");
    (
        output.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&output.stdout).into_owned(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

/// The words of `line` split at white space: an argument list written on one line. For
/// flags, values and the repository's own paths; a path that may hold a space is given as an
/// argument of its own.
pub fn words(line: &str) -> Vec<&str> {
    line.split_whitespace().collect()
}

/// [`words`] of `line` with each word `{}` replaced by the next of `values`, whole (paths
/// and other computed arguments).
pub fn argv<'a>(line: &'a str, values: &[&'a str]) -> Vec<&'a str> {
    let mut values = values.iter();
    let args = words(line)
        .into_iter()
        .map(|word| match word {
            "{}" => *values.next().expect("a value for each {}"),
            word => word,
        })
        .collect();
    assert!(values.next().is_none(), "a {{}} for each value");
    args
}

/// [`argv`] as owned strings (for argument lists that grow).
pub fn argv_owned(line: &str, values: &[&str]) -> Vec<String> {
    argv(line, values).into_iter().map(String::from).collect()
}

/// The header and rows of a study table (after its first line), split at commas.
pub fn study_table(file: &std::path::Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(file).unwrap();
    let mut lines = text.lines().skip(1);
    let split = |l: &str| l.split(',').map(String::from).collect::<Vec<_>>();
    let header = split(lines.next().unwrap());
    (header, lines.map(split).collect())
}

/// The rows of a study table (after its first line and header), split at commas.
pub fn study_rows(file: &std::path::Path) -> Vec<Vec<String>> {
    std::fs::read_to_string(file)
        .unwrap()
        .lines()
        .skip(2)
        .map(|l| l.split(',').map(String::from).collect())
        .collect()
}

/// A fresh empty directory under the target dir for a test's outputs.
pub fn scratch_dir(name: &str) -> std::path::PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch directory");
    dir
}

use longstep::integrators::{self, Integrator};
use longstep::io::scene::{Scene, build_scene};
use longstep::settings::MethodSettings;

/// A scene from TOML text.
pub fn scene(text: &str) -> Scene {
    build_scene(text, std::path::Path::new("test-scene.toml"), &[])
        .unwrap_or_else(|e| panic!("test scene: {e}"))
}

/// A scene from a file with `--set` overrides.
pub fn scene_file(path: &str, set: &[&str]) -> Scene {
    let set: Vec<String> = set.iter().map(|s| s.to_string()).collect();
    longstep::io::scene::load_scene(std::path::Path::new(path), &set)
        .unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// An integrator for `method` with outer step `h` and `inner` inner steps.
pub fn method(name: &str, h: f64, inner: Option<usize>) -> Box<dyn Integrator> {
    let mut settings = MethodSettings::new(name, h);
    settings.inner_steps = inner;
    let mut notices = Vec::new();
    integrators::build(&settings, &mut notices).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// Set up `integrator` on `scene` and take `steps` steps; returns the final (q, p).
pub fn integrate(
    scene: &mut Scene,
    integrator: &mut dyn Integrator,
    steps: usize,
) -> (Vec<f64>, Vec<f64>) {
    integrator.setup(&mut scene.system).unwrap();
    for _ in 0..steps {
        integrator.step(&mut scene.system).unwrap();
    }
    (scene.system.state.q.clone(), scene.system.state.p.clone())
}

/// The three-spring system (GSS98 section 3): two particles on stiff springs to walls in
/// group `stiff_group` (rest length 1, so each is held on a circle), with the middle spring
/// given as `middle` (TOML, empty for none).
pub fn three_spring(middle: &str, stiff_group: &str) -> String {
    let stiff = include_str!("../data/three-spring-stiff.toml");
    format!("{stiff}group = \"{stiff_group}\"\n{middle}\n")
}

/// The three-spring system's slow middle spring, for [`three_spring`].
pub const SLOW_MIDDLE: &str = include_str!("../data/three-spring-slow-middle.toml");

/// `max |Jᵀ Ω J − Ω|` of the one-step map of the integrator `make` builds on the scene `text`,
/// and `max |J|`; J by fourth-order central differences,
/// `(f(−2ε) − 8f(−ε) + 8f(ε) − f(2ε)) / 12ε`: truncation ε⁴|f⁽⁵⁾|/30, round-off ≈ 1.5u|f|/ε.
pub fn symplecticity_defect(text: &str, make: &dyn Fn() -> Box<dyn Integrator>) -> (f64, f64) {
    let base = scene(text);
    let z0: Vec<f64> = base
        .system
        .state
        .q
        .iter()
        .chain(&base.system.state.p)
        .copied()
        .collect();
    let n = z0.len();
    let step = |z: &[f64]| -> Vec<f64> {
        let mut s = scene(text);
        s.system.state.q.copy_from_slice(&z[..n / 2]);
        s.system.state.p.copy_from_slice(&z[n / 2..]);
        let (q, p) = integrate(&mut s, make().as_mut(), 1);
        q.into_iter().chain(p).collect()
    };
    let epsilon = 1e-3;
    let mut jacobian = nalgebra::DMatrix::zeros(n, n);
    for j in 0..n {
        let shifted = |s: f64| {
            let mut z = z0.clone();
            z[j] += s * epsilon;
            step(&z)
        };
        let (m2, m1, p1, p2) = (shifted(-2.0), shifted(-1.0), shifted(1.0), shifted(2.0));
        for i in 0..n {
            jacobian[(i, j)] = (m2[i] - 8.0 * m1[i] + 8.0 * p1[i] - p2[i]) / (12.0 * epsilon);
        }
    }
    let half = n / 2;
    let mut omega = nalgebra::DMatrix::zeros(n, n);
    for i in 0..half {
        omega[(i, half + i)] = 1.0;
        omega[(half + i, i)] = -1.0;
    }
    let defect = (jacobian.transpose() * &omega * &jacobian - &omega).amax();
    (defect, jacobian.amax())
}

/// The methods of the impulse family, with their names.
pub const MTS_METHODS: [&str; 5] = [
    "impulse",
    "impulse-midpoint",
    "short-average",
    "long-average",
    "linear-average",
];

/// Central-difference gradient of `term`'s energy with step `epsilon`.
pub fn finite_difference_gradient(
    term: &dyn longstep::forces::ForceTerm,
    q: &[f64],
    epsilon: f64,
) -> Vec<f64> {
    let mut x = q.to_vec();
    (0..q.len())
        .map(|k| {
            x[k] = q[k] + epsilon;
            let plus = term.energy(&x);
            x[k] = q[k] - epsilon;
            let minus = term.energy(&x);
            x[k] = q[k];
            (plus - minus) / (2.0 * epsilon)
        })
        .collect()
}

/// Central-difference Hessian-vector product (of `term`'s gradient along `v`).
pub fn finite_difference_hessian_vector(
    term: &dyn longstep::forces::ForceTerm,
    q: &[f64],
    v: &[f64],
    epsilon: f64,
) -> Vec<f64> {
    let shifted = |sign: f64| -> Vec<f64> {
        let x: Vec<f64> = q
            .iter()
            .zip(v)
            .map(|(a, b)| a + sign * epsilon * b)
            .collect();
        let mut g = vec![0.0; q.len()];
        term.add_gradient(&x, &mut g);
        g
    };
    let (plus, minus) = (shifted(1.0), shifted(-1.0));
    plus.iter()
        .zip(&minus)
        .map(|(p, m)| (p - m) / (2.0 * epsilon))
        .collect()
}

/// A finite-difference check of a term's derivatives: central differences with step
/// `epsilon`, each result within `tolerance · max(1, |exact|)` (the bound is derived where the
/// check is used), and the exact gradient's and Hessian-vector products' largest entries above
/// `floor`, so that the check is not empty.
pub struct FdCheck {
    pub epsilon: f64,
    pub tolerance: f64,
    pub floor: f64,
}

impl FdCheck {
    /// Checks `term`'s gradient at `q`, then its Hessian-vector product along three random
    /// directions from `rng`.
    pub fn check(
        &self,
        term: &dyn longstep::forces::ForceTerm,
        q: &[f64],
        rng: &mut TestRng,
        label: &str,
    ) {
        let mut gradient = vec![0.0; q.len()];
        term.add_gradient(q, &mut gradient);
        let fd = finite_difference_gradient(term, q, self.epsilon);
        self.compare(&gradient, &fd, &format!("{label}: gradient"));
        for _ in 0..3 {
            let v = rng.vector(q.len(), -1.0, 1.0);
            let mut hv = vec![0.0; q.len()];
            term.add_hessian_vector(q, &v, &mut hv);
            let fd = finite_difference_hessian_vector(term, q, &v, self.epsilon);
            self.compare(&hv, &fd, &format!("{label}: Hessian-vector product"));
        }
    }

    fn compare(&self, exact: &[f64], fd: &[f64], what: &str) {
        let error = max_abs_difference(exact, fd);
        let scale = max_abs(exact).max(1.0);
        assert!(
            error <= self.tolerance * scale,
            "{what} differs from finite differences by {error:e} (scale {scale:e})"
        );
        assert!(
            max_abs(exact) > self.floor,
            "{what} is zero, the check is empty"
        );
    }
}

/// `scan stiffness` on the two-spring system where Verlet blows up: h = 0.5, ω1 over
/// [0, 4π] in 7 points, t = 60. Verlet is unstable once ω1 h > 2 (ω1 > 4); its error
/// reaches 1e34–1e140 and overflows from ω1 = 10π/3 on, while impulse stays bounded.
/// Writes `scan.csv` and `err.svg` into `dir` and returns their paths.
pub fn verlet_blowup_stiffness_scan(
    dir: &std::path::Path,
) -> (std::path::PathBuf, std::path::PathBuf) {
    let (csv, svg) = (dir.join("scan.csv"), dir.join("err.svg"));
    let output = longstep()
        .args([
            "scan",
            "stiffness",
            "systems/two-spring.toml",
            "--methods",
            "verlet,impulse",
        ])
        .args([
            "--param", "omega1", "--range", "0:4*pi", "--n", "7", "--h", "0.5",
        ])
        .args(["--t-end", "60", "--quiet", "--out", csv.to_str().unwrap()])
        .args(["--svg", svg.to_str().unwrap()])
        .output()
        .expect("longstep runs");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    (csv, svg)
}

// The OpenMM force-field comparisons of the topology tests (prmtop and GROMACS top).

pub fn flat(forces: &serde_json::Value) -> Vec<f64> {
    forces
        .as_array()
        .expect("forces")
        .iter()
        .flat_map(|row| {
            row.as_array()
                .expect("row")
                .iter()
                .map(|x| x.as_f64().expect("number"))
        })
        .collect()
}

/// OpenMM's energy groups in the reference files, as [`group_energy`] names them.
pub const OPENMM_GROUPS: [&str; 7] = [
    "bonds",
    "angles",
    "torsions",
    "lj",
    "coulomb",
    "lj_14",
    "coulomb_14",
];

/// The OpenMM reference `tests/data/openmm-{name}.json`.
pub fn openmm_json(name: &str) -> serde_json::Value {
    let path = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join(format!("tests/data/openmm-{name}.json"));
    let text = std::fs::read_to_string(&path).expect("reference JSON");
    serde_json::from_str(&text).expect("valid JSON")
}

/// longstep's energy per OpenMM group.
pub fn group_energy(built: &longstep::io::topology::BuiltTopology, q: &[f64], group: &str) -> f64 {
    let term = |name: &str| -> Option<&dyn longstep::forces::ForceTerm> {
        built
            .terms
            .iter()
            .find(|(n, _, _)| n == name)
            .map(|(_, t, _)| t.as_ref())
    };
    let energy = |name: &str| term(name).map_or(0.0, |t| t.energy(q));
    let component = |part: &str| -> f64 {
        term("nonbonded")
            .expect("a nonbonded term")
            .energy_components(q)
            .iter()
            .find(|(n, _)| *n == part)
            .map(|(_, e)| *e)
            .expect("component")
    };
    match group {
        "bonds" => energy("bonds"),
        "angles" => energy("angles"),
        "torsions" => energy("torsions") + energy("impropers"),
        "lj" => component("lennard-jones"),
        // With PME, the mesh term carries the reciprocal sum, the excluded-pair
        // correction and the self energy, all in OpenMM's Coulomb group.
        "coulomb" => component("coulomb") + energy("pme-reciprocal"),
        "lj_14" => energy("lj-14"),
        "coulomb_14" => energy("coulomb-14"),
        other => panic!("unknown group {other}"),
    }
}

pub fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (sum, count) = v.fold((0.0, 0), |(s, c), x| (s + x * x, c + 1));
    (sum / count as f64).sqrt()
}

/// The bonded, non-bonded and total forces (−gradients) of `built` at `q` against a
/// reference's (`expected(part)`, flat `n × 3`, for "bonded", "nonbonded" and "total"):
/// each RMS difference within `tolerance` of that part's RMS force, the total's within
/// `tolerance` of the non-bonded RMS (the bonded and non-bonded forces nearly cancel at a
/// minimum, so the total's own RMS is no scale).
pub fn assert_forces_match(
    label: &str,
    built: &longstep::io::topology::BuiltTopology,
    q: &[f64],
    expected: &dyn Fn(&str) -> Vec<f64>,
    tolerance: f64,
) {
    use longstep::forces::TermClass;
    let mut by_class = [vec![0.0; q.len()], vec![0.0; q.len()]];
    for (_, term, _) in &built.terms {
        let class = usize::from(term.class() == TermClass::Nonbonded);
        term.add_gradient(q, &mut by_class[class]);
    }
    let total: Vec<f64> = by_class[0]
        .iter()
        .zip(&by_class[1])
        .map(|(a, b)| a + b)
        .collect();
    let nonbonded_scale = rms(expected("nonbonded").into_iter());
    for (part, gradient) in [
        ("bonded", &by_class[0]),
        ("nonbonded", &by_class[1]),
        ("total", &total),
    ] {
        let reference = expected(part);
        assert_eq!(gradient.len(), reference.len());
        let difference = rms(gradient.iter().zip(&reference).map(|(g, f)| -g - f));
        let scale = if part == "total" {
            nonbonded_scale
        } else {
            rms(reference.iter().copied())
        };
        eprintln!(
            "{label} {part} forces: RMS difference / scale {:.1e}",
            difference / scale
        );
        assert!(
            difference <= tolerance * scale,
            "{label} {part} forces: RMS difference {difference:e} against {scale:e} kcal/mol/Å"
        );
    }
}
pub mod svg;

/// Gradient, Hessian-vector product (along `v`) and energy of `term` at `q` as bits, computed
/// on a rayon pool of `threads` threads: equal results at every count are the same bits.
pub fn term_bits(
    term: &dyn longstep::forces::ForceTerm,
    q: &[f64],
    v: &[f64],
    threads: usize,
) -> (Vec<u64>, Vec<u64>, u64) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("pool");
    pool.install(|| {
        let mut g = vec![0.0; q.len()];
        term.add_gradient(q, &mut g);
        let mut hv = vec![0.0; q.len()];
        term.add_hessian_vector(q, v, &mut hv);
        let bits = |x: &[f64]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        (bits(&g), bits(&hv), term.energy(q).to_bits())
    })
}

/// A water-box run (`systems/water-box/scene.toml`, impulse at 2 fs with 4 inner steps) of
/// `t_end` into `out`, with an energy row and a trajectory frame every step: the input that
/// `analyze --blocks 2` takes at 20 fs.
pub fn water_run(out: &std::path::Path, t_end: &str) {
    let (code, _, stderr) = run_cli(&[
        "run",
        "systems/water-box/scene.toml",
        "--method",
        "impulse",
        "--h",
        "2fs",
        "--inner",
        "4",
        "--t-end",
        t_end,
        "--energy-every",
        "1",
        "--trajectory-every",
        "1",
        "--quiet",
        "--out",
        out.to_str().expect("path"),
    ]);
    assert_eq!(code, 0, "{stderr}");
}
