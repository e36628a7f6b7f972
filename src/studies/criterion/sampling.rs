//! The sampling criterion of the step-size scan (`scan steps --criterion sampling`): a
//! thermostatted run is judged by what it samples, not by an energy it does not conserve.
//!
//! Each point's run and a reference run (BAOAB at a small step, e.g. 0.5 fs with γ = 1/ps,
//! at the same temperature) are analysed with the estimators of `longstep analyze`
//! ([`crate::analysis::run_analysis`], its default options: the same frames, blocks, g(r)
//! bins and Hutchinson probes) and judged by **the criteria of `longstep analyze
//! --reference`** ([`super::reference::judge_runs`], one module for both): the mean
//! potential energy per molecule, the configurational temperature, the mean of each
//! force-field term, the first-peak height of one pair's g(r) and the backbone basins —
//! each difference to the reference, with its combined error `√(σ_run² + σ_ref²)`, against
//! its bound: **pass** when its whole 2σ interval lies within the bound, **fail** when
//! wholly outside, **undecided** otherwise; a criterion that does not apply (no water, no
//! backbone) is **absent** and takes no part. The point passes when every present criterion
//! passes and fails when any fails; otherwise it is undecided, and the run length that
//! would decide it follows from the run's error shrinking as `1/√T` over the analysed span
//! while the reference's stays (a longer run of the point does not improve the reference:
//! when the reference's error alone is too wide, no run length of the point decides). The
//! errors are treated as independent; paired runs (same start, same noise) are correlated,
//! so the combined error overstates theirs — a conservative verdict. Each point's criteria
//! are written to `criteria.json` in its run directory, as `analyze --json` gives them.
//!
//! The per-term bounds are at the scan's temperature (the thermostat's, `--temperature`);
//! `analyze --reference … --temperature T` with the same discard and blocks gives the same
//! verdicts on the same run directories.
//!
//! **Backbone basins.** When the scene is a topology whose atom names give a peptide
//! backbone ([`crate::analysis::dihedrals::backbone_residues`]), the populations of the (φ, ψ) basins
//! C7eq/β, αR and αL ([`crate::analysis::dihedrals::BASINS`]) are compared too, **pooled over every
//! residue with φ and ψ** ([`crate::analysis::dihedrals::pooled_populations`]: one row per basin
//! whatever the protein's length; the alanine dipeptide has one such residue, so pooled is
//! its own). Each Δp, with the run's block error (shrinking as `1/√T`) and the reference's
//! as the fixed error, gets the same three-way verdict against `basin_bound` (default 0.1
//! in absolute population, [`DEFAULT_BASIN_BOUND`]). A basin whose population has a zero
//! error in both runs (the same in every block: no transition seen) is undecided, never a
//! pass on no information.
//!
//! **Cost.** The analysis visits only the trajectory frames the point's run wrote
//! (`--frames` per run, default 100): per frame one energy evaluation of every term (the
//! per-term series), a gradient and [`DEFAULT_PROBES`] Hessian-vector products (the
//! configurational temperature), the g(r) histogram and the dihedrals.
//!
//! The reference is compared at equal temperature, not equal friction: SIN(R)'s γ acts on its
//! thermostat variables, not on the velocities, so no γ of it corresponds to BAOAB's.

use std::path::{Path, PathBuf};

use serde::Serialize;

pub use super::basins::{BasinComparison, Bounds, compare_basins, compare_populations};
use super::reference::{Criterion, CriterionSettings, Kind, judge_runs, overall};
use crate::analysis::block_average::Estimate;
pub use crate::analysis::configurational::DEFAULT_PROBES;
use crate::analysis::dihedrals::BackboneResidue;
use crate::analysis::run_analysis::{AnalysisOptions, Analyzer, RunAnalysis, RunFiles};
use crate::error::{Error, Result};
use crate::io::scene::Scene;
use crate::run::verdict;
use crate::units::Units;

/// What the sampling criterion compares, and its bounds.
#[derive(Clone, Debug)]
pub struct SamplingCriterion {
    /// The reference run directory (energy.csv and a trajectory).
    pub reference: PathBuf,
    /// The g(r) pair whose first-peak height is compared.
    pub pair: (String, String),
    /// Largest |ΔPE per molecule| that passes, in the scene's energy unit.
    pub potential_bound: f64,
    /// Largest |Δ g(r) first-peak height| that passes.
    pub peak_bound: f64,
    /// Largest |Δ population| of a backbone basin that passes.
    pub basin_bound: f64,
    /// The temperature error `ΔT` the configurational temperature and each term's mean are
    /// held to ([`super::reference::DEFAULT_TEMPERATURE_BOUND`]).
    pub temperature_bound: f64,
    /// The scan's temperature, that of the per-term bounds (`None`: those criteria are
    /// absent).
    pub temperature: Option<f64>,
    /// The scene's backbone residues whose basins are compared (empty: no peptide backbone).
    pub backbone: Vec<BackboneResidue>,
    /// Start of each run left out (equilibration), in the scene's time unit.
    pub discard: f64,
    /// Blocks of the error bars.
    pub blocks: usize,
    /// Trajectory frames per run (about; one every `t_end / (frames h)` steps).
    pub frames: usize,
    /// Where each point's run directory is written.
    pub runs: PathBuf,
}

/// The default bound on a basin's |Δ population|: 0.1 of the frames, the resolution a user
/// of a Ramachandran population asks for (a basin's share to one decimal: whether αR holds
/// 0.2 or 0.3 of the time). It is a choice, not a derived figure: a basin's indicator is
/// correlated over the time between transitions (tens of ps for the solvated dipeptide), so
/// whether a run resolves it is for its error bar to say — a run too short for 0.1 is
/// undecided, and says how long a run would decide.
pub const DEFAULT_BASIN_BOUND: f64 = 0.1;

/// Most trajectory frames per run (a bound on a user-given count).
pub const MAX_FRAMES: usize = 100_000;

impl SamplingCriterion {
    /// The analysis both runs go through: the pair's g(r) and every other default of
    /// `longstep analyze` (bins, peak fit, [`DEFAULT_PROBES`] probes of the configurational
    /// temperature, seed 1).
    pub fn analysis_options(&self) -> AnalysisOptions {
        self.analysis_options_for(None)
    }

    /// [`Self::analysis_options`] with the kinetic temperature over `dof` degrees of
    /// freedom (`None`: the analyzer's `3N`), for a constrained model ([`constrained_dof`]).
    pub fn analysis_options_for(&self, dof: Option<f64>) -> AnalysisOptions {
        AnalysisOptions {
            pairs: vec![self.pair.clone()],
            intramolecular: false,
            skip: self.discard,
            until: None,
            blocks: self.blocks,
            bin_width: 0.02,
            r_max: None,
            peak_window: 0.25,
            peak_fit: 0.1,
            probes: DEFAULT_PROBES,
            seed: 1,
            configurational: true,
            dof,
            kinetic_column: "kinetic".into(),
            stride: 1,
        }
    }

    /// Check the user-given sizes and bounds.
    pub fn check(&self, t_end: f64) -> Result<()> {
        for (value, flag) in [
            (self.potential_bound, "--potential-bound"),
            (self.peak_bound, "--peak-bound"),
            (self.basin_bound, "--basin-bound"),
            (self.temperature_bound, "--temperature-bound"),
        ] {
            if !(value > 0.0 && value.is_finite()) {
                return Err(Error::flag(flag, format!("{flag} must be positive"))
                    .expected("a positive number")
                    .got(value.to_string()));
            }
        }
        if !(1..=MAX_FRAMES).contains(&self.frames) {
            return Err(Error::flag(
                "--frames",
                format!("--frames must be between 1 and {MAX_FRAMES}"),
            )
            .expected(format!("1 to {MAX_FRAMES}"))
            .got(self.frames.to_string()));
        }
        if !(0.0..t_end).contains(&self.discard) {
            return Err(Error::flag("--discard", format!("--discard {} is outside the run [0, {t_end}): nothing would be left to compare", self.discard)).expected(format!("a time in [0, {t_end})")).got_named(self.discard.to_string()));
        }
        if self.frames < self.blocks {
            return Err(Error::flag(
                "--frames",
                format!(
                    "--frames {} is fewer than --blocks {}: every block needs a trajectory frame",
                    self.frames, self.blocks
                ),
            )
            .expected(format!("at least --blocks {}", self.blocks))
            .got_named(self.frames.to_string()));
        }
        Ok(())
    }

    /// The analyzer of a run of `scene` (the point's or the reference's): the options of
    /// [`Self::analysis_options_for`] and the backbone's basins.
    pub fn analyzer<'a>(&self, scene: &'a Scene, dof: Option<f64>) -> Result<Analyzer<'a>> {
        let mut analyzer = Analyzer::new(scene, self.analysis_options_for(dof))?;
        analyzer.set_backbone(self.backbone.clone());
        Ok(analyzer)
    }

    /// What the output says of the basins: the residues they are pooled over, or that the
    /// scene has no peptide backbone.
    pub fn basins_note(&self) -> String {
        if self.backbone.is_empty() {
            return "no peptide backbone: no basin populations compared".into();
        }
        let labels: Vec<&str> = self.backbone.iter().map(|r| r.label.as_str()).collect();
        format!("pooled over {}", labels.join(" "))
    }

    /// The bounds and temperature of the criteria ([`super::reference`]), with `k_B` of
    /// the scene's `units`.
    pub fn settings(&self, units: Units) -> CriterionSettings {
        CriterionSettings {
            potential_bound: self.potential_bound,
            peak_bound: self.peak_bound,
            basin_bound: self.basin_bound,
            temperature_bound: self.temperature_bound,
            temperature: self.temperature,
            boltzmann: units.boltzmann(),
        }
    }

    /// Trajectory frame interval in steps of outer step `h` over a run of `t_end`.
    pub fn frame_every(&self, t_end: f64, h: f64) -> usize {
        let steps = (t_end / h).round().max(1.0);
        ((steps / self.frames as f64).floor() as usize).max(1)
    }
}

/// One point's run against the reference: every criterion ([`super::reference`]), and the
/// numbers of the scan table's fixed columns.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Comparison {
    /// The run's mean potential energy per molecule and its standard error.
    pub potential: f64,
    pub potential_error: f64,
    /// Run minus reference, and `√(σ_run² + σ_ref²)`.
    pub potential_difference: f64,
    pub potential_combined_error: f64,
    /// The run's g(r) first-peak height and its standard error (NaN: no peak found).
    pub peak: f64,
    pub peak_error: f64,
    pub peak_difference: f64,
    pub peak_combined_error: f64,
    /// The run's mean kinetic temperature and its standard error.
    pub kinetic_temperature: f64,
    pub kinetic_temperature_error: f64,
    /// The backbone basins, pooled over residues (empty without a backbone).
    pub basins: Vec<BasinComparison>,
    /// Every criterion, present or absent, as `analyze --reference` gives them.
    pub criteria: Vec<Criterion>,
    /// The point's verdict: that of every present criterion together ([`verdict::all`]).
    pub verdict: verdict::Verdict,
}

/// The first-peak height of the analysed pair, `None` when no peak was found.
pub fn peak_height(analysis: &RunAnalysis) -> Option<Estimate> {
    analysis.rdf.first().and_then(|r| r.peak_height)
}

/// Compare a run's analysis with the reference's by every criterion of
/// [`super::reference::judge_runs`] (module documentation), in the energy and temperature
/// units of `units`; a run or reference whose g(r) shows no first peak fails.
pub fn compare(
    reference: &RunAnalysis,
    run: &RunAnalysis,
    settings: &CriterionSettings,
    units: Units,
) -> Comparison {
    let names = (units.energy_name(), units.temperature_name());
    let criteria = judge_runs(reference, run, settings, names);
    let of = |kind: Kind| criteria.iter().find(|c| c.kind == kind);
    let numbers = |c: Option<&Criterion>| {
        let c = c.and_then(|c| c.difference.zip(c.error));
        c.unwrap_or((f64::NAN, f64::NAN))
    };
    let (potential_difference, potential_combined_error) = numbers(of(Kind::Potential));
    let (peak_difference, peak_combined_error) = numbers(of(Kind::Peak));
    let peak = peak_height(run);
    let bounds = Bounds {
        potential: settings.potential_bound,
        peak: settings.peak_bound,
        start: run.blocks.start,
        span: run.blocks.end - run.blocks.start,
    };
    let verdict = overall(&criteria).unwrap_or(verdict::Verdict::Undecided { decide_at: None });
    Comparison {
        potential: run.potential_per_molecule.mean,
        potential_error: run.potential_per_molecule.error,
        potential_difference,
        potential_combined_error,
        peak: peak.map_or(f64::NAN, |p| p.mean),
        peak_error: peak.map_or(f64::NAN, |p| p.error),
        peak_difference,
        peak_combined_error,
        kinetic_temperature: run.kinetic_temperature.mean,
        kinetic_temperature_error: run.kinetic_temperature.error,
        basins: compare_populations(
            reference.basin_populations(),
            run.basin_populations(),
            &bounds,
            settings.basin_bound,
        ),
        criteria,
        verdict,
    }
}

/// Relative slack of the reference's temperature check: beyond five standard errors, a
/// reference whose mean kinetic temperature is more than 2 % off the target was run at
/// another temperature (a 0.5 fs BAOAB reference holds its target far closer than that).
pub const TEMPERATURE_SLACK: f64 = 0.02;

/// Refuse a reference run at another temperature than `target` (both in the scene's
/// temperature unit; K in a real scene).
pub fn check_reference_temperature(
    reference: &RunAnalysis,
    target: f64,
    unit: &str,
    dir: &std::path::Path,
) -> Result<()> {
    let t = &reference.kinetic_temperature;
    let tolerance = 5.0 * t.error + TEMPERATURE_SLACK * target;
    // A NaN mean or error (too few blocks to tell) is refused too.
    let within = (t.mean - target).abs() <= tolerance;
    if !within {
        return Err(Error::flag(
            "--reference",
            format!(
                "the reference run {} has a mean kinetic temperature of {:.2} ± {:.2}{unit}, not \
             the scan's {target}{unit}: compare at equal temperature (give the reference's \
             --temperature, or a reference run at {target}{unit})",
                dir.display(),
                t.mean,
                t.error
            ),
        )
        .expected(format!("a reference run at {target}{unit}"))
        .got_named(format!("{:.2}{unit}", t.mean)));
    }
    Ok(())
}

/// The directory of one point's run under the criterion's `runs` directory.
pub fn point_dir(criterion: &SamplingCriterion, index: usize, method: &str, h: f64) -> PathBuf {
    criterion.runs.join(format!("{index:04}-{method}-h{h}"))
}

impl SamplingCriterion {
    /// Judge a finished run in `dir` (energy.csv and trajectory.xyz) of `scene`, its
    /// kinetic temperature over `dof` degrees of freedom, against the reference's analysis
    /// ([`compare`]), and write its criteria to `dir/criteria.json`.
    pub fn judge_run(
        &self,
        scene: &Scene,
        dof: Option<f64>,
        reference: &RunAnalysis,
        dir: &Path,
    ) -> Result<Comparison> {
        let analysis = self.analyzer(scene, dof)?.analyze(&RunFiles {
            energy: dir.join("energy.csv"),
            trajectory: dir.join("trajectory.xyz"),
            dof: None,
        })?;
        let comparison = compare(
            reference,
            &analysis,
            &self.settings(scene.units),
            scene.units,
        );
        let path = dir.join("criteria.json");
        let text = serde_json::to_string_pretty(&comparison.criteria)
            .map_err(|e| Error::input(format!("cannot write JSON: {e}")))?;
        std::fs::write(&path, text + "\n").map_err(|e| Error::io(path, e))?;
        Ok(comparison)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::block_average::from_block_means;
    use crate::analysis::dihedrals::{ResidueBasins, pooled_populations};

    /// A residue whose basins have these block means (C7eq/β, αR; αL a constant), seen
    /// changing basin a million times (so the transition floor, 2p(1 − p)/1000 ≤ 5e-4, stays
    /// below the block errors) unless `transitions` says otherwise.
    fn residue(c7eq: &[f64], alpha_r: &[f64], alpha_l: f64) -> ResidueBasins {
        residue_changing(c7eq, alpha_r, alpha_l, 1_000_000)
    }

    fn residue_changing(
        c7eq: &[f64],
        alpha_r: &[f64],
        alpha_l: f64,
        transitions: usize,
    ) -> ResidueBasins {
        let block_means = [c7eq.to_vec(), alpha_r.to_vec(), vec![alpha_l; c7eq.len()]];
        ResidueBasins {
            label: "ALA2".into(),
            transitions,
            populations: std::array::from_fn(|k| from_block_means(&block_means[k])),
            block_means,
            histogram: Vec::new(),
            frames: 100,
        }
    }

    const BOUNDS: Bounds = Bounds {
        potential: 0.1,
        peak: 0.05,
        start: 0.0,
        span: 100.0,
    };

    #[test]
    fn basin_populations_are_judged_against_the_reference() {
        // Reference C7eq/β block means 0.6 ± 0.02 (alternating): mean 0.6, error
        // 0.02·√(4/(4·3)) = 0.02/√3 = 0.01155; αR 0.3 alike; αL never visited (0 in every block: zero error).
        let reference = [residue(
            &[0.62, 0.58, 0.62, 0.58],
            &[0.28, 0.32, 0.28, 0.32],
            0.0,
        )];
        let e = 0.02 / 3f64.sqrt();
        // The same populations: Δp = 0 ± √2·0.01155 = 0.0163, 2σ = 0.033 ≤ 0.1: pass; αL,
        // never visited in a million basin changes, has an error of ~1e-9: pass too.
        let same = compare_basins(&reference, &reference, &BOUNDS, 0.1);
        assert_eq!(same.len(), 3);
        assert_eq!(same[0].basin, "C7eq/beta");
        assert!(same[0].difference.abs() < 1e-15);
        assert!(
            (same[0].combined_error - e * 2f64.sqrt()).abs() < 1e-12,
            "{same:?}"
        );
        assert_eq!(same[0].verdict, verdict::Verdict::Pass);
        assert_eq!(same[2].verdict, verdict::Verdict::Pass);
        // αR moved to 0.6 and C7eq/β to 0.3: |Δp| = 0.3, 0.3 − 0.033 > 0.1: fail.
        let moved = [residue(
            &[0.32, 0.28, 0.32, 0.28],
            &[0.58, 0.62, 0.58, 0.62],
            0.0,
        )];
        let wrong = compare_basins(&reference, &moved, &BOUNDS, 0.1);
        assert!((wrong[1].difference - 0.3).abs() < 1e-12, "{wrong:?}");
        assert_eq!(wrong[1].verdict, verdict::Verdict::Fail);
        // Δp = 0.09 ± 0.0163: the interval [0.057, 0.123] straddles 0.1: undecided.
        let near = [residue(
            &[0.53, 0.49, 0.53, 0.49],
            &[0.37, 0.41, 0.37, 0.41],
            0.0,
        )];
        let open = compare_basins(&reference, &near, &BOUNDS, 0.1);
        assert!((open[0].difference + 0.09).abs() < 1e-12, "{open:?}");
        assert_eq!(open[0].verdict.name(), "undecided");
        // No backbone: nothing compared.
        assert!(compare_basins(&[], &reference, &BOUNDS, 0.1).is_empty());
    }

    #[test]
    fn residues_pool_by_their_block_means() {
        // Two residues, one always C7eq/β and one always αR in blocks 1–2 and swapped in
        // blocks 3–4: each residue's own error is 0.5/√3, but their pooled block means are
        // 0.5 in every block, so with many basin changes the pooled C7eq/β population is
        // 0.5 with zero error.
        let pooled = pooled_populations(&[
            residue(&[1.0, 1.0, 0.0, 0.0], &[0.0, 0.0, 1.0, 1.0], 0.0),
            residue(&[0.0, 0.0, 1.0, 1.0], &[1.0, 1.0, 0.0, 0.0], 0.0),
        ])
        .unwrap();
        assert_eq!(pooled[0].mean, 0.5);
        assert!(pooled[0].error < 1e-3, "{pooled:?}");
        // The same block means from residues that each changed basin once: two dwells, so
        // each residue's population is known to 2·0.5·0.5/√2 = 0.354 (p̃ = p = 1/2), pooled
        // √(2·0.125)/2 = 0.25, whatever the blocks say.
        let once = pooled_populations(&[
            residue_changing(&[1.0, 1.0, 0.0, 0.0], &[0.0, 0.0, 1.0, 1.0], 0.0, 1),
            residue_changing(&[0.0, 0.0, 1.0, 1.0], &[1.0, 1.0, 0.0, 0.0], 0.0, 1),
        ])
        .unwrap();
        assert!((once[0].error - 0.25).abs() < 1e-12, "{once:?}");
    }

    #[test]
    fn a_telegraph_series_has_the_error_its_transitions_give() {
        // A two-state series that switches every 10 frames over 10 000 frames: p = 1/2,
        // 999 changes, correlation time τ = 1/(k_A + k_B) = 5 frames, so the error of p is
        // √(2 p(1 − p) τ/T) = √(2·0.25·5/10⁴) = 0.0158; 2p(1 − p)/√n = 0.5/√999 = 0.0158.
        let exact = (2.0 * 0.25 * 5.0 / 1e4f64).sqrt();
        let floor = crate::analysis::dihedrals::transition_error(0.5, 999);
        assert!((floor / exact - 1.0).abs() < 1e-3, "{floor} vs {exact}");
        // No change seen: one dwell, error 1/2 whatever the population read.
        assert_eq!(crate::analysis::dihedrals::transition_error(1.0, 0), 0.5);
        assert_eq!(crate::analysis::dihedrals::transition_error(0.0, 0), 0.5);
    }
}
