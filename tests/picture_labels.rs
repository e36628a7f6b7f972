//! Issue 14 item 13: the text on study pictures is readable and says what a reader needs —
//! resonance labels that do not print over each other, work-precision points labelled with
//! their outer step, and a logarithmic colour bar ticked down to its bottom. Checked on the
//! SVG files, whose `<text>` elements carry position, size and content.

mod common;
use common::{argv, longstep, scratch_dir};

use common::svg::{SvgText, overlap, svg_texts, text_box};

fn run_ok(args: &[&str]) {
    let output = longstep().args(args).output().expect("longstep runs");
    assert!(
        output.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&output.stderr)
    );
}

/// Butane's fast modes predict six resonant steps within 0.2 fs of 5.7 fs: their labels
/// printed over each other. Now no two resonance labels overlap, and every predicted
/// kind is still named.
#[test]
fn butane_resonance_labels_do_not_overlap() {
    let out = scratch_dir("butane-guides");
    run_ok(&argv(
        "scan steps systems/molecules/butane.toml --methods impulse --h 1fs:8fs:1fs \
         --dt 0.25fs --t-end 0.1ps --repeats 0 --quiet --out {}",
        &[out.to_str().unwrap()],
    ));
    let svg = std::fs::read_to_string(out.join("scan.svg")).unwrap();
    let labels: Vec<SvgText> = svg_texts(&svg)
        .into_iter()
        .filter(|t| t.content.contains("k="))
        .collect();
    assert!(!labels.is_empty(), "no resonance labels drawn");
    for kind in ["type1", "type2"] {
        assert!(
            labels.iter().any(|l| l.content.contains(kind)),
            "{kind} not named: {labels:?}"
        );
    }
    for (i, a) in labels.iter().enumerate() {
        for b in &labels[i + 1..] {
            assert!(
                !overlap(text_box(a), text_box(b)),
                "'{}' overlaps '{}'",
                a.content,
                b.content
            );
        }
    }
}

/// Every outer step of a work-precision study is written beside its points.
#[test]
fn work_precision_points_are_labelled_with_h() {
    let out = scratch_dir("work-precision-h-labels");
    run_ok(&argv(
        "chart work-precision systems/two-spring.toml --methods impulse,long-average \
         --h-list 0.4,0.2,0.1 --inner 10 --t-end 8 --weights 1,1,1 --quiet --out {}",
        &[out.to_str().unwrap()],
    ));
    let svg = std::fs::read_to_string(out.join("error-vs-slow-evaluations.svg")).unwrap();
    let texts = svg_texts(&svg);
    for h in ["0.4", "0.2", "0.1"] {
        let label = format!("h = {h}");
        assert!(
            texts.iter().any(|t| t.content == label),
            "no '{label}' on the chart"
        );
    }
    let labels: Vec<&SvgText> = texts
        .iter()
        .filter(|t| t.content.starts_with("h = "))
        .collect();
    for (i, a) in labels.iter().enumerate() {
        for b in &labels[i + 1..] {
            assert!(!overlap(text_box(a), text_box(b)), "{a:?} overlaps {b:?}");
        }
    }
}

/// The tick values of a map's colour bar: texts that read as positive numbers, right of
/// the map.
fn colour_bar_ticks(svg: &str, right_of: f64) -> Vec<(f64, String)> {
    svg_texts(svg)
        .into_iter()
        .filter(|t| t.x > right_of)
        .filter_map(|t| t.content.parse::<f64>().ok().map(|v| (v, t.content)))
        .filter(|(v, _)| *v > 0.0)
        .collect()
}

/// The map's SVG and CSV.
fn radius_map(method: &str, name: &str) -> (String, String) {
    let dir = scratch_dir(name);
    let svg = dir.join("map.svg");
    run_ok(&argv(
        "stability-map --method {} --h 0.5 --gamma1 0:6.5 --gamma2 0:6.5 --n 150 \
         --colour radius --quiet --out {} --svg {}",
        &[
            method,
            dir.join("map.csv").to_str().unwrap(),
            svg.to_str().unwrap(),
        ],
    ));
    (
        std::fs::read_to_string(&svg).unwrap(),
        std::fs::read_to_string(dir.join("map.csv")).unwrap(),
    )
}

/// LongAverage at h = 0.5 has ρ − 1 between about 3e-4 and 3.5e-3: the bar was ticked only
/// at 0.001–0.003, its lower third unlabelled. Now it is ticked below 0.001, and on the
/// impulse map (two decades) no tick value is written twice.
#[test]
fn log_colour_bar_is_ticked_to_its_bottom() {
    let map_right = 850.0;
    let (svg, csv) = radius_map("long-average", "radius-bar-long-average");
    let smallest = csv
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("gamma1"))
        .filter_map(|l| l.split(',').nth(2)?.parse::<f64>().ok())
        .map(|rho| rho - 1.0)
        .filter(|excess| *excess > 0.0)
        .fold(f64::INFINITY, f64::min);
    assert!(
        smallest < 1e-3,
        "the map no longer reaches below 0.001: {smallest}"
    );
    let ticks = colour_bar_ticks(&svg, map_right);
    assert!(
        ticks.iter().any(|(v, _)| *v < 1e-3),
        "no tick below 0.001 (smallest value {smallest}): {ticks:?}"
    );
    let (svg, _) = radius_map("impulse", "radius-bar-impulse");
    let ticks = colour_bar_ticks(&svg, map_right);
    assert!(ticks.len() >= 3, "{ticks:?}");
    for (i, a) in ticks.iter().enumerate() {
        assert!(
            ticks[i + 1..].iter().all(|b| b.1 != a.1),
            "tick {} written twice: {ticks:?}",
            a.1
        );
    }
}

/// A stiffness scan's unstable runs are crosses under their method's name, not anonymous
/// red crosses (the scan of `common::verlet_blowup_stiffness_scan`: Verlet overflows,
/// impulse does not).
#[test]
fn stiffness_scan_unstable_points_carry_their_method() {
    let (_, svg) = common::verlet_blowup_stiffness_scan(&scratch_dir("stiffness-unstable-method"));
    let texts = svg_texts(&std::fs::read_to_string(&svg).unwrap());
    assert!(
        texts
            .iter()
            .any(|t| t.content.starts_with("verlet") && t.content.ends_with(" unstable")),
        "no legend entry for verlet's unstable runs"
    );
    assert!(
        texts.iter().all(|t| t.content != "unstable"),
        "an anonymous 'unstable' legend entry"
    );
}
