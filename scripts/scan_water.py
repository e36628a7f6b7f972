#!/usr/bin/env python3
"""Stability scan of MTS methods on the 216-water box over the outer step h.

For each method and h (inner step dt = 0.5 fs, NVE from the kit's 300 K velocities) run
`longstep run systems/water-box/scene.toml` for T ps, read energy.csv and report
  drift  = slope of a least-squares line through E(t), in kT/ns/dof
           (kT at 300 K, dof = 3N - 3 = 1941 as the kit counts them),
  max |E - E0| in kT/dof, the fit offset, T at the start and end, and whether it blew up.
Stable (the issue's criterion, as the peer kit's RESULTS.md): no blow-up and
|drift| <= 0.05 kT/ns/dof; the kit also asks max |E - E0| <= 0.05 kT/dof, shown as well.

    python3 scripts/scan_water.py                         # impulse and long-average, 20 ps
    python3 scripts/scan_water.py --methods long-average --steps 6,8,10 --ps 20
    python3 scripts/scan_water.py --json out/scan.json

Energies are sampled every ~40 fs as in the kit. Needs a release build.
"""
import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, ".."))
BIN = os.path.join(ROOT, "target", "release", "longstep")
KB = 1.380649e-23 * 6.02214076e23 / 4184.0  # kcal/mol/K
KT = KB * 300.0
DOF = 3 * 648 - 3


def run(method, h, inner_dt, ps, extra, workdir):
    k = round(h / inner_dt)
    every = max(1, round(40.0 / h))
    out = os.path.join(workdir, "%s-%g" % (method, h))
    cmd = [BIN, "run", "systems/water-box/scene.toml", "--method", method,
           "--h", "%gfs" % h, "--inner", str(k), "--t-end", "%gps" % ps,
           "--energy-every", str(every), "--quiet", "--json", "--out", out] + extra
    res = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    summary = json.loads(res.stdout)
    t, e, ke, em = [], [], [], []
    with open(os.path.join(out, "energy.csv")) as f:
        for row in csv.DictReader(f):
            # Column names carry their unit in brackets (`t[fs]`): key by the name alone.
            row = {key.split("[")[0]: value for key, value in row.items()}
            t.append(float(row["t"]))
            e.append(float(row["total"]))
            ke.append(float(row["kinetic"]))
            em.append(float(row.get("mollified_total", row["total"])))
    blew = summary["status"] != "ok" or any(x != x for x in e)

    def fit(values):
        n = len(t)
        tm = sum(t) / n
        vm = sum(values) / n
        stt = sum((x - tm) ** 2 for x in t)
        slope = sum((x - tm) * (y - vm) for x, y in zip(t, values)) / stt if stt > 0 else float("nan")
        return slope, vm - slope * tm - values[0]

    slope, offset = fit(e)
    drift = slope * 1e6 / KT / DOF  # kcal/mol/fs -> kT/ns/dof
    mollified_drift = fit(em)[0] * 1e6 / KT / DOF
    max_dev = max(abs(y - e[0]) for y in e) / KT / DOF
    temp = lambda k: 2 * k / (DOF * KB)
    return {
        "method": method, "h_fs": h, "inner_steps": k, "ps": t[-1] / 1000.0,
        "status": summary["status"], "blew_up": blew,
        "drift_kT_per_ns_dof": drift, "max_abs_dE_kT_per_dof": max_dev,
        "mollified_drift_kT_per_ns_dof": mollified_drift,
        "fit_offset_kcal": offset, "T0": temp(ke[0]), "T_end": temp(ke[-1]),
        "wall_s": summary["wall_seconds"], "steps": summary["steps"],
        "stable": (not blew) and abs(drift) <= 0.05,
        "stable_kit": (not blew) and abs(drift) <= 0.05 and max_dev <= 0.05,
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--methods", default="impulse,long-average")
    ap.add_argument("--steps", default="1,2,3,4,5,6,8")
    ap.add_argument("--inner-dt", type=float, default=0.5)
    ap.add_argument("--ps", type=float, default=20.0)
    ap.add_argument("--json", help="also write the rows to this file")
    ap.add_argument("extra", nargs="*", help="more longstep flags after --")
    args = ap.parse_args()
    rows = []
    print("%-14s %6s %4s %7s %14s %12s %10s %12s %8s %6s %s" % (
        "method", "h fs", "K", "ps", "drift kT/ns/df", "max|dE| kT/df", "offset", "moll. drift",
        "T0->T", "wall", "stable"))
    with tempfile.TemporaryDirectory() as workdir:
        for method in args.methods.split(","):
            for h in [float(x) for x in args.steps.split(",")]:
                r = run(method, h, args.inner_dt, args.ps, args.extra, workdir)
                rows.append(r)
                print("%-14s %6g %4d %7.2f %14.4g %12.4g %10.4g %12.4g %4.0f->%-4.0f %6.1f %s%s" % (
                    method, h, r["inner_steps"], r["ps"], r["drift_kT_per_ns_dof"],
                    r["max_abs_dE_kT_per_dof"], r["fit_offset_kcal"],
                    r["mollified_drift_kT_per_ns_dof"], r["T0"], r["T_end"],
                    r["wall_s"], "yes" if r["stable"] else "no",
                    " (BLEW UP)" if r["blew_up"] else ""), flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)
    for method in args.methods.split(","):
        largest = None
        for r in sorted((r for r in rows if r["method"] == method), key=lambda r: r["h_fs"]):
            if not r["stable"]:
                break
            largest = r["h_fs"]
        print("largest stable h (contiguous from the smallest), %s: %s fs" % (method, largest))


if __name__ == "__main__":
    sys.exit(main())
