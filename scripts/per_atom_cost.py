#!/usr/bin/env python3
"""Wall time per atom and outer step of one method on several scenes, runs interleaved.

Every repeat runs each scene once, in turn, so a change of machine load hits all sizes
alike; the script prints every run, the median per scene and each median's ratio to the
previous scene's (issue 13: ≤ 1.3× from 648 to 5 184 atoms, ≤ 1.15× from 5 184 to 41 472).
Run from a clone after `cargo build --release`, e.g.

    python3 scripts/replicate_box.py systems/water-box-1728 2 out/water-box-41472
    RAYON_NUM_THREADS=1 python3 scripts/per_atom_cost.py --method impulse --h 4fs --inner 8 \\
        --steps 50 --repeats 3 systems/water-box/scene.toml \\
        systems/water-box-1728/scene.toml out/water-box-41472/scene.toml

`--steps` sets each scene's run to that many outer steps; the time includes loading the
scene and building its first neighbour list, as a user's run does.
"""

import argparse
import statistics
import sys
import tempfile
import tomllib
from pathlib import Path

from interleaved_cost import LONGSTEP, one_run


def atom_count(scene):
    """The atom count from the header of the scene's structure file."""
    path = Path(scene)
    structure = tomllib.loads(path.read_text()).get("structure", {})
    if "file" not in structure:
        sys.exit(f"{scene}: per-atom cost needs a scene with a [structure] file")
    return int((path.parent / structure["file"]).read_text().split()[0])


def parse_femtoseconds(text):
    if not text.endswith("fs"):
        sys.exit(f"--h {text}: give it in fs, e.g. 4fs")
    return float(text[:-2])


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="+")
    parser.add_argument("--method", default="impulse")
    parser.add_argument("--h", default="4fs")
    parser.add_argument("--inner", default="8")
    parser.add_argument("--steps", type=int, default=50)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    if not LONGSTEP.exists():
        sys.exit(f"{LONGSTEP} not found: run `cargo build --release` first")
    t_end = f"{parse_femtoseconds(args.h) * args.steps}fs"
    common = ["--h", args.h, "--inner", args.inner, "--t-end", t_end]
    atoms = {s: atom_count(s) for s in args.scenes}
    times = {s: [] for s in args.scenes}
    with tempfile.TemporaryDirectory() as scratch:
        for repeat in range(args.repeats):
            for k, scene in enumerate(args.scenes):
                per_step, status = one_run(scene, args.method, common, f"{scratch}/{k}")
                per_atom = per_step / atoms[scene]
                times[scene].append(per_atom)
                print(f"run {repeat + 1} {scene:45s} {atoms[scene]:7d} atoms "
                      f"{per_step * 1e3:9.3f} ms/step {per_atom * 1e6:7.4f} µs/atom/step  {status}")
    print(f"\nmedians over {args.repeats} interleaved repeats (µs per atom and outer step, "
          "ratio to the previous scene):")
    previous = None
    for scene in args.scenes:
        median = statistics.median(times[scene])
        ratio = f"{median / previous:6.3f}x" if previous else "      -"
        print(f"  {scene:45s} {atoms[scene]:7d} atoms {median * 1e6:8.4f}  {ratio}")
        previous = median


if __name__ == "__main__":
    main()
