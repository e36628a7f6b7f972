#!/usr/bin/env python3
"""Head-to-head throughput: longstep against GROMACS, LAMMPS and OpenMM on the kit's water boxes.

Runs from a clone and reads no file outside it: the longstep scenes are systems/water-box/
(216 waters, 648 atoms) and systems/water-box-1728/ (1728 waters, 5 184 atoms); the peers'
inputs are copies of the peers' comparison kit in scripts/peers/ (OpenMM system builder
mdsys.py with the systems' JSON, LAMMPS data and input, GROMACS .gro/.top).

Model and integrator (NVE, the kit's coordinates and 300 K velocities): SPC/Fw water, LJ
O-O energy-shifted at 9 A, shifted-force Coulomb at 9 A, all intramolecular pairs excluded;
r-RESPA impulse with bonds and angles inner at 0.5 fs and non-bonded outer at h.

  longstep : `longstep run SCENE --method impulse --h H --inner K [--precision mixed]`, wall
             time of the stepping loop from the JSON summary; threads = RAYON_NUM_THREADS
  GROMACS  : `gmx mdrun` (mixed precision) and `gmx_d mdrun` (double), two-level MTS (non-bonded
             every K steps of 0.5 fs), -ntmpi 1 -ntomp THREADS -pin on -resethway, ns/day from
             the log. Its closest model: reaction-field Coulomb with eps_rf = infinity (same
             cost, a different model: potential energy -4.3 %); nstlist as the kit chose it
  LAMMPS   : `lmp` with run_style respa 2 K bond 1 angle 1 pair 2 ("Loop time"), the same
             model (lj/cut/coul/dsf); 2 threads = mpirun -np 2 (no OpenMP package in Debian's)
  OpenMM   : CPU platform (its own mixed precision), CustomNonbondedForce with the same model,
             MTSIntegrator(h, [(1, 1), (0, K)]), Threads = THREADS

The codes are interleaved (each repeat runs every code once, in turn) so all see the same
machine load; each configuration runs --repeats times (default 3). Printed: every run, the
median, ns/day, and the ratios of longstep (double and mixed) to each peer and to the fastest.

    python3 scripts/head_to_head.py                       # the full sitting (see --help)
    python3 scripts/head_to_head.py --quick               # smoke test: a few steps per run
    python3 scripts/head_to_head.py --sizes 648 --threads 1 --h 4 --codes longstep,gromacs

The peers are installed when missing (--install): OpenMM with pip, LAMMPS, GROMACS and
Open MPI with apt-get. Needs a release build of longstep (`cargo build --release`).
"""
import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, ".."))
PEERS = os.path.join(HERE, "peers")
BIN = os.path.join(ROOT, "target", "release", "longstep")
INNER = 0.5  # fs

# atoms -> (kit name, longstep scene, structure dir)
SYSTEMS = {
    648: ("water216", "systems/water-box/scene.toml", "systems/water-box"),
    5184: ("water1728", "systems/water-box-1728/scene.toml", "systems/water-box-1728"),
}
# Outer steps per run, chosen for a few seconds of stepping on this machine kind at 1 thread
# (about 1-4 s each; the peers' start-up is outside their timed loops).
STEPS = {
    "longstep": {648: 3000, 5184: 400},
    "gromacs": {648: 4000, 5184: 800},
    "lammps": {648: 600, 5184: 80},
    "openmm": {648: 400, 5184: 60},
}
# GROMACS nstlist per (atoms, K), as the kit chose it (a multiple of the MTS factor K).
NSTLIST = {(648, 4): 12, (648, 8): 16, (5184, 4): 20, (5184, 8): 32}

MDP = """integrator = md
dt = 0.0005
nsteps = {nsteps}
tcoupl = no
pcoupl = no
cutoff-scheme = Verlet
coulombtype = Reaction-Field
epsilon-rf = 0
rcoulomb = 0.9
vdwtype = Cut-off
vdw-modifier = Potential-shift
rvdw = 0.9
DispCorr = no
constraints = none
continuation = yes
gen-vel = no
nstcalcenergy = {nstcalc}
nstenergy = 0
nstlog = 0
nstxout = 0
nstvout = 0
nstfout = 0
comm-mode = Linear
nstcomm = {nstcalc}
nstlist = {nstlist}
mts = yes
mts-levels = 2
mts-level2-forces = longrange-nonbonded nonbonded pair dihedral
mts-level2-factor = {k}
"""


def sh(cmd, **kw):
    return subprocess.run(cmd, capture_output=True, text=True, **kw)


def run_longstep(atoms, h, k, steps, threads, precision):
    scene = SYSTEMS[atoms][1]
    with tempfile.TemporaryDirectory() as out:
        env = dict(os.environ, RAYON_NUM_THREADS=str(threads))
        cmd = [BIN, "run", scene, "--method", "impulse", "--h", "%gfs" % h, "--inner", str(k),
               "--t-end", "%gfs" % (h * steps), "--energy-every", str(steps),
               "--quiet", "--json", "--out", out, "--precision", precision]
        res = sh(cmd, cwd=ROOT, env=env)
        if res.returncode != 0:
            raise RuntimeError("longstep failed: %s" % res.stderr[-2000:])
        s = json.loads(res.stdout)
        return s["steps"] / s["wall_seconds"]


def run_gromacs(atoms, h, k, steps, threads, precision):
    name = SYSTEMS[atoms][0]
    gmx = "gmx_d" if precision == "double" else "gmx"
    nstlist = NSTLIST.get((atoms, k), 4 * k)
    inner_steps = steps * k
    with tempfile.TemporaryDirectory() as work:
        mdp = os.path.join(work, "run.mdp")
        with open(mdp, "w") as f:
            f.write(MDP.format(nsteps=inner_steps, nstcalc=inner_steps, nstlist=nstlist, k=k))
        tpr = os.path.join(work, "run.tpr")
        res = sh([gmx, "grompp", "-f", mdp, "-c", os.path.join(PEERS, "gromacs", name + ".gro"),
                  "-p", os.path.join(PEERS, "gromacs", name + ".top"), "-o", tpr,
                  "-po", os.path.join(work, "out.mdp"), "-maxwarn", "1"], cwd=work)
        if res.returncode != 0:
            raise RuntimeError("grompp failed: %s" % res.stderr[-2000:])
        log = os.path.join(work, "md.log")
        res = sh([gmx, "mdrun", "-s", tpr, "-nsteps", str(inner_steps), "-ntmpi", "1",
                  "-ntomp", str(threads), "-pin", "on", "-noconfout", "-resethway", "-g", log,
                  "-e", os.path.join(work, "ener.edr")], cwd=work,
                 env=dict(os.environ, GMX_MAXBACKUP="-1"))
        if res.returncode != 0:
            raise RuntimeError("mdrun failed: %s" % res.stderr[-2000:])
        text = open(log).read()
        ns_per_day = float(re.search(r"^Performance:\s+([0-9.eE+-]+)", text, re.M).group(1))
        return ns_per_day / (h * 1e-6 * 86400.0)


def run_lammps(atoms, h, k, steps, threads, precision):
    name = SYSTEMS[atoms][0]
    with tempfile.TemporaryDirectory() as work:
        log = os.path.join(work, "log")
        lmp = ["lmp", "-nocite", "-screen", "none", "-var", "dir", os.path.join(PEERS, "systems"),
               "-var", "sys", name, "-var", "integ", "respa", "-var", "dt", str(h),
               "-var", "k", str(k), "-var", "nsteps", str(steps), "-var", "thermo", str(steps),
               "-in", os.path.join(PEERS, "lammps", "in.md"), "-log", log]
        if threads > 1:
            lmp = ["mpirun", "-np", str(threads), "--bind-to", "core"] + lmp
        env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
                   OMP_NUM_THREADS="1")
        res = sh(lmp, cwd=work, env=env, stdin=subprocess.DEVNULL)
        if res.returncode != 0:
            raise RuntimeError("lmp failed: %s" % (res.stderr or res.stdout)[-2000:])
        loop = float(re.search(r"Loop time of ([0-9.eE+-]+) on", open(log).read()).group(1))
        return steps / loop


def run_openmm(atoms, h, k, steps, threads, precision):
    sys.path.insert(0, PEERS)
    import mdsys
    import openmm as mm
    name, _, directory = SYSTEMS[atoms]
    p = mdsys.load_params(name)
    system = mdsys.build_openmm_system(p, "identical")
    integ = mm.MTSIntegrator(h * 1e-3, [(1, 1), (0, k)])
    ctx = mm.Context(system, integ, mm.Platform.getPlatformByName("CPU"), {"Threads": str(threads)})
    x = mdsys.read_xyz(os.path.join(ROOT, directory, name + ".xyz"))[1]
    v = mdsys.read_xyz(os.path.join(ROOT, directory, name + ".vel.xyz"))[1]
    ctx.setPositions(x * mdsys.A2NM)
    ctx.setVelocities(v * mdsys.V_A_FS_TO_NM_PS)
    integ.step(2)  # first steps build the neighbour list and compile kernels
    start = time.perf_counter()
    integ.step(steps)
    ctx.getState(getEnergy=True)  # waits for the steps to finish
    return steps / (time.perf_counter() - start)


RUNNERS = {"longstep": run_longstep, "gromacs": run_gromacs, "lammps": run_lammps,
           "openmm": run_openmm}
# Each code with the precisions it runs: GROMACS both (gmx, gmx_d), LAMMPS double only,
# OpenMM's CPU platform its own mixed precision only.
PRECISIONS = {"longstep": ["double", "mixed"], "gromacs": ["mixed", "double"],
              "lammps": ["double"], "openmm": ["mixed"]}


def install(codes):
    """Install what is missing: OpenMM by pip, the rest by apt-get."""
    missing = []
    if "gromacs" in codes and not (shutil.which("gmx") and shutil.which("gmx_d")):
        missing.append("gromacs")
    if "lammps" in codes and not shutil.which("lmp"):
        missing.append("lammps")
    if "lammps" in codes and not shutil.which("mpirun"):
        missing.append("openmpi-bin")
    if missing:
        print("installing %s with apt-get" % " ".join(missing), flush=True)
        subprocess.run(["apt-get", "update", "-qq"], check=True)
        subprocess.run(["apt-get", "install", "-y", "-qq"] + missing, check=True)
    if "openmm" in codes:
        try:
            import openmm  # noqa: F401
        except ImportError:
            print("installing openmm with pip", flush=True)
            subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "openmm", "numpy"],
                           check=True)


def versions(codes):
    out = []
    if "gromacs" in codes:
        line = sh(["gmx", "--version"]).stdout
        m = re.search(r"GROMACS version:\s+(\S+)", line)
        simd = re.search(r"SIMD instructions:\s+(\S+)", line)
        out.append("GROMACS %s (SIMD %s)" % (m.group(1) if m else "?", simd.group(1) if simd else "?"))
    if "lammps" in codes:
        m = re.search(r"Simulator - (.+)", sh(["lmp", "-h"]).stdout)
        out.append("LAMMPS %s" % (m.group(1) if m else "?"))
    if "openmm" in codes:
        import openmm
        out.append("OpenMM %s" % openmm.__version__)
    commit = sh(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT).stdout.strip()
    out.append("longstep %s" % (commit or "?"))
    return ", ".join(out)


def configurations(args):
    for atoms in args.sizes:
        for threads in args.threads:
            for h in args.h:
                yield atoms, threads, h


def sitting(args):
    """Every configuration, codes interleaved within each repeat; returns the rows."""
    rows = []
    for atoms, threads, h in configurations(args):
        k = round(h / INNER)
        runs = [(c, p) for c in args.codes for p in PRECISIONS[c] if p in args.precisions]
        speeds = {r: [] for r in runs}
        for repeat in range(args.repeats):
            for code, precision in runs:
                steps = max(2 * k, int(STEPS[code][atoms] * args.steps_factor))
                try:
                    speed = RUNNERS[code](atoms, h, k, steps, threads, precision)
                except (RuntimeError, OSError) as e:
                    print("  %s %s failed: %s" % (code, precision, e), flush=True)
                    continue
                speeds[(code, precision)].append(speed)
                print("  %5d atoms  %d thr  %g/%g fs  %-8s %-6s run %d: %9.2f outer steps/s" % (
                    atoms, threads, h, INNER, code, precision, repeat + 1, speed), flush=True)
        for (code, precision), values in speeds.items():
            if values:
                rows.append({"atoms": atoms, "threads": threads, "h_fs": h, "inner_fs": INNER,
                             "code": code, "precision": precision, "runs": values,
                             "median": statistics.median(values)})
        report(rows, atoms, threads, h)
    return rows


def report(rows, atoms, threads, h):
    here = [r for r in rows if (r["atoms"], r["threads"], r["h_fs"]) == (atoms, threads, h)]
    print("\n%d atoms, %d thread(s), impulse %g fs / %g fs: outer steps/s, median of %s" % (
        atoms, threads, h, INNER, "/".join(str(len(r["runs"])) for r in here)))
    for r in here:
        print("  %-8s %-6s %9.2f  (runs %s)  %7.1f ns/day  %6.3f us per atom and step" % (
            r["code"], r["precision"], r["median"], ", ".join("%.2f" % v for v in r["runs"]),
            r["median"] * h * 86400e-6, 1e6 / (r["median"] * atoms)))
    peers = [r for r in here if r["code"] != "longstep"]
    for ours in (r for r in here if r["code"] == "longstep"):
        ratios = ["%s %s %.2f" % (p["code"], p["precision"], ours["median"] / p["median"])
                  for p in peers]
        fastest = max(peers, key=lambda p: p["median"]) if peers else None
        print("  longstep %-6s / peer: %s%s" % (
            ours["precision"], ", ".join(ratios),
            "; / fastest (%s %s): %.2f" % (fastest["code"], fastest["precision"],
                                          ours["median"] / fastest["median"]) if fastest else ""))
    print(flush=True)


def scaling_summary(rows):
    """Cost per atom and outer step of longstep, 5184 against 648 atoms, and 2 threads against 1."""
    def median(atoms, threads, h, precision):
        for r in rows:
            if (r["code"], r["atoms"], r["threads"], r["h_fs"], r["precision"]) == (
                    "longstep", atoms, threads, h, precision):
                return r["median"]
        return None
    print("longstep summary")
    for h in sorted({r["h_fs"] for r in rows}):
        for precision in ("double", "mixed"):
            small, large = median(648, 1, h, precision), median(5184, 1, h, precision)
            if small and large:
                print("  %g fs %-6s: cost per atom and step, 5184 / 648 atoms: %.2f" % (
                    h, precision, (small * 648) / (large * 5184)))
            for atoms in (648, 5184):
                one, two = median(atoms, 1, h, precision), median(atoms, 2, h, precision)
                if one and two:
                    print("  %g fs %-6s: %5d atoms, 2 threads / 1 thread: %.2f" % (
                        h, precision, atoms, two / one))


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog=__doc__.split("\n", 1)[1])
    ints = lambda s: [int(x) for x in s.split(",")]
    floats = lambda s: [float(x) for x in s.split(",")]
    words = lambda s: s.split(",")
    ap.add_argument("--sizes", type=ints, default=[648, 5184], help="atoms: 648 and/or 5184")
    ap.add_argument("--threads", type=ints, default=[1, 2])
    ap.add_argument("--h", type=floats, default=[4.0, 2.0], help="outer steps in fs (inner 0.5)")
    ap.add_argument("--codes", type=words, default=["longstep", "gromacs", "lammps", "openmm"])
    ap.add_argument("--precisions", type=words, default=["double", "mixed"])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--steps-factor", type=float, default=1.0,
                    help="scale every run's number of outer steps")
    ap.add_argument("--quick", action="store_true",
                    help="smoke test: one repeat, 1/20 of the steps")
    ap.add_argument("--no-install", dest="install", action="store_false")
    ap.add_argument("--json", help="also write every run to this file")
    args = ap.parse_args()
    if args.quick:
        args.repeats, args.steps_factor = 1, args.steps_factor / 20.0
    for atoms in args.sizes:
        if atoms not in SYSTEMS:
            ap.error("--sizes: %d atoms is not one of %s" % (atoms, sorted(SYSTEMS)))
    for code in args.codes:
        if code not in RUNNERS:
            ap.error("--codes: unknown code %s (%s)" % (code, ", ".join(RUNNERS)))
    for h in args.h:
        if abs(h / INNER - round(h / INNER)) > 1e-9 or h < INNER:
            ap.error("--h: %g fs is not a whole number of %g fs inner steps" % (h, INNER))
    return args


def main():
    args = parse_args()
    if not os.path.exists(BIN):
        sys.exit("no release build at %s: run `cargo build --release` first" % BIN)
    if args.install:
        install(args.codes)
    cpu = open("/proc/cpuinfo").read().split("model name")[1].split(":")[1].split("\n")[0].strip()
    print("machine: %s, %d cores, load average %s; %s; %s" % (
        cpu, os.cpu_count(), " ".join("%.2f" % x for x in os.getloadavg()), versions(args.codes),
        time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())), flush=True)
    start = time.time()
    rows = sitting(args)
    scaling_summary(rows)
    print("sitting took %.0f s" % (time.time() - start))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
