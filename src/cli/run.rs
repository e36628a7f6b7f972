//! `longstep run` and `longstep check`.

use std::path::PathBuf;

use super::{CheckArgs, EXIT_UNSTABLE, RunArgs};
use crate::error::{Error, Result};
use crate::integrators;
use crate::io::scene::load_scene;
use crate::io::summary::Status;
use crate::run::{RunOptions, TrajectoryOptions, run};
use crate::split::ParticleClass;
use crate::system::exact::position_error;

/// Runs inside a rayon pool (threads from `RAYON_NUM_THREADS`, default all cores): parallel
/// force loops then split their work from a worker thread, with no allocation per call.
pub fn run_command(args: &RunArgs) -> Result<i32> {
    let pool = rayon::ThreadPoolBuilder::new()
        .build()
        .map_err(|e| Error::input(format!("cannot start the thread pool: {e}")))?;
    pool.install(|| run_in_pool(args))
}

fn run_in_pool(args: &RunArgs) -> Result<i32> {
    let mut scene = load_scene(&args.scene, &args.set)?;
    let settings = scene
        .run
        .overridden_by(&args.run)
        .resolve_with_units(&scene.parameters, scene.units)?;
    let t_end = settings.t_end.ok_or_else(|| {
        Error::input("no end time: give --t-end or set t_end in the scene's [run] table")
    })?;
    let energy_every = args.energy_every.or(scene.output.energy_every).unwrap_or(1);
    if energy_every == 0 {
        return Err(Error::input("--energy-every must be at least 1"));
    }

    let mut notices = Vec::new();
    let mut integrator = integrators::build(&settings, &mut notices)?;
    if settings.method == "async-pseudo-energy" {
        // On a scratch copy: the check steps the scene.
        let mut scratch = load_scene(&args.scene, &args.set)?;
        if let Some(warning) =
            crate::analysis::async_stability::band_warning(&mut scratch.system, &settings)
        {
            notices.push(warning);
        }
    }
    notices.extend(integrator.notices(&scene.system));

    let out_dir = args
        .out
        .clone()
        .or_else(|| scene.output.dir.as_ref().map(PathBuf::from))
        .unwrap_or_else(|| {
            PathBuf::from("out").join(format!("{}-{}", scene.name, settings.method))
        });
    std::fs::create_dir_all(&out_dir).map_err(|e| Error::io(&out_dir, e))?;

    if !args.quiet {
        for line in &scene.forcefield_report {
            eprintln!("{line}");
        }
        eprintln!("{}", scene.system.forces.level_table());
        for notice in &notices {
            eprintln!("notice: {notice}");
        }
    }
    let trajectory_every = args.trajectory_every.or(scene.output.trajectory_every);
    if trajectory_every == Some(0) {
        return Err(Error::input("--trajectory-every must be at least 1"));
    }
    let trajectory = trajectory_every.map(|every| TrajectoryOptions {
        path: out_dir.join(
            scene
                .output
                .trajectory
                .as_deref()
                .unwrap_or("trajectory.xyz"),
        ),
        every,
        names: scene.elements.clone(),
    });
    let options = RunOptions {
        t_end,
        energy_every,
        blowup: settings.blowup,
        energy_csv: Some(out_dir.join("energy.csv")),
        trajectory,
        ..Default::default()
    };
    let mut summary = run(
        &scene.name,
        &mut scene.system,
        integrator.as_mut(),
        &options,
    )?;
    if let Some(exact) = &scene.exact {
        let error = position_error(exact.as_ref(), &scene.system.state)?;
        let value = serde_json::to_value(&error)
            .map_err(|e| Error::input(format!("cannot write the exact error as JSON: {e}")))?;
        summary.extra.insert("exact_error".into(), value);
    }
    if args.plot {
        plot_energies(&out_dir.join("energy.csv"), &summary, &out_dir)?;
    }
    if let Some(t) = &options.trajectory
        && !args.quiet
    {
        eprintln!("trajectory {}", t.path.display());
    }
    if args.json {
        let json = serde_json::to_string_pretty(&summary)
            .map_err(|e| Error::input(format!("cannot write the summary as JSON: {e}")))?;
        println!("{json}");
    } else {
        println!("{}", summary.to_text());
    }
    if summary.status != Status::Ok {
        if args.json && !args.quiet {
            eprintln!(
                "{} at t = {}: {}",
                if summary.status == Status::Unstable {
                    "unstable"
                } else {
                    "failed"
                },
                summary.t_end,
                summary.message.as_deref().unwrap_or("")
            );
        }
        return Ok(EXIT_UNSTABLE);
    }
    Ok(0)
}

pub fn check_command(args: &CheckArgs) -> Result<()> {
    let scene = load_scene(&args.scene, &args.set)?;
    let system = &scene.system;
    println!("scene      {} — {}", scene.name, scene.description);
    println!(
        "particles  {} in {} D{}",
        system.n_particles(),
        system.dim,
        match &system.periodic_box {
            Some(b) => format!(", periodic box {:?}", &b.lengths[..system.dim]),
            None => String::new(),
        }
    );
    if !scene.parameters.is_empty() {
        let parameters: Vec<String> = scene
            .parameters
            .iter()
            .map(|(name, value)| format!("{name} = {value}"))
            .collect();
        println!("parameters {}", parameters.join(", "));
    }
    println!("{}", system.forces.level_table());
    let classes = system.forces.classify_particles(system.n_particles());
    let count = |class| classes.iter().filter(|&&c| c == class).count();
    println!(
        "classes    {} fast, {} mixed, {} slow (MEMM18 section 4.1)",
        count(ParticleClass::Fast),
        count(ParticleClass::Mixed),
        count(ParticleClass::Slow)
    );
    let components = system.forces.fast_components(system.n_particles());
    let largest = components.iter().map(Vec::len).max().unwrap_or(0);
    println!(
        "fast graph {} connected components, the largest with {largest} particles",
        components.len()
    );
    if let Some(mass) = &system.mass_matrix {
        println!(
            "mass       non-diagonal, bandwidth {} (only pseudo-energy solves with it)",
            mass.bandwidth()
        );
    }
    if let Some(exact) = &scene.exact {
        println!("exact      {}", exact.describe());
    }
    println!(
        "energy     E0 = {} (kinetic {}, potential per level {:?})",
        system.total_energy(),
        system.kinetic_energy(),
        system.potential_energies()
    );
    Ok(())
}

/// Kinetic, potential and total energy against time from energy.csv, and the relative
/// error of the total on a second chart.
fn plot_energies(
    csv: &std::path::Path,
    summary: &crate::io::summary::RunSummary,
    out: &std::path::Path,
) -> Result<()> {
    use crate::plot::{AxisSpec, Corner, LineChart, Series};
    let text = std::fs::read_to_string(csv).map_err(|e| Error::io(csv, e))?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap_or_default().split(',').collect();
    let column = |name: &str| header.iter().position(|h| *h == name);
    let (Some(t), Some(k), Some(v), Some(e)) = (
        column("t"),
        column("kinetic"),
        column("potential"),
        column("total"),
    ) else {
        return Err(Error::input(format!(
            "{}: not an energy table",
            csv.display()
        )));
    };
    let rows: Vec<Vec<f64>> = lines
        .map(|l| {
            l.split(',')
                .map(|x| x.parse().unwrap_or(f64::NAN))
                .collect()
        })
        .collect();
    let series =
        |name: &str, c: usize| Series::line(name, rows.iter().map(|r| (r[t], r[c])).collect());
    let title = format!("{}: {}, h = {}", summary.scene, summary.method, summary.h);
    let mut chart = LineChart::new(
        &title,
        AxisSpec::linear("time t"),
        AxisSpec::linear("energy"),
    );
    chart.series = vec![
        series("kinetic", k),
        series("potential", v),
        series("total", e),
    ];
    chart.legend = Corner::UpperRight;
    let initial = summary.energy.initial;
    let scale = if initial != 0.0 { initial.abs() } else { 1.0 };
    let mut error = LineChart::new(
        &format!("{title}: energy error"),
        AxisSpec::linear("time t"),
        AxisSpec::linear("(E − E0)/|E0|"),
    );
    error.series = vec![Series::line(
        "total",
        rows.iter()
            .map(|r| (r[t], (r[e] - initial) / scale))
            .collect(),
    )];
    for extension in ["png", "svg"] {
        chart.save(&out.join(format!("energy.{extension}")))?;
        error.save(&out.join(format!("energy-error.{extension}")))?;
    }
    Ok(())
}
