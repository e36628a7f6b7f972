#!/usr/bin/env python3
"""Head-to-head throughput: longstep vs OpenMM (CPU platform) vs LAMMPS on the kit's water box.

Same system (the kit's 216 SPC/Fw waters: coordinates, seeded velocities, LJ + shifted-force
Coulomb at 9 Å, all intramolecular pairs excluded), same integrator (impulse r-RESPA: bonds and
angles inner at 0.5 fs, non-bonded outer at h), NVE, interleaved runs (longstep, OpenMM,
LAMMPS, repeated) so all codes see the same machine load; medians of the repeats.

  longstep : `longstep run systems/water-box/scene.toml --method impulse --h H --inner K`,
             wall time of the stepping loop from the JSON summary, RAYON_NUM_THREADS = threads
  OpenMM   : the kit's mdsys.build_openmm_system (CustomNonbondedForce, identical model),
             MTSIntegrator(h, [(1, 1), (0, K)]), CPU platform, Threads = threads; integ.step(n)
  LAMMPS   : the kit's lammps/in.md with run_style respa 2 K bond 1 angle 1 pair 2 ("Loop time"
             from the log); 2 threads = mpirun -np 2 (the Debian build has no OpenMP package)

Reported: outer steps/s, ns/day, (E_end - E0)/t in kT/ns/dof over the run (short runs: this
is dominated by the initial energy jump, see scripts/scan_water.py for drift), the ratio to the
faster peer, and non-bonded pair interactions (pairs within the cutoff) per second per core.

    python3 scripts/bench_vs_openmm.py                      # h = 2, 4, 6 fs; 1 and 2 threads
    python3 scripts/bench_vs_openmm.py --scaling            # longstep (and OpenMM) 648 -> 41k atoms
    python3 scripts/bench_vs_openmm.py --steps 400 --repeats 3 --json out/bench.json

Needs `pip install openmm numpy`, `apt-get install -y lammps`, a release build, and the kit in
../shared/anchors/md.
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

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, ".."))
BIN = os.path.join(ROOT, "target", "release", "longstep")
KIT = os.path.abspath(os.path.join(ROOT, "..", "shared", "anchors", "md"))
sys.path.insert(0, KIT)
KB = 1.380649e-23 * 6.02214076e23 / 4184.0
INNER = 0.5


def kt_per_ns_dof(e0, e1, t_fs, n_atoms):
    return (e1 - e0) / (t_fs * 1e-6) / (KB * 300.0) / (3 * n_atoms - 3)


def pairs_within_cutoff(xyz_path, box, rc=9.0):
    """Non-bonded pairs within the cutoff (intramolecular water pairs excluded)."""
    import mdsys
    _, x = mdsys.read_xyz(xyz_path)
    n = len(x)
    L = np.array(box)
    count = 0
    for i0 in range(0, n, 512):
        d = x[None, :, :] - x[i0:i0 + 512, None, :]
        d -= L * np.round(d / L)
        r2 = (d * d).sum(axis=2)
        ii = np.arange(i0, min(n, i0 + 512))[:, None]
        jj = np.arange(n)[None, :]
        mask = (jj > ii) & (r2 < rc * rc) & (jj // 3 != ii // 3)
        count += int(mask.sum())
    return count


def run_longstep(scene, h, k, steps, threads):
    with tempfile.TemporaryDirectory() as out:
        env = dict(os.environ, RAYON_NUM_THREADS=str(threads))
        cmd = [BIN, "run", scene, "--method", "impulse", "--h", "%gfs" % h, "--inner", str(k),
               "--t-end", "%gfs" % (h * steps), "--energy-every", str(steps),
               "--trajectory-every", str(10 * steps), "--quiet", "--json", "--out", out]
        res = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, env=env)
        s = json.loads(res.stdout)
        return {"steps_per_s": s["steps"] / s["wall_seconds"], "e0": s["energy"]["initial"],
                "e1": s["energy"]["final"], "t_fs": s["t_end"], "status": s["status"]}


def run_openmm(name, h, k, steps, threads, positions=None, velocities=None, box=None):
    import mdsys
    import openmm as mm
    import openmm.unit as u
    p = mdsys.load_params(name)
    if box is not None:
        p = dict(p)
        p["box"] = box
    system = mdsys.build_openmm_system(p, "identical")
    if positions is not None:
        n_rep = len(positions) // p["n_atoms"]
        # Replicated box: copy particles, bonds, angles and exclusions of the base system.
        system = replicate_openmm(p, n_rep, box)
    integ = mm.MTSIntegrator(h * 1e-3, [(1, 1), (0, k)])
    ctx = mm.Context(system, integ, mm.Platform.getPlatformByName("CPU"), {"Threads": str(threads)})
    x = mdsys.load_positions(name) if positions is None else positions
    v = mdsys.load_velocities(name) if velocities is None else velocities
    ctx.setPositions(x * mdsys.A2NM)
    ctx.setVelocities(v * mdsys.V_A_FS_TO_NM_PS)

    def energy():
        st = ctx.getState(getEnergy=True)
        return (st.getPotentialEnergy() + st.getKineticEnergy()).value_in_unit(u.kilojoule_per_mole) / mdsys.KCAL

    integ.step(2)
    e0 = energy()
    t = time.perf_counter()
    integ.step(steps)
    wall = time.perf_counter() - t
    e1 = energy()
    return {"steps_per_s": steps / wall, "e0": e0, "e1": e1, "t_fs": h * steps, "status": "ok"}


def replicate_openmm(p, n_rep, box):
    """The kit's water model for n_rep copies of its molecules (positions given separately)."""
    import mdsys
    q = dict(p)
    n = p["n_atoms"]
    q["n_atoms"] = n * n_rep
    q["atom_type_of"] = p["atom_type_of"] * n_rep
    q["bonds"] = [[i + r * n, j + r * n, t] for r in range(n_rep) for i, j, t in p["bonds"]]
    q["angles"] = [[i + r * n, j + r * n, k + r * n, t] for r in range(n_rep) for i, j, k, t in p["angles"]]
    q["exclusion_pairs"] = [[i + r * n, j + r * n] for r in range(n_rep) for i, j in p["exclusion_pairs"]]
    q["box"] = box
    return mdsys.build_openmm_system(q, "identical")


def run_lammps(name, h, k, steps, threads):
    with tempfile.TemporaryDirectory() as out:
        log = os.path.join(out, "log")
        lmp = ["lmp", "-nocite", "-screen", "none", "-var", "sys", name, "-var", "integ", "respa",
               "-var", "dt", str(h), "-var", "k", str(k), "-var", "nsteps", str(steps),
               "-var", "thermo", str(steps), "-in", "in.md", "-log", log]
        if threads > 1:
            lmp = ["mpirun", "-np", str(threads), "--bind-to", "core"] + lmp
        env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
                   OMP_NUM_THREADS="1")
        subprocess.run(lmp, cwd=os.path.join(KIT, "lammps"), env=env, check=True,
                       stdin=subprocess.DEVNULL, capture_output=True)
        text = open(log).read()
        loop = float(re.search(r"Loop time of ([0-9.eE+-]+) on", text).group(1))
        rows = re.findall(r"^\s*(\d+)\s+([-0-9.eE+]+(?:\s+[-0-9.eE+]+){8})\s*$", text, re.M)
        vals = [list(map(float, r[1].split())) for r in rows]
        # thermo: step time temp pe ke etotal ebond eangle evdwl ecoul
        e0, e1 = vals[0][4], vals[-1][4]
        return {"steps_per_s": steps / loop, "e0": e0, "e1": e1, "t_fs": h * steps, "status": "ok"}


def head_to_head(args):
    rows = []
    box = json.load(open(os.path.join(KIT, "systems", "water216.json")))["box"]
    pairs = pairs_within_cutoff(os.path.join(KIT, "systems", "water216.xyz"), box)
    print("water216: 648 atoms, %d non-bonded pairs within 9 A" % pairs)
    codes = ["longstep", "openmm", "lammps"]
    for threads in [int(t) for t in args.threads.split(",")]:
        for h in [float(x) for x in args.h.split(",")]:
            k = round(h / INNER)
            steps = args.steps
            results = {c: [] for c in codes}
            for _ in range(args.repeats):
                results["longstep"].append(run_longstep("systems/water-box/scene.toml", h, k, steps, threads))
                results["openmm"].append(run_openmm("water216", h, k, steps, threads))
                if shutil.which("lmp"):
                    results["lammps"].append(run_lammps("water216", h, k, steps, threads))
            for code in codes:
                if not results[code]:
                    continue
                speeds = [r["steps_per_s"] for r in results[code]]
                med = statistics.median(speeds)
                r0 = results[code][0]
                rows.append({
                    "code": code, "threads": threads, "h_fs": h, "inner_steps": k, "steps": steps,
                    "steps_per_s": med, "all": speeds, "ns_per_day": med * h * 86400 * 1e-6,
                    "dE_kT_per_ns_dof": kt_per_ns_dof(r0["e0"], r0["e1"], r0["t_fs"], 648),
                    "pairs_per_s_per_core": med * pairs / threads,
                })
            peers = [r for r in rows[-3:] if r["code"] != "longstep"]
            ours = [r for r in rows[-3:] if r["code"] == "longstep"][0]
            best = max(p["steps_per_s"] for p in peers) if peers else float("nan")
            ours["ratio_to_faster_peer"] = ours["steps_per_s"] / best
            for r in rows[-3:]:
                print("%-9s threads %d  h %g fs / 0.5 fs  %8.1f outer steps/s (%s)  %7.2f ns/day  "
                      "(E1-E0)/t %9.3g kT/ns/dof  %.3g pairs/s/core%s" % (
                          r["code"], threads, h, r["steps_per_s"],
                          ", ".join("%.0f" % s for s in r["all"]), r["ns_per_day"],
                          r["dE_kT_per_ns_dof"], r["pairs_per_s_per_core"],
                          "  ratio %.2f" % r["ratio_to_faster_peer"] if "ratio_to_faster_peer" in r else ""),
                      flush=True)
    return rows


def replicated_scene(base_name, reps, workdir):
    """A longstep scene of the kit's box replicated reps^3 times (bonds listed, not guessed)."""
    import mdsys
    p = mdsys.load_params(base_name)
    elements, x = mdsys.read_xyz(mdsys.sys_path(base_name, ".xyz"))
    _, v = mdsys.read_xyz(mdsys.sys_path(base_name, ".vel.xyz"))
    L = np.array(p["box"])
    shifts = [np.array([a, b, c]) * L for a in range(reps) for b in range(reps) for c in range(reps)]
    X = np.concatenate([x + s for s in shifts])
    V = np.concatenate([v for _ in shifts])
    E = elements * len(shifts)
    box = [float(v) for v in L * reps]
    name = "%s-x%d" % (base_name, reps)
    mdsys.write_xyz(os.path.join(workdir, name + ".xyz"), E, X, "replicated")
    mdsys.write_xyz(os.path.join(workdir, name + ".vel.xyz"), E, V, "replicated velocities")
    with open(os.path.join(ROOT, "systems", "water-box", "scene.toml")) as f:
        text = f.read()
    text = re.sub(r"^box = .*$", "box = [%r, %r, %r]" % tuple(box), text, flags=re.M)
    text = text.replace('file = "water216.xyz"', 'file = "%s.xyz"\nguess_bonds = false\nbonds = [[0, 1], [0, 2]]\nbond_repeat = 3' % name)
    text = text.replace('velocities = "water216.vel.xyz"', 'velocities = "%s.vel.xyz"' % name)
    scene = os.path.join(workdir, name + ".toml")
    with open(scene, "w") as f:
        f.write(text)
    return scene, X, V, box


def scaling(args):
    rows = []
    with tempfile.TemporaryDirectory() as workdir:
        systems = [("water216", 1), ("water1728", 1), ("water1728", 2)]
        for base, reps in systems:
            scene, X, V, box = replicated_scene(base, reps, workdir)
            n = len(X)
            steps = max(10, int(args.scaling_atom_steps / n))
            for threads in [int(t) for t in args.threads.split(",")]:
                ls = statistics.median(
                    run_longstep(scene, 4.0, 8, steps, threads)["steps_per_s"] for _ in range(args.repeats))
                row = {"atoms": n, "threads": threads, "h_fs": 4.0, "steps": steps, "longstep_steps_per_s": ls,
                       "longstep_us_per_atom_step": 1e6 / (ls * n)}
                if n <= args.openmm_max_atoms:
                    om = run_openmm(base, 4.0, 8, max(5, steps // 4), threads,
                                    positions=X if reps > 1 else None, velocities=V if reps > 1 else None,
                                    box=box if reps > 1 else None)["steps_per_s"]
                    row["openmm_steps_per_s"] = om
                    row["ratio"] = ls / om
                rows.append(row)
                print("%6d atoms  threads %d  longstep %8.2f outer steps/s (%.3f us per atom-step)%s" % (
                    n, threads, ls, row["longstep_us_per_atom_step"],
                    "  OpenMM %.2f  ratio %.2f" % (row["openmm_steps_per_s"], row["ratio"]) if "ratio" in row else ""),
                      flush=True)
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--h", default="2,4,6")
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--steps", type=int, default=600)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--scaling", action="store_true")
    ap.add_argument("--scaling-atom-steps", type=float, default=2.0e6,
                    help="atoms x outer steps per scaling run")
    ap.add_argument("--openmm-max-atoms", type=int, default=50000)
    ap.add_argument("--json")
    args = ap.parse_args()
    import openmm
    print("machine: %s, %d cores; OpenMM %s; %s" % (
        open("/proc/cpuinfo").read().split("model name")[1].split(":")[1].split("\n")[0].strip(),
        os.cpu_count(), openmm.__version__, time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())))
    out = {"scaling": scaling(args)} if args.scaling else {"head_to_head": head_to_head(args)}
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
