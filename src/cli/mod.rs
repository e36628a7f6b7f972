//! The `longstep` command line.
//!
//! Exit codes: 0 success, 1 bad input or I/O error (the message names what and where),
//! 2 bad command-line usage, 3 a run that went unstable or whose method failed (its
//! outputs up to that point are written, and the summary says when).

mod analyze;
mod analyze_output;
mod analyze_verdicts;
mod async_map;
mod charts;
mod common;
mod draw;
mod forces;
mod growth;
mod merge;
mod minimize;
mod modes;
mod modes_lanczos;
mod run;
mod run_dof;
mod scan_report;
mod scan_steps;
pub mod stability;
mod stiffness;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};

pub use common::{EXIT_ERROR, EXIT_UNSTABLE, parse_shard, parse_steps};

#[derive(Parser, Debug)]
#[command(
    name = "longstep",
    version,
    about = "Multiple-time-step molecular dynamics: r-RESPA, mollified impulse and \
             pseudo-energy methods, and the maps of where they fail",
    long_about = "Multiple-time-step molecular dynamics.\n\n\
        longstep integrates scenes (TOML files in systems/) with single- and \
        multiple-time-step methods. Forces are split into levels: bonded terms are fast \
        (sampled every inner step dt), non-bonded terms slow (sampled every outer step h). \
        Every run prints its level table, writes energy.csv and a summary.\n\n\
        Start with:  longstep run systems/three-spring.toml --method verlet --h 0.05 --t-end 100",
    arg_required_else_help = true
)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Integrate a scene and report energy conservation and force-evaluation counts.
    Run(Box<run::RunArgs>),
    /// Print a scene's level table, particle classes and fast components without running.
    Check(Box<run::CheckArgs>),
    /// List the integration methods.
    Methods,
    /// Normal modes of the fast forces and the outer steps where MTS methods resonate.
    Modes(Box<modes::ModesArgs>),
    /// Minimise a scene's potential energy (FIRE) and report it.
    Minimize(Box<minimize::MinimizeArgs>),
    /// Scans over outer steps (and, for the three-spring maps, stiffness).
    #[command(subcommand)]
    Scan(ScanCommand),
    /// Charts of accuracy against cost.
    #[command(subcommand)]
    Chart(Box<charts::ChartCommand>),
    /// Combine the outputs of --shard runs into what a single run writes.
    Merge(merge::MergeArgs),
    /// Map the spectral radius of one outer step over (Γ1, Γ2) = (hΩ1, hΩ2) for the
    /// linear three-spring problem (GSS98 eq. (27)): CSV and a heat map. With
    /// `--method async-pseudo-energy SCENE` it maps MEMM18's asynchronous scheme instead
    /// (the arguments of async-stability-map).
    StabilityMap(Box<stability::StabilityMapArgs>),
    /// The spectral radius and instability type at one (Γ1, Γ2).
    SpectralRadius(Box<stability::SpectralRadiusArgs>),
    /// Spectral radius of the asynchronous pseudo-energy scheme over h_slow (or h_fast) and K on a linear scene, as CSV.
    AsyncStabilityMap(async_map::AsyncMapArgs),
    /// Energy per group and per-atom forces at the scene's starting positions.
    Forces(Box<forces::ForcesArgs>),
    /// Configurational analysis of finished runs: g(r), potential energy per molecule,
    /// kinetic and configurational temperature, bond lengths and angles, with block-average
    /// error bars (docs/analysis.md).
    Analyze(Box<analyze::AnalyzeArgs>),
}

#[derive(Subcommand, Debug)]
pub enum ScanCommand {
    /// Run each method at each outer step and classify it: stable, drifting or unstable.
    Steps(Box<scan_steps::ScanStepsArgs>),
    /// The largest position error against a scene parameter such as a stiff spring's
    /// frequency (GSS98 Figures 11–13), against an extrapolated Verlet reference.
    Stiffness(Box<stiffness::ScanStiffnessArgs>),
    /// Long runs: the energy error's envelope, its fitted growth rate per step, and 2 ln ρ
    /// from the linearised step of the same method (GSS98 Figures 6–10).
    Growth(Box<growth::ScanGrowthArgs>),
}

/// Every option of `command` and its subcommands that takes a value takes one that starts
/// with `-` as that value, so `--inner -3` or `--skip -1ps` is refused for its value
/// (naming the flag) instead of being read as an unknown flag `-3`.
fn negative_values(mut command: clap::Command) -> clap::Command {
    let ids: Vec<clap::Id> = command
        .get_arguments()
        .filter(|a| {
            // Not a flag whose value is optional (`--rigid-water [BOOL]`): it would take
            // the next flag as its value.
            let optional = a.get_num_args().is_some_and(|n| n.min_values() == 0);
            a.get_action().takes_values() && !a.is_positional() && !optional
        })
        .map(|a| a.get_id().clone())
        .collect();
    for id in ids {
        command = command.mut_arg(id, |a| a.allow_hyphen_values(true));
    }
    let names: Vec<String> = command
        .get_subcommands()
        .map(|s| s.get_name().to_string())
        .collect();
    for name in names {
        command = command.mut_subcommand(name, negative_values);
    }
    command
}

/// A negative value given to a count (`--inner -3`, `--energy-every -1`) is refused by clap
/// with Rust's "invalid digit found in string": say what the flag takes instead.
fn explain_negative_count(e: clap::Error) -> clap::Error {
    use clap::error::{ContextKind, ContextValue, ErrorKind};
    use std::error::Error as _;
    let from_integer = e
        .source()
        .is_some_and(|s| s.downcast_ref::<std::num::ParseIntError>().is_some());
    if e.kind() != ErrorKind::ValueValidation || !from_integer {
        return e;
    }
    match (
        e.get(ContextKind::InvalidArg),
        e.get(ContextKind::InvalidValue),
    ) {
        (Some(ContextValue::String(flag)), Some(ContextValue::String(value)))
            if value.starts_with('-') =>
        {
            clap::Error::raw(
                ErrorKind::ValueValidation,
                format!("{flag} takes a count (a whole number, zero or more), got {value}\n"),
            )
        }
        _ => e,
    }
}

/// Run the command line; returns the process exit code.
pub fn main() -> i32 {
    let parsed = negative_values(Cli::command())
        .try_get_matches_from(std::env::args())
        .and_then(|matches| Cli::from_arg_matches(&matches));
    let cli = match parsed {
        Ok(cli) => cli,
        Err(e) => {
            let e = explain_negative_count(e);
            let code = e.exit_code();
            let _ = e.print();
            return code;
        }
    };
    let result = match cli.command {
        Command::Run(args) => run::run_command(&args),
        Command::Check(args) => run::check_command(&args).map(|()| 0),
        Command::Modes(args) => modes::modes_command(&args).map(|()| 0),
        Command::Minimize(args) => minimize::minimize_command(&args).map(|()| 0),
        Command::Scan(ScanCommand::Steps(args)) => {
            scan_steps::scan_steps_command(&args).map(|()| 0)
        }
        Command::Chart(chart) => match *chart {
            charts::ChartCommand::WorkPrecision(args) => {
                charts::work_precision_command(&args).map(|()| 0)
            }
        },
        Command::Merge(args) => merge::merge_command(&args).map(|()| 0),
        Command::Scan(ScanCommand::Stiffness(args)) => {
            stiffness::scan_stiffness_command(&args).map(|()| 0)
        }
        Command::Scan(ScanCommand::Growth(args)) => growth::scan_growth_command(&args).map(|()| 0),
        Command::StabilityMap(args) => stability::stability_map_command(&args),
        Command::SpectralRadius(args) => stability::spectral_radius_command(&args).map(|()| 0),
        Command::AsyncStabilityMap(args) => async_map::async_map_command(&args),
        Command::Forces(args) => forces::forces_command(&args).map(|()| 0),
        Command::Analyze(args) => analyze::analyze_command(&args).map(|()| 0),
        Command::Methods => {
            for method in crate::integrators::METHODS {
                println!("{:<22} {}", method.name, method.help);
            }
            Ok(0)
        }
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e}");
            EXIT_ERROR
        }
    }
}
