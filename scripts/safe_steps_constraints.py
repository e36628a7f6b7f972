#!/usr/bin/env python3
"""The largest NVE-safe outer step with and without constraints and HMR (issue 28, Done-when 3).

Runs `longstep run … --json` for each row and step below, one at a time, and judges each
drift by the run's own error bar: the drift verdict (src/run/drift.rs) fits a line to the
total energy and calls the drift resolved when the fitted change exceeds twice the rms
residual about the line, so the residual is the fitted change's standard error and
`σ = |drift| · residual / |change|` that of the rate (kT/ns/dof). A point passes when
`|drift| + 2σ ≤ 0.05`, fails when `|drift| − 2σ > 0.05` (or the run blows up), and is
undecided otherwise. The largest safe step of a row is its largest passing step below
every failing or undecided one.

    RAYON_NUM_THREADS=1 python3 scripts/safe_steps_constraints.py               # every row
    RAYON_NUM_THREADS=1 python3 scripts/safe_steps_constraints.py --only peptide
    RAYON_NUM_THREADS=1 python3 scripts/safe_steps_constraints.py --rows 7 8 --append

It writes docs/data/constraints/safe-steps.csv (one line per run, with its command) and
prints each verdict. The committed file was made in five sittings, one run at a time (rows
as numbered now): 0–6 and 11–13, then `--rows 7 8 9 10`, `--rows 18 19`, `--rows 16 17` and
`--rows 14 15`, each with `--append` (a plain run redoes them all in one). Needs a release build (`cargo build --release`).
Standard library only.
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
OUT = os.path.join(ROOT, "docs", "data", "constraints", "safe-steps.csv")
BOUND = 0.05

PEPTIDE = "systems/alanine-dipeptide-amber/ala2-solvated.toml"
PEPTIDE_TOP = "systems/alanine-dipeptide-amber/ala2-solvated.prmtop"
WATER = "systems/water-box/scene.toml"
CONSTRAINED = ["--constraints", "h-bonds", "--rigid-water"]
HMR = CONSTRAINED + ["--hydrogen-mass", "3amu"]
PME = ["--coulomb", "pme", "--ewald-tolerance", "1e-6"]
SPLIT_PME = PME + ["--nonbonded-level", "0", "--pme-level", "1"]

# (system, row label, scene, method and flags, outer steps in fs, run length in ps)
ROWS = [
    ("peptide", "verlet, flexible", PEPTIDE, ["--method", "verlet"], [0.5, 1.0], 20),
    ("peptide", "verlet, h-bonds + rigid water", PEPTIDE,
     ["--method", "verlet"] + CONSTRAINED, [1.0, 2.0, 2.5], 40),
    ("peptide", "verlet, h-bonds + rigid water + HMR 3 amu", PEPTIDE,
     ["--method", "verlet"] + HMR, [3.0, 4.0, 5.0], 40),
    ("peptide", "impulse --inner 2 (reaction field at h), h-bonds + rigid water", PEPTIDE,
     ["--method", "impulse", "--inner", "2"] + CONSTRAINED, [4.0], 40),
    ("peptide", "impulse --inner 2 (reaction field at h), + HMR 3 amu", PEPTIDE,
     ["--method", "impulse", "--inner", "2"] + HMR, [6.0, 8.0], 40),
    ("peptide", "verlet, PME (real space to 1e-6), + HMR 3 amu", PEPTIDE_TOP,
     ["--method", "verlet"] + HMR + PME, [4.0], 40),
    ("peptide", "impulse --inner 2 (PME reciprocal at h), + HMR 3 amu", PEPTIDE_TOP,
     ["--method", "impulse", "--inner", "2"] + HMR + SPLIT_PME, [8.0], 40),
    ("peptide", "verlet, PME (real space to 1e-6), h-bonds + rigid water", PEPTIDE_TOP,
     ["--method", "verlet"] + CONSTRAINED + PME, [2.0, 2.5], 40),
    ("peptide", "verlet, PME (real space to 1e-6), + HMR 3 amu", PEPTIDE_TOP,
     ["--method", "verlet"] + HMR + PME, [5.0], 40),
    ("peptide", "impulse --inner 2 (PME reciprocal at h), h-bonds + rigid water", PEPTIDE_TOP,
     ["--method", "impulse", "--inner", "2"] + CONSTRAINED + SPLIT_PME, [4.0], 40),
    ("peptide", "impulse --inner 2 (PME reciprocal at h), + HMR 3 amu", PEPTIDE_TOP,
     ["--method", "impulse", "--inner", "2"] + HMR + SPLIT_PME, [6.0], 40),
    ("water", "verlet, flexible", WATER, ["--method", "verlet"], [0.5, 1.0, 1.5], 20),
    ("water", "verlet, rigid water", WATER, ["--method", "verlet", "--rigid-water"],
     [1.0, 2.0, 2.5, 4.0, 5.0], 40),
    ("water", "impulse --inner 2 (non-bonded at h), rigid water", WATER,
     ["--method", "impulse", "--inner", "2", "--rigid-water"], [4.0, 6.0], 40),
    # The undecided points again over 100 ps (σ shrinks as 1/T).
    ("peptide", "verlet, flexible", PEPTIDE, ["--method", "verlet"], [1.0], 100),
    ("water", "verlet, flexible", WATER, ["--method", "verlet"], [1.0], 100),
    ("peptide", "verlet, PME (real space to 1e-6), + HMR 3 amu", PEPTIDE_TOP,
     ["--method", "verlet"] + HMR + PME, [5.0], 100),
    ("peptide", "impulse --inner 2 (PME reciprocal at h), + HMR 3 amu", PEPTIDE_TOP,
     ["--method", "impulse", "--inner", "2"] + HMR + SPLIT_PME, [8.0], 100),
    ("water", "verlet, rigid water", WATER, ["--method", "verlet", "--rigid-water"],
     [4.0, 5.0], 100),
    ("water", "impulse --inner 2 (non-bonded at h), rigid water", WATER,
     ["--method", "impulse", "--inner", "2", "--rigid-water"], [4.0, 6.0], 100),
]


def command(scene, flags, h, t_end, out):
    # The peptide's topology coordinates sit near a minimum: start at 300 K and fit from 5 ps.
    start = ["--temperature", "300K"] if "alanine" in scene else []
    return ([BIN, "run", scene] + flags + start
            + ["--h", f"{h:g}fs", "--t-end", f"{t_end}ps", "--fit-from", "5ps",
               "--energy-every", "5", "--force", "--json", "--quiet", "--out", out])


def judge(summary):
    """(drift, σ, verdict) from a run's JSON summary."""
    drift = summary.get("drift")
    if summary.get("status", "ok") != "ok" or drift is None:
        return None, None, "fail (blows up)"
    value, change, residual = drift["value"], drift["change"], drift["fluctuation"]
    sigma = abs(value) * residual / abs(change) if change != 0 else float("inf")
    if abs(value) + 2 * sigma <= BOUND:
        verdict = "pass"
    elif abs(value) - 2 * sigma > BOUND:
        verdict = "fail"
    else:
        verdict = "undecided"
    return value, sigma, verdict


def run_point(scene, flags, h, t_end, workdir):
    out = os.path.join(workdir, "run")
    cmd = command(scene, flags, h, t_end, out)
    done = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    shown = " ".join(["longstep"] + cmd[1:-2])
    if done.returncode == 3:
        return shown, {"status": "blew up"}, None
    if done.returncode != 0:
        sys.exit(f"{shown}: exit {done.returncode}\n{done.stderr}")
    summary = json.loads(done.stdout)
    return shown, summary, summary.get("temperature", {}).get("degrees_of_freedom")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--only", choices=["peptide", "water"])
    parser.add_argument("--out", default=OUT)
    parser.add_argument("--rows", type=int, nargs="*",
                        help="run only these rows (0-based indices into ROWS)")
    parser.add_argument("--append", action="store_true", help="append to --out")
    args = parser.parse_args()
    lines = []
    with tempfile.TemporaryDirectory() as workdir:
        for index, (system, label, scene, flags, steps, t_end) in enumerate(ROWS):
            if args.only and system != args.only:
                continue
            if args.rows is not None and index not in args.rows:
                continue
            for h in steps:
                shown, summary, dof = run_point(scene, flags, h, t_end, workdir)
                value, sigma, verdict = judge(summary)
                line = {"system": system, "row": label, "h_fs": h, "t_end_ps": t_end,
                        "drift": value, "sigma": sigma, "verdict": verdict,
                        "degrees_of_freedom": dof, "command": shown}
                lines.append(line)
                shown_drift = "-" if value is None else f"{value:+.4f} ± {sigma:.4f}"
                print(f"{system:8s} {label:60s} {h:4g} fs  {shown_drift:20s} {verdict}",
                      flush=True)
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    append = args.append and os.path.exists(args.out)
    with open(args.out, "a" if append else "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(lines[0]))
        if not append:
            writer.writeheader()
        writer.writerows(lines)
    print("wrote", os.path.relpath(args.out, ROOT))


if __name__ == "__main__":
    main()
