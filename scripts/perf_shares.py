#!/usr/bin/env python3
"""Where a step's CPU time goes, by sampling on the software clock (issue 39 item 2).

perf's hardware counters do not work on every machine (a VM often has none), but sampling on
the software clock (`-e cpu-clock`) does: each sample is a slice of the process's own CPU
time, so the shares are robust to other load on the machine. Each sample goes to the first
of its six innermost stack frames that a group's pattern matches, so the generic SIMD
closures (`simd::run_on::*`) go to their caller (SETTLE, PME spread, gather, ...).

    python3 scripts/perf_shares.py --delay-ms 800 -- target/release/longstep run \\
        systems/protein-amber/trpcage-pme.toml --method langevin-respa --inner 1 --h 4fs ...

Runs the command once under `perf record` (one thread unless RAYON_NUM_THREADS is set) and
prints each group's share of the samples. Needs `perf` (Debian: linux-perf).
"""
import argparse
import collections
import os
import re
import subprocess
import sys
import tempfile

GROUPS = [
    ("pair kernel", r"nonbonded::kernel"),
    ("pair lists: builds", r"clusters::search|ClusterList::build"),
    ("pair lists: pruning", r"clusters::prune"),
    ("pair lists: displacements, positions", r"ClusterList::"),
    ("SETTLE positions", r"constrain_positions|settle::positions"),
    ("SETTLE velocities", r"constrain_velocities|settle::velocit"),
    ("RATTLE", r"rattle"),
    ("SETTLE fit", r"fit_settle"),
    ("PME reciprocal sum", r"ewald::reciprocal|ewald::fft|rustfft|realfft|spline"),
    ("Ewald exclusions", r"ewald::exclusions"),
    ("bonded terms", r"angle|torsion|Torsion|PairTerm|dihedral|atan2|sin_fma|cos_fma"),
    ("non-bonded engine (reduce, refresh)", r"nonbonded::engine|Nonbonded"),
    ("integrator, random numbers", r"integrators::|rand|StandardNormal"),
    ("memmove, memset", r"memmove|memset|memcpy"),
    ("rayon: waiting, stealing, waking", r"rayon_core|crossbeam|futex|sched_yield|__lll"),
]


def samples(script_text):
    """(thread id, stack) of `perf script -F tid,ip,sym` output, innermost frame first."""
    tid, stack = None, []
    for line in script_text.splitlines():
        if not line.strip():
            if stack:
                yield tid, stack
            tid, stack = None, []
            continue
        if not line.startswith("\t"):  # a sample's first line: its thread id (padded)
            tid = line.split()[0]
            continue
        parts = line.strip().split(None, 1)
        stack.append(parts[1] if len(parts) > 1 else "?")
    if stack:
        yield tid, stack


def print_per_thread(found):
    """Each group's samples on each thread, the busiest thread (the one that runs the
    integrator, "main role") first: what only it runs is the serial part."""
    by_thread = collections.Counter(tid for tid, _ in found)
    tids = [t for t, _ in by_thread.most_common()]
    counts = collections.Counter((tid, group_of(s)) for tid, s in found)
    groups = collections.Counter(group_of(s) for _, s in found)
    main_total = by_thread[tids[0]]
    print("per thread, %% of the busiest thread's samples (%d); threads: %s"
          % (main_total, " ".join("%s=%d" % (t, by_thread[t]) for t in tids)))
    for name, _ in groups.most_common():
        cells = "".join("  %7.2f" % (100.0 * counts[(t, name)] / main_total) for t in tids)
        print("%s  %s" % (cells, name))


def group_of(stack):
    for frame in stack[:6]:
        for name, pattern in GROUPS:
            if re.search(pattern, frame):
                return name
    return "other"


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--delay-ms", type=int, default=0, help="leave the start-up out (perf -D)")
    ap.add_argument("--frequency", type=int, default=1000, help="samples per CPU-second")
    ap.add_argument("--per-thread", action="store_true",
                    help="each group's samples per thread (with RAYON_NUM_THREADS > 1)")
    ap.add_argument("command", nargs=argparse.REMAINDER, help="-- COMMAND ...")
    args = ap.parse_args(argv)
    command = args.command[1:] if args.command[:1] == ["--"] else args.command
    if not command:
        ap.error("give the command to profile after --")
    env = dict(os.environ)
    env.setdefault("RAYON_NUM_THREADS", "1")
    with tempfile.TemporaryDirectory() as tmp:
        data = os.path.join(tmp, "perf.data")
        record = ["perf", "record", "-q", "-e", "cpu-clock", "-F", str(args.frequency),
                  "--call-graph", "dwarf,8192", "-o", data]
        if args.delay_ms:
            record += ["-D", str(args.delay_ms)]
        run = subprocess.run(record + ["--"] + command, env=env,
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        if run.returncode != 0:
            sys.exit("perf record failed (exit %d): %s" % (run.returncode, run.stderr[-1500:]))
        script = subprocess.run(["perf", "script", "-i", data, "-F", "tid,ip,sym"],
                                capture_output=True, text=True, check=True).stdout
    found = list(samples(script))
    counts = collections.Counter(group_of(s) for _, s in found)
    total = sum(counts.values())
    print("command: %s" % " ".join(command))
    print("%d samples of the software clock at %d Hz" % (total, args.frequency))
    for name, n in counts.most_common():
        print("  %6.2f %%  %s" % (100.0 * n / total, name))
    if args.per_thread:
        print_per_thread(found)


if __name__ == "__main__":
    main(sys.argv[1:])
