#!/usr/bin/env python3
"""The equilibrium-mollifier study on the 216-water box (docs/performance.md).

For each variant and outer step h (inner step 0.5 fs, NVE from the kit's velocities) run

    longstep run systems/water-box/scene.toml --method M --h Hfs --inner K --t-end 20ps \\
        --energy-every E --fit-from 2ps --json [--molly-constraints C --molly-jacobian J]

and report longstep's own fitted drifts from its JSON summary (least-squares slope of the
energy against time over the rows from 2 ps on, in kT/ns/dof with kT = 2<K>/dof over those
rows): by the true energy K + V and by the conserved energy K + W(q) + U(A(q))
(`mollified_total`) where the method has one, and that drift fitted on each half of the
window separately (a rough error bar); the time reached (a blow-up stops the run
with exit 3 and its time), the mean temperature, and ns/day as the run measured it (wall
clock, on whatever else the machine was doing). Stable = no blow-up and |drift| <= 0.05
kT/ns/dof by the energy the method conserves (the true one for impulse).

    python3 scripts/molly_water.py                                  # every variant, 3-8 fs
    python3 scripts/molly_water.py --variants molly-bonds-exact --steps 4,5 --ps 20
    python3 scripts/molly_water.py --scene systems/polymer-melt/scene.toml --inner-dt 1 ...
    python3 scripts/molly_water.py --variants molly-bonds-angles-exact --steps 4 --seeds 4

A 20 ps drift from one start is one draw of a quantity that scatters from start to start
(and from build to build: a change in the forces' last bits changes a chaotic trajectory).
`--seeds N` runs every point also from N Maxwell-Boltzmann starts at 300 K (`--temperature
300K --seed 1..N`) and prints, per variant and step, the mean conserved drift over the starts
with its standard error; the largest stable step is then judged by that mean.

Variants: impulse, long-average, molly-{bonds,bonds-angles}-{exact,projection}.
Runs one simulation at a time. Needs a release build (or LONGSTEP=path).
"""
import argparse
import csv
import math
import statistics
import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, ".."))
BIN = os.environ.get("LONGSTEP", os.path.join(ROOT, "target", "release", "longstep"))
VARIANTS = ["impulse", "long-average"] + [
    "molly-%s-%s" % (c, j) for c in ("bonds", "bonds-angles") for j in ("exact", "projection")
]


def method_flags(variant):
    if not variant.startswith("molly-"):
        return ["--method", variant]
    rest = variant[len("molly-"):]
    constraints, jacobian = rest.rsplit("-", 1)
    return ["--method", "equilibrium-molly", "--molly-constraints", constraints,
            "--molly-jacobian", jacobian]


def halves(path, fit_from, dof):
    """Conserved-energy drift (kT/ns/dof) fitted separately on the two halves after
    fit_from: their spread is a rough error bar of the whole fit."""
    rows = []
    with open(path) as f:
        for row in csv.DictReader(f):
            row = {key.split("[")[0]: float(value) for key, value in row.items()}
            if row["t"] >= fit_from * 1000.0:
                rows.append((row["t"], row.get("mollified_total", row["total"]), row["kinetic"]))
    out = []
    for part in (rows[: len(rows) // 2], rows[len(rows) // 2:]):
        n = len(part)
        if n < 3:
            return None
        tm = sum(r[0] for r in part) / n
        em = sum(r[1] for r in part) / n
        kt = 2.0 * sum(r[2] for r in part) / n / dof
        slope = sum((r[0] - tm) * (r[1] - em) for r in part) / sum((r[0] - tm) ** 2 for r in part)
        out.append(slope * 1e6 / kt / dof)  # per fs -> per ns
    return out


def run(scene, variant, h, inner_dt, ps, fit_from, workdir, seed=None):
    k = round(h / inner_dt)
    every = max(1, round(40.0 / h))
    out = os.path.join(workdir, "%s-%g-%s" % (variant, h, seed))
    start = [] if seed is None else ["--temperature", "300K", "--seed", str(seed)]
    cmd = [BIN, "run", scene] + method_flags(variant) + [
        "--h", "%gfs" % h, "--inner", str(k), "--t-end", "%gps" % ps,
        "--energy-every", str(every), "--trajectory-every", "1000000000", "--fit-from", "%gps" % fit_from,
        ] + start + ["--quiet", "--json", "--out", out]
    res = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    try:
        summary = json.loads(res.stdout)
    except json.JSONDecodeError:
        sys.exit("no JSON from %s:\n%s" % (" ".join(cmd), res.stderr))
    drift = summary.get("drift") or {}
    t_reached = summary["steps"] * summary["h"] / 1000.0
    conserved = drift.get("conserved_energy")
    true = drift.get("true_energy")
    judged = conserved if conserved is not None else true
    ok = summary["status"] == "ok"
    dof = (summary.get("temperature") or {}).get("degrees_of_freedom")
    split = halves(os.path.join(out, "energy.csv"), fit_from, dof) if ok and dof else None
    return {
        "variant": variant, "h_fs": h, "inner_steps": k, "seed": seed, "ps": t_reached,
        "status": summary["status"], "exit": res.returncode,
        "true_drift": true if ok else None,
        "conserved_drift": conserved if ok else None,
        "conserved_drift_halves": split,
        "T_mean": (summary.get("temperature") or {}).get("mean"),
        "ns_per_day": summary.get("ns_per_day"),
        "mean_newton": (summary.get("mollifier") or {}).get("mean_newton_iterations"),
        "stable": ok and judged is not None and abs(judged) <= 0.05,
        "command": " ".join(["longstep"] + cmd[1:-2]),
    }


def fmt(x, spec="%.3g"):
    return "—" if x is None else spec % x


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scene", default="systems/water-box/scene.toml")
    ap.add_argument("--variants", default=",".join(VARIANTS))
    ap.add_argument("--steps", default="3,4,5,6,8")
    ap.add_argument("--inner-dt", type=float, default=0.5)
    ap.add_argument("--ps", type=float, default=20.0)
    ap.add_argument("--fit-from", type=float, default=2.0, help="ps")
    ap.add_argument("--seeds", type=int, default=0,
                    help="also run every point from Maxwell-Boltzmann starts with seeds 1..N")
    ap.add_argument("--json", help="also write the rows to this file")
    args = ap.parse_args()
    rows = []
    starts = [None] + list(range(1, args.seeds + 1))
    print("| variant | h (fs) | start | ps reached | true drift | conserved drift | its halves "
          "| ⟨T⟩ (K) | ns/day (noisy) | Newton its | stable |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as workdir:
        for variant in args.variants.split(","):
            for h in [float(x) for x in args.steps.split(",")]:
                for seed in starts:
                    r = run(args.scene, variant, h, args.inner_dt, args.ps, args.fit_from,
                            workdir, seed)
                    rows.append(r)
                    print_row(r)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)
    for variant in args.variants.split(","):
        print_largest(variant, [r for r in rows if r["variant"] == variant], args.seeds)


def print_row(r):
    status = "yes" if r["stable"] else (
        "no" if r["status"] == "ok" else "blew up at %.2f ps" % r["ps"])
    split = r["conserved_drift_halves"]
    print("| %s | %g | %s | %.2f | %s | %s | %s | %s | %s | %s | %s |" % (
        r["variant"], r["h_fs"], "kit" if r["seed"] is None else "seed %d" % r["seed"],
        r["ps"], fmt(r["true_drift"]), fmt(r["conserved_drift"]),
        "—" if split is None else "%.3g, %.3g" % tuple(split),
        fmt(r["T_mean"], "%.0f"), fmt(r["ns_per_day"], "%.0f"),
        fmt(r["mean_newton"], "%.2f"), status), flush=True)


def print_largest(variant, rows, seeds):
    """The largest stable step, contiguous from the smallest: from the kit's start alone,
    or (with seeds) by the mean over the starts, |mean| <= 0.05 with every start run through."""
    largest = None
    for h in sorted({r["h_fs"] for r in rows}):
        here = [r for r in rows if r["h_fs"] == h]
        if not seeds:
            if not here[0]["stable"]:
                break
        else:
            drifts = [r["conserved_drift"] if r["conserved_drift"] is not None else r["true_drift"]
                      for r in here]
            if any(d is None for d in drifts):
                print("%s at %g fs: a start blew up" % (variant, h))
                break
            mean = statistics.mean(drifts)
            sem = statistics.stdev(drifts) / math.sqrt(len(drifts))
            print("%s at %g fs: mean drift %.4f +- %.4f kT/ns/dof over %d starts" % (
                variant, h, mean, sem, len(drifts)))
            if abs(mean) > 0.05:
                break
        largest = h
    print("largest stable h (contiguous from the smallest%s), %s: %s fs" % (
        ", by the mean over the starts" if seeds else "", variant, largest))


if __name__ == "__main__":
    sys.exit(main())
