#!/usr/bin/env python3
"""Where a PME step's instructions go: callgrind per part, per outer step.

Runs `longstep run SCENE --coulomb pme ...` twice under callgrind (N1 and N2 outer steps, one
thread, so the counts are repeatable on a busy machine) and divides the differences of the
inclusive counts of each part by N2 - N1, so scene loading, set-up and output cancel:

  splines      PmeReciprocal::place (B-spline weights and grid indices per atom)
  spread       PmeReciprocal::spread (charges onto the grid)
  FFT planes   Fft3::forward_planes (real FFTs of the z-rows, complex FFTs along y)
  FFT x+theta  Fft3::x_lines (x-lines forward, influence function, x-lines inverse)
  FFT inverse  Fft3::inverse_planes (inverse y-lines, inverse real FFTs)
  gather       PmeReciprocal::gather (forces from the potential grid)
  exclusions   Exclusions::add_gradient (-Q erf(ar)/r on excluded pairs)
  real space   Nonbonded::add_gradient (cluster-pair kernel with erfc, list updates)
  bonded       bonds and angles
  constr pos   Constraints::constrain_positions (SETTLE and SHAKE after a drift)
  constr vel   Constraints::constrain_velocities (SETTLE and RATTLE after a kick)
  normals      StandardNormal::sample (the normals of BAOAB's O step)
  the rest     the integrator and everything else in the step

    cargo build --release
    python3 scripts/pme_profile.py                       # 5 184 atoms, Verlet 0.5 fs
    python3 scripts/pme_profile.py --scene systems/water-box/scene.toml --n1 10 --n2 50
    python3 scripts/pme_profile.py --scene systems/protein-amber/trpcage-pme.toml --h 4 \
        --n1 4 --n2 14 -- --method langevin-respa --inner 1 --friction 1/ps \
        --constraints h-bonds --rigid-water --hydrogen-mass 3amu --temperature 300K \
        --seed 1 --precision mixed --start systems/protein-amber/trpcage-300K.xyz

Needs valgrind (callgrind_annotate). Runs from a clone; `--bin` profiles another build.
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, ".."))

# (label, regular expression on callgrind_annotate's inclusive function names)
PARTS = [
    ("splines", r"PmeReciprocal::place$"),
    ("spread", r"PmeReciprocal::spread$"),
    ("FFT planes", r"Fft3(<\w+>)?::forward_planes$"),
    ("FFT x+theta", r"Fft3(<\w+>)?::x_lines$"),
    ("FFT inverse", r"Fft3(<\w+>)?::inverse_planes$"),
    ("gather", r"PmeReciprocal::gather$"),
    ("exclusions", r"ewald::exclusions::Exclusions::add_gradient$"),
    ("real space", r"<longstep::forces::nonbonded::Nonbonded as longstep::forces::ForceTerm>"
                   r"::add_gradient$"),
    ("bonded", r"(HarmonicAngles as longstep::forces::ForceTerm>::add_gradient|"
               r"PairTerm<P> as longstep::forces::ForceTerm>::add_gradient)$"),
    ("constr pos", r"constraints::Constraints::constrain_positions$"),
    ("constr vel", r"constraints::Constraints::constrain_velocities$"),
    ("normals", r"StandardNormal as rand::distr::distribution::Distribution<f64>>::sample$"),
]
RECIPROCAL = r"<longstep::forces::ewald::reciprocal::PmeReciprocal as " \
             r"longstep::forces::ForceTerm>::add_gradient$"


def counts(binary, scene, steps, h, flags):
    """Inclusive instruction counts per function name, and the program total."""
    with tempfile.TemporaryDirectory() as work:
        out = os.path.join(work, "cg.out")
        t_end = "%gfs" % (h * steps)
        cmd = ["valgrind", "--tool=callgrind", "--callgrind-out-file=" + out, binary, "run",
               scene, "--coulomb", "pme", "--h", "%gfs" % h, "--t-end", t_end,
               "--energy-every", "1000000", "--quiet", "--out", os.path.join(work, "run")] + flags
        res = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True,
                             env=dict(os.environ, RAYON_NUM_THREADS="1"))
        if res.returncode != 0:
            sys.exit("longstep under callgrind failed:\n" + res.stderr[-3000:])
        text = subprocess.run(["callgrind_annotate", "--inclusive=yes", "--threshold=100", out],
                              capture_output=True, text=True).stdout
    table, total = {}, None
    for line in text.splitlines():
        m = re.match(r"\s*([\d,]+)\s+(?:\([^)]*\)\s+)?(\S.*?)\s*$", line)
        if not m:
            continue
        value = int(m.group(1).replace(",", ""))
        name = m.group(2)
        if "PROGRAM TOTALS" in name:
            total = value
            continue
        # "file:function [object]" -> function
        name = re.sub(r"\s*\[[^\]]*\]$", "", name)
        name = name.split(":", 1)[1] if name.startswith("???:") else name
        table[name] = table.get(name, 0) + value
    return table, total


def part(table, pattern):
    return sum(v for name, v in table.items() if re.search(pattern, name))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog=__doc__.split("\n", 1)[1])
    ap.add_argument("--scene", default="systems/water-box-1728/scene.toml")
    ap.add_argument("--bin", default=os.path.join(ROOT, "target", "release", "longstep"))
    ap.add_argument("--h", type=float, default=0.5, help="outer step, fs")
    ap.add_argument("--n1", type=int, default=5)
    ap.add_argument("--n2", type=int, default=25)
    ap.add_argument("flags", nargs="*",
                    help="more `longstep run` flags after --, e.g. -- --method impulse --inner 2")
    args = ap.parse_args()
    flags = args.flags or ["--method", "verlet", "--pme-order", "4"]
    a, ta = counts(args.bin, args.scene, args.n1, args.h, flags)
    b, tb = counts(args.bin, args.scene, args.n2, args.h, flags)
    steps = args.n2 - args.n1
    total = (tb - ta) / steps
    print("%s, h %g fs, %s; callgrind, 1 thread, (runs of %d and %d outer steps)" % (
        args.scene, args.h, " ".join(flags), args.n1, args.n2))
    print("%-12s %14s %7s" % ("part", "M instr/step", "share"))
    known = 0.0
    for label, pattern in PARTS:
        value = (part(b, pattern) - part(a, pattern)) / steps
        known += value
        print("%-12s %14.2f %6.1f%%" % (label, value / 1e6, 100 * value / total))
    print("%-12s %14.2f %6.1f%%" % ("the rest", (total - known) / 1e6,
                                    100 * (total - known) / total))
    print("%-12s %14.2f %6.1f%%" % ("total", total / 1e6, 100.0))
    rec = (part(b, RECIPROCAL) - part(a, RECIPROCAL)) / steps
    print("%-12s %14.2f %6.1f%%  (pme-reciprocal add_gradient, inclusive)" % (
        "reciprocal", rec / 1e6, 100 * rec / total))


if __name__ == "__main__":
    main()
