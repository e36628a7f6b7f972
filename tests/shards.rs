//! `--shard k/n` and `longstep merge`: shards merged give exactly the tables and pictures of
//! a single run.

mod common;
use common::{argv, argv_owned, longstep, scratch_dir, words};

use std::path::Path;

fn run(args: &[&str]) {
    let output = longstep().args(args).output().unwrap();
    assert!(
        output.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&output.stderr)
    );
}

fn same_files(a: &Path, b: &Path, names: &[&str]) {
    for name in names {
        let (x, y) = (
            std::fs::read(a.join(name)).unwrap(),
            std::fs::read(b.join(name)).unwrap(),
        );
        assert!(
            x == y,
            "{name} differs between the single run and the merged shards"
        );
    }
}

#[test]
fn work_precision_shards_merge_into_the_single_run() {
    let single = scratch_dir("wp-single");
    let (first, second, merged) = (
        scratch_dir("wp-1"),
        scratch_dir("wp-2"),
        scratch_dir("wp-merged"),
    );
    let base = words(
        "chart work-precision systems/two-spring.toml --methods impulse,long-average \
         --h-list 0.2,0.1 --inner 5 --t-end 2 --weights 1,0.5,1.5 --quiet --out",
    );
    let with = |out: &Path, shard: Option<&str>| {
        let mut args: Vec<String> = base.iter().map(|s| s.to_string()).collect();
        args.push(out.display().to_string());
        if let Some(shard) = shard {
            args.extend(["--shard".to_string(), shard.to_string()]);
        }
        args
    };
    let call = |args: Vec<String>| run(&args.iter().map(String::as_str).collect::<Vec<_>>());
    call(with(&single, None));
    call(with(&first, Some("1/2")));
    call(with(&second, Some("2/2")));
    run(&[
        "merge",
        first.to_str().unwrap(),
        second.to_str().unwrap(),
        "--out",
        merged.to_str().unwrap(),
    ]);
    same_files(
        &single,
        &merged,
        &[
            "work-precision.csv",
            "error-vs-slow-evaluations.png",
            "error-vs-force-evaluations.svg",
            "energy-error-vs-force-evaluations.png",
        ],
    );
    // A shard alone is not the study: merging it refuses with the missing point.
    let output = longstep()
        .args([
            "merge",
            first.to_str().unwrap(),
            "--out",
            merged.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("point 1 is missing"), "{stderr}");
}

#[test]
fn scan_shards_merge_into_the_single_run() {
    let single = scratch_dir("scan-single");
    let (first, second, third, merged) = (
        scratch_dir("scan-1"),
        scratch_dir("scan-2"),
        scratch_dir("scan-3"),
        scratch_dir("scan-merged"),
    );
    let args = |out: &Path| -> Vec<String> {
        argv_owned(
            "scan steps systems/three-spring.toml --methods impulse,long-average \
             --h 0.2:0.5:0.1 --inner 10 --t-end 20 --quiet --out {}",
            &[&out.display().to_string()],
        )
    };
    let call = |mut a: Vec<String>, shard: Option<&str>| {
        if let Some(s) = shard {
            a.extend(["--shard".into(), s.into()]);
        }
        run(&a.iter().map(String::as_str).collect::<Vec<_>>());
    };
    call(args(&single), None);
    call(args(&first), Some("1/3"));
    call(args(&second), Some("2/3"));
    call(args(&third), Some("3/3"));
    run(&[
        "merge",
        third.to_str().unwrap(),
        first.to_str().unwrap(),
        second.to_str().unwrap(),
        "--out",
        merged.to_str().unwrap(),
    ]);
    same_files(&single, &merged, &["scan.csv", "scan.png", "scan.svg"]);
}

/// `longstep` with the words of `line`, then `--out out` and `--shard k/n` when given.
fn run_shard(line: &str, out: &str, shard: Option<&str>) {
    let mut args = words(line);
    args.extend(["--out", out]);
    if let Some(s) = shard {
        args.extend(["--shard", s]);
    }
    run(&args);
}

#[test]
fn stiffness_scan_shards_merge_into_the_single_run_table() {
    let dir = scratch_dir("stiffness-shards");
    let out = |name: &str| dir.join(name).display().to_string();
    let scan = |file: &str, shard: Option<&str>| {
        let line = "scan stiffness systems/two-spring.toml --method impulse --param omega1 \
                    --range 0:32 --n 6 --h 0.5 --t-end 4 --quiet";
        run_shard(line, &out(file), shard);
    };
    scan("single.csv", None);
    scan("a.csv", Some("1/2"));
    scan("b.csv", Some("2/2"));
    run(&[
        "merge",
        &out("b.csv"),
        &out("a.csv"),
        "--out",
        &out("merged"),
    ]);
    let single = std::fs::read_to_string(dir.join("single.csv")).unwrap();
    let merged = std::fs::read_to_string(dir.join("merged/scan-stiffness.csv")).unwrap();
    assert_eq!(single, merged);
}

#[test]
fn stability_map_shards_merge_into_the_single_run_map() {
    let dir = scratch_dir("map-shards");
    let out = |name: &str| dir.join(name).display().to_string();
    let map = |file: &str, shard: Option<&str>| {
        let line = "stability-map --method impulse --h 0.5 --gamma1 0:2*pi --gamma2 0:2*pi \
                    --n 25 --quiet";
        run_shard(line, &out(file), shard);
    };
    map("single.csv", None);
    for k in 1..=4 {
        map(&format!("part{k}.csv"), Some(&format!("{k}/4")));
    }
    run(&[
        "merge",
        &out("part4.csv"),
        &out("part2.csv"),
        &out("part1.csv"),
        &out("part3.csv"),
        "--out",
        &out("m"),
    ]);
    assert_eq!(
        std::fs::read_to_string(dir.join("single.csv")).unwrap(),
        std::fs::read_to_string(dir.join("m/stability-map.csv")).unwrap()
    );
}

/// Run `longstep` and return (exit code, stderr).
fn status_of(args: &[&str]) -> (Option<i32>, String) {
    let output = longstep().args(args).output().unwrap();
    (
        output.status.code(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

#[test]
fn stability_map_merge_checks_its_shards() {
    let dir = scratch_dir("map-shard-checks");
    let out = |name: &str| dir.join(name).display().to_string();
    let map = |file: &str, method: &str, shard: &str| {
        run(&argv(
            "stability-map --method {} --h 0.5 --n 6 --quiet --out {} --shard {}",
            &[method, &out(file), shard],
        ));
    };
    map("a.csv", "impulse", "1/2");
    map("b.csv", "long-average", "2/2");
    map("c.csv", "impulse", "1/3");
    // One shard of two is not the map.
    let (code, stderr) = status_of(&["merge", &out("a.csv"), "--out", &out("m1")]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("shard 2/2 is missing"), "{stderr}");
    // Shards of different methods: the message names the setting and both values.
    let (code, stderr) = status_of(&["merge", &out("a.csv"), &out("b.csv"), "--out", &out("m2")]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("method") && stderr.contains("impulse") && stderr.contains("long-average"),
        "{stderr}"
    );
    // Shards of different splits.
    let (code, stderr) = status_of(&["merge", &out("a.csv"), &out("c.csv"), "--out", &out("m3")]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("1/3"), "{stderr}");
    assert!(!dir.join("m1/stability-map.csv").exists());
}

#[test]
fn merge_names_the_differing_setting_in_the_users_terms() {
    let dir = scratch_dir("scan-shard-settings");
    let scan = |name: &str, t_end: &str, shard: &str| {
        run(&argv(
            "scan steps systems/three-spring.toml --methods impulse --h 0.2:0.3:0.1 \
             --inner 10 --t-end {} --quiet --out {} --shard {}",
            &[t_end, &dir.join(name).display().to_string(), shard],
        ));
    };
    scan("a", "20", "1/2");
    scan("b", "10", "2/2");
    let text = std::fs::read_to_string(dir.join("a/scan.csv")).unwrap();
    let first = text.lines().next().unwrap();
    assert!(
        !first.contains("Some(") && !first.contains("Number("),
        "{first}"
    );
    let (code, stderr) = status_of(&[
        "merge",
        &dir.join("a").display().to_string(),
        &dir.join("b").display().to_string(),
        "--out",
        &dir.join("m").display().to_string(),
    ]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("t_end: ") && stderr.contains("20") && stderr.contains("10"),
        "{stderr}"
    );
    assert!(
        !stderr.contains("Number(") && !stderr.contains("Some("),
        "{stderr}"
    );
}

#[test]
fn stiffness_scan_merge_checks_the_method() {
    let dir = scratch_dir("stiffness-shard-settings");
    let out = |name: &str| dir.join(name).display().to_string();
    let scan = |file: &str, method: &str, shard: &str| {
        run(&argv(
            "scan stiffness systems/two-spring.toml --method {} --param omega1 --range 0:32 \
             --n 4 --h 0.5 --t-end 2 --quiet --out {} --shard {}",
            &[method, &out(file), shard],
        ));
    };
    scan("a.csv", "impulse", "1/2");
    scan("b.csv", "long-average", "2/2");
    let (code, stderr) = status_of(&["merge", &out("a.csv"), &out("b.csv"), "--out", &out("m")]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("method"), "{stderr}");
}

/// Issue 30 item 11: a shard prints no safe-step table of its own slice; a merge that fails
/// leaves no `--out`; map shards mixed with a scan's are refused by what they are.
#[test]
fn shards_do_not_answer_alone_and_failed_merges_leave_nothing() {
    let dir = common::scratch_dir("shards-answers");
    let shard = dir.join("s1").display().to_string();
    let (code, stdout, stderr) = common::run_cli(&argv(
        "scan steps systems/three-spring.toml --methods impulse --h 0.1:0.3:0.1 \
         --inner 10 --t-end 10 --repeats 0 --quiet --shard 1/2 --out {}",
        &[&shard],
    ));
    assert_eq!(code, 0, "{stderr}");
    assert!(!stdout.contains("safe up to"), "{stdout}");
    assert!(stdout.contains("longstep merge"), "{stdout}");
    let map = dir.join("map.csv").display().to_string();
    let (code, _, stderr) = common::run_cli(&argv(
        "stability-map --method impulse --h 0.5 --n 4 --shard 1/2 --out {} --quiet",
        &[&map],
    ));
    assert_eq!(code, 0, "{stderr}");
    let out = dir.join("merged");
    let (code, _, stderr) =
        common::run_cli(&["merge", &shard, &map, "--out", &out.display().to_string()]);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("mix stability-map shards"), "{stderr}");
    assert!(!out.exists(), "a failed merge left {}", out.display());
}
