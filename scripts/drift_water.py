#!/usr/bin/env python3
"""NVE energy drift of one method and step on the 216-water box over several starts, with its
error bar: the drift of each start (slope of a least-squares line through E(t), in
kT/ns/dof, as scripts/scan_water.py computes it) and their mean with the standard error of
the mean over the starts. The starts are the kit's 300 K velocities and Maxwell-Boltzmann
velocities at 300 K from seeds 1..N (`--temperature 300K --seed S`).

    python3 scripts/drift_water.py                                  # impulse 3 fs, 20 ps, 5 starts
    python3 scripts/drift_water.py --precision mixed                # the same in mixed precision
    python3 scripts/drift_water.py --method impulse --h 3 --ps 20 --seeds 4 --bin path/to/longstep

One thread per run (RAYON_NUM_THREADS=1: the runs are small). Needs a release build.
"""
import argparse
import math
import os
import statistics
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scan_water  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--method", default="impulse")
    ap.add_argument("--h", type=float, default=3.0, help="outer step in fs")
    ap.add_argument("--inner-dt", type=float, default=0.5)
    ap.add_argument("--ps", type=float, default=20.0)
    ap.add_argument("--seeds", type=int, default=4, help="seeded starts besides the kit's")
    ap.add_argument("--precision", default="double", choices=["double", "mixed"])
    ap.add_argument("--bin", help="longstep binary (default: this clone's release build)")
    args = ap.parse_args()
    if args.bin:
        scan_water.BIN = os.path.abspath(args.bin)
    os.environ["RAYON_NUM_THREADS"] = "1"
    extra_precision = [] if args.precision == "double" else ["--precision", args.precision]
    starts = [("kit", [])] + [
        ("seed %d" % s, ["--temperature", "300K", "--seed", str(s)]) for s in range(1, args.seeds + 1)
    ]
    drifts = []
    print("%s %g fs / %g fs, %g ps, %s precision" % (
        args.method, args.h, args.inner_dt, args.ps, args.precision))
    with tempfile.TemporaryDirectory() as workdir:
        for name, extra in starts:
            r = scan_water.run(args.method, args.h, args.inner_dt, args.ps,
                               extra + extra_precision, workdir)
            if r["blew_up"]:
                print("%-8s blew up (%s)" % (name, r["status"]), flush=True)
                continue
            drifts.append(r["drift_kT_per_ns_dof"])
            print("%-8s drift %8.4f kT/ns/dof  max|dE| %.4f kT/dof  T %.0f -> %.0f K  wall %.1f s" % (
                name, r["drift_kT_per_ns_dof"], r["max_abs_dE_kT_per_dof"], r["T0"], r["T_end"],
                r["wall_s"]), flush=True)
    if len(drifts) >= 2:
        mean = statistics.mean(drifts)
        sem = statistics.stdev(drifts) / math.sqrt(len(drifts))
        print("mean drift %.4f +- %.4f kT/ns/dof (standard error over %d starts)" % (
            mean, sem, len(drifts)))


if __name__ == "__main__":
    sys.exit(main())
