#!/usr/bin/env python3
"""Wall time per outer step of several methods on one scene, runs interleaved.

Every repeat runs each method once, in turn, so a change of machine load hits all methods
alike; the script prints every run, the median per method and each median's ratio to the
first method's. Run from a clone after `cargo build --release`, e.g.

    RAYON_NUM_THREADS=1 python3 scripts/interleaved_cost.py systems/water-box/scene.toml \
        --h 4fs --inner 8 --t-end 2ps --repeats 5 \
        --method impulse \
        --method "equilibrium-molly --molly-constraints bonds" \
        --method "equilibrium-molly --molly-constraints bonds-angles" \
        --method long-average
"""

import argparse
import json
import shlex
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
LONGSTEP = ROOT / "target" / "release" / "longstep"


def one_run(scene, method, common, out):
    words = shlex.split(method)
    command = [str(LONGSTEP), "run", scene, "--method", *words, *common, "--json", "--quiet",
               "--energy-every", "100", "--drift-bound", "1e9", "--force", "--out", out]
    done = subprocess.run(command, capture_output=True, text=True)
    if done.returncode not in (0, 3):
        sys.exit(f"{' '.join(command)} failed:\n{done.stderr}")
    summary = json.loads(done.stdout)
    return summary["wall_seconds"] / summary["steps"], summary["status"]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene")
    parser.add_argument("--method", action="append", required=True,
                        help="a method and its flags, quoted (repeat; the first is the baseline)")
    parser.add_argument("--h", required=True)
    parser.add_argument("--inner", required=True)
    parser.add_argument("--t-end", required=True)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    if not LONGSTEP.exists():
        sys.exit(f"{LONGSTEP} not found: run `cargo build --release` first")
    common = ["--h", args.h, "--inner", args.inner, "--t-end", args.t_end]
    times = {m: [] for m in args.method}
    with tempfile.TemporaryDirectory() as scratch:
        for repeat in range(args.repeats):
            for k, method in enumerate(args.method):
                per_step, status = one_run(args.scene, method, common, f"{scratch}/{k}")
                times[method].append(per_step)
                print(f"run {repeat + 1} {method:55s} {per_step * 1e3:9.4f} ms/step  {status}")
    base = statistics.median(times[args.method[0]])
    print(f"\nmedians over {args.repeats} interleaved repeats (ms per outer step, ratio to "
          f"{args.method[0]}):")
    for method in args.method:
        median = statistics.median(times[method])
        print(f"  {method:55s} {median * 1e3:9.4f}  {median / base:6.3f}x")


if __name__ == "__main__":
    main()
