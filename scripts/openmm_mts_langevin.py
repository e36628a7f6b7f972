#!/usr/bin/env python3
"""OpenMM's MTSLangevinIntegrator (BAOAB-RESPA) on a longstep scene, analysed by `longstep analyze`.

The cross-check of longstep's `--method langevin-respa` (issue 12 item 6): the same system
(built in OpenMM from `longstep forces SCENE --parameters`, the way scripts/compare_openmm.py
validates the force field: bonds, angles, torsions, LJ and shifted-force Coulomb as custom
forces, no centre-of-mass motion remover), the same start (the scene's coordinates and
velocities), the same settings: bonded forces (group 0) every inner step h/K, non-bonded
(group 1) every outer step h, friction γ and bath temperature T, BAOAB at the innermost
level (openmm.mtsintegrator.MTSLangevinIntegrator, groups [(1, 1), (0, K)]).

It writes OUT/energy.csv (t [fs], kinetic, potential, total [kcal/mol]) every
--energy-every outer steps and OUT/trajectory.xyz (extended XYZ with the cell and a `time`
property in fs) every --frame-every outer steps, then runs
`longstep analyze SCENE OUT [COMPARE…]` and prints the mean potential energy per molecule,
the kinetic and configurational temperatures and the first peak of the O–O g(r), each with
its block-average error bar, and every compared run's difference in combined standard errors.

    python3 scripts/openmm_mts_langevin.py --t-end 2 --skip 0.5 --blocks 5      # a quick check
    python3 scripts/openmm_mts_langevin.py --t-end 50 --skip 5 --longstep       # the comparison
    python3 scripts/openmm_mts_langevin.py --t-end 50 --skip 5 --compare out/my-langevin-run
    python3 scripts/openmm_mts_langevin.py --t-end 50 --skip 5 --reuse-openmm --longstep

--longstep also runs `longstep run SCENE --method langevin-respa` with the same h, K, T, γ
and output intervals (seeded by --seed; the random streams differ from OpenMM's, so the two
agree only statistically). Times are in fs (--h) and ps (--t-end, --skip).

Needs `pip install openmm numpy` and a release build (`cargo build --release`).
"""
import argparse
import json
import os
import subprocess
import sys
import time
import tomllib

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, ".."))
BIN = os.path.join(ROOT, "target", "release", "longstep")
sys.path.insert(0, HERE)
from compare_openmm import A2NM, KCAL, build_openmm, read_xyz  # noqa: E402

BONDED_GROUPS = {0, 1, 2}  # compare_openmm: bonds, angles, torsions; 3-6 non-bonded


def scene_files(scene):
    """The scene's structure file and its velocities file (or None)."""
    with open(scene, "rb") as f:
        s = tomllib.load(f)
    base = os.path.dirname(scene)
    structure = s["structure"]
    velocities = structure.get("velocities")
    return (os.path.join(base, structure["file"]),
            os.path.join(base, velocities) if velocities else None)


def longstep_parameters(scene, workdir):
    path = os.path.join(workdir, "parameters.json")
    res = subprocess.run([BIN, "forces", scene, "--quiet", "--json", "--parameters", path],
                         check=True, capture_output=True, text=True, cwd=ROOT)
    with open(path) as f:
        return json.load(f), json.loads(res.stdout)["energy"]


def make_simulation(args, p):
    import openmm as mm
    import openmm.unit as u
    from openmm.mtsintegrator import MTSLangevinIntegrator
    system = build_openmm(p)
    for force in system.getForces():
        force.setForceGroup(0 if force.getForceGroup() in BONDED_GROUPS else 1)
    integrator = MTSLangevinIntegrator(args.temperature * u.kelvin, args.friction / u.picosecond,
                                       args.h * u.femtosecond, [(1, 1), (0, args.inner)])
    integrator.setRandomNumberSeed(args.seed)
    platform = mm.Platform.getPlatformByName(args.platform)
    props = {"Threads": str(args.threads)} if args.platform == "CPU" else {}
    context = mm.Context(system, integrator, platform, props)
    return context, integrator


def energies(context):
    import openmm.unit as u
    state = context.getState(getEnergy=True)
    kj = u.kilojoule_per_mole
    return (state.getKineticEnergy().value_in_unit(kj) / KCAL,
            state.getPotentialEnergy().value_in_unit(kj) / KCAL)


def write_frame(f, context, elements, box, t_fs):
    import openmm.unit as u
    x = context.getState(getPositions=True).getPositions(asNumpy=True).value_in_unit(u.nanometer) / A2NM
    lattice = "%.10f 0 0 0 %.10f 0 0 0 %.10f" % tuple(box)
    f.write("%d\nLattice=\"%s\" Properties=species:S:1:pos:R:3 time=%.6f\n" % (len(elements), lattice, t_fs))
    for e, r in zip(elements, x):
        f.write("%s %.8f %.8f %.8f\n" % (e, r[0], r[1], r[2]))


def run_openmm(args, out):
    os.makedirs(out, exist_ok=True)
    p, longstep_energy = longstep_parameters(args.scene, out)
    context, integrator = make_simulation(args, p)
    structure, velocities = scene_files(os.path.join(ROOT, args.scene))
    _, x = read_xyz(structure)
    context.setPositions(x * A2NM)
    if velocities:
        _, v = read_xyz(velocities)
        context.setVelocities(v * 100.0)  # Å/fs → nm/ps
    else:
        context.setVelocitiesToTemperature(args.temperature, args.seed)
    kinetic, potential = energies(context)
    print("start: potential %.6f kcal/mol (OpenMM) vs %.6f (longstep forces)"
          % (potential, longstep_energy["total"]), flush=True)
    steps = round(args.t_end * 1000.0 / args.h)
    started = time.perf_counter()
    cpu = time.process_time()
    with open(os.path.join(out, "energy.csv"), "w") as ecsv, \
            open(os.path.join(out, "trajectory.xyz"), "w") as traj:
        ecsv.write("t,kinetic,potential,total\n")
        step = 0
        while True:
            t = step * args.h
            if step % args.energy_every == 0 or step == steps:
                kinetic, potential = energies(context)
                ecsv.write("%r,%r,%r,%r\n" % (t, kinetic, potential, kinetic + potential))
            if step % args.frame_every == 0 or step == steps:
                write_frame(traj, context, p["elements"], p["box"], t)
            if step == steps:
                break
            # Step to the next output (in one call: no Python overhead per step).
            nxt = min(steps, (step // args.energy_every + 1) * args.energy_every,
                      (step // args.frame_every + 1) * args.frame_every)
            integrator.step(nxt - step)
            step = nxt
    wall = time.perf_counter() - started
    print("OpenMM %s, %s platform, %d thread(s): %d outer steps in %.1f s wall, %.1f s CPU "
          "(%.1f ns/day by wall time on a shared machine)"
          % (__import__("openmm").__version__, args.platform, args.threads, steps, wall,
             time.process_time() - cpu, steps * args.h * 1e-6 / wall * 86400.0), flush=True)


def run_longstep(args, out):
    methods = subprocess.run([BIN, "methods"], check=True, capture_output=True, text=True).stdout
    if not any(line.split()[:1] == ["langevin-respa"] for line in methods.splitlines()):
        sys.exit("this longstep has no --method langevin-respa yet: run OpenMM alone, or "
                 "compare with --compare RUN_DIR")
    cmd = [BIN, "run", args.scene, "--method", "langevin-respa", "--h", "%gfs" % args.h,
           "--inner", str(args.inner), "--temperature", "%gK" % args.temperature,
           "--friction", "%g/ps" % args.friction, "--seed", str(args.seed),
           "--t-end", "%gps" % args.t_end, "--energy-every", str(args.energy_every),
           "--trajectory-every", str(args.frame_every), "--force", "--quiet", "--out", out]
    print("running:", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True, cwd=ROOT, stdout=subprocess.DEVNULL)


def report(args, runs, labels):
    cmd = [BIN, "analyze", args.scene] + runs + [
        "--skip", "%gps" % args.skip, "--blocks", str(args.blocks), "--pairs", args.pairs,
        "--labels", ",".join(labels), "--json"]
    print("running:", " ".join(cmd), flush=True)
    res = subprocess.run(cmd, check=True, capture_output=True, text=True, cwd=ROOT)
    summaries = json.loads(res.stdout)
    rows = []
    for s in summaries:
        pe, tk = s["potential_energy_per_molecule"], s["kinetic_temperature"]
        tc = s["configurational_temperature"] or {"mean": float("nan"), "error": float("nan")}
        peak = s["rdf"].get("O-O", {}).get("first_peak") or {}
        height = peak.get("height") or {"mean": float("nan"), "error": float("nan")}
        position = peak.get("position") or {"mean": float("nan"), "error": float("nan")}
        rows.append((s["label"], pe, tk, tc, height, position))
        print("%-22s PE/molecule %.4f ± %.4f kcal/mol | T_kin %.2f ± %.2f K | T_conf %.2f ± %.2f K | "
              "g_OO peak %.4f ± %.4f at %.4f ± %.4f Å%s"
              % (s["label"], pe["mean"], pe["error"], tk["mean"], tk["error"], tc["mean"], tc["error"],
                 height["mean"], height["error"], position["mean"], position["error"],
                 "" if pe["blocks_long_enough"] else "  (blocks too short for PE)"))
    for label, *values in rows[1:]:
        diffs = []
        for name, a, b in zip(("PE", "T_kin", "T_conf", "g_OO height", "g_OO position"), values, rows[0][1:]):
            d = a["mean"] - b["mean"]
            diffs.append("%s %+.4f (%+.2f σ)" % (name, d, d / np.hypot(a["error"], b["error"])))
        print("%s − %s: %s" % (label, rows[0][0], "; ".join(diffs)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scene", default="systems/water-box/scene.toml")
    ap.add_argument("--h", type=float, default=2.0, help="outer step, fs")
    ap.add_argument("--inner", type=int, default=4, help="inner steps per outer step")
    ap.add_argument("--temperature", type=float, default=300.0, help="K")
    ap.add_argument("--friction", type=float, default=1.0, help="1/ps")
    ap.add_argument("--t-end", type=float, default=2.0, help="ps")
    ap.add_argument("--skip", type=float, default=0.5, help="equilibration left out, ps")
    ap.add_argument("--blocks", type=int, default=10)
    ap.add_argument("--energy-every", type=int, default=10, help="outer steps")
    ap.add_argument("--frame-every", type=int, default=100, help="outer steps")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--platform", default="CPU", choices=["CPU", "Reference"])
    ap.add_argument("--pairs", default="O-O,O-H,H-H")
    ap.add_argument("--out", default="out/openmm-mts-langevin")
    ap.add_argument("--longstep", action="store_true", help="also run longstep's langevin-respa")
    ap.add_argument("--compare", nargs="*", default=[], help="other run directories to analyse")
    ap.add_argument("--reuse-openmm", action="store_true",
                    help="do not rerun OpenMM: analyse the run already in OUT")
    ap.add_argument("--analyze-only", action="store_true",
                    help="rerun nothing (neither OpenMM nor --longstep): analyse what is there")
    args = ap.parse_args()
    args.scene = os.path.relpath(os.path.abspath(args.scene), ROOT)
    out = os.path.abspath(args.out)
    if not (args.analyze_only or args.reuse_openmm):
        run_openmm(args, out)
    runs, labels = [out], ["openmm-mts-langevin"]
    if args.longstep:
        ls_out = out + "-longstep"
        if not args.analyze_only:
            run_longstep(args, ls_out)
        runs.append(ls_out)
        labels.append("longstep-langevin-respa")
    for d in args.compare:
        runs.append(os.path.abspath(d))
        labels.append(os.path.basename(os.path.normpath(d)))
    report(args, runs, labels)


if __name__ == "__main__":
    main()
