//! The run summary: printed on one screen, or as one JSON object with `--json`.
//!
//! The JSON keys are a contract with scripts and later commands: `method`, `h`, `steps`,
//! `t_end`, `force_evaluations` (`fast`, `slow`, `hessian_vector`, …), `energy`
//! (`initial`, `final`, `max_abs_error`, `max_relative_error`), `wall_seconds`, `status`
//! (`"ok"`, `"unstable"` or `"failed"`) and `unstable_at` when not ok; methods and scenes
//! may add objects of their own (`pseudo_energy`, `exact_error`).

use std::collections::BTreeMap;

use serde::Serialize;

use crate::split::ForceCounts;

#[derive(Clone, Debug, Serialize)]
pub struct ForceEvaluations {
    /// Gradient evaluations of level 0.
    pub fast: u64,
    /// Gradient evaluations of the outermost level.
    pub slow: u64,
    /// Hessian-vector products, all levels.
    pub hessian_vector: u64,
    /// Gradient evaluations per level, innermost first (more than two with recursive
    /// r-RESPA).
    pub levels: Vec<u64>,
    /// Elementary interactions evaluated (springs, pairs, angles), gradients and
    /// Hessian-vector products together.
    pub interactions: u64,
    /// Term evaluations: one per elementary interaction per force evaluation (quadrature
    /// node), the unit of MEMM18's counts N_s and N_a (4.3.1). The same number as
    /// `interactions`, under the name the pseudo-energy comparisons use.
    pub terms: u64,
}

impl From<&ForceCounts> for ForceEvaluations {
    fn from(counts: &ForceCounts) -> Self {
        ForceEvaluations {
            fast: counts.gradient.first().copied().unwrap_or(0),
            slow: counts.gradient.last().copied().unwrap_or(0),
            hessian_vector: counts.hessian_vector_total(),
            levels: counts.gradient.clone(),
            interactions: counts.interactions,
            terms: counts.interactions,
        }
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct EnergySummary {
    pub initial: f64,
    #[serde(rename = "final")]
    pub last: f64,
    pub max_abs_error: f64,
    pub max_relative_error: f64,
}

#[derive(Clone, Debug, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    Ok,
    Unstable,
    Failed,
}

#[derive(Clone, Debug, Serialize)]
pub struct RunSummary {
    pub scene: String,
    pub method: String,
    pub parameters: String,
    pub h: f64,
    pub steps: u64,
    /// The time reached (the requested end time, or the time of a blow-up).
    pub t_end: f64,
    pub force_evaluations: ForceEvaluations,
    pub energy: EnergySummary,
    pub wall_seconds: f64,
    pub status: Status,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unstable_at: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub message: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub energy_csv: Option<String>,
    /// `(t, kinetic, total)` per recorded row, when the run was asked to keep them.
    #[serde(skip)]
    pub series: Vec<[f64; 3]>,
    /// Method- or scene-specific objects, each a top-level key of the JSON summary
    /// (`pseudo_energy` from the pseudo-energy methods, `exact_error` from scenes with an
    /// exact solution).
    #[serde(flatten)]
    pub extra: BTreeMap<String, serde_json::Value>,
}

impl RunSummary {
    /// The one-screen text form.
    pub fn to_text(&self) -> String {
        let f = &self.force_evaluations;
        let mut lines = vec![
            format!("scene      {}", self.scene),
            format!("method     {} ({})", self.method, self.parameters),
            format!("steps      {} to t = {}", self.steps, self.t_end),
            format!(
                "forces     fast {}, slow {}, hessian-vector {}  (per level: {:?})",
                f.fast, f.slow, f.hessian_vector, f.levels
            ),
            format!(
                "energy     E0 = {:.10e}, final = {:.10e}, max |dE| = {:.3e}, max |dE|/|E0| = {:.3e}",
                self.energy.initial,
                self.energy.last,
                self.energy.max_abs_error,
                self.energy.max_relative_error
            ),
            format!("wall time  {:.3} s", self.wall_seconds),
        ];
        let status = match (&self.status, self.unstable_at) {
            (Status::Ok, _) => "ok".to_string(),
            (status, Some(t)) => format!(
                "{} at t = {t}: {}",
                if *status == Status::Unstable {
                    "UNSTABLE"
                } else {
                    "FAILED"
                },
                self.message.as_deref().unwrap_or("")
            ),
            (_, None) => "failed".to_string(),
        };
        lines.push(format!("status     {status}"));
        for (key, value) in &self.extra {
            lines.push(format!(
                "{:<10} {}",
                key.replace('_', "-"),
                compact_json(value)
            ));
        }
        if let Some(path) = &self.energy_csv {
            lines.push(format!("output     {path}"));
        }
        lines.join("\n")
    }
}

/// A JSON object on one line, numbers in short exponent form: `a = 1.2e-13, b = "gl3"`.
fn compact_json(value: &serde_json::Value) -> String {
    match value {
        serde_json::Value::Object(map) => map
            .iter()
            .map(|(k, v)| format!("{k} = {}", compact_json(v)))
            .collect::<Vec<_>>()
            .join(", "),
        serde_json::Value::Number(n) => match n.as_f64() {
            Some(x) if n.is_f64() => format!("{x:.6e}"),
            _ => n.to_string(),
        },
        other => other.to_string(),
    }
}
