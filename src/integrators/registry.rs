//! The method registry: the names `--method` accepts ([`METHODS`]) and [`build`], which
//! turns resolved settings into the integrator. The only module that knows every method
//! file; the method files import nothing from it.

use super::adaptive_verlet::{self, AdaptiveVerlet};
use super::async_pseudo_energy::AsyncPseudoEnergy;
use super::equilibrium_molly;
use super::impulse::{self, Impulse};
use super::innermost::InnermostStep;
use super::integrator::Integrator;
use super::langevin;
use super::mollified;
use super::pseudo_energy::PseudoEnergy;
use super::sinr;
use super::structural::{self, Structural, StructuralKind};
use super::verlet::VelocityVerlet;
use crate::error::{Error, Result};
use crate::settings::MethodSettings;

/// A method `--method` accepts: its name, a line of help, and the settings it uses
/// (others given are reported as ignored, never silently dropped).
pub struct MethodInfo {
    pub name: &'static str,
    pub help: &'static str,
    pub uses: &'static [&'static str],
}

const MTS: &[&str] = &["inner_steps", "level_steps"];
const MOLLIFIED: &[&str] = &["inner_steps", "jacobian"];
const LANGEVIN: &[&str] = &[
    "inner_steps",
    "level_steps",
    "temperature",
    "seed",
    "friction",
    "mollifier",
    "jacobian",
    "molly_constraints",
    "molly_jacobian",
    "tol",
    "max_iter",
];
const SINR: &[&str] = &[
    "inner_steps",
    "level_steps",
    "temperature",
    "seed",
    "friction",
    "thermostats",
    "tau",
    "mollifier",
    "jacobian",
    "molly_constraints",
    "molly_jacobian",
    "tol",
    "max_iter",
];
const EQUILIBRIUM_MOLLY: &[&str] = &[
    "inner_steps",
    "molly_constraints",
    "molly_jacobian",
    "tol",
    "max_iter",
];

/// `settings` with the defaults its method fills in written out — the seed (start
/// velocities and noise), and in a real scene the friction and SIN(R)'s thermostats and τ
/// — so a run that spells a default out (`--seed 2013`, `--friction 1/ps`) compares
/// equal to one that leaves it to the method (a checkpoint's fingerprint). Settings with
/// no default (a dimensionless scene's friction) stay unset.
pub fn with_defaults(settings: &MethodSettings) -> MethodSettings {
    let mut s = settings.clone();
    s.seed.get_or_insert(langevin::DEFAULT_SEED);
    if s.units != crate::units::Units::Real {
        return s;
    }
    match s.method.as_str() {
        "sinr" => {
            s.thermostats.get_or_insert(sinr::DEFAULT_THERMOSTATS);
            let tau = *s.tau.get_or_insert(sinr::DEFAULT_TAU_FS);
            s.friction.get_or_insert(1.0 / tau);
        }
        "langevin-respa" => {
            s.friction.get_or_insert(langevin::DEFAULT_FRICTION_PER_FS);
        }
        _ => {}
    }
    s
}

pub const METHODS: &[MethodInfo] = &[
    MethodInfo {
        name: "verlet",
        help: "velocity Verlet: every force level at every step h (single time step)",
        uses: &[],
    },
    MethodInfo {
        name: "impulse",
        help: "r-RESPA / Verlet-I impulse, endpoint version (kick, oscillate, kick); recursive over levels",
        uses: MTS,
    },
    MethodInfo {
        name: "impulse-midpoint",
        help: "r-RESPA impulse, midpoint version (oscillate h/2, kick, oscillate h/2)",
        uses: MTS,
    },
    MethodInfo {
        name: "short-average",
        help: "mollified impulse, ShortAverage: mean over [-h/2, h/2] (GSS98)",
        uses: MOLLIFIED,
    },
    MethodInfo {
        name: "long-average",
        help: "mollified impulse, LongAverage: mean over [-h, h] (GSS98)",
        uses: MOLLIFIED,
    },
    MethodInfo {
        name: "linear-average",
        help: "mollified impulse, LinearAverage: triangle over [-h, h] (GSS98)",
        uses: MOLLIFIED,
    },
    MethodInfo {
        name: "langevin-respa",
        help: "BAOAB r-RESPA (OpenMM MTSLangevinIntegrator): impulse kicks, BAOAB innermost step; \
               --temperature, --friction (default 1/ps), --seed; one level = BAOAB",
        uses: LANGEVIN,
    },
    MethodInfo {
        name: "sinr",
        help: "SIN(R) stochastic isokinetic r-RESPA (LMT13): --temperature, --thermostats L, \
               --tau, --friction (on the thermostats), --seed; kinetic T is L/(L+1) T",
        uses: SINR,
    },
    MethodInfo {
        name: "equilibrium-molly",
        help: "mollified impulse with the equilibrium projection (IRS99): the slow force at the \
               positions with fast bonds (--molly-constraints bonds|bonds-angles) at rest, \
               --molly-jacobian exact|projection, Newton --tol, --max-iter",
        uses: EQUILIBRIUM_MOLLY,
    },
    MethodInfo {
        name: "adaptive-verlet",
        help: "time-reversible adaptive Verlet (HL97 4.2): h is the fictive step Δs; \
               --control arclength|min-distance[=α], --h-min, --h-max",
        uses: &["control", "h_min", "h_max"],
    },
    MethodInfo {
        name: "structural-zd",
        help: "structural ZD scheme (CFM25 2–4), order R+2 for even R: --block R, \
               fixed point --tol, --max-iter",
        uses: &["block", "tol", "max_iter"],
    },
    MethodInfo {
        name: "structural-zds",
        help: "structural ZDS scheme with second derivatives (CFM25 2–4), order 2(R+1): \
               --block R, --tol, --max-iter",
        uses: &["block", "tol", "max_iter"],
    },
    MethodInfo {
        name: "pseudo-energy",
        help: "MEMM18 (3): explicit, conserves a pseudo-energy for any steps; forces integrated along free flights",
        uses: &["quadrature", "adaptive", "h_min"],
    },
    MethodInfo {
        name: "async-pseudo-energy",
        help: "MEMM18 (20)-(24): slow particles step h_slow = K h_fast, fast and mixed particles h_fast",
        uses: &["quadrature", "h_slow", "h_fast", "ratio"],
    },
];

/// Build the integrator the settings ask for. `notices` collects what the user should
/// know, such as a setting the method does not use.
pub fn build(settings: &MethodSettings, notices: &mut Vec<String>) -> Result<Box<dyn Integrator>> {
    use impulse::Variant;
    let info = method_info(settings, notices)?;
    let mollifier = slow_mollifier(settings, info.name)?;
    if settings.constrained() {
        return super::constrained::build(settings, mollifier);
    }
    match info.name {
        "verlet" => Ok(Box::new(VelocityVerlet::new(settings.h)?)),
        "impulse" => Ok(Box::new(Impulse::new(settings, Variant::Endpoint, None)?)),
        "impulse-midpoint" => Ok(Box::new(Impulse::new(settings, Variant::Midpoint, None)?)),
        "short-average" | "long-average" | "linear-average" | "equilibrium-molly" => Ok(Box::new(
            Impulse::new(settings, Variant::Endpoint, mollifier)?,
        )),
        "langevin-respa" | "sinr" => thermostatted(settings, info.name == "sinr", mollifier),
        "adaptive-verlet" => adaptive(settings),
        "structural-zd" => structural_scheme(settings, StructuralKind::Zd),
        "structural-zds" => structural_scheme(settings, StructuralKind::Zds),
        "pseudo-energy" => Ok(Box::new(PseudoEnergy::from_settings(settings)?)),
        "async-pseudo-energy" => Ok(Box::new(AsyncPseudoEnergy::from_settings(
            settings, notices,
        )?)),
        other => unreachable!("method {other} is listed but not built"),
    }
}

/// The method's entry in [`METHODS`], with a notice for every given setting it ignores.
fn method_info(
    settings: &MethodSettings,
    notices: &mut Vec<String>,
) -> Result<&'static MethodInfo> {
    let Some(info) = METHODS.iter().find(|m| m.name == settings.method) else {
        let known: Vec<&str> = METHODS.iter().map(|m| m.name).collect();
        return Err(Error::setting(
            "method",
            format!(
                "unknown method \"{}\"; known methods: {}",
                settings.method,
                known.join(", ")
            ),
        )
        .expected(known.join(", "))
        .got_named(&settings.method));
    };
    for setting in settings.given() {
        if !info.uses.contains(&setting) {
            notices.push(format!(
                "{} does not use the setting {setting}; it is ignored",
                info.name
            ));
        }
    }
    Ok(info)
}

/// The mollifier of a mollified method or of `langevin-respa`/`sinr --mollifier`, if any.
fn slow_mollifier(
    settings: &MethodSettings,
    method: &str,
) -> Result<Option<Box<dyn mollified::SlowMollifier>>> {
    use mollified::Average;
    let name = match method {
        "short-average" | "long-average" | "linear-average" | "equilibrium-molly" => method,
        "langevin-respa" | "sinr" => match settings.mollifier.as_deref() {
            Some(name) => name,
            None => return Ok(None),
        },
        _ => return Ok(None),
    };
    Ok(Some(match name {
        "equilibrium-molly" => Box::new(equilibrium_molly::EquilibriumMolly::from_settings(
            settings,
        )?),
        other => averaging(settings, Average::parse(other)?)?,
    }))
}

/// A GSS98 average for the slow force, over the inner step's Verlet.
fn averaging(
    settings: &MethodSettings,
    average: mollified::Average,
) -> Result<Box<dyn mollified::SlowMollifier>> {
    let choice = mollified::JacobianChoice::parse(settings.jacobian.as_deref())?;
    let inner_steps = settings.inner_steps.ok_or_else(|| {
        Error::setting(
            "inner_steps",
            format!(
                "{} needs the inner step: give --inner K (dt = h/K) or --dt",
                average.name()
            ),
        )
        .expected("--inner K or --dt")
    })?;
    Ok(Box::new(mollified::Mollifier::new(
        average,
        choice,
        settings.h,
        inner_steps,
    )))
}

/// langevin-respa or sinr, with the same slow-force hook as the NVE methods: a GSS98
/// average or the IRS99 projection.
fn thermostatted(
    settings: &MethodSettings,
    sinr: bool,
    mollify: Option<Box<dyn mollified::SlowMollifier>>,
) -> Result<Box<dyn Integrator>> {
    let step: Box<dyn InnermostStep> = if sinr {
        Box::new(sinr::Sinr::from_settings(settings)?)
    } else {
        Box::new(langevin::Baoab(langevin::Langevin::from_settings(
            settings,
        )?))
    };
    Ok(Box::new(Impulse::with_innermost(settings, mollify, step)?))
}

fn adaptive(settings: &MethodSettings) -> Result<Box<dyn Integrator>> {
    let control = match &settings.control {
        Some(text) => adaptive_verlet::Control::parse(text)?,
        None => adaptive_verlet::Control::Arclength,
    };
    Ok(Box::new(AdaptiveVerlet::new(
        settings.h,
        control,
        settings.h_min,
        settings.h_max,
    )?))
}

fn structural_scheme(
    settings: &MethodSettings,
    kind: StructuralKind,
) -> Result<Box<dyn Integrator>> {
    Ok(Box::new(Structural::new(
        kind,
        settings.h,
        settings.block.unwrap_or(kind.default_block()),
        settings.tol.unwrap_or(structural::DEFAULT_TOLERANCE),
        settings
            .max_iter
            .unwrap_or(structural::DEFAULT_MAX_ITERATIONS),
    )?))
}
