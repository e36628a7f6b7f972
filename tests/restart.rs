//! Checkpoint and restart (issue 30 item 7): a run continued from a checkpoint writes the
//! same energy.csv rows, as text, as the uninterrupted run from the checkpoint's time on,
//! at 1 and 2 threads; bad checkpoints are refused with the file named and nothing written.
//!
//! The comparison is exact (byte for byte): the continued run restores the positions,
//! momenta, time, step count, the method's hidden state (random-number generator,
//! thermostat variables, staggered momenta, a structural block) and every pair list as
//! the writing run had it, and recomputes its cached forces at the same positions over the
//! same lists, so no tolerance is needed and none is allowed. Writing a checkpoint changes
//! nothing: a run with checkpoints writes the same energy.csv as one without (except where
//! a term keeps lists it cannot save, which the checkpoint says: `rebuilt_lists`).

mod common;
use common::{argv, longstep, scratch_dir, words};

use std::path::{Path, PathBuf};

/// Run longstep with `args` on `threads` rayon threads: exit code and stderr.
fn run(args: &[&str], threads: usize) -> (i32, String) {
    let output = longstep()
        .args(args)
        .env("RAYON_NUM_THREADS", threads.to_string())
        .output()
        .expect("longstep runs");
    (
        output.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

fn run_ok(args: &[&str], threads: usize) {
    let (code, stderr) = run(args, threads);
    assert_eq!(code, 0, "longstep {args:?} failed:\n{stderr}");
}

fn run_strings(args: &[String], threads: usize) {
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    run_ok(&args, threads);
}

fn lines(path: &Path) -> Vec<String> {
    std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .lines()
        .map(str::to_string)
        .collect()
}

/// A scene with its run arguments, and the whole run's end and the checkpoint's time.
struct Case<'a> {
    name: &'a str,
    scene: &'a str,
    args: &'a [&'a str],
    t_end: &'a str,
    half: &'a str,
}

/// The uninterrupted run (with the checkpoint taken at `half`), the run to `half`, and the
/// run continued from its checkpoint to `t_end`: the continued run's energy.csv must be
/// the uninterrupted run's from the checkpoint's row on, byte for byte. And the
/// uninterrupted run without checkpoints: its energy.csv must be the one with them, byte
/// for byte, unless the checkpoint says it rebuilt pair lists. Returns that flag.
fn continued_rows_match(case: &Case, threads: usize) -> bool {
    let dir = scratch_dir(&format!("restart-{}-{threads}", case.name));
    let out = |name: &str| -> PathBuf { dir.join(name) };
    let whole = out("whole");
    let first = out("first");
    let second = out("second");
    let checkpoint = first.join("checkpoint.json");
    let common = |t_end: &str, out: &Path| -> Vec<String> {
        let mut args: Vec<String> = vec!["run".into(), case.scene.into()];
        args.extend(case.args.iter().map(|s| s.to_string()));
        args.extend(
            [
                "--t-end",
                t_end,
                "--checkpoint-every",
                case.half,
                "--energy-every",
                "1",
                "--quiet",
                "--out",
            ]
            .map(String::from),
        );
        args.push(out.display().to_string());
        args
    };
    let whole_args = common(case.t_end, &whole);
    run_strings(&whole_args, threads);
    let plain = out("plain");
    let mut plain_args = common(case.t_end, &plain);
    let every = plain_args
        .iter()
        .position(|a| a == "--checkpoint-every")
        .unwrap();
    plain_args.drain(every..every + 2);
    run_strings(&plain_args, threads);
    let first_args = common(case.half, &first);
    run_strings(&first_args, threads);
    assert!(checkpoint.is_file(), "{}: no checkpoint written", case.name);
    let mut second_args = common(case.t_end, &second);
    second_args.push("--restart".into());
    second_args.push(checkpoint.display().to_string());
    run_strings(&second_args, threads);

    let whole_rows = lines(&whole.join("energy.csv"));
    let first_rows = lines(&first.join("energy.csv"));
    let second_rows = lines(&second.join("energy.csv"));
    assert_eq!(
        second_rows[0], whole_rows[0],
        "{}: headers differ",
        case.name
    );
    // The first run is the whole run's beginning (it took its checkpoint at the same step).
    assert_eq!(
        &whole_rows[..first_rows.len()],
        &first_rows[..],
        "{}: the first run is not the whole run's beginning",
        case.name
    );
    // With a row every step, the checkpoint's step is its row (after the header).
    let saved: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&checkpoint).unwrap()).unwrap();
    let at = saved["step"].as_u64().unwrap() as usize + 1;
    let rebuilt = saved["rebuilt_lists"]
        .as_bool()
        .expect("the checkpoint says whether it rebuilt lists");
    if !rebuilt {
        assert!(
            std::fs::read(whole.join("energy.csv")).unwrap()
                == std::fs::read(plain.join("energy.csv")).unwrap(),
            "{} at {threads} threads: energy.csv with checkpoints differs from the one without",
            case.name
        );
    }
    assert!(
        second_rows.len() > 2,
        "{}: the continued run took no steps",
        case.name
    );
    assert_eq!(
        second_rows.len() - 1 + at,
        whole_rows.len(),
        "{}: row counts differ",
        case.name
    );
    for (k, (continued, uninterrupted)) in
        second_rows[1..].iter().zip(&whole_rows[at..]).enumerate()
    {
        assert_eq!(
            continued, uninterrupted,
            "{} at {threads} threads: row {k} from the checkpoint on differs",
            case.name
        );
    }
    rebuilt
}

fn both_thread_counts(case: Case) {
    for threads in [1, 2] {
        continued_rows_match(&case, threads);
    }
}

/// As [`both_thread_counts`], for a model whose every list-keeping term saves its lists:
/// the checkpoint must say it rebuilt none (so the run without checkpoints was compared).
fn both_thread_counts_nothing_rebuilt(case: Case) {
    for threads in [1, 2] {
        let rebuilt = continued_rows_match(&case, threads);
        assert!(!rebuilt, "{}: the checkpoint rebuilt pair lists", case.name);
    }
}

#[test]
fn verlet_continues_bit_for_bit() {
    both_thread_counts(Case {
        name: "verlet",
        scene: "systems/chain/scene.toml",
        args: &["--method", "verlet", "--h", "0.01"],
        t_end: "0.6",
        half: "0.3",
    });
}

#[test]
fn impulse_continues_bit_for_bit() {
    both_thread_counts(Case {
        name: "impulse",
        scene: "systems/chain/scene.toml",
        args: &["--method", "impulse", "--h", "0.04", "--inner", "4"],
        t_end: "1.2",
        half: "0.6",
    });
}

/// BAOAB inner steps: the generator's state must come back, else the noise differs.
#[test]
fn langevin_respa_continues_bit_for_bit() {
    both_thread_counts(Case {
        name: "langevin-respa",
        scene: "systems/chain/scene.toml",
        args: &words(
            "--method langevin-respa --h 0.04 --inner 4 --temperature 0.5 --friction 1 \
             --seed 7",
        ),
        t_end: "1.2",
        half: "0.6",
    });
}

/// SIN(R): the generator and the thermostat variables v1, v2.
#[test]
fn sinr_continues_bit_for_bit() {
    both_thread_counts(Case {
        name: "sinr",
        scene: "systems/chain/scene.toml",
        args: &words("--method sinr --h 0.04 --inner 4 --temperature 0.5 --tau 0.5 --seed 11"),
        t_end: "1.2",
        half: "0.6",
    });
}

/// MEMM18 (6): the staggered momenta p^{n∓½}.
#[test]
fn pseudo_energy_continues_bit_for_bit() {
    both_thread_counts(Case {
        name: "pseudo-energy",
        scene: "systems/chain/scene.toml",
        args: &["--method", "pseudo-energy", "--h", "0.01"],
        t_end: "0.4",
        half: "0.2",
    });
}

/// Adaptive Verlet: ρ_{n−½} and a time that is not a multiple of a step.
#[test]
fn adaptive_verlet_continues_bit_for_bit() {
    both_thread_counts(Case {
        name: "adaptive-verlet",
        scene: "systems/kepler.toml",
        args: &["--method", "adaptive-verlet", "--h", "0.05"],
        t_end: "4",
        half: "2",
    });
}

/// Constrained bonds (RATTLE) with Langevin inner steps on a topology.
#[test]
fn constrained_topology_continues_bit_for_bit() {
    both_thread_counts(Case {
        name: "ala2-constrained",
        scene: "systems/alanine-dipeptide-amber/ala2.toml",
        args: &words(
            "--method langevin-respa --h 2fs --inner 2 --constraints h-bonds \
             --temperature 300K",
        ),
        t_end: "80fs",
        half: "40fs",
    });
}

/// A periodic water box with cluster pair lists: the checkpoint saves where they were
/// built and pruned, so the continued run sums over the same lists, and the run that wrote
/// it goes on as if it had not.
#[test]
fn water_box_with_pair_lists_continues_bit_for_bit() {
    both_thread_counts_nothing_rebuilt(Case {
        name: "water-box",
        scene: "systems/water-box/scene.toml",
        args: &["--method", "impulse", "--h", "4fs", "--inner", "4"],
        t_end: "200fs",
        half: "100fs",
    });
}

/// Langevin r-RESPA on the solvated dipeptide (prmtop) with PME: the real-space term's
/// cluster lists are saved; the reciprocal sum keeps no lists.
#[test]
fn langevin_respa_on_pme_dipeptide_continues_bit_for_bit() {
    both_thread_counts_nothing_rebuilt(Case {
        name: "ala2-pme-langevin-respa",
        scene: "systems/alanine-dipeptide-amber/ala2-solvated-pme.toml",
        args: &words("--method langevin-respa --h 2fs --inner 4 --temperature 300K --seed 3"),
        t_end: "40fs",
        half: "20fs",
    });
}

/// Three levels with the non-bonded term split by distance: the short part's lists are the
/// distance split's own. Ignored until the distance-split terms save their lists
/// (`ForceTerm::list_state`): until then the checkpoint rebuilds them
/// (`"rebuilt_lists": true`), and a rebuilt distance-split term does not give the bits of a
/// freshly built one, so the writing run and the continued run part in the last bits from
/// the checkpoint's row on (the same with the rebuild-every-checkpoint scheme this replaced;
/// the continued run here matches the run without checkpoints). Once they save them,
/// [`continued_rows_match`] also compares the run without checkpoints.
#[test]
fn three_level_distance_split_continues_bit_for_bit() {
    both_thread_counts(Case {
        name: "three-level",
        scene: "systems/water-box/three-level.toml",
        args: &["--method", "impulse", "--h", "2fs", "--level-steps", "2,2"],
        t_end: "40fs",
        half: "20fs",
    });
}

/// ZD, block of four: checkpoints at steps 3, 6 and 9 fall inside blocks, so the solved
/// nodes still to hand out and the block's start are part of the state.
#[test]
fn structural_zd_continues_bit_for_bit() {
    both_thread_counts_nothing_rebuilt(Case {
        name: "structural-zd",
        scene: "systems/chain/scene.toml",
        args: &["--method", "structural-zd", "--h", "0.01"],
        t_end: "0.1",
        half: "0.03",
    });
}

/// ZDS, block of two, with second derivatives: checkpoints at odd steps, inside blocks.
#[test]
fn structural_zds_continues_bit_for_bit() {
    both_thread_counts_nothing_rebuilt(Case {
        name: "structural-zds",
        scene: "systems/chain/scene.toml",
        args: &["--method", "structural-zds", "--h", "0.01"],
        t_end: "0.1",
        half: "0.03",
    });
}

/// ZD on the water box: a checkpoint inside a block (step 3 of 4) with cluster pair lists,
/// so the block's nodes must come back without solving it again over other lists.
#[test]
fn structural_zd_on_the_water_box_continues_bit_for_bit() {
    both_thread_counts_nothing_rebuilt(Case {
        name: "structural-zd-water",
        scene: "systems/water-box/scene.toml",
        args: &["--method", "structural-zd", "--h", "0.5fs"],
        t_end: "5fs",
        half: "1.5fs",
    });
}

/// Equilibrium MOLLY on the water box (cluster lists, the slow force at `A(q)`): the
/// projection is a function of `q`, recomputed by the continued run's setup.
#[test]
fn equilibrium_molly_continues_bit_for_bit() {
    both_thread_counts_nothing_rebuilt(Case {
        name: "equilibrium-molly",
        scene: "systems/water-box/scene.toml",
        args: &words("--method equilibrium-molly --h 2fs --inner 4"),
        t_end: "40fs",
        half: "20fs",
    });
}

/// A checkpoint of the chain under verlet, to spoil in the refusal tests.
fn chain_checkpoint(dir: &Path) -> PathBuf {
    let out = dir.join("origin");
    let out_text = out.display().to_string();
    run_ok(
        &argv(
            "run systems/chain/scene.toml --method verlet --h 0.01 --t-end 0.1 \
             --checkpoint-every 0.05 --quiet --out {}",
            &[&out_text],
        ),
        1,
    );
    out.join("checkpoint.json")
}

/// Restart the chain from `checkpoint` with `extra` arguments: the refusal must exit 1,
/// say `error:`, name the checkpoint and `what`, and leave no energy.csv.
fn refused(dir: &Path, checkpoint: &Path, scene: &str, extra: &[&str], what: &str) {
    let out = dir.join(format!("refused-{}", what.replace(' ', "-")));
    let out_text = out.display().to_string();
    let checkpoint_text = checkpoint.display().to_string();
    let mut args = argv(
        "run {} --t-end 0.2 --quiet --out {} --restart {}",
        &[scene, &out_text, &checkpoint_text],
    );
    args.extend(extra);
    let (code, stderr) = run(&args, 1);
    assert_eq!(code, 1, "{what}: exit {code}\n{stderr}");
    assert!(stderr.contains("error:"), "{what}: {stderr}");
    assert!(
        stderr.contains(&checkpoint_text),
        "{what}: the message does not name the checkpoint:\n{stderr}"
    );
    assert!(stderr.contains(what), "{what}: not said:\n{stderr}");
    assert!(
        !out.join("energy.csv").exists(),
        "{what}: energy.csv written"
    );
}

#[test]
fn bad_checkpoints_are_refused_naming_the_file() {
    let dir = scratch_dir("restart-refusals");
    let checkpoint = chain_checkpoint(&dir);
    let text = std::fs::read_to_string(&checkpoint).unwrap();
    let chain = "systems/chain/scene.toml";
    let verlet = ["--method", "verlet", "--h", "0.01"];

    let truncated = dir.join("truncated.json");
    std::fs::write(&truncated, &text[..text.len() / 2]).unwrap();
    refused(&dir, &truncated, chain, &verlet, "truncated or corrupted");

    let version = dir.join("version.json");
    let current = format!("\"version\":{}", longstep::io::checkpoint::VERSION);
    std::fs::write(&version, text.replacen(&current, "\"version\":99", 1)).unwrap();
    assert_ne!(std::fs::read_to_string(&version).unwrap(), text);
    refused(&dir, &version, chain, &verlet, "format version 99");

    let short = dir.join("short.json");
    let value: serde_json::Value = serde_json::from_str(&text).unwrap();
    let mut spoiled = value.clone();
    spoiled["q"].as_array_mut().unwrap().pop();
    std::fs::write(&short, spoiled.to_string()).unwrap();
    refused(&dir, &short, chain, &verlet, "positions");

    // Another method, another step, another scene: each named.
    refused(
        &dir,
        &checkpoint,
        chain,
        &["--method", "impulse", "--h", "0.01", "--inner", "2"],
        "method",
    );
    refused(
        &dir,
        &checkpoint,
        chain,
        &["--method", "verlet", "--h", "0.02"],
        "h:",
    );
    refused(
        &dir,
        &checkpoint,
        "systems/two-spring.toml",
        &["--method", "verlet", "--h", "0.01"],
        "scene",
    );
    // A time before the checkpoint is no continuation.
    let out = dir.join("early");
    let (code, stderr) = run(
        &argv(
            "run {} --method verlet --h 0.01 --t-end 0.03 --quiet --out {} --restart {}",
            &[
                chain,
                &out.display().to_string(),
                &checkpoint.display().to_string(),
            ],
        ),
        1,
    );
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("must lie after the checkpoint"), "{stderr}");
}

/// The manifest lists the checkpoint, and the summary says the run is a continuation.
#[test]
fn manifest_lists_the_checkpoint_and_summary_says_continued() {
    let dir = scratch_dir("restart-manifest");
    let checkpoint = chain_checkpoint(&dir);
    let manifest = std::fs::read_to_string(dir.join("origin/manifest.json")).unwrap();
    assert!(manifest.contains("checkpoint.json"), "{manifest}");
    let out = dir.join("continued");
    let output = longstep()
        .args(argv(
            "run systems/chain/scene.toml --method verlet --h 0.01 --t-end 0.2 --quiet \
             --out {} --restart {}",
            &[
                &out.display().to_string(),
                &checkpoint.display().to_string(),
            ],
        ))
        .env("RAYON_NUM_THREADS", "1")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(output.status.success(), "{stdout}");
    assert!(stdout.contains("continued  from"), "{stdout}");
    // 10 steps were taken before the checkpoint, 10 after it.
    assert!(stdout.contains("steps      10 to t = 0.2"), "{stdout}");
}

/// A trajectory written with --trajectory-velocities carries the velocities, and its last
/// frame given to --start restarts with them: the kinetic energy at the start is the first
/// run's final one. Not bit for bit (v = p/m goes through a decimal and chemfiles' parser,
/// and p = m v rounds again): a few ulps per component, so a relative 1e-12 is ample, while
/// a start that lost the velocities would be off by O(1).
#[test]
fn trajectory_velocities_are_a_start() {
    let dir = scratch_dir("restart-trajectory-velocities");
    let first = dir.join("first");
    run_ok(
        &argv(
            "run systems/two-spring.toml --method verlet --h 0.1 --t-end 1 \
             --trajectory-every 5 --trajectory-velocities --quiet --out {}",
            &[&first.display().to_string()],
        ),
        1,
    );
    let frames = lines(&first.join("trajectory.xyz"));
    let n: usize = frames[0].parse().unwrap();
    let last = &frames[frames.len() - (n + 2)..];
    assert!(last[1].contains("velo:R:3"), "{}", last[1]);
    assert_eq!(last[2].split_whitespace().count(), 7, "{}", last[2]);
    let frame = dir.join("last.xyz");
    std::fs::write(&frame, last.join("\n") + "\n").unwrap();
    let second = dir.join("second");
    run_ok(
        &argv(
            "run systems/two-spring.toml --method verlet --h 0.1 --t-end 0.1 --start {} \
             --quiet --out {}",
            &[&frame.display().to_string(), &second.display().to_string()],
        ),
        1,
    );
    let kinetic = |row: &str| -> f64 { row.split(',').nth(1).unwrap().parse().unwrap() };
    let end = kinetic(lines(&first.join("energy.csv")).last().unwrap());
    let start = kinetic(&lines(&second.join("energy.csv"))[1]);
    assert!(
        (start - end).abs() <= 1e-12 * end.abs(),
        "kinetic energy {start} at the start, {end} at the frame"
    );
}

/// MEMM18 (20)–(24): the staggered momenta of both grids. On the slow-fast FPU chain the
/// scheme runs asynchronously (Gauss–Lobatto, so the end-node gradients that `setup`
/// recomputes are reused across steps); on the FPU chain every particle feels a fast
/// spring and it runs the synchronous scheme at `h_fast`, whose state it saves instead.
#[test]
fn async_pseudo_energy_continues_bit_for_bit() {
    both_thread_counts(Case {
        name: "async-pseudo-energy",
        scene: "systems/fpu-slow-fast.toml",
        args: &words("--method async-pseudo-energy --h 0.01 --h-fast 0.001 --quadrature gl3"),
        t_end: "2",
        half: "1",
    });
    both_thread_counts(Case {
        name: "async-pseudo-energy-synchronous",
        scene: "systems/fpu.toml",
        args: &words("--method async-pseudo-energy --h 0.01 --ratio 5"),
        t_end: "2",
        half: "1",
    });
}
