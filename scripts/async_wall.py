#!/usr/bin/env python3
"""Wall time of the asynchronous pseudo-energy scheme against the synchronous one (issue 13 item 5).

Runs from a clone (needs `cargo build --release`) and reads no file outside it. The scene is
systems/fpu-slow-fast.toml at its defaults (MEMM18 4.3.1: h_S = 0.01, h_F = 2e-4, K = 50,
five-point Gauss-Lobatto) against the synchronous scheme at h_F:

  async : longstep run systems/fpu-slow-fast.toml --t-end T --energy-every 1 --json --quiet
  sync  : longstep run systems/fpu-slow-fast.toml --method pseudo-energy --h 2e-4 \
              --quadrature gl5 --t-end T --energy-every 50 --json --quiet

Both write one row of energy.csv per 0.01 time units (--outputs same, the default); with
--outputs default both write a row per step (the synchronous run then writes 50 times more
rows). Every run has RAYON_NUM_THREADS=1. The two commands alternate (async, sync, async, ...)
so both see the same machine load; each runs --repeats times (default 5). Printed: the load
average before and after, every run (the summary's wall time of the stepping loop, output
included, and the process's wall time), the medians and the ratios async / sync.

    python3 scripts/async_wall.py                      # T = 100, 5 repeats each
    python3 scripts/async_wall.py --outputs default    # a row per step for both
    python3 scripts/async_wall.py --t-end 4 --repeats 1   # smoke test
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, ".."))
BIN = os.path.join(ROOT, "target", "release", "longstep")
SCENE = os.path.join(ROOT, "systems", "fpu-slow-fast.toml")


def commands(t_end, outputs):
    """The two runs, as argument lists without --out."""
    every_async, every_sync = ("1", "50") if outputs == "same" else ("1", "1")
    common = [BIN, "run", SCENE, "--t-end", str(t_end), "--json", "--quiet"]
    return {
        "async": common + ["--energy-every", every_async],
        "sync": common
        + ["--method", "pseudo-energy", "--h", "2e-4", "--quadrature", "gl5"]
        + ["--energy-every", every_sync],
    }


def run_once(args, out_dir):
    """(stepping-loop wall time from the summary, process wall time), in seconds."""
    env = dict(os.environ, RAYON_NUM_THREADS="1")
    started = time.perf_counter()
    done = subprocess.run(args + ["--force", "--out", out_dir], env=env, capture_output=True, text=True)
    process = time.perf_counter() - started
    if done.returncode != 0:
        sys.exit(f"failed ({done.returncode}): {' '.join(args)}\n{done.stderr}")
    summary = json.loads(done.stdout)
    if summary.get("status") != "ok":
        sys.exit(f"run not ok: {' '.join(args)}: {summary.get('status')}")
    return summary["wall_seconds"], process


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--t-end", type=float, default=100.0)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--outputs", choices=["same", "default"], default="same")
    options = parser.parse_args()
    if not os.path.exists(BIN):
        sys.exit(f"{BIN} is missing: run `cargo build --release` first")
    cmds = commands(options.t_end, options.outputs)
    for name, args in cmds.items():
        shown = " ".join(os.path.relpath(a, ROOT) if a.startswith(ROOT) else a for a in args)
        print(f"{name:5}: RAYON_NUM_THREADS=1 {shown}")
    print(f"start {time.strftime('%Y-%m-%d %H:%M:%S UTC', time.gmtime())}, "
          f"load average {os.getloadavg()[0]:.2f}")
    runs = {name: [] for name in cmds}
    with tempfile.TemporaryDirectory() as scratch:
        for repeat in range(options.repeats):
            for name, args in cmds.items():
                loop, process = run_once(args, os.path.join(scratch, name))
                runs[name].append((loop, process))
                print(f"repeat {repeat + 1} {name:5}: loop {loop:.4f} s, process {process:.4f} s",
                      flush=True)
    print(f"end   {time.strftime('%Y-%m-%d %H:%M:%S UTC', time.gmtime())}, "
          f"load average {os.getloadavg()[0]:.2f}")
    medians = {}
    for name, values in runs.items():
        loop = statistics.median(v[0] for v in values)
        process = statistics.median(v[1] for v in values)
        medians[name] = (loop, process)
        print(f"median {name:5}: loop {loop:.4f} s, process {process:.4f} s")
    for k, label in [(0, "loop"), (1, "process")]:
        ratio = medians["async"][k] / medians["sync"][k]
        print(f"async / sync ({label} wall, medians): {ratio:.3f}")


if __name__ == "__main__":
    main()
