#!/usr/bin/env python3
"""Where a multi-threaded `longstep run` step is serial, by instruction counts (callgrind).

Runs `longstep run SCENE … --t-end N·H` for N = N1 and N2 outer steps under
`valgrind --tool=callgrind --separate-threads=yes` with RAYON_NUM_THREADS=THREADS (default 2)
and takes the per-thread differences divided by N2 − N1, so setup cancels. Prints per outer
step, in millions of instructions:

- main-role: the thread that runs the integrator (the largest inclusive `…Integrator>::step`;
  it and the other rayon worker can swap between runs), helper: the other threads' total;
- serial: the main-role thread's instructions outside rayon's parallel iterators (its total
  less the inclusive cost of `<rayon::iter::plumbing::bridge::Callback as
  ProducerCallback>::callback`, the one entry of every parallel iterator), a count that
  does not depend on how valgrind schedules the threads;
- two bounds on the speed-up at THREADS threads: total / main-role (as valgrind happened to
  share the parallel work: valgrind runs one thread at a time and hands over only every
  ~100 000 blocks or at a system call, so short parallel loops stay on the thread that
  started them) and the work/span bound total / (serial + (total − serial) / THREADS);
- with --rows R, the R symbols of the largest main-role inclusive cost per step.

  python3 scripts/callgrind_threads.py systems/protein-amber/trpcage-pme.toml 4fs 2 22 -- \\
      --method langevin-respa --inner 1 --friction 1/ps --constraints h-bonds --rigid-water \\
      --hydrogen-mass 3amu --temperature 300K --seed 1 --precision mixed \\
      --start systems/protein-amber/trpcage-300K.xyz

Needs valgrind (callgrind_annotate) and a release build; runs from a clone. About 5 minutes
per run on the 6 920-atom Trp-cage at 22 steps on an idle core.
"""
import argparse
import glob
import os
import re
import subprocess
import sys
import tempfile
from collections import defaultdict

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LINE = re.compile(r'^\s*([\d,]+)\s+\(\s*[\d.]+%\)\s+(.*)$')
CALLBACK = ('???:<rayon::iter::plumbing::bridge::Callback<C> as '
            'rayon::iter::plumbing::ProducerCallback<I>>::callback')


def inclusive(path):
    """Symbol -> inclusive instructions of one callgrind thread file."""
    text = subprocess.run(['callgrind_annotate', '--inclusive=yes', '--threshold=100', path],
                          capture_output=True, text=True, check=True).stdout
    costs = defaultdict(int)
    for line in text.splitlines():
        m = LINE.match(line)
        if m:
            costs[m.group(2).split(' [')[0].strip()] += int(m.group(1).replace(',', ''))
    return costs


def total(costs):
    return costs.get('PROGRAM TOTALS', 0)


def step_cost(costs):
    return max((v for k, v in costs.items() if k.endswith('Integrator>::step')), default=0)


def run(args, work, n):
    """The thread files of one run of n outer steps: (main-role, [other threads])."""
    value, unit = re.fullmatch(r'([0-9.eE+-]+)([a-z]*)', args.h).groups()
    t_end = '%g%s' % (float(value) * n, unit)
    prefix = os.path.join(work, 'cg.%d' % n)
    env = dict(os.environ, RAYON_NUM_THREADS=str(args.threads))
    cmd = ['valgrind', '--tool=callgrind', '--separate-threads=yes',
           '--callgrind-out-file=%s.%%p' % prefix, args.bin, 'run', args.scene,
           '--h', args.h, '--t-end', t_end, '--energy-every', '1000000', '--quiet',
           '--out', os.path.join(work, 'out.%d' % n)] + args.options
    res = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
    if res.returncode != 0:
        sys.exit('longstep failed under valgrind:\n' + res.stderr[-3000:])
    threads = [inclusive(f) for f in sorted(glob.glob(prefix + '.*-*'))]
    main = max(threads, key=step_cost)
    return main, [t for t in threads if t is not main]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('scene')
    ap.add_argument('h', help='outer step with its unit, e.g. 4fs')
    ap.add_argument('n1', type=int)
    ap.add_argument('n2', type=int)
    ap.add_argument('options', nargs='*', help='more `longstep run` options (after --)')
    ap.add_argument('--threads', type=int, default=2)
    ap.add_argument('--rows', type=int, default=0)
    ap.add_argument('--bin', default=os.path.join(ROOT, 'target/release/longstep'))
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as work:
        m1, o1 = run(args, work, args.n1)
        m2, o2 = run(args, work, args.n2)
    per = 1e6 * (args.n2 - args.n1)
    main_role = (total(m2) - total(m1)) / per
    helper = (sum(map(total, o2)) - sum(map(total, o1))) / per
    whole = main_role + helper
    serial = main_role - (m2.get(CALLBACK, 0) - m1.get(CALLBACK, 0)) / per
    span = serial + (whole - serial) / args.threads
    print('%s, RAYON_NUM_THREADS=%d, M instructions per outer step (N = %d and %d)'
          % (args.scene, args.threads, args.n1, args.n2))
    print('  main-role %.2f  helper %.2f  total %.2f' % (main_role, helper, whole))
    print('  serial (main-role outside parallel iterators) %.2f = %.1f %% of the total'
          % (serial, 100 * serial / whole))
    print('  bound total/main-role %.3f   work/span bound total/(serial + rest/%d) %.3f'
          % (whole / main_role, args.threads, whole / span))
    if args.rows:
        rows = sorted(set(m1) | set(m2), key=lambda s: m1.get(s, 0) - m2.get(s, 0))
        print('  main-role inclusive M/step, symbol')
        for s in rows[:args.rows]:
            print('  %8.2f  %s' % ((m2.get(s, 0) - m1.get(s, 0)) / per, s[:130]))


if __name__ == '__main__':
    main()
