//! The verdicts of a run against a reference run (`longstep analyze … --reference REF`),
//! criterion by criterion, from any engine's run ([`crate::analysis::run_analysis`]).
//!
//! Every criterion is a difference of two means, the run's minus the reference's, each with
//! its block-average standard error; the difference gets the three-way verdict of
//! [`crate::run::verdict`] (the 2σ interval of the combined error `√(σ_run² + σ_ref²)`
//! against a bound: pass, fail or undecided, with the run length that would decide). A
//! criterion that does not apply is **absent** (no water, no backbone, no such term, no
//! configurational temperature computed), never a pass. The criteria:
//!
//! * **Potential energy per molecule**, bound [`DEFAULT_POTENTIAL_BOUND`] (the sampling
//!   criterion's, [`super::sampling`]).
//! * **Configurational temperature** `⟨|∇U|²⟩/⟨∇²U⟩` (Rugh 1997; Butler et al. 1998), bound
//!   `ΔT T_conf,ref/T` ([`configurational_bound`], `ΔT` = [`DEFAULT_TEMPERATURE_BOUND`]
//!   kelvin): a relative tolerance on the reference's reading, since under constraints the
//!   estimator is biased and only the comparison of run and reference means anything.
//! * **Each force-field term's mean energy** ([`crate::analysis::term_energies`]: bonds, angles,
//!   torsions, impropers, 1-4 Lennard-Jones and Coulomb, Lennard-Jones, real-space Coulomb,
//!   the reciprocal sum), bound [`term_bound`]: the shift of the term's mean that a
//!   temperature error of `ΔT` would make, `Var(E_term) ΔT/(k_B T²)`, the variance the
//!   reference's frames show. For a harmonic term of `n` interactions that is `n k_B ΔT/2`:
//!   the equipartition temperature of the term is held to `ΔT`. A term of few degrees of
//!   freedom (four impropers) would get a bound far below what any run resolves, so the
//!   bound is never below [`TERM_FLOOR_KT`]` k_B T`. docs/studies.md derives both.
//! * **The first-peak height of g(r)** of the analysed pair (O–O), bound
//!   [`DEFAULT_PEAK_BOUND`]; a run or reference without a first peak fails.
//! * **Backbone basin populations**, pooled over residues ([`super::basins::compare_basins`]),
//!   bound [`super::sampling::DEFAULT_BASIN_BOUND`].
//!
//! The run's error shrinks with a longer run, the reference's does not (the verdict's
//! "fixed" error). Kinetic temperature is not a criterion: a thermostat sets it, and a
//! trajectory file has no velocities.

use serde::Serialize;

use super::basins::{Bounds, compare_populations};
use crate::analysis::block_average::Estimate;
use crate::analysis::run_analysis::{EnergySource, RunAnalysis};
use crate::run::verdict::{self, MEAN_EXPONENT, Measurement, Verdict};

/// Largest |Δ potential energy per molecule| that passes (kcal/mol in a real scene).
pub const DEFAULT_POTENTIAL_BOUND: f64 = 0.1;

/// Largest |Δ g(r) first-peak height| that passes.
pub const DEFAULT_PEAK_BOUND: f64 = 0.05;

/// The temperature error `ΔT` the configurational temperature and each term's mean are
/// held to, in kelvin: 1 % of 300 K. docs/studies.md says why this size.
pub const DEFAULT_TEMPERATURE_BOUND: f64 = 3.0;

/// The smallest per-term bound, in `k_B T`: a term's mean off by less than a tenth of
/// `k_B T` is not told apart. A choice, as `ΔT` is: with `ΔT/T` = 1 % the temperature
/// bound `Var ΔT/(k_B T²)` is the larger for a harmonic term of more than 20 pieces
/// (`n k_B ΔT/2 ≥ 0.1 k_B T`), the floor for smaller ones, whose 1 % would need
/// ~10⁴ independent frames to resolve.
pub const TERM_FLOOR_KT: f64 = 0.1;

/// The bounds and the temperature the criteria judge at (scene units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CriterionSettings {
    pub potential_bound: f64,
    pub peak_bound: f64,
    pub basin_bound: f64,
    /// `ΔT`.
    pub temperature_bound: f64,
    /// The temperature `T` of the per-term bounds; `None`: no per-term criterion.
    pub temperature: Option<f64>,
    /// `k_B` in the scene's units.
    pub boltzmann: f64,
}

/// What a criterion measures: the scan's table finds its columns by it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    Potential,
    ConfigurationalTemperature,
    Term,
    Peak,
    Basin,
}

/// One criterion of a run against the reference.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Criterion {
    pub name: String,
    pub kind: Kind,
    pub unit: String,
    /// `pass`, `fail`, `undecided` or `absent`.
    pub verdict: &'static str,
    /// The run's mean, the reference's, their difference and its combined standard error
    /// (absent: none).
    pub value: Option<f64>,
    pub reference: Option<f64>,
    pub difference: Option<f64>,
    pub error: Option<f64>,
    pub bound: Option<f64>,
    /// Undecided: the run length that would decide (the run's time unit), if any.
    pub decide_at: Option<f64>,
    /// Why it is absent, or what else a reader needs.
    pub note: Option<String>,
    #[serde(skip)]
    pub judged: Option<Verdict>,
}

impl Criterion {
    /// A criterion that does not apply, and why.
    pub fn absent(name: &str, unit: &str, why: &str) -> Self {
        Criterion {
            name: name.into(),
            kind: Kind::Potential,
            unit: unit.into(),
            verdict: "absent",
            value: None,
            reference: None,
            difference: None,
            error: None,
            bound: None,
            decide_at: None,
            note: Some(why.into()),
            judged: None,
        }
    }

    fn with_note(mut self, note: String) -> Self {
        self.note = Some(note);
        self
    }

    fn of_kind(mut self, kind: Kind) -> Self {
        self.kind = kind;
        self
    }

    /// The criterion's name as a column key: lower case, every run of other characters
    /// than letters and digits one `_` (`mean nonbonded/lennard-jones energy` →
    /// `mean_nonbonded_lennard_jones_energy`).
    pub fn key(&self) -> String {
        let mut key = String::new();
        for c in self.name.chars() {
            if c.is_ascii_alphanumeric() {
                key.push(c.to_ascii_lowercase());
            } else if !key.ends_with('_') && !key.is_empty() {
                key.push('_');
            }
        }
        key.trim_end_matches('_').to_string()
    }
}

/// `Var(E) ΔT/(k_B T²)`: the shift of a term's mean energy that a temperature error `ΔT`
/// makes, `d⟨E⟩/dT = Cov(E, U)/(k_B T²)`, with the term's own variance standing for its
/// covariance with the whole potential energy (exact for a sum of independent harmonic
/// pieces, where both are `n (k_B T)²/2` and the bound is `n k_B ΔT/2`).
pub fn term_bound(variance: f64, temperature: f64, temperature_bound: f64, boltzmann: f64) -> f64 {
    variance * temperature_bound / (boltzmann * temperature * temperature)
}

/// The verdict on `run − reference` against `bound`, the run's error shrinking over the
/// span `[start, start + span]`, the reference's fixed.
pub fn judge_mean(
    name: &str,
    unit: &str,
    run: &Estimate,
    reference: &Estimate,
    bound: f64,
    (start, span): (f64, f64),
) -> Criterion {
    let m = Measurement {
        value: run.mean - reference.mean,
        error: run.error,
        fixed_error: reference.error,
        start,
        span,
        exponent: MEAN_EXPONENT,
    };
    let judged = verdict::judge(&m, bound);
    Criterion {
        name: name.into(),
        kind: Kind::Potential,
        unit: unit.into(),
        verdict: judged.name(),
        value: Some(run.mean),
        reference: Some(reference.mean),
        difference: Some(m.value),
        error: Some(m.standard_error()),
        bound: Some(bound),
        decide_at: match judged {
            Verdict::Undecided { decide_at } => decide_at,
            _ => None,
        },
        note: None,
        judged: Some(judged),
    }
}

/// Every criterion of `run` against `reference` (module documentation), in the units
/// `energy` and `temperature` of the scene.
pub fn judge_runs(
    reference: &RunAnalysis,
    run: &RunAnalysis,
    settings: &CriterionSettings,
    (energy, temperature): (&str, &str),
) -> Vec<Criterion> {
    let span = (run.blocks.start, run.blocks.end - run.blocks.start);
    let mut criteria = vec![judge_mean(
        "potential energy per molecule",
        &format!("{energy}/molecule"),
        &run.potential_per_molecule,
        &reference.potential_per_molecule,
        settings.potential_bound,
        span,
    )];
    criteria.push(configurational_criterion(
        reference,
        run,
        settings,
        temperature,
        span,
    ));
    let terms = term_criteria(reference, run, settings, energy, span);
    criteria.extend(terms.into_iter().map(|c| c.of_kind(Kind::Term)));
    criteria.push(peak_criterion(reference, run, settings, span).of_kind(Kind::Peak));
    let basins = basin_criteria(reference, run, settings, span);
    criteria.extend(basins.into_iter().map(|c| c.of_kind(Kind::Basin)));
    criteria
}

/// The configurational temperature estimator `⟨|∇U|²⟩/⟨∇²U⟩` of the run against the
/// reference's, held to the relative tolerance `ΔT/T`: the bound is
/// [`configurational_bound`]. Under holonomic constraints (h-bonds, rigid water) the
/// unconstrained estimator is biased (it reads ~160 K for Trp-cage at 300 K: `∇²U` keeps
/// the curvature along the constrained coordinates, whose forces no longer fluctuate into
/// `|∇U|²`), so it is compared with the
/// reference's reading, not with `T`, and the note says so when the reference's reading is
/// off `T` by more than [`CONFIGURATIONAL_BIAS`].
fn configurational_criterion(
    reference: &RunAnalysis,
    run: &RunAnalysis,
    settings: &CriterionSettings,
    unit: &str,
    span: (f64, f64),
) -> Criterion {
    const T_CONF: &str = "configurational temperature";
    let (Some(a), Some(b)) = (&run.configurational, &reference.configurational) else {
        return Criterion::absent(T_CONF, unit, "not computed (--no-configurational)")
            .of_kind(Kind::ConfigurationalTemperature);
    };
    let reading = b.temperature.mean;
    let bound = configurational_bound(reading, settings);
    let criterion = judge_mean(T_CONF, unit, &a.temperature, &b.temperature, bound, span);
    let note = match settings.temperature {
        Some(t) if (reading - t).abs() > CONFIGURATIONAL_BIAS * t => format!(
            "configurational temperature estimator, biased under constraints (or a reference \
             not at T): the reference reads {reading:.2} at T = {t:.2}; compared with the \
             reference's at the relative tolerance {}/{t:.2}",
            settings.temperature_bound
        ),
        Some(t) => format!(
            "bound: the relative tolerance {}/{t:.2} of the reference's reading",
            settings.temperature_bound
        ),
        None => "bound: ΔT (no temperature given)".into(),
    };
    criterion
        .with_note(note)
        .of_kind(Kind::ConfigurationalTemperature)
}

/// A reference's configurational temperature estimate further than this share of `T` from
/// `T` is called biased in the criterion's note (an unconstrained model's estimate is `T`
/// within its error bar; a constrained one's is off by tens of percent).
pub const CONFIGURATIONAL_BIAS: f64 = 0.05;

/// The configurational temperature criterion's bound: `ΔT · T_conf,ref / T`, the same
/// relative tolerance `ΔT/T` as the per-term bounds, applied to the reference's reading
/// `T_conf,ref` (an estimator biased by a factor scales a temperature error by that
/// factor); `ΔT` when no temperature is given or the reading is not a positive number.
pub fn configurational_bound(reading: f64, settings: &CriterionSettings) -> f64 {
    match settings.temperature {
        Some(t) if reading > 0.0 && reading.is_finite() => settings.temperature_bound * reading / t,
        _ => settings.temperature_bound,
    }
}

fn term_criteria(
    reference: &RunAnalysis,
    run: &RunAnalysis,
    settings: &CriterionSettings,
    energy: &str,
    span: (f64, f64),
) -> Vec<Criterion> {
    reference
        .terms
        .iter()
        .map(|r| {
            let name = format!("mean {} energy", r.name);
            let Some(p) = run.terms.iter().find(|p| p.name == r.name) else {
                return Criterion::absent(&name, energy, "the run's model has no such term");
            };
            let Some(t) = settings.temperature else {
                return Criterion::absent(&name, energy, "no temperature: give --temperature");
            };
            if r.variance.is_nan() || r.variance <= 0.0 {
                return Criterion::absent(&name, energy, "constant in the reference");
            }
            let bound = term_bound(
                r.variance,
                t,
                settings.temperature_bound,
                settings.boltzmann,
            )
            .max(TERM_FLOOR_KT * settings.boltzmann * t);
            judge_mean(&name, energy, &p.mean, &r.mean, bound, span).with_note(format!(
                "bound: the shift a {} error in T = {t} would make (Var = {:.4e}), at least \
                 {TERM_FLOOR_KT} k_B T",
                settings.temperature_bound, r.variance
            ))
        })
        .collect()
}

fn peak_criterion(
    reference: &RunAnalysis,
    run: &RunAnalysis,
    settings: &CriterionSettings,
    span: (f64, f64),
) -> Criterion {
    let Some(pair) = run.rdf.first() else {
        return Criterion::absent(
            "g(r) first-peak height",
            "",
            "no g(r) pair (no periodic box)",
        );
    };
    let name = format!("g {} first-peak height", pair.name);
    let reference_peak = reference.rdf.first().and_then(|r| r.peak_height);
    match (pair.peak_height, reference_peak) {
        (Some(p), Some(r)) => judge_mean(&name, "", &p, &r, settings.peak_bound, span),
        _ => Criterion {
            verdict: "fail",
            judged: Some(Verdict::Fail),
            bound: Some(settings.peak_bound),
            note: Some("no first peak found in the run or the reference".into()),
            ..Criterion::absent(&name, "", "")
        },
    }
}

fn basin_criteria(
    reference: &RunAnalysis,
    run: &RunAnalysis,
    settings: &CriterionSettings,
    span: (f64, f64),
) -> Vec<Criterion> {
    let bounds = Bounds {
        potential: settings.potential_bound,
        peak: settings.peak_bound,
        start: span.0,
        span: span.1,
    };
    let basins = compare_populations(
        reference.basin_populations(),
        run.basin_populations(),
        &bounds,
        settings.basin_bound,
    );
    if basins.is_empty() {
        return vec![Criterion::absent(
            "basin populations",
            "",
            "no peptide backbone in the model",
        )];
    }
    basins
        .into_iter()
        .map(|b| Criterion {
            name: format!("basin {} population", b.basin),
            kind: Kind::Basin,
            unit: String::new(),
            verdict: b.verdict.name(),
            value: Some(b.population),
            reference: Some(b.population - b.difference),
            difference: Some(b.difference),
            error: Some(b.combined_error),
            bound: Some(settings.basin_bound),
            decide_at: match b.verdict {
                Verdict::Undecided { decide_at } => decide_at,
                _ => None,
            },
            note: None,
            judged: Some(b.verdict),
        })
        .collect()
}

/// The verdict on all present criteria together ([`verdict::all`]); `None` when every
/// criterion is absent.
pub fn overall(criteria: &[Criterion]) -> Option<Verdict> {
    let judged: Vec<Verdict> = criteria.iter().filter_map(|c| c.judged).collect();
    (!judged.is_empty()).then(|| verdict::all(&judged))
}

/// The time unit of a run's span: `frames` when its times are frame numbers.
pub fn time_unit<'a>(run: &RunAnalysis, scene_time: &'a str) -> &'a str {
    match run.source {
        EnergySource::Frames { times: false } => "frames",
        _ => scene_time,
    }
}
