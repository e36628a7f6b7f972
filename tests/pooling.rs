//! Independent runs pooled into one reference (`src/analysis/pooling.rs`): the pooled mean,
//! the within-run error where the runs agree, the between-run error where they disagree
//! beyond their error bars, and the between-run estimate unbiased on synthetic runs of
//! unequal lengths (docs/studies.md, "A reference of several runs").

mod common;
use common::{TestRng, estimate};

use longstep::analysis::block_average::Estimate;
use longstep::analysis::pooled::pool;

#[test]
fn two_runs_that_agree_keep_their_own_error() {
    // Equal lengths: x̄ = (1 + 1.01)/2; σ_w = √(0.1² + 0.1²)/2 = 0.0707;
    // σ_b = √(½ (0.005² + 0.005²)/1) = 0.005 < σ_w. Sums of a few numbers: 1e-15.
    let p = pool(&[estimate(1.0, 0.1), estimate(1.01, 0.1)], &[1.0, 1.0]);
    assert!((p.mean - 1.005).abs() < 1e-15);
    assert!((p.within - 0.1 / 2f64.sqrt()).abs() < 1e-15);
    assert!((p.between.unwrap() - 0.005).abs() < 1e-15);
    assert_eq!(p.error, p.within);
}

#[test]
fn two_runs_that_disagree_take_their_scatter() {
    // Lengths 3:1: w = (3/4, 1/4), x̄ = 0.75·0 + 0.25·1 = 0.25; with two runs
    // σ_b² = w₁ w₂ (x₁ − x₂)² = 3/16, far above σ_w² = (0.75·0.01)² + (0.25·0.01)².
    let p = pool(&[estimate(0.0, 0.01), estimate(1.0, 0.01)], &[3.0, 1.0]);
    assert!((p.mean - 0.25).abs() < 1e-15);
    assert!((p.between.unwrap() - (3.0f64 / 16.0).sqrt()).abs() < 1e-15);
    assert_eq!(p.error, p.between.unwrap());
    assert_eq!(p.runs, 2);
}

#[test]
fn one_run_has_no_between_run_part() {
    let p = pool(&[estimate(2.0, 0.3)], &[5.0]);
    assert_eq!((p.mean, p.error, p.between), (2.0, 0.3, None));
}

#[test]
fn a_run_without_an_error_bar_leaves_the_pool_without_one() {
    let p = pool(&[estimate(2.0, f64::NAN), estimate(2.5, 0.1)], &[1.0, 1.0]);
    assert!(p.error.is_nan() && p.within.is_nan());
}

#[test]
fn the_between_run_error_measures_the_scatter_the_runs_own_bars_miss() {
    // Five runs of lengths 1, 2, 3, 4, 10 of a quantity whose run means scatter with
    // variance c/T_i (c = 4), each reporting an error bar 1.7× too small (the dipeptide's
    // basins). True Var(x̄) = c/ΣT = 0.2. Over N = 4000 trials:
    // * the mean of σ_b² is unbiased: σ_b² ~ Var(x̄) χ²₄/4, relative sd √(2/4) per trial,
    //   √(1/2)/√N = 1.1 % for the mean: within 5 % (4.5 sd);
    // * the within-run error alone is 1.7× too small: its square is 0.2/2.89 = 0.069 in
    //   every trial, while max(σ_w, σ_b)² averages above the truth's 0.2 × (1 − 2.5 %).
    // * the pooled mean scatters about the true mean with variance 0.2: |mean| < 5·√(0.2/N).
    let lengths = [1.0, 2.0, 3.0, 4.0, 10.0];
    let (c, truth, understated) = (4.0, 0.0, 1.7);
    let total: f64 = lengths.iter().sum();
    let variance = c / total;
    let mut rng = TestRng::new(40);
    let trials = 4000;
    let (mut between, mut error, mut within, mut mean) = (0.0, 0.0, 0.0, 0.0);
    for _ in 0..trials {
        let runs: Vec<Estimate> = lengths
            .iter()
            .map(|t| {
                let sd = (c / t).sqrt();
                estimate(truth + sd * rng.normal(), sd / understated)
            })
            .collect();
        let p = pool(&runs, &lengths);
        between += p.between.unwrap().powi(2);
        error += p.error.powi(2);
        within += p.within.powi(2);
        mean += p.mean;
    }
    let n = trials as f64;
    let (between, error, within, mean) = (between / n, error / n, within / n, mean / n);
    assert!(
        (between / variance - 1.0).abs() < 0.05,
        "E[σ_b²] = {between}, Var(x̄) = {variance}"
    );
    assert!(
        (within - variance / (understated * understated)).abs() < 1e-12,
        "{within}"
    );
    assert!(error > 0.975 * variance, "E[error²] = {error}");
    assert!(mean.abs() < 5.0 * (variance / n).sqrt(), "{mean}");
}
