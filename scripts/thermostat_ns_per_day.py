#!/usr/bin/env python3
"""ns/day of the thermostatted methods at their largest passing steps, runs interleaved.

The cases of docs/thermostats.md, "ns/day of valid sampling": each repeat runs every case
once, in turn, so a change of machine load hits all alike. Prints every run (wall time from
the run's JSON summary — its stepping loop, without loading and set-up — and the user CPU
time of the whole process), the median per case, its ns/day and its ratio to the langevin-respa case of the same
box. Run from a clone after `cargo build --release`:

    RAYON_NUM_THREADS=1 python3 scripts/thermostat_ns_per_day.py --repeats 3

`--box 15` keeps one box's cases and `--ps T` runs every case for T picoseconds (the
README's headline: `--box 15 --ps 10 --repeats 5`). Each repeat's ratio to the box's
baseline in the same repeat is printed too, and their range beside the median.
"""

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
LONGSTEP = ROOT / "target" / "release" / "longstep"
NINE = "systems/water-box/scene.toml"
NINE_SPLIT = "systems/water-box/three-level.toml"
TWELVE = "systems/water-box/long-cutoff.toml"
TWELVE_SPLIT = "systems/water-box/long-cutoff-three-level-wide.toml"
FIFTEEN = "systems/water-box/long-cutoff-15.toml"
FIFTEEN_SPLIT = "systems/water-box/long-cutoff-15-three-level-wide.toml"
SINR = "--method sinr --thermostats 1 --temperature 300K --tau"
LANGEVIN = "--method langevin-respa --temperature 300K"


def langevin(box, scene, h, inner, ps):
    """langevin-respa at outer step `h` fs with `inner` bonded steps, `ps` picoseconds."""
    return (box, f"langevin-respa {h} fs / {h / inner:g} fs", scene,
            f"{LANGEVIN} --h {h}fs --inner {inner}", ps)


def sinr(box, scene, h, levels, tau, ps):
    """SIN(R) at outer step `h` fs, `--level-steps levels`, τ = `tau` fs."""
    return (box, f"sinr {h} fs ({levels}), tau {tau} fs", scene,
            f"{SINR} {tau}fs --h {h}fs --level-steps {levels}", ps)


# The SIN(R) configurations of the 12 and 15 A boxes: (outer step in fs, level steps).
LONG_CUTOFF_SINR = [(48, "16,3"), (96, "32,3"), (96, "32,2")]

# (box, label, scene, flags, --t-end in ps); the first case of each box is its baseline.
CASES = [
    langevin("9 A", NINE, 1, 2, 5),
    sinr("9 A", NINE_SPLIT, 50, "25,2", 5, 5),
    sinr("9 A", NINE_SPLIT, 48, "16,3", 3, 5),
    langevin("12 A", TWELVE, 2, 4, 1),
    sinr("12 A", TWELVE_SPLIT, 50, "25,2", 5, 1),
    *[sinr("12 A", TWELVE_SPLIT, h, levels, 3, 1) for h, levels in LONG_CUTOFF_SINR],
    langevin("15 A", FIFTEEN, 2, 4, 1),
    *[sinr("15 A", FIFTEEN_SPLIT, h, levels, 3, 1) for h, levels in LONG_CUTOFF_SINR],
]


def one_run(scene, flags, ps, out):
    command = [str(LONGSTEP), "run", scene, *flags.split(), "--t-end", f"{ps}ps",
               "--json", "--quiet", "--force", "--out", out]
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_utime
    done = subprocess.run(command, capture_output=True, text=True)
    user = resource.getrusage(resource.RUSAGE_CHILDREN).ru_utime - before
    if done.returncode != 0:
        sys.exit(f"{' '.join(command)} failed:\n{done.stderr}")
    summary = json.loads(done.stdout)
    # The run ends at the first whole outer step at or past --t-end (1.008 ps for 1 ps at
    # 48 fs): ns/day is of the time it simulated, `t_end` in fs.
    return summary["wall_seconds"], user, summary["status"], summary["t_end"] * 1e-3


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--box", choices=["9", "12", "15"],
                        help="only this box's cases (its baseline first)")
    parser.add_argument("--ps", type=float,
                        help="simulated time of every case, in ps (default: each case's own)")
    args = parser.parse_args()
    cases = [(box, label, scene, flags, args.ps or ps)
             for box, label, scene, flags, ps in CASES
             if args.box is None or box == f"{args.box} A"]
    if not LONGSTEP.exists():
        sys.exit(f"{LONGSTEP} not found: run `cargo build --release` first")
    print(f"# RAYON_NUM_THREADS={os.environ.get('RAYON_NUM_THREADS', '(unset)')}, "
          f"load before: {os.getloadavg()[0]:.2f}")
    for k, (box, label, scene, flags, ps) in enumerate(cases, 1):
        print(f"# case {k} ({box}): longstep run {scene} {flags} --t-end {ps}ps")
    walls = [[] for _ in cases]
    simulated = [0.0 for _ in cases]
    with tempfile.TemporaryDirectory() as scratch:
        for repeat in range(1, args.repeats + 1):
            for k, (_, _, scene, flags, ps) in enumerate(cases):
                wall, user, status, simulated[k] = one_run(scene, flags, ps, f"{scratch}/{k}")
                walls[k].append(wall)
                print(f"run {repeat} case {k + 1} wall_s {wall:.3f} user_s {user:.2f} "
                      f"simulated_ps {simulated[k]:.3f} {status}")
    print(f"\n# load after: {os.getloadavg()[0]:.2f}")
    print("box  case                             median wall s (runs)          ns/day  ratio"
          "  (range over repeats)")
    baseline = {}
    for k, (box, label, _, _, _) in enumerate(cases):
        median = statistics.median(walls[k])
        ns_per_day = simulated[k] * 1e-3 * 86400 / median
        first = baseline.setdefault(box, (k, ns_per_day))
        # Per repeat: the case's ns/day over its baseline's in the same repeat.
        base_k = first[0]
        ratios = [(simulated[k] / w) / (simulated[base_k] / b)
                  for w, b in zip(walls[k], walls[base_k])]
        runs = ", ".join(f"{w:.2f}" for w in walls[k])
        print(f"{box:4s} {label:32s} {median:7.2f} ({runs})  {ns_per_day:7.1f}  "
              f"{ns_per_day / first[1]:.2f}x  ({min(ratios):.2f}-{max(ratios):.2f})")

if __name__ == "__main__":
    main()
