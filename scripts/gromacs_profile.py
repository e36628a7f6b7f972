#!/usr/bin/env python3
"""Where GROMACS's step goes: md.log's cycle accounting of the native build, one thread.

GROMACS's side of the step-by-step profile of issue 39 item 2, on the two systems the
head-to-head sittings time:

  trpcage    Trp-cage in water (6 920 atoms, systems/protein-amber/trpcage.top/.gro), exactly
             production_peers.py's row `native-hmr-4fs`: leap-frog 4 fs, constraints = h-bonds
             (LINCS), water SETTLE, hydrogens 3 amu, v-rescale 300 K, PME at GROMACS's defaults
             (ewald-rtol 1e-5, fourier-spacing 0.12 nm, order 4, r_c 0.9 nm), nstcalcenergy
             100, nstlist raised by mdrun;
  water5184  the 5 184-atom SPC/Fw water box with PME as head_to_head.py --coulomb pme runs it
             (NVE, 0.5 fs, nstlist as mdrun tunes it, nstcalcenergy 100): plain Verlet
             (--h 0.5) and MTS with the mesh every 4 steps (--h 2).

Each case runs `gmx mdrun -ntmpi 1 -ntomp 1 -pin on -notunepme -resethway` of the native build
(scripts/build_gromacs_native.sh; built when missing unless --no-build-native) and keeps from
md.log the SIMD line, mdrun's nstlist change and pair-list set-up, the flop accounting (the
work of each kernel: non-bonded, bonded, PME, LINCS, SETTLE), the cycle and time accounting
table (both for the second half of the run: -resethway) and the Performance line. The
counters' shares are what a profile compares; the wall seconds depend on the machine's load,
which is printed before and after. GROMACS's "Force" counter holds the non-bonded kernel, its
list pruning and the bonded terms together; splitting it needs a build with
-DGMX_CYCLE_SUBCOUNTERS=ON (not the anchor's build).

    python3 scripts/gromacs_profile.py --out docs/data/sittings/profile-gromacs-native-DATE.txt
    python3 scripts/gromacs_profile.py --cases trpcage --trpcage-steps 500   # quick look
"""
import argparse
import os
import re
import shlex
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import head_to_head as h2h  # noqa: E402
import production_peers as peers  # noqa: E402

ROW = "native-hmr-4fs"


def log_parts(text):
    """SIMD, nstlist change, the flop and the cycle accounting tables and Performance from a
    md.log."""
    keep = []
    for pattern in (r"^SIMD instructions:.*$", r"^Changing nstlist from .*$",
                    r"^Using \d+ OpenMP threads?.*$", r"^\s*(?:outer|inner) list: .*$",
                    r"^Overriding nsteps.*$"):
        keep += re.findall(pattern, text, re.M)
    start = text.find("M E G A - F L O P S   A C C O U N T I N G")
    start = text.rfind("\n", 0, start) + 1 if start >= 0 else text.find(
        "     R E A L   C Y C L E   A N D   T I M E   A C C O U N T I N G")
    end = text.find("Performance:", start)
    if start < 0 or end < 0:
        return "\n".join(keep) + "\n(no cycle accounting table in md.log)\n"
    line_end = text.find("\n", text.find("\n", end) + 1)
    return "\n".join(keep) + "\n\n" + text[start:line_end].rstrip() + "\n"


def trpcage(steps):
    files = peers.system_files("trpcage")
    with tempfile.TemporaryDirectory(prefix="profile-gmx-") as work:
        mdp, top = peers.gromacs_inputs(work, ROW, files, steps, 1)
        mdp_text = open(mdp).read()
        text = h2h.gromacs_mdrun(h2h.NATIVE, "mixed", mdp_text, files["gro"], top, steps, 1,
                                 extra=["-notunepme"])
    head = ("Trp-cage, production_peers.py row %s: %d steps of 4 fs (%g ps); the .top is "
            "%s with every non-water hydrogen at 3 amu (production_peers.repartitioned_top)"
            % (ROW, steps, steps * 0.004, os.path.relpath(files["top"], h2h.ROOT)))
    return head, mdp_text, text


def water(steps, h):
    k = round(h / h2h.INNER)
    h2h.PME = h2h.PmeInputs([5184], [h2h.NATIVE])
    try:
        gro, top = h2h.PME.gro[5184], h2h.PME.top[5184]
        mdp = lambda nstlist: h2h.PME_MDP.format(
            nsteps=steps, nstcalc=h2h.NSTCALCENERGY_DEFAULT, nstlist=nstlist) + (
            h2h.PME_MDP_MTS.format(k=k) if k > 1 else "")
        nstlist = h2h.tuned_nstlist((h2h.NATIVE, "mixed", "pme", 5184, k), mdp, 1, gro, top)
        mdp_text = mdp(nstlist)
        text = h2h.gromacs_mdrun(h2h.NATIVE, "mixed", mdp_text, gro, top, steps, 1,
                                 extra=["-notunepme"])
    finally:
        h2h.PME.close()
    head = ("water box 5 184 atoms (%s), PME, %s: %d steps of 0.5 fs; nstlist %d is what "
            "mdrun chose for this input with v-rescale (it does not tune in NVE)" % (
                os.path.relpath(gro, h2h.ROOT), "plain Verlet" if k == 1 else
                "MTS, mesh every %d steps" % k, steps, nstlist))
    return head, mdp_text, text


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog=__doc__.split("\n", 1)[1])
    ap.add_argument("--cases", default="trpcage,water5184",
                    help="trpcage and/or water5184 (default both)")
    ap.add_argument("--trpcage-steps", type=int, default=2500)
    ap.add_argument("--water-steps", type=int, default=2000)
    ap.add_argument("--out", help="write the report here too")
    ap.add_argument("--no-build-native", dest="build_native", action="store_false")
    args = ap.parse_args()
    if not h2h.native_ready(args.build_native):
        sys.exit("no native GROMACS: run scripts/build_gromacs_native.sh")
    cases = args.cases.split(",")
    for case in cases:
        if case not in ("trpcage", "water5184"):
            ap.error("--cases: unknown case %r" % case)
    load = lambda: " ".join("%.2f" % x for x in os.getloadavg())
    lines = ["command: " + shlex.join(["python3", "scripts/gromacs_profile.py"] + sys.argv[1:]),
             "each case: gmx grompp -f run.mdp -c GRO -p TOP -o run.tpr -maxwarn 1; gmx mdrun "
             "-s run.tpr -nsteps N -ntmpi 1 -ntomp 1 -pin on -noconfout -resethway -notunepme "
             "(gmx = %s)" % h2h.native_gmx(),
             "versions: " + h2h.versions([h2h.NATIVE]),
             "machine: %s, %d cores; load average %s at %s" % (
                 h2h.cpu_name(), os.cpu_count(), load(),
                 time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()))]
    runs = []
    if "trpcage" in cases:
        runs.append(trpcage(args.trpcage_steps))
    if "water5184" in cases:
        runs.append(water(args.water_steps, 0.5))
        runs.append(water(args.water_steps, 2.0))
    for head, mdp_text, text in runs:
        lines += ["", "=" * 100, head, "", "mdp:", mdp_text.rstrip(), "", log_parts(text)]
    lines.append("load average at the end %s at %s" % (
        load(), time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())))
    report = "\n".join(lines) + "\n"
    print(report)
    if args.out:
        with open(args.out, "w") as f:
            f.write(report)


if __name__ == "__main__":
    main()
