#!/usr/bin/env python3
"""The peers at their production settings and longstep, in one interleaved timing sitting.

One system, GROMACS (mixed precision, CPU) and OpenMM (CPU platform) at the settings their
users run in production, and the longstep configurations given with --longstep, timed in turn
on the same machine (issue 29 item 4). Two builds of GROMACS 2022.5, the same sources:
`gromacs-native`, built for this machine's SIMD (cmake GMX_SIMD=AUTO: AVX2_256 or AVX_512 on
current x86) by scripts/build_gromacs_native.sh into a cache folder outside the repository,
the anchor (what a user who compiles GROMACS or loads a cluster's module runs); and Debian's
package `gmx`, built for SSE4.1 only (portability), kept as a row because many users have only
that. Each GROMACS's check line names the SIMD its mdrun used (md.log). Runs from a clone and
reads nothing outside it; installs Debian's GROMACS (apt-get) and OpenMM (pip) when they are
missing, and builds the native GROMACS the first time (about 12 minutes on 2 idle cores,
over an hour on a loaded machine; --no-build-native skips it and leaves its rows out),
saying so (scripts/head_to_head.py's `install` and `native_ready`). Needs a release build (`cargo build --release`).

    python3 scripts/production_peers.py --system ala2 \\
        --longstep 'verlet-hbonds-2fs=--method verlet --h 2fs --constraints h-bonds
                    --rigid-water --temperature 300K --seed 1 --energy-every 100'
    python3 scripts/production_peers.py --system trpcage --threads 1 --repeats 1 --ps 0.2 \\
        --rows native-hmr-4fs,gmx-hmr-4fs

Systems (--system): `ala2`, the alanine dipeptide in 423 TIP3P waters (1291 atoms,
systems/alanine-dipeptide-amber/ala2-solvated.*), and `trpcage`, Trp-cage in 2205 TIP3P waters
with one Cl- (6920 atoms, systems/protein-amber/trpcage.*), Amber ff14SB. GROMACS reads the
.top/.gro (made from the prmtop by ParmEd; water is [ settles ] there), OpenMM the
.prmtop/.inpcrd, longstep the *-pme.toml scene (the prmtop). The model, as longstep's scene
has it: PME at GROMACS's defaults (real space cut at 9 A, ewald-rtol 1e-5, so
alpha = 0.347/A, fourier-spacing 1.2 A, order 4), Lennard-Jones cut at 9 A without a
long-range correction. Where the peers differ (every difference below leaves the forces the
same, or changes only the PME accuracy):
  - GROMACS shifts the LJ and real-space Coulomb energies to zero at the cut-off
    (vdw-modifier, coulomb-modifier = Potential-shift, its default; forces unchanged) and
    picks its own PME grid from the spacing (its list of FFT-friendly sizes; printed);
  - OpenMM's CPU PME is always order 5; it gets longstep's alpha and grid (read from
    `longstep check SCENE`), dispersion correction off, no switching;
  - the constraint solvers differ: GROMACS LINCS (order 4, 1 iteration) and SETTLE, OpenMM
    its CPU constraint solver (tolerance 1e-5) and SETTLE, longstep RATTLE (1e-8) and SETTLE.

The rows (--rows picks some; default all). GROMACS rows, GROMACS's production defaults:
`integrator = md` (leap-frog), v-rescale at 300 K (tau-t 0.1 ps, one group), Maxwell-Boltzmann
start (gen-vel, seed = the repeat), energies every 100 steps (nstcalcenergy's default), the
Verlet buffer from verlet-buffer-tolerance's default 0.005 and nstlist left at its default 10
for mdrun to raise (it does, to 40-100; printed), no output, `mdrun -ntmpi 1 -ntomp N -pin on
-notunepme` (mdrun does not tune PME on one rank without a GPU anyway). Every gmx-* row has a
native-* twin run by the native build, with the same mdp. OpenMM
rows: Langevin at 300 K, friction 1/ps, rigid water (SETTLE; the script adds the H-H
constraint the prmtop lacks, see rigid_water), velocities at 300 K (seed = the repeat), no
reporters, CPU platform property Threads = N (checked after every run).
  gmx-hbonds-2fs     dt 2 fs, constraints = h-bonds (LINCS), water SETTLE
  gmx-hmr-4fs        as gmx-hbonds-2fs, dt 4 fs, hydrogens 3 amu: GROMACS 2022 has no
                     mass-repartition-factor (2023 and later), so the script writes a .top
                     with every hydrogen bonded to a heavy atom at 3 amu, the difference taken
                     from that atom, water untouched (OpenMM's and longstep's rule); a GROMACS
                     that has the option gets `mass-repartition-factor = 3` instead (3.024 amu;
                     the check line shows the masses the tpr holds)
  gmx-mts-2fs        as gmx-hbonds-2fs with mts = yes, mts-levels = 2, mts-level2-forces =
                     longrange-nonbonded, mts-level2-factor = 2: PME mesh every 4 fs
  gmx-mts-hmr-4fs    as gmx-hmr-4fs with the same mts: dt 4 fs, PME mesh every 8 fs
  gmx-nve-hmr-4fs    as gmx-hmr-4fs in NVE (tcoupl = no; the Maxwell-Boltzmann start stays):
                     GROMACS's `md` beside longstep's `verlet`. mdrun does not tune nstlist in
                     NVE, so the row takes the nstlist mdrun chose for the same input with
                     v-rescale (`mdrun -nsteps 0`, once per row; printed), the buffer sized for
                     it by grompp from the starting temperature
  openmm-hbonds-2fs  LangevinMiddleIntegrator 2 fs, constraints HBonds
  openmm-hmr-4fs     LangevinMiddleIntegrator 4 fs, HBonds, hydrogenMass 3 amu
  openmm-mts-4fs     MTSLangevinIntegrator 4 fs, the reciprocal sum in force group 1 once a
                     step, the rest (group 0) twice (2 fs), HBonds
  LABEL              --longstep LABEL=ARGS: `longstep run SCENE ARGS --t-end Pps --quiet --out
                     TMP` with RAYON_NUM_THREADS=N (ARGS may not set --t-end or --out)

Before the first timed run each row is checked once (outside the timings) and a line printed:
GROMACS's tpr (`gmx dump`: constraints, SETTLEs, hydrogen masses) and log (dt, mts, nstlist,
PME grid), OpenMM's System (constraints, masses, force groups, PME parameters in the context),
longstep's summary line (method, h, inner steps, constraints).

Timing. Each run is a fresh process. ns/day comes from each code's timed loop, which leaves
out set-up: GROMACS's log (`Performance:`; its loop wall time from `Time:`), OpenMM's stepping
loop after the Context is made and 10 warm-up steps are taken (timed inside the process),
longstep's summary (`wall time ... (X ns/day)`: the stepping loop of run::run only, from after
the scene is read, the force field built, the integrator set up and the first energy row
written; it includes the energy rows every --energy-every steps, default every step, each a
full energy evaluation, so give --energy-every in ARGS: GROMACS computes energies every 100
steps, OpenMM never). wall_s is the wall time of the whole process (mdrun alone for GROMACS,
grompp is outside), and setup_fraction = 1 - (timed loop) / wall_s, printed per run. --ps
sets the simulated time of every run, or with --seconds S of each row's calibration run,
from which each row gets the length that times about S seconds (default: ala2 40 ps,
trpcage 12 ps, so that the fastest GROMACS row's set-up is about 5 % or less at 2 threads; a row whose median set-up fraction is
over 5 % is marked `!` in the summary). Run it on a quiet machine: with -pin on GROMACS's
OpenMP threads spin, and its 2-thread runs collapse when another process shares a core (ala2,
0.2 ps, load 3 on 2 cores: 28 ns/day at 2 threads against 155 at 1).

Interleaving: for each repeat, for each thread count, every row once in the same order.
Output (--out PREFIX, default docs/data/sittings/production-SYSTEM-DATE): PREFIX.csv, every
run (system, row, threads, repeat, ns_day, wall_s, setup_fraction, loop_s), written as the
sitting goes; PREFIX.txt, the exact command line, machine and versions, each row's check
line, and per thread count each row's median ns/day with its min-max over the repeats, the
median wall and set-up fraction, and its ratios to the fastest native GROMACS row and to the
fastest Debian GROMACS row at that thread count (each the one with the highest median
ns/day; the native first): the ratio of the medians, and in brackets the
widest ratio the repeats allow (the row's min over the reference's max, its max over the
reference's min).

Judged rows (--judge REF, issue 40 item 3). In place of the timing sitting, every row is run
once from the 300 K start of longstep's rows (SYSTEM-300K.xyz), for --ps at one thread,
writing its frames every --frame-fs fs (default 48, longstep's
sampling runs' interval): GROMACS an .xtc at compressed-x-precision XTC_PRECISION (0.0001 nm;
the default 0.001 nm biases the bond and angle criteria by several kelvin), OpenMM a .dcd
(float32), a --longstep row its run directory (its ARGS must carry --trajectory-every N for the
same interval), under out/peers-judged-SYSTEM/. Each is then judged by `longstep analyze SCENE
TRAJ… --reference REF --temperature 300K --skip --skip-ps --json` (plus --analyze-args; all
rows in one call, so the reference is analysed once, with --threads' first count), the same
criteria and run length as longstep's rows. Output: PREFIX-verdicts.txt (each row's
verdict, the criteria that fail or are undecided, the analyze command; with --timings CSV, a
timing sitting's one-thread median ns/day and the ratio to the fastest peer row that does not
fail, a failing row keeping its ns/day, marked) and PREFIX-verdicts.json (analyze's JSON
array, labelled by row: `scripts/verdict_table.py PREFIX-verdicts.json` tabulates it).

    python3 scripts/production_peers.py --system trpcage --ps 24 --rows native-hmr-4fs,\
        gmx-hmr-4fs,native-mts-hmr-4fs,openmm-hmr-4fs --judge REF_DIR \
        --timings docs/data/sittings/production-trpcage-2026-11-29-b.csv
"""
import argparse
import csv
import json
import math
import os
import re
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import head_to_head as h2h  # noqa: E402  (sh, install, versions, pme_alpha, the PME constants)

ROOT = h2h.ROOT
BIN = h2h.BIN
SYSTEMS = {
    "ala2": ("systems/alanine-dipeptide-amber", "ala2-solvated", "ala2-solvated-pme.toml"),
    "trpcage": ("systems/protein-amber", "trpcage", "trpcage-pme.toml"),
}
# Simulated ps per run. Set-up (process wall less timed loop) in 0.2 ps runs on the 2-core
# EPYC, 2026-11-26, under load: ala2 gmx mdrun 0.15 s, OpenMM 0.3-0.5 s, longstep 0.06 s;
# trpcage 0.35 s, 0.6-0.7 s, 0.26 s. The fastest row (gmx-hmr-4fs, 0.2 s/ps for ala2, 1.0 s/ps
# for trpcage at 1 thread, about 0.6x that at 2) then needs ~30 and ~11 ps for 5 % at 2 threads.
DEFAULT_PS = {"ala2": 40.0, "trpcage": 12.0}
TEMPERATURE = 300.0  # K
HYDROGEN_MASS = 3.0  # amu
# .xtc positions in 1/XTC_PRECISION nm: 10000 puts the rounding's bias on the bond and angle
# criteria at 0.09 K of equipartition temperature, 3 % of their 3 K bound (the default 1000
# costs 9 K; docs/studies.md, "The floor an .xtc puts on them").
XTC_PRECISION = 10000
OPENMM_WARMUP = 10   # steps before the timed loop
WATER = {"HOH", "WAT", "SOL"}  # water residue names

# name -> (code, dt fs, hydrogen mass repartitioning?, MTS factor of the slow level)
PEER_ROWS = {
    "native-hbonds-2fs": ("gromacs-native", 2.0, False, 1),
    "native-hmr-4fs": ("gromacs-native", 4.0, True, 1),
    "native-mts-2fs": ("gromacs-native", 2.0, False, 2),
    "native-mts-hmr-4fs": ("gromacs-native", 4.0, True, 2),
    "gmx-hbonds-2fs": ("gromacs", 2.0, False, 1),
    "gmx-hmr-4fs": ("gromacs", 4.0, True, 1),
    "gmx-mts-2fs": ("gromacs", 2.0, False, 2),
    "gmx-mts-hmr-4fs": ("gromacs", 4.0, True, 2),
    "native-nve-hmr-4fs": ("gromacs-native", 4.0, True, 1),
    "gmx-nve-hmr-4fs": ("gromacs", 4.0, True, 1),
    "openmm-hbonds-2fs": ("openmm", 2.0, False, 1),
    "openmm-hmr-4fs": ("openmm", 4.0, True, 1),
    "openmm-mts-4fs": ("openmm", 4.0, False, 2),  # dt is the outer step here
}

MDP = """integrator = md
dt = {dt}
nsteps = {nsteps}
tcoupl = v-rescale
tc-grps = System
tau-t = 0.1
ref-t = {temperature}
pcoupl = no
cutoff-scheme = Verlet
coulombtype = PME
rcoulomb = 0.9
ewald-rtol = {rtol}
fourier-spacing = 0.12
pme-order = {order}
vdwtype = Cut-off
vdw-modifier = Potential-shift
rvdw = 0.9
DispCorr = no
constraints = h-bonds
constraint-algorithm = lincs
continuation = no
gen-vel = yes
gen-temp = {temperature}
gen-seed = {seed}
nstcalcenergy = 100
nstenergy = 0
nstlog = 0
nstxout-compressed = 0
"""
# NVE rows: no thermostat (the Maxwell-Boltzmann start at 300 K stays), and the nstlist that
# mdrun chose for the same input with v-rescale (mdrun does not tune nstlist in NVE).
NVE_ROWS = {"native-nve-hmr-4fs", "gmx-nve-hmr-4fs"}
THERMOSTAT = """tcoupl = v-rescale
tc-grps = System
tau-t = 0.1
ref-t = {temperature}
""".format(temperature=TEMPERATURE)
NVE_NSTLIST = {}  # row -> nstlist from its NVT probe
MDP_MTS = """mts = yes
mts-levels = 2
mts-level2-forces = longrange-nonbonded
mts-level2-factor = {factor}
"""


def system_files(name):
    directory, stem, scene = SYSTEMS[name]
    base = os.path.join(ROOT, directory, stem)
    return {"prmtop": base + ".prmtop", "inpcrd": base + ".inpcrd", "top": base + ".top",
            "gro": base + ".gro", "scene": os.path.join(ROOT, directory, scene),
            "start": base + "-300K.xyz"}


def read_xyz(path):
    """The positions (A) of an extended-XYZ frame's atoms."""
    with open(path) as f:
        lines = f.read().splitlines()
    n = int(lines[0])
    return [[float(x) for x in line.split()[1:4]] for line in lines[2:2 + n]]


def start_gro(work, files):
    """The system's .gro with the positions of its 300 K start (the --start of longstep's
    rows), A -> nm: what a judged GROMACS row starts from."""
    positions = read_xyz(files["start"])
    with open(files["gro"]) as f:
        lines = f.read().splitlines()
    n = int(lines[1])
    if n != len(positions):
        raise RuntimeError("%s and %s differ in atom count" % (files["start"], files["gro"]))
    out = lines[:2] + [line[:20] + "%8.3f%8.3f%8.3f" % (x / 10, y / 10, z / 10)
                       for line, (x, y, z) in zip(lines[2:2 + n], positions)]
    path = os.path.join(work, "start.gro")
    with open(path, "w") as f:
        f.write("\n".join(out + [lines[2 + n]]) + "\n")
    return path


# ------------------------------------------------------------------ GROMACS ------------------
GROMACS_CODES = h2h.GROMACS_CODES


def gmx_of(row):
    """The gmx binary of a GROMACS row: Debian's `gmx`, or the native build's."""
    return h2h.gmx_binary(PEER_ROWS[row][0], "mixed")


def gromacs_has_repartition(gmx):
    """GROMACS 2023 added mass-repartition-factor; 2022 and before do not have it."""
    m = re.search(r"GROMACS version:\s+(\d+)", h2h.sh([gmx, "--version"]).stdout)
    return bool(m) and int(m.group(1)) >= 2023


def top_sections(lines):
    """(line index, section name, molecule type) for every line of a .top."""
    section, moltype, out = None, None, []
    for i, line in enumerate(lines):
        head = re.match(r"\s*\[\s*(\w+)\s*\]", line)
        if head:
            section = head.group(1)
        elif section == "moleculetype" and line.split() and not line.lstrip().startswith(";"):
            moltype = line.split()[0]
        out.append((i, section, moltype))
    return out


def repartitioned_top(text, mass):
    """The .top with every hydrogen bonded to a heavy atom at `mass` amu, the difference taken
    from that heavy atom, molecule types with [ settles ] (water) left as they are."""
    lines = text.splitlines()
    sections = top_sections(lines)
    atomic = {}
    for i, section, _ in sections:
        fields = lines[i].split(";")[0].split()
        if section == "atomtypes" and len(fields) >= 3 and not lines[i].lstrip().startswith("["):
            atomic[fields[0]] = int(fields[1])
    water = {m for i, s, m in sections if s == "settles"}
    atoms, bonds = {}, {}
    for i, section, mol in sections:
        fields = lines[i].split(";")[0].split()
        if mol in water or not fields or fields[0].startswith(("[", "#")):
            continue
        if section == "atoms":
            atoms.setdefault(mol, {})[int(fields[0])] = [i, fields, float(fields[7])]
        elif section == "bonds":
            bonds.setdefault(mol, []).append((int(fields[0]), int(fields[1])))
    for mol, pairs in bonds.items():
        table = atoms[mol]
        hydrogen = lambda a: atomic[table[a][1][1]] == 1
        for a, b in pairs:
            if hydrogen(a) == hydrogen(b):
                continue
            h, heavy = (a, b) if hydrogen(a) else (b, a)
            table[heavy][2] -= mass - table[h][2]
            table[h][2] = mass
    for table in atoms.values():
        for i, fields, m in table.values():
            comment = lines[i].split(";", 1)[1] if ";" in lines[i] else None
            fields = fields[:7] + ["%.6f" % m] + fields[8:]
            lines[i] = "  ".join(fields) + ("   ;" + comment if comment is not None else "")
    return "\n".join(lines) + "\n"


def nve_nstlist(row, files):
    """The nstlist mdrun picks for an NVE row's input with v-rescale at 300 K (`mdrun -nsteps
    0` of the thermostatted twin, from nstlist 10), once per row."""
    if row not in NVE_NSTLIST:
        gmx = gmx_of(row)
        with tempfile.TemporaryDirectory(prefix="peers-gmx-probe-") as work:
            mdp, top = gromacs_inputs(work, row, files, 0, 1, nstlist=0)
            tpr, log = os.path.join(work, "run.tpr"), os.path.join(work, "md.log")
            res = h2h.sh([gmx, "grompp", "-f", mdp, "-c", files["gro"], "-p", top, "-o", tpr,
                          "-po", os.path.join(work, "out.mdp")], cwd=work)
            if res.returncode == 0:
                res = h2h.sh([gmx, "mdrun", "-s", tpr, "-nsteps", "0", "-ntmpi", "1", "-ntomp",
                              "1", "-g", log, "-noconfout"], cwd=work,
                             env=dict(os.environ, GMX_MAXBACKUP="-1"))
            if res.returncode != 0:
                raise RuntimeError("nstlist probe failed: %s" % res.stderr[-1500:])
            m = re.search(r"Changing nstlist from \d+ to (\d+)", open(log).read())
            NVE_NSTLIST[row] = int(m.group(1)) if m else 10
    return NVE_NSTLIST[row]


def gromacs_inputs(work, row, files, nsteps, seed, nstlist=None, frame_steps=0):
    """Write run.mdp (and the repartitioned .top) into work; returns (mdp, top) paths. An NVE
    row gets no thermostat and `nstlist` (default: its NVT probe's, nve_nstlist; 0: the probe
    itself, thermostat kept and nstlist at GROMACS's default). frame_steps > 0: an .xtc frame
    every frame_steps steps at XTC_PRECISION."""
    _, dt, hmr, factor = PEER_ROWS[row]
    top = files["top"]
    text = MDP.format(dt=dt / 1000.0, nsteps=nsteps, temperature=TEMPERATURE,
                      rtol=h2h.PME_RTOL, order=h2h.PME_ORDER, seed=seed)
    if frame_steps:
        text = text.replace("nstxout-compressed = 0\n", "nstxout-compressed = %d\n"
                            "compressed-x-precision = %d\n" % (frame_steps, XTC_PRECISION))
    if factor > 1:
        text += MDP_MTS.format(factor=factor)
    if row in NVE_ROWS and nstlist != 0:
        nstlist = nve_nstlist(row, files) if nstlist is None else nstlist
        text = text.replace(THERMOSTAT, "tcoupl = no\n") + "nstlist = %d\n" % nstlist
    if hmr and gromacs_has_repartition(gmx_of(row)):
        text += "mass-repartition-factor = 3\n"
    elif hmr:
        top = os.path.join(work, "hmr.top")
        with open(top, "w") as f:
            f.write(repartitioned_top(open(files["top"]).read(), HYDROGEN_MASS))
    mdp = os.path.join(work, "run.mdp")
    with open(mdp, "w") as f:
        f.write(text)
    return mdp, top


def gromacs_dump_check(gmx, tpr):
    """Constraints, SETTLEs and hydrogen masses from `gmx dump` of the tpr."""
    text = h2h.sh([gmx, "dump", "-s", tpr]).stdout
    counts = {int(k): int(n) for k, n in re.findall(
        r"moltype\s+=\s+(\d+) \"[^\"]*\"\s*\n\s*#molecules\s+=\s+(\d+)", text)}
    blocks = re.split(r"\n\s*moltype \((\d+)\):", text)
    constraints = settles = 0
    masses = {"water": set(), "other": set()}
    for k, body in zip(blocks[1::2], blocks[2::2]):
        n = counts.get(int(k), 0)
        c = re.search(r"Constraint:\s*\n\s*nr: (\d+)", body)
        s = re.search(r"Settle:\s*\n\s*nr: (\d+)", body)
        constraints += n * int(c.group(1)) // 3 if c else 0
        nsettle = n * int(s.group(1)) // 4 if s else 0
        settles += nsettle
        for m in re.findall(r"m=\s*([0-9.e+-]+), q=[^}]*atomnumber=\s*1\}", body):
            masses["water" if nsettle else "other"].add(round(float(m), 4))
    return "%d LINCS constraints, %d SETTLE waters, H masses %s" % (
        constraints, settles, masses_text(masses))


def gromacs_log_check(log):
    value = lambda key: (re.findall(r"^\s*%s\s*=\s*(\S+)" % key, log, re.M) or ["?"])[0]
    nstlist = re.search(r"Changing nstlist from \d+ to (\d+)", log)
    mts = value("mts")
    text = "dt %s ps, mts %s" % (value("dt"), mts)
    if mts == "true":
        text += " (%s every %s steps)" % (value("mts-level2-forces"), value("mts-level2-factor"))
    width = re.search(r"Gaussian width \(1/beta\) of ([0-9.eE+-]+) nm", log)
    simd = re.search(r"^SIMD instructions:\s+(\S+)", log, re.M)
    text = "SIMD %s, %s" % (simd.group(1) if simd else "?", text)
    return text + ", nstlist %s, PME grid %sx%sx%s order %s alpha %s/A, tcoupl %s" % (
        nstlist.group(1) if nstlist else value("nstlist"), value("fourier-nx"),
        value("fourier-ny"), value("fourier-nz"), value("pme-order"),
        "%.4f" % (0.1 / float(width.group(1))) if width else "?", value("tcoupl"))


def run_gromacs(row, files, ps, threads, seed, check, trajectory=None):
    """One mdrun; trajectory = (path.xtc, frame interval in fs) writes its frames there."""
    _, dt, _, factor = PEER_ROWS[row]
    nsteps = max(factor, int(round(ps * 1000.0 / dt / factor)) * factor)
    gmx = gmx_of(row)
    frame_steps, xtc = 0, []
    if trajectory:
        frame_steps = frame_interval(trajectory[1], dt, factor)
        xtc = ["-x", trajectory[0]]
    with tempfile.TemporaryDirectory(prefix="peers-gmx-") as work:
        mdp, top = gromacs_inputs(work, row, files, nsteps, seed, frame_steps=frame_steps)
        tpr = os.path.join(work, "run.tpr")
        gro = start_gro(work, files) if trajectory else files["gro"]
        res = h2h.sh([gmx, "grompp", "-f", mdp, "-c", gro, "-p", top, "-o", tpr,
                      "-po", os.path.join(work, "out.mdp"), "-maxwarn", "0"], cwd=work)
        if res.returncode != 0:
            raise RuntimeError("grompp failed: %s" % res.stderr[-1500:])
        log = os.path.join(work, "md.log")
        start = time.perf_counter()
        res = h2h.sh([gmx, "mdrun", "-s", tpr, "-ntmpi", "1", "-ntomp", str(threads),
                      "-pin", "on", "-notunepme", "-noconfout", "-g", log,
                      "-e", os.path.join(work, "ener.edr")] + xtc, cwd=work,
                     env=dict(os.environ, GMX_MAXBACKUP="-1"))
        wall = time.perf_counter() - start
        if res.returncode != 0:
            raise RuntimeError("mdrun failed: %s" % res.stderr[-1500:])
        text = open(log).read()
        used = re.search(r"^Using (\d+) OpenMP threads?\s*$", text, re.M)
        if not used or int(used.group(1)) != threads:
            raise RuntimeError("mdrun did not say it used %d OpenMP threads" % threads)
        ns_day = float(re.search(r"^Performance:\s+([0-9.eE+-]+)", text, re.M).group(1))
        loop = float(re.search(r"^\s+Time:\s+[0-9.eE+-]+\s+([0-9.eE+-]+)", text, re.M).group(1))
        note = None
        if check:
            note = "%s; %s" % (gromacs_log_check(text), gromacs_dump_check(gmx, tpr))
        return ns_day, wall, loop, note


# ------------------------------------------------------------------ OpenMM -------------------
def run_openmm(row, files, ps, threads, seed, check, pme, trajectory=None):
    """One OpenMM run in its own Python process (openmm_worker); the process wall here.
    trajectory = (path.dcd, frame interval in fs) writes its frames there."""
    spec = {"row": row, "prmtop": files["prmtop"], "inpcrd": files["inpcrd"], "ps": ps,
            "threads": threads, "seed": seed, "check": check, "alpha": pme["alpha"],
            "grid": pme["grid"]}
    if trajectory:
        _, dt, _, _ = PEER_ROWS[row]
        spec["dcd"] = trajectory[0]
        spec["start"] = files["start"]
        spec["frame_steps"] = frame_interval(trajectory[1], dt, 1)
    start = time.perf_counter()
    res = h2h.sh([sys.executable, os.path.abspath(__file__), "--openmm-worker",
                  json.dumps(spec)], cwd=ROOT)
    wall = time.perf_counter() - start
    if res.returncode != 0:
        raise RuntimeError("OpenMM failed: %s" % res.stderr[-1500:])
    out = json.loads(res.stdout.strip().splitlines()[-1])
    if out["threads"] != str(threads):
        raise RuntimeError("OpenMM ran %s threads, not %d" % (out["threads"], threads))
    return out["ns_day"], wall, out["loop_s"], out.get("check")


def openmm_system(spec):
    """The prmtop as OpenMM's System at the row's settings, PME with longstep's alpha/grid."""
    import openmm as mm
    from openmm import app, unit
    _, dt, hmr, factor = PEER_ROWS[spec["row"]]
    prmtop = app.AmberPrmtopFile(spec["prmtop"])
    inpcrd = app.AmberInpcrdFile(spec["inpcrd"])
    system = prmtop.createSystem(
        nonbondedMethod=app.PME, nonbondedCutoff=h2h.PME_CUTOFF * 0.1 * unit.nanometer,
        constraints=app.HBonds, rigidWater=True,
        hydrogenMass=HYDROGEN_MASS * unit.amu if hmr else None)
    rigid_water(system, prmtop.topology)
    nb = [f for f in system.getForces() if isinstance(f, mm.NonbondedForce)][0]
    n = spec["grid"]
    nb.setPMEParameters(spec["alpha"] * 10.0, n[0], n[1], n[2])  # 1/A -> 1/nm
    nb.setUseDispersionCorrection(False)
    nb.setUseSwitchingFunction(False)
    if factor > 1:
        nb.setReciprocalSpaceForceGroup(1)
    if inpcrd.boxVectors is not None:
        system.setDefaultPeriodicBoxVectors(*inpcrd.boxVectors)
    temperature, friction = TEMPERATURE * unit.kelvin, 1.0 / unit.picosecond
    if factor > 1:
        integrator = mm.MTSLangevinIntegrator(temperature, friction, dt * unit.femtosecond,
                                              [(1, 1), (0, factor)])
    else:
        integrator = mm.LangevinMiddleIntegrator(temperature, friction, dt * unit.femtosecond)
    integrator.setRandomNumberSeed(spec["seed"])
    return prmtop, inpcrd, system, nb, integrator


def rigid_water(system, topology):
    """Make each water rigid: OpenMM's AmberPrmtopFile constrains a water's H-H distance only
    when the prmtop has an H-H bond (tleap's TIP3P has one, these ParmEd prmtops do not), so
    rigidWater alone leaves the water angle flexible. Add the H-H constraint from the O-H
    lengths and the angle term's rest angle, and zero that angle term (held by the
    constraints); OpenMM then solves each water by SETTLE."""
    import openmm as mm
    from openmm import unit
    water = {a.index for a in topology.atoms() if a.residue.name in WATER}
    lengths = {}
    for k in range(system.getNumConstraints()):
        i, j, d = system.getConstraintParameters(k)
        if i in water and j in water:
            lengths[frozenset((i, j))] = d.value_in_unit(unit.nanometer)
    for force in system.getForces():
        if not isinstance(force, mm.HarmonicAngleForce):
            continue
        for k in range(force.getNumAngles()):
            i, j, m, theta, _ = force.getAngleParameters(k)
            if not {i, j, m} <= water:
                continue
            a, b = lengths[frozenset((i, j))], lengths[frozenset((j, m))]
            angle = theta.value_in_unit(unit.radian)
            system.addConstraint(i, m, math.sqrt(a * a + b * b - 2.0 * a * b * math.cos(angle)))
            force.setAngleParameters(k, i, j, m, theta, 0.0)


def masses_text(masses):
    """'3 amu (water H 1.0079)' from {"water": {...}, "other": {...}} hydrogen masses."""
    fmt = lambda s: "/".join("%g" % m for m in sorted(s)) or "-"
    return "%s amu (water H %s)" % (fmt(masses["other"]), fmt(masses["water"]))


def openmm_constraints_text(topology, system):
    """Constraints, how many waters hold three (rigid), and the hydrogens' masses."""
    from openmm import app, unit
    masses = {"water": set(), "other": set()}
    residue = {}
    for atom in topology.atoms():
        water = atom.residue.name in WATER
        if water:
            residue[atom.index] = atom.residue.index
        if atom.element == app.element.hydrogen:
            m = system.getParticleMass(atom.index).value_in_unit(unit.amu)
            masses["water" if water else "other"].add(round(m, 4))
    per_water = {}
    for k in range(system.getNumConstraints()):
        i, j, _ = system.getConstraintParameters(k)
        if i in residue and j in residue:
            per_water[residue[i]] = per_water.get(residue[i], 0) + 1
    rigid = sum(1 for n in per_water.values() if n == 3)
    return "%d constraints (%d waters with 3), H masses %s" % (
        system.getNumConstraints(), rigid, masses_text(masses))


def openmm_pme_text(system, nb, context):
    """Force groups, the reciprocal sum's group and the PME parameters the context uses."""
    from openmm import unit
    try:
        alpha, nx, ny, nz = nb.getPMEParametersInContext(context)
        source = "in the context"
    except Exception:  # OpenMM 8.6's CPU platform fails here now and then (bad_cast)
        alpha, nx, ny, nz = nb.getPMEParameters()
        alpha, source = getattr(alpha, "_value", alpha), "as set"
    groups = sorted({system.getForce(i).getForceGroup() for i in range(system.getNumForces())})
    recip = nb.getReciprocalSpaceForceGroup()
    return ("force groups %s, reciprocal in group %d, PME grid %dx%dx%d order 5 alpha %.4f/A "
            "(%s), dispersion correction %s, cutoff %.2f nm" % (
                groups, recip if recip >= 0 else nb.getForceGroup(), nx, ny, nz, alpha / 10.0,
                source, nb.getUseDispersionCorrection(),
                nb.getCutoffDistance().value_in_unit(unit.nanometer)))


def openmm_check(prmtop, system, nb, context, integrator):
    from openmm import unit
    return "%s dt %g fs, %s, %s" % (
        type(integrator).__name__, integrator.getStepSize().value_in_unit(unit.femtosecond),
        openmm_constraints_text(prmtop.topology, system), openmm_pme_text(system, nb, context))


def openmm_worker(spec):
    """Build, warm up and time one OpenMM run; print one JSON line."""
    import openmm as mm
    from openmm import unit
    prmtop, inpcrd, system, nb, integrator = openmm_system(spec)
    platform = mm.Platform.getPlatformByName("CPU")
    context = mm.Context(system, integrator, platform, {"Threads": str(spec["threads"])})
    if "start" in spec:  # a judged row: the 300 K start of longstep's rows
        context.setPositions([mm.Vec3(*(x / 10.0 for x in q)) for q in read_xyz(spec["start"])]
                             * unit.nanometer)
    else:
        context.setPositions(inpcrd.positions)
    context.applyConstraints(1e-6)
    context.setVelocitiesToTemperature(TEMPERATURE * unit.kelvin, spec["seed"])
    dt = PEER_ROWS[spec["row"]][1]
    steps = max(1, int(round(spec["ps"] * 1000.0 / dt)))
    integrator.step(OPENMM_WARMUP)
    context.getState(getEnergy=True)
    start = time.perf_counter()
    if "dcd" in spec:
        openmm_frames(spec, prmtop, context, integrator, steps, dt)
    else:
        integrator.step(steps)
    context.getState(getPositions=True)  # waits for the steps to finish
    loop = time.perf_counter() - start
    out = {"loop_s": loop, "ns_day": steps * dt * 1e-6 / loop * 86400.0,
           "threads": context.getPlatform().getPropertyValue(context, "Threads")}
    if spec["check"]:
        kinetic = context.getState(getEnergy=True).getKineticEnergy()
        dof = 3 * system.getNumParticles() - system.getNumConstraints() - 3
        kelvin = 2.0 * kinetic / (dof * unit.MOLAR_GAS_CONSTANT_R)
        out["check"] = "%s, T at the end %.0f K" % (
            openmm_check(prmtop, system, nb, context, integrator),
            kelvin.value_in_unit(unit.kelvin))
    print(json.dumps(out))


def openmm_frames(spec, prmtop, context, integrator, steps, dt):
    """Step in runs of frame_steps, a .dcd frame (float32, A, with the box) after each: the
    frames at t = k * frame_steps * dt after the warm-up, the first at one interval."""
    from openmm import app, unit
    every = spec["frame_steps"]
    with open(spec["dcd"], "wb") as sink:
        dcd = app.DCDFile(sink, prmtop.topology, dt * unit.femtosecond, firstStep=every,
                          interval=every)
        for _ in range(max(1, steps // every)):
            integrator.step(every)
            state = context.getState(getPositions=True)
            dcd.writeModel(state.getPositions(), periodicBoxVectors=state.getPeriodicBoxVectors())


def frame_interval(frame_fs, dt, factor):
    """Steps between frames: frame_fs / dt, a whole number and a multiple of the MTS factor
    (GROMACS requires it of its output intervals), or an error."""
    steps = frame_fs / dt
    if abs(steps - round(steps)) > 1e-9 or round(steps) % factor:
        raise RuntimeError("--frame-fs %g is not a multiple of %g fs steps (times %d)" % (
            frame_fs, dt, factor))
    return int(round(steps))


# ------------------------------------------------------------------ longstep -----------------
def longstep_pme(scene):
    """alpha (1/A) and grid that `longstep check` reports for the scene's reciprocal sum."""
    res = h2h.sh([BIN, "check", scene], cwd=ROOT)
    m = re.search(r"pme-reciprocal: PME, alpha = (\S+) 1/\S+, grid (\d+)x(\d+)x(\d+), "
                  r"order (\d+)", res.stdout + res.stderr)
    if res.returncode != 0 or not m:
        sys.exit("longstep check %s did not report its PME parameters:\n%s" % (
            scene, (res.stderr or res.stdout)[-1500:]))
    return {"alpha": float(m.group(1)), "grid": [int(m.group(i)) for i in (2, 3, 4)],
            "order": int(m.group(5))}


def longstep_summary(stdout):
    """(ns/day, loop wall s, the method line) from the text summary or --json's object."""
    m = re.search(r"^wall time\s+([0-9.eE+-]+) s \(([0-9.eE+-]+) ns/day\)", stdout, re.M)
    if m:
        method = re.search(r"^method\s+(.*)$", stdout, re.M)
        return float(m.group(2)), float(m.group(1)), method.group(1) if method else "?"
    s = json.loads(stdout)
    return s["ns_per_day"], s["wall_seconds"], "%s (%s)" % (s["method"], s["parameters"])


def run_longstep(args_text, scene, ps, threads, check):
    with tempfile.TemporaryDirectory(prefix="peers-longstep-") as out:
        cmd = [BIN, "run", scene] + shlex.split(args_text) + [
            "--t-end", "%gps" % ps, "--quiet", "--out", out]
        start = time.perf_counter()
        res = h2h.sh(cmd, cwd=ROOT, env=dict(os.environ, RAYON_NUM_THREADS=str(threads)))
        wall = time.perf_counter() - start
        if res.returncode != 0:
            raise RuntimeError("longstep failed (exit %d): %s" % (
                res.returncode, (res.stderr or res.stdout)[-1500:]))
        ns_day, loop, method = longstep_summary(res.stdout)
        return ns_day, wall, loop, method if check else None


# ------------------------------------------------------------------ the sitting --------------
def run_row(row, args, ps, threads, repeat, check, pme):
    files = system_files(args.system)
    if row in args.longstep:
        return run_longstep(args.longstep[row], files["scene"], ps, threads, check)
    if PEER_ROWS[row][0] in GROMACS_CODES:
        return run_gromacs(row, files, ps, threads, repeat + 1, check)
    return run_openmm(row, files, ps, threads, repeat + 1, check, pme)


def run_lengths(args, pme, checks):
    """{(row, threads): ps}: --ps for every run, or with --seconds S each row's length from
    one untimed calibration run of --ps, so that its timed loop takes about S seconds (ps =
    ns/day * S / 86.4, never below --ps). The calibration runs make the check lines."""
    lengths = {(row, t): args.ps for row in args.rows for t in args.threads}
    if args.seconds is None:
        return lengths
    for threads in args.threads:
        for row in args.rows:
            check = row not in checks
            try:
                ns_day, _, _, note = run_row(row, args, args.ps, threads, 0, check, pme)
            except Exception as e:
                print("  %-20s %d thr  calibration FAILED: %s" % (row, threads, e), flush=True)
                continue
            if check:
                checks[row] = note
                print("  check %-20s %s" % (row, note), flush=True)
            lengths[(row, threads)] = max(args.ps, round(ns_day * args.seconds / 86.4, 1))
            print("  %-20s %d thr  calibration %.1f ns/day: %g ps per run" % (
                row, threads, ns_day, lengths[(row, threads)]), flush=True)
    return lengths


def sitting(args, pme, writer, sink):
    """Every row at every thread count, interleaved; returns {(row, threads): [runs]}."""
    runs, checks = {}, {}
    lengths = run_lengths(args, pme, checks)
    args.lengths = lengths
    for repeat in range(args.repeats):
        for threads in args.threads:
            for row in args.rows:
                check = row not in checks
                ps = lengths[(row, threads)]
                try:
                    ns_day, wall, loop, note = run_row(row, args, ps, threads, repeat, check,
                                                       pme)
                except Exception as e:  # a failed run is reported; the sitting goes on
                    print("  %-20s %d thr  run %d FAILED: %s" % (row, threads, repeat + 1, e),
                          flush=True)
                    continue
                if check:
                    checks[row] = note
                    print("  check %-20s %s" % (row, note), flush=True)
                setup = 1.0 - loop / wall
                runs.setdefault((row, threads), []).append((ns_day, wall, setup))
                writer.writerow([args.system, row, threads, repeat + 1, "%.4f" % ns_day,
                                 "%.3f" % wall, "%.4f" % setup, "%.3f" % loop, ps])
                sink.flush()
                print("  %-20s %d thr  run %d: %9.2f ns/day  process %7.2f s  set-up %5.1f %%" % (
                    row, threads, repeat + 1, ns_day, wall, 100.0 * setup), flush=True)
    return runs, checks


def fastest_row(args, runs, threads, code):
    """The row of `code` with the highest median ns/day at this thread count, or None."""
    rows = [r for r in args.rows if r in PEER_ROWS and PEER_ROWS[r][0] == code
            and (r, threads) in runs]
    median = lambda r: statistics.median(x[0] for x in runs[(r, threads)])
    return max(rows, key=median) if rows else None


def summary(args, runs, checks, header):
    lines = list(header) + ["", "checks (once per row, outside the timings):"]
    lines += ["  %-20s %s" % (row, checks.get(row, "(no successful run)")) for row in args.rows]
    for threads in args.threads:
        refs = [r for r in (fastest_row(args, runs, threads, c) for c in GROMACS_CODES) if r]
        lines += ["", "%d thread(s): ns/day median [min-max] of n runs; process wall and set-up "
                  "fraction medians; ratio to %s (median ratio [widest by the repeats])" % (
                      threads, " and to ".join(refs) or "no GROMACS row"),
                  "  %-20s %9s %21s %3s %9s %8s  %s" % ("row", "ns/day", "[min-max]", "n",
                                                        "wall s", "set-up", "ratios")]
        for row in args.rows:
            lines.append(summary_line(row, runs.get((row, threads)),
                                      [runs[(ref, threads)] for ref in refs]))
    return lines


def summary_line(row, these, refs):
    if not these:
        return "  %-20s (no successful run)" % row
    ns = [x[0] for x in these]
    setup = statistics.median(x[2] for x in these)
    text = "  %-20s %9.2f %21s %3d %9.2f %7.1f%%%s" % (
        row, statistics.median(ns), "[%.2f-%.2f]" % (min(ns), max(ns)), len(ns),
        statistics.median(x[1] for x in these), 100.0 * setup, "!" if setup > 0.05 else " ")
    for ref in refs:
        rs = [x[0] for x in ref]
        text += " %6.2f [%.2f-%.2f]" % (statistics.median(ns) / statistics.median(rs),
                                         min(ns) / max(rs), max(ns) / min(rs))
    return text


# ------------------------------------------------------------------ judged runs --------------
def judged_trajectory(row, args, runs_dir):
    """Run a row once for --ps at 1 thread, writing its frames every --frame-fs fs; returns
    (the path analyze reads, ns/day of this run)."""
    files = system_files(args.system)
    if row in args.longstep:
        out = os.path.join(runs_dir, row)
        shutil.rmtree(out, ignore_errors=True)
        cmd = [BIN, "run", files["scene"]] + shlex.split(args.longstep[row]) + [
            "--t-end", "%gps" % args.ps, "--quiet", "--allow-large", "--out", out]
        res = h2h.sh(cmd, cwd=ROOT, env=dict(os.environ, RAYON_NUM_THREADS="1"))
        if res.returncode != 0:
            raise RuntimeError("longstep failed (exit %d): %s" % (
                res.returncode, (res.stderr or res.stdout)[-1500:]))
        return out, longstep_summary(res.stdout)[0]
    if PEER_ROWS[row][0] in GROMACS_CODES:
        path = os.path.join(runs_dir, row + ".xtc")
        ns_day = run_gromacs(row, files, args.ps, 1, 1, False, (path, args.frame_fs))[0]
        return path, ns_day
    path = os.path.join(runs_dir, row + ".dcd")
    pme = longstep_pme(files["scene"])
    ns_day = run_openmm(row, files, args.ps, 1, 1, False, pme, (path, args.frame_fs))[0]
    return path, ns_day


def analyze_command(args, paths, labels):
    """One `longstep analyze` of every judged trajectory (or run directory) against --judge
    REF, so that the reference is analysed once; .dcd frames carry no time (--frame-time)."""
    return [BIN, "analyze", system_files(args.system)["scene"]] + paths + [
        "--labels", ",".join(labels), "--reference", args.judge, "--temperature",
        "%gK" % TEMPERATURE, "--skip", "%gps" % args.skip_ps, "--frame-time",
        "%gfs" % args.frame_fs, "--json", "--quiet", "--out",
        os.path.join(os.path.dirname(paths[0]), "analysis")] + shlex.split(args.analyze_args)


def verdict_text(summary):
    """'pass', or the verdict with the criteria that fail and those undecided."""
    text = summary["verdict"]
    for kind in ("fail", "undecided"):
        names = [c["name"] for c in summary["criteria"] if c["verdict"] == kind]
        if names and text != "pass":
            text += "; %s: %s" % (kind, ", ".join(names))
    return text


def judge_sitting(args):
    """Every row once (its trajectory), then one analyze of them all against --judge; returns
    ({row: (verdict word, verdict text, ns/day of the judged run)}, the analyze command),
    writing PREFIX-verdicts.json (every analysis)."""
    runs_dir = os.path.join(ROOT, "out", "peers-judged-" + args.system)
    os.makedirs(runs_dir, exist_ok=True)
    made = {}
    for row in args.rows:
        try:
            made[row] = judged_trajectory(row, args, runs_dir)
        except Exception as e:  # a failed row is reported; the others go on
            print("  %-20s FAILED: %s" % (row, e), flush=True)
            continue
        print("  %-20s %s (%.2f ns/day with its frames)" % (row, made[row][0], made[row][1]),
              flush=True)
    if not made:
        return {}, None
    cmd = analyze_command(args, [p for p, _ in made.values()], list(made))
    shown = shlex.join([os.path.relpath(w, ROOT) if w.startswith(ROOT) else w for w in cmd])
    print("  " + shown, flush=True)
    res = h2h.sh(cmd, cwd=ROOT, env=dict(os.environ, RAYON_NUM_THREADS=str(args.threads[0])))
    if res.returncode != 0:
        sys.exit("analyze failed: %s" % res.stderr[-1500:])
    summaries = json.loads(res.stdout)
    with open(args.out + "-verdicts.json", "w") as f:  # analyze's array: verdict_table.py
        json.dump(summaries, f, indent=1)
    analyses = dict(zip(made, summaries))
    verdicts = {row: (a["verdict"], verdict_text(a), made[row][1])
                for row, a in analyses.items()}
    return verdicts, shown


def timing_medians(paths):
    """{row: median one-thread ns/day} from sittings' csv files (--timings; a row in several
    takes the last file's)."""
    medians = {}
    for path in paths:
        runs = {}
        with open(path) as f:
            for r in csv.DictReader(f):
                if r["threads"] == "1":
                    runs.setdefault(r["row"], []).append(float(r["ns_day"]))
        medians.update({row: statistics.median(v) for row, v in runs.items()})
    return medians


def judged_table(args, verdicts, command):
    """The rows with their verdicts; with --timings each row's one-thread median ns/day and
    its ratio to the fastest peer row that does not fail (a failing row keeps its ns/day)."""
    medians = timing_medians(args.timings) if args.timings else {}
    peers = [r for r in verdicts if r in PEER_ROWS and verdicts[r][0] != "fail"
             and r in medians]
    anchor = max(peers, key=lambda r: medians[r]) if peers else None
    lines = ["", "verdicts against %s (%g ps per row, %g ps skipped, a frame every %g fs); "
             "ns/day: %s; ratio to %s, the fastest peer row that does not fail" % (
                 args.judge, args.ps, args.skip_ps, args.frame_fs,
                 " and ".join(args.timings) or "the judged run itself (frames written)",
                 anchor or "none"),
             "analyze: " + (command or "(not run)")]
    for row in args.rows:
        if row not in verdicts:
            lines.append("  %-20s (no verdict: the run or its analysis failed)" % row)
            continue
        word, text, ns_day = verdicts[row]
        ns = medians.get(row, ns_day)
        ratio = "%.2f" % (ns / medians[anchor]) if anchor and row in medians else "-"
        mark = " (fails)" if word == "fail" else ""
        lines.append("  %-20s %9.2f ns/day%s  ratio %s  %s" % (row, ns, mark, ratio, text))
    return lines


# ------------------------------------------------------------------ command line -------------
def parse_args(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog=__doc__.split("\n", 1)[1])
    ap.add_argument("--system", choices=sorted(SYSTEMS), required=True)
    ap.add_argument("--longstep", action="append", default=[], metavar="LABEL=ARGS",
                    help="a longstep row: LABEL and the flags of `longstep run` (repeatable)")
    ap.add_argument("--rows", default=",".join(PEER_ROWS),
                    help="peer rows, comma-separated (default all; 'none' for none)")
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--ps", type=float, default=None,
                    help="simulated ps per run (default ala2 %g, trpcage %g)" % (
                        DEFAULT_PS["ala2"], DEFAULT_PS["trpcage"]))
    ap.add_argument("--seconds", type=float, default=None,
                    help="length each row's runs for about this many seconds of timed loop, "
                         "from a calibration run of --ps (default: every run --ps)")
    ap.add_argument("--out", default=None, help="PREFIX of PREFIX.csv and PREFIX.txt")
    ap.add_argument("--no-install", dest="install", action="store_false")
    ap.add_argument("--judge", metavar="REF", default=None,
                    help="judge every row instead of timing it: one run of --ps at 1 thread "
                         "writing its frames (GROMACS .xtc, OpenMM .dcd, longstep's run "
                         "directory), then `longstep analyze ... --reference REF --json`")
    ap.add_argument("--frame-fs", type=float, default=48.0,
                    help="with --judge: fs between frames (default 48)")
    ap.add_argument("--skip-ps", type=float, default=4.0,
                    help="with --judge: ps left out of each run (default 4)")
    ap.add_argument("--analyze-args", default="",
                    help="with --judge: more flags for analyze (e.g. '--stride 4')")
    ap.add_argument("--timings", metavar="CSV", action="append", default=[],
                    help="with --judge: a timing sitting's csv, for ns/day and the ratios "
                         "(repeatable; a row in several takes the last one's)")
    ap.add_argument("--no-build-native", dest="build_native", action="store_false",
                    help="do not build the native GROMACS when it is missing (its rows are "
                         "then left out)")
    args = ap.parse_args(argv)
    check_args(ap, args)
    return args


def check_args(ap, args):
    try:
        args.threads = [int(t) for t in args.threads.split(",")]
    except ValueError:
        ap.error("--threads: %r is not a comma-separated list of integers" % args.threads)
    if args.repeats < 1 or min(args.threads) < 1:
        ap.error("--repeats and --threads must be at least 1")
    peers = [] if args.rows == "none" else args.rows.split(",")
    for row in peers:
        if row not in PEER_ROWS:
            ap.error("--rows: unknown row %r (known: %s)" % (row, ", ".join(PEER_ROWS)))
    longstep = {}
    for item in args.longstep:
        label, eq, flags = item.partition("=")
        if not eq or not label or label in longstep or label in PEER_ROWS:
            ap.error("--longstep %r: give LABEL=ARGS with a new label" % item)
        words = shlex.split(flags)
        if any(w.split("=")[0] in ("--t-end", "--out") for w in words):
            ap.error("--longstep %s: --t-end and --out are set by the script (--ps)" % label)
        if "--energy-every" not in " ".join(words):
            print("note: --longstep %s has no --energy-every: longstep evaluates the energy "
                  "every step, inside its timed loop" % label, file=sys.stderr)
        longstep[label] = flags
    args.longstep = longstep
    args.rows = peers + list(longstep)
    if not args.rows:
        ap.error("no rows: give --rows or --longstep")
    args.ps = DEFAULT_PS[args.system] if args.ps is None else args.ps
    if not args.ps > 0:
        ap.error("--ps must be positive")
    if args.seconds is not None and not args.seconds > 0:
        ap.error("--seconds must be positive")
    if args.judge is not None:
        if not os.path.exists(args.judge):
            ap.error("--judge %s: no such reference run directory or trajectory" % args.judge)
        args.judge = os.path.abspath(args.judge)
        if not (args.frame_fs > 0 and args.skip_ps >= 0 and args.skip_ps < args.ps):
            ap.error("--frame-fs must be positive and --skip-ps in [0, --ps)")
        for label, flags in args.longstep.items():
            if "--trajectory-every" not in flags:
                ap.error("--longstep %s: a judged row needs --trajectory-every N (its frames "
                         "every --frame-fs)" % label)
    for path in args.timings:
        if not os.path.isfile(path):
            ap.error("--timings %s: no such file" % path)
    if args.out is None:
        args.out = os.path.join(ROOT, "docs", "data", "sittings", "production-%s-%s" % (
            args.system, time.strftime("%Y-%m-%d", time.gmtime())))


def header_lines(args, pme):
    cpu = open("/proc/cpuinfo").read().split("model name")[1].split(":")[1].split("\n")[0]
    codes = sorted({PEER_ROWS[r][0] for r in args.rows if r in PEER_ROWS})
    return [
        "command: " + shlex.join(["python3", os.path.relpath(os.path.abspath(__file__), ROOT)]
                                 + sys.argv[1:]),
        "machine: %s, %d cores, load average %s at %s" % (
            cpu.strip(), os.cpu_count(), " ".join("%.2f" % x for x in os.getloadavg()),
            time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())),
        "versions: " + h2h.versions(codes),
        "system: %s (%s), %s, %d repeats, threads %s" % (
            args.system, os.path.relpath(system_files(args.system)["scene"], ROOT),
            "%g ps per run" % args.ps if args.seconds is None else
            "runs of about %g s of timed loop (each row's ps from a %g ps calibration run; "
            "column ps of the csv)" % (args.seconds, args.ps),
            args.repeats, ",".join(map(str, args.threads))),
        "longstep PME: alpha %.6f 1/A, grid %s, order %d (OpenMM gets this alpha and grid, "
        "order 5); GROMACS ewald-rtol %g, fourier-spacing 0.12 nm, order %d" % (
            pme["alpha"], "x".join(map(str, pme["grid"])), pme["order"], h2h.PME_RTOL,
            h2h.PME_ORDER),
    ] + ["longstep row %s: longstep run SCENE %s --t-end PS --quiet --out TMP" % (
        label, flags) for label, flags in args.longstep.items()]


def main(argv):
    if len(argv) == 2 and argv[0] == "--openmm-worker":
        return openmm_worker(json.loads(argv[1]))
    args = parse_args(argv)
    if not os.path.exists(BIN):
        sys.exit("no release build at %s: run `cargo build --release` first" % BIN)
    codes = sorted({PEER_ROWS[r][0] for r in args.rows if r in PEER_ROWS})
    if args.install and codes:
        h2h.install(codes)
    if h2h.NATIVE in codes and not h2h.native_ready(args.build_native):
        args.rows = [r for r in args.rows if PEER_ROWS.get(r, ("",))[0] != h2h.NATIVE]
        codes.remove(h2h.NATIVE)
        if not args.rows:
            sys.exit("no rows left without the native GROMACS")
    for code in codes:
        if code == "gromacs" and not shutil.which("gmx"):
            sys.exit("gmx is not on PATH (install GROMACS, or leave out the gmx rows)")
    pme = longstep_pme(system_files(args.system)["scene"])
    header = header_lines(args, pme)
    print("\n".join(header), flush=True)
    os.makedirs(os.path.dirname(os.path.abspath(args.out)) or ".", exist_ok=True)
    if args.judge is not None:
        lines = header + judged_table(args, *judge_sitting(args))
        with open(args.out + "-verdicts.txt", "w") as f:
            f.write("\n".join(lines) + "\n")
        print("\n".join(lines[len(header):]))
        return
    with open(args.out + ".csv", "w", newline="") as sink:
        writer = csv.writer(sink)
        writer.writerow(["system", "row", "threads", "repeat", "ns_day", "wall_s",
                         "setup_fraction", "loop_s", "ps"])
        start = time.time()
        runs, checks = sitting(args, pme, writer, sink)
    lines = summary(args, runs, checks, header)
    lines += ["", "sitting took %.0f s; every run in %s.csv" % (
        time.time() - start, os.path.basename(args.out))]
    with open(args.out + ".txt", "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines[len(header):]))


if __name__ == "__main__":
    main(sys.argv[1:])
