#!/usr/bin/env python3
"""Wall time per outer step of two longstep builds on the scenes a refactor could slow,
runs interleaved (each repeat runs every case with both builds, in turn), one thread.

Prints every run in ms per outer step, the medians and after/before. Run from a clone:

    python3 scripts/build_against_build.py BEFORE_BINARY AFTER_BINARY --repeats 9
    python3 scripts/build_against_build.py BEFORE AFTER --repeats 11 --after-first --cases three-level-648,dipeptide-split-molecule
"""

import argparse
import json
import os
import shlex
import statistics
import subprocess
import sys
import tempfile

CASES = {
    "dsf-648-mixed": "systems/water-box/scene.toml --method impulse --h 2fs --inner 4 --t-end 4ps --precision mixed",
    "pme-648": "systems/water-box/pme.toml --method impulse --h 1fs --inner 2 --t-end 2ps",
    "pme-5184-mixed": "systems/water-box-1728/scene.toml --coulomb pme --method impulse --h 1fs --inner 2 --t-end 0.4ps --precision mixed",
    "three-level-648": "systems/water-box/three-level.toml --method impulse --h 2fs --level-steps 2,2 --t-end 2ps",
    "dipeptide-split-molecule": "systems/alanine-dipeptide-amber/ala2-solvated-pme.toml --split r_in=5,r_out=6,by=molecule,short_level=0,remainder_level=1 --method impulse --h 2fs --inner 2 --t-end 1ps",
}


def ms_per_step(binary, args):
    with tempfile.TemporaryDirectory() as d:
        cmd = [binary, "run", *shlex.split(args), "--json", "--quiet", "--energy-every", "100",
               "--drift-bound", "1e9", "--out", os.path.join(d, "out")]
        env = dict(os.environ, RAYON_NUM_THREADS="1")
        done = subprocess.run(cmd, capture_output=True, text=True, env=env)
        if done.returncode not in (0, 3):
            sys.exit(f"{' '.join(cmd)} failed:\n{done.stderr}")
        summary = json.loads(done.stdout)
        return 1e3 * summary["wall_seconds"] / summary["steps"]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("before")
    parser.add_argument("after")
    parser.add_argument("--repeats", type=int, default=9)
    parser.add_argument("--after-first", action="store_true", help="run the after build first in each pair")
    parser.add_argument("--cases", default=",".join(CASES), help="comma-separated names from: " + ", ".join(CASES))
    a = parser.parse_args()
    names = a.cases.split(",")
    for name in names:
        if name not in CASES:
            sys.exit(f"unknown case {name!r}; known: {', '.join(CASES)}")
    order = [("after", a.after), ("before", a.before)] if a.after_first else [("before", a.before), ("after", a.after)]
    runs = {(n, side): [] for n in names for side in ("before", "after")}
    for _ in range(a.repeats):
        for name in names:
            for side, binary in order:
                runs[(name, side)].append(ms_per_step(binary, CASES[name]))
    print("case | before ms/step (runs) | after ms/step (runs) | after/before")
    for name in names:
        b, f = runs[(name, "before")], runs[(name, "after")]
        text = lambda v: ", ".join(f"{x:.4f}" for x in v)
        print(f"{name} | {statistics.median(b):.4f} ({text(b)}) | {statistics.median(f):.4f} ({text(f)}) | "
              f"{statistics.median(f) / statistics.median(b):.3f}")


if __name__ == "__main__":
    main()
