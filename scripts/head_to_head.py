#!/usr/bin/env python3
"""Head-to-head throughput: longstep against GROMACS, LAMMPS and OpenMM on the kit's water boxes.

Runs from a clone and reads no file outside it: the longstep scenes are systems/water-box/
(216 waters, 648 atoms) and systems/water-box-1728/ (1728 waters, 5 184 atoms); the peers'
inputs are copies of the peers' comparison kit in scripts/peers/ (OpenMM system builder
mdsys.py with the systems' JSON, LAMMPS data and input, GROMACS .gro/.top).

Model and integrator (NVE, the kit's coordinates and 300 K velocities): SPC/Fw water, LJ
O-O energy-shifted at 9 A, shifted-force Coulomb at 9 A, all intramolecular pairs excluded;
r-RESPA impulse with bonds and angles inner at 0.5 fs and non-bonded outer at h.

  longstep : `longstep run SCENE --method impulse --h H --inner K [--precision mixed]`, wall
             time of the stepping loop from the JSON summary; threads = RAYON_NUM_THREADS
  GROMACS  : two builds of the same 2022.5 sources, both run:
             `gromacs-native`: GROMACS built for this machine's SIMD (cmake GMX_SIMD=AUTO,
               AVX2_256 or AVX_512 on current x86) by scripts/build_gromacs_native.sh into a
               cache folder outside the repository (built the first time: about 12 minutes
               on 2 idle cores, over an hour on a loaded machine; --no-build-native skips
               it), mixed precision: the anchor, what a user who
               compiles GROMACS or loads a cluster's module runs;
             `gromacs`: Debian's package, `gmx` (mixed) and `gmx_d` (double), built for
               SSE4.1 only (portability), kept because many users have only that.
             Two-level MTS (non-bonded every K steps of 0.5 fs), -ntmpi 1 -ntomp THREADS -pin
             on -resethway, ns/day from the log. Its closest model: reaction-field Coulomb
             with eps_rf = infinity (same cost, a different model: potential energy -4.3 %).
             The mdp is GROMACS's production default: the Verlet buffer from
             verlet-buffer-tolerance 0.005, nstcalcenergy and nstcomm 100 (rounded up to a
             multiple of K), nstlist as mdrun tunes it. mdrun does not tune nstlist in NVE
             ("Can not increase nstlist because an NVE ensemble is used"), so each GROMACS
             first runs mdrun -nsteps 0 on the same input with v-rescale at 300 K from nstlist
             10 (the smallest multiple of K from 10 with MTS) and the timed NVE runs use the
             nstlist it chose (grompp sizes the buffer for it from the initial temperature).
             Each GROMACS's SIMD level and nstlist are printed once per size and scheme
  LAMMPS   : `lmp` with run_style respa 2 K bond 1 angle 1 pair 2 ("Loop time"), the same
             model (lj/cut/coul/dsf); 2 threads = mpirun -np 2 (no OpenMP package in Debian's)
  OpenMM   : CPU platform (its own mixed precision), CustomNonbondedForce with the same model,
             MTSIntegrator(h, [(1, 1), (0, K)]), Threads = THREADS

The codes are interleaved (each repeat runs every code once, in turn) so all see the same
machine load; each configuration runs --repeats times (default 3). Printed: every run, the
median, ns/day, and the ratios of longstep (double and mixed) to each peer and to the fastest.

    python3 scripts/head_to_head.py                       # the full sitting (see --help)
    python3 scripts/head_to_head.py --quick               # smoke test: a few steps per run
    python3 scripts/head_to_head.py --sizes 648 --threads 1 --h 4 --codes longstep,gromacs

--coulomb pme: the same water model with smooth particle-mesh Ewald at GROMACS's defaults
(r_c 9 A, ewald-rtol 1e-5 so alpha = 0.347/A, fourier-spacing 1.2 A, order 4) on the 648-,
5 184- and 41 472-atom boxes (the last the 1728-water box replicated 2x2x2, written at the
start into a temporary directory for every code). --h 0.5 is plain velocity Verlet at
0.5 fs; --h 1 and 2 are MTS with bonds, angles and real space at 0.5 fs and the reciprocal
sum every 2 and 4 inner steps (defaults: 0.5,1,2). Each code's own PME parameters are
printed once per size (alpha, grid, order) so that the runs can be checked to be the same
accuracy:

  longstep : --coulomb pme --pme-order 4; plain `--method verlet --h 0.5fs`, MTS `--method
             impulse --inner K --nonbonded-level 0 --pme-level 1`
  GROMACS  : both builds; coulombtype = PME, ewald-rtol 1e-5, fourier-spacing 0.12, pme-order
             4, nstlist as mdrun tunes it (as above), nstcalcenergy 100; MTS
             mts-level2-forces = longrange-nonbonded, mts-level2-factor = K; -notunepme (on
             one rank without a GPU mdrun does not tune PME anyway)
  LAMMPS   : lj/cut/coul/long 9 with pppm, kspace_modify gewald/mesh/order 4/diff ad (the
             analytic-derivative SPME of the others) with longstep's alpha and grid; excluded
             pairs by special_bonds (their erf correction); MTS run_style respa 2 K bond 1
             angle 1 pair 1 kspace 2
  OpenMM   : NonbondedForce PME with longstep's alpha and grid (OpenMM's order is always 5;
             LJ forces identical, its energy unshifted); MTS MTSIntegrator with the
             reciprocal space in its own force group, [(2, 1), (1, K), (0, K)]

    python3 scripts/head_to_head.py --coulomb pme --json out/pme.json | tee out/pme.txt

The peers are installed when missing (--no-install to skip): OpenMM with pip, LAMMPS, GROMACS
and Open MPI with apt-get, the native GROMACS by scripts/build_gromacs_native.sh
(--no-build-native to skip; the row is then dropped when the build is not there). Needs a
release build of longstep (`cargo build --release`).
"""
import argparse
import functools
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

import math

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, ".."))
PEERS = os.path.join(HERE, "peers")
BIN = os.path.join(ROOT, "target", "release", "longstep")
BUILD_NATIVE = os.path.join(HERE, "build_gromacs_native.sh")
NATIVE = "gromacs-native"
GROMACS_CODES = (NATIVE, "gromacs")
INNER = 0.5  # fs

# atoms -> (kit name, longstep scene, structure dir)
SYSTEMS = {
    648: ("water216", "systems/water-box/scene.toml", "systems/water-box"),
    5184: ("water1728", "systems/water-box-1728/scene.toml", "systems/water-box-1728"),
}
# Outer steps per run, chosen for a few seconds of stepping on this machine kind at 1 thread
# (about 1-4 s each; the peers' start-up is outside their timed loops).
STEPS = {
    "longstep": {648: 3000, 5184: 400},
    "gromacs": {648: 4000, 5184: 800},
    NATIVE: {648: 6000, 5184: 1200},
    "lammps": {648: 600, 5184: 80},
    "openmm": {648: 400, 5184: 60},
}
# GROMACS's production defaults: nstlist 10 (mdrun raises it; with MTS it must be a multiple
# of the factor K) and energies every 100 steps (nstcalcenergy; a multiple of K).
NSTLIST_DEFAULT = 10
NSTCALCENERGY_DEFAULT = 100


def multiple_of(k, at_least):
    """The smallest multiple of k that is at least `at_least`."""
    return k * -(-at_least // k)

# The GROMACS run settings both electrostatics share: plain MD from the given velocities,
# no thermostat or barostat, Lennard-Jones cut and shifted at 0.9 nm, nothing written.
MDP_HEAD = """integrator = md
dt = 0.0005
nsteps = {nsteps}
tcoupl = no
pcoupl = no
cutoff-scheme = Verlet
"""
MDP_RUN = """vdwtype = Cut-off
vdw-modifier = Potential-shift
rvdw = 0.9
DispCorr = no
constraints = none
continuation = yes
gen-vel = no
nstcalcenergy = {nstcalc}
verlet-buffer-tolerance = 0.005
nstenergy = 0
nstlog = 0
nstxout = 0
nstvout = 0
nstfout = 0
comm-mode = Linear
nstcomm = {nstcalc}
"""
MDP = (MDP_HEAD + """coulombtype = Reaction-Field
epsilon-rf = 0
rcoulomb = 0.9
""" + MDP_RUN + """nstlist = {nstlist}
mts = yes
mts-levels = 2
mts-level2-forces = longrange-nonbonded nonbonded pair dihedral
mts-level2-factor = {k}
""")


def sh(cmd, **kw):
    return subprocess.run(cmd, capture_output=True, text=True, **kw)


def run_longstep(atoms, h, k, steps, threads, precision):
    scene = SYSTEMS[atoms][1]
    with tempfile.TemporaryDirectory() as out:
        env = dict(os.environ, RAYON_NUM_THREADS=str(threads))
        cmd = [BIN, "run", scene, "--method", "impulse", "--h", "%gfs" % h, "--inner", str(k),
               "--t-end", "%gfs" % (h * steps), "--energy-every", str(steps),
               "--quiet", "--json", "--out", out, "--precision", precision]
        res = sh(cmd, cwd=ROOT, env=env)
        if res.returncode != 0:
            raise RuntimeError("longstep failed: %s" % res.stderr[-2000:])
        s = json.loads(res.stdout)
        return s["steps"] / s["wall_seconds"]


def gmx_binary(code, precision):
    """The gmx of a GROMACS code: Debian's gmx / gmx_d, or the native build's gmx."""
    if code == NATIVE:
        return native_gmx()
    return "gmx_d" if precision == "double" else "gmx"


@functools.lru_cache(maxsize=None)
def native_gmx():
    """Where scripts/build_gromacs_native.sh installs (or would install) the native gmx."""
    res = sh(["bash", BUILD_NATIVE, "--path"])
    if res.returncode != 0:
        raise RuntimeError("build_gromacs_native.sh --path failed: %s" % res.stderr[-500:])
    return res.stdout.strip()


def gromacs_log_note(text):
    """The SIMD level the mdrun binary used and the nstlist / rlist mdrun chose, from md.log."""
    simd = re.search(r"^SIMD instructions:\s+(\S+)", text, re.M)
    changed = re.search(r"Changing nstlist from (\d+) to (\d+), rlist from (\S+) to (\S+)", text)
    if changed:
        nstlist = "nstlist %s -> %s, rlist %s -> %s nm (mdrun)" % changed.groups()
    else:
        found = re.findall(r"^\s*nstlist\s*=\s*(\d+)", text, re.M)
        rlist = re.findall(r"^\s*rlist\s*=\s*(\S+)", text, re.M)
        nstlist = "nstlist %s, rlist %s nm" % (found[-1] if found else "?",
                                                rlist[-1] if rlist else "?")
    return "SIMD %s, %s" % (simd.group(1) if simd else "?", nstlist)


def gromacs_mdrun(code, precision, mdp_text, gro, top, inner_steps, threads, extra=()):
    """grompp and mdrun one run in a temporary directory; returns md.log's text."""
    gmx = gmx_binary(code, precision)
    with tempfile.TemporaryDirectory() as work:
        mdp = os.path.join(work, "run.mdp")
        with open(mdp, "w") as f:
            f.write(mdp_text)
        tpr = os.path.join(work, "run.tpr")
        res = sh([gmx, "grompp", "-f", mdp, "-c", gro, "-p", top, "-o", tpr,
                  "-po", os.path.join(work, "out.mdp"), "-maxwarn", "1"], cwd=work)
        if res.returncode != 0:
            raise RuntimeError("grompp failed: %s" % res.stderr[-2000:])
        log = os.path.join(work, "md.log")
        res = sh([gmx, "mdrun", "-s", tpr, "-nsteps", str(inner_steps), "-ntmpi", "1",
                  "-ntomp", str(threads), "-pin", "on", "-noconfout", "-resethway", "-g", log,
                  "-e", os.path.join(work, "ener.edr")] + list(extra), cwd=work,
                 env=dict(os.environ, GMX_MAXBACKUP="-1"))
        if res.returncode != 0:
            raise RuntimeError("mdrun failed: %s" % res.stderr[-2000:])
        return open(log).read()


def gromacs_outer_steps_per_s(text, h):
    ns_per_day = float(re.search(r"^Performance:\s+([0-9.eE+-]+)", text, re.M).group(1))
    return ns_per_day / (h * 1e-6 * 86400.0)


# (code, precision, coulomb, atoms, K) -> the nstlist mdrun chose in its NVT probe.
TUNED_NSTLIST = {}
NVT_PROBE = """tcoupl = v-rescale
tc-grps = System
tau-t = 0.1
ref-t = 300
"""


def tuned_nstlist(key, mdp_format, k, gro, top):
    """The nstlist mdrun picks for this input at 300 K with v-rescale (mdrun -nsteps 0 from
    nstlist 10, or the smallest multiple of K above it), once per key. mdrun raises nstlist
    only with a thermostat; the NVE runs then use its choice."""
    if key not in TUNED_NSTLIST:
        start = multiple_of(k, NSTLIST_DEFAULT)
        mdp = mdp_format(start).replace("tcoupl = no\n", NVT_PROBE)
        text = gromacs_mdrun(key[0], key[1], mdp, gro, top, 0, 1)
        changed = re.search(r"Changing nstlist from \d+ to (\d+)", text)
        TUNED_NSTLIST[key] = int(changed.group(1)) if changed else start
    return TUNED_NSTLIST[key]


def run_gromacs(atoms, h, k, steps, threads, precision, code="gromacs"):
    name = SYSTEMS[atoms][0]
    gro = os.path.join(PEERS, "gromacs", name + ".gro")
    top = os.path.join(PEERS, "gromacs", name + ".top")
    inner_steps = steps * k
    nstcalc = multiple_of(k, NSTCALCENERGY_DEFAULT)
    mdp = lambda nstlist: MDP.format(nsteps=inner_steps, nstcalc=nstcalc, nstlist=nstlist, k=k)
    nstlist = tuned_nstlist((code, precision, "rf", atoms, k), mdp, k, gro, top)
    text = gromacs_mdrun(code, precision, mdp(nstlist), gro, top, inner_steps, threads)
    check_note("%s %s" % (code, precision), atoms, k, gromacs_log_note(text))
    return gromacs_outer_steps_per_s(text, h)


def run_gromacs_native(atoms, h, k, steps, threads, precision):
    return run_gromacs(atoms, h, k, steps, threads, precision, code=NATIVE)


def run_lammps(atoms, h, k, steps, threads, precision):
    name = SYSTEMS[atoms][0]
    with tempfile.TemporaryDirectory() as work:
        log = os.path.join(work, "log")
        lmp = ["lmp", "-nocite", "-screen", "none", "-var", "dir", os.path.join(PEERS, "systems"),
               "-var", "sys", name, "-var", "integ", "respa", "-var", "dt", str(h),
               "-var", "k", str(k), "-var", "nsteps", str(steps), "-var", "thermo", str(steps),
               "-in", os.path.join(PEERS, "lammps", "in.md"), "-log", log]
        if threads > 1:
            lmp = ["mpirun", "-np", str(threads), "--bind-to", "core"] + lmp
        env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
                   OMP_NUM_THREADS="1")
        res = sh(lmp, cwd=work, env=env, stdin=subprocess.DEVNULL)
        if res.returncode != 0:
            raise RuntimeError("lmp failed: %s" % (res.stderr or res.stdout)[-2000:])
        loop = float(re.search(r"Loop time of ([0-9.eE+-]+) on", open(log).read()).group(1))
        return steps / loop


def run_openmm(atoms, h, k, steps, threads, precision):
    sys.path.insert(0, PEERS)
    import mdsys
    import openmm as mm
    name, _, directory = SYSTEMS[atoms]
    p = mdsys.load_params(name)
    system = mdsys.build_openmm_system(p, "identical")
    integ = mm.MTSIntegrator(h * 1e-3, [(1, 1), (0, k)])
    ctx = mm.Context(system, integ, mm.Platform.getPlatformByName("CPU"), {"Threads": str(threads)})
    x = mdsys.read_xyz(os.path.join(ROOT, directory, name + ".xyz"))[1]
    v = mdsys.read_xyz(os.path.join(ROOT, directory, name + ".vel.xyz"))[1]
    ctx.setPositions(x * mdsys.A2NM)
    ctx.setVelocities(v * mdsys.V_A_FS_TO_NM_PS)
    integ.step(2)  # first steps build the neighbour list and compile kernels
    start = time.perf_counter()
    integ.step(steps)
    ctx.getState(getEnergy=True)  # waits for the steps to finish
    return steps / (time.perf_counter() - start)


RUNNERS = {"longstep": run_longstep, "gromacs": run_gromacs, NATIVE: run_gromacs_native,
           "lammps": run_lammps, "openmm": run_openmm}
# (code, atoms, K) -> the settings a code reported (SIMD, nstlist), printed once.
CHECKS = {}


def check_note(code, atoms, k, text):
    if (code, atoms, k) not in CHECKS:
        CHECKS[(code, atoms, k)] = text
        print("  %5d atoms  K %d  %-22s check: %s" % (atoms, k, code, text), flush=True)

# ---------------------------------------------------------------- PME mode ------------------
PME_SYSTEMS = {
    648: ("water216", "systems/water-box", 1),
    5184: ("water1728", "systems/water-box-1728", 1),
    41472: ("water1728", "systems/water-box-1728", 2),
}
PME_CUTOFF = 9.0     # A
PME_RTOL = 1e-5      # GROMACS ewald-rtol: erfc(alpha r_c) = rtol
PME_SPACING = 1.2    # A
PME_ORDER = 4
# Inner steps (0.5 fs) per run, for about 1-2 s of stepping at 1 thread on this machine kind
# (GROMACS times the second half of its steps: -resethway). A whole PME sitting (3 sizes,
# 1 and 2 threads, 3 schemes, 3 repeats, 324 runs) takes about 20 minutes.
PME_STEPS = {
    "longstep": {648: 800, 5184: 120, 41472: 40},
    "gromacs": {648: 1600, 5184: 240, 41472: 40},
    NATIVE: {648: 2400, 5184: 360, 41472: 60},
    "lammps": {648: 320, 5184: 48, 41472: 8},
    "openmm": {648: 400, 5184: 48, 41472: 8},
}
# (code, atoms) -> the PME parameters the code reported, printed once.
PME_SEEN = {}


def pme_alpha():
    """alpha with erfc(alpha r_c) = ewald-rtol, by bisection (1/A)."""
    low, high = 0.0, 10.0
    for _ in range(200):
        mid = 0.5 * (low + high)
        if math.erfc(mid) > PME_RTOL:
            low = mid
        else:
            high = mid
    return 0.5 * (low + high) / PME_CUTOFF


def pme_note(code, atoms, text):
    if (code, atoms) not in PME_SEEN:
        PME_SEEN[(code, atoms)] = text
        print("  %5d atoms  %-8s PME: %s" % (atoms, code, text), flush=True)


class PmeInputs:
    """The 41 472-atom inputs of every code, written once into a temporary directory."""

    def __init__(self, sizes, codes):
        self.codes = codes
        self.work = tempfile.mkdtemp(prefix="h2h-pme-")
        self.scenes = {a: os.path.join(PME_SYSTEMS[a][1], "scene.toml") for a in sizes}
        self.gro, self.top = {}, {}
        for atoms in sizes:
            name = PME_SYSTEMS[atoms][0]
            self.gro[atoms] = os.path.join(PEERS, "gromacs", name + ".gro")
            self.top[atoms] = os.path.join(PEERS, "gromacs", name + ".top")
        if 41472 in sizes:
            self.replicate()

    def replicate(self):
        box = os.path.join(self.work, "water-box-41472")
        res = sh([sys.executable, os.path.join(HERE, "replicate_box.py"),
                  os.path.join(ROOT, "systems", "water-box-1728"), "2", box])
        if res.returncode != 0:
            sys.exit("replicate_box.py failed: %s" % res.stderr)
        self.scenes[41472] = os.path.join(box, "scene.toml")
        gmx = [gmx_binary(c, "mixed") for c in GROMACS_CODES if c in self.codes]
        if not gmx:
            return
        gro = os.path.join(self.work, "water13824.gro")
        res = sh([gmx[0], "genconf", "-f", os.path.join(PEERS, "gromacs", "water1728.gro"),
                  "-nbox", "2", "2", "2", "-o", gro], cwd=self.work)
        if res.returncode != 0:
            sys.exit("gmx genconf failed: %s" % res.stderr[-2000:])
        top = open(os.path.join(PEERS, "gromacs", "water1728.top")).read()
        top = re.sub(r"^SOL\s+1728\s*$", "SOL 13824", top, flags=re.M)
        top = top.replace("water1728\n[ molecules", "water13824\n[ molecules")
        self.gro[41472], self.top[41472] = gro, os.path.join(self.work, "water13824.top")
        with open(self.top[41472], "w") as f:
            f.write(top)

    def close(self):
        shutil.rmtree(self.work, ignore_errors=True)


PME = None  # PmeInputs of the sitting


def pme_scheme(h):
    """(inner steps K per outer step, plain?) for an outer step h in fs."""
    k = round(h / INNER)
    return k, k == 1


def run_longstep_pme(atoms, h, k, steps, threads, precision):
    scene = PME.scenes[atoms]
    with tempfile.TemporaryDirectory() as out:
        env = dict(os.environ, RAYON_NUM_THREADS=str(threads))
        method = (["--method", "verlet"] if k == 1 else
                  ["--method", "impulse", "--inner", str(k), "--nonbonded-level", "0",
                   "--pme-level", "1"])
        cmd = [BIN, "run", scene, "--coulomb", "pme", "--pme-order", str(PME_ORDER),
               "--h", "%gfs" % h, "--t-end", "%gfs" % (h * steps), "--energy-every", str(steps),
               "--json", "--out", out, "--precision", precision] + method
        res = sh(cmd, cwd=ROOT, env=env)
        if res.returncode != 0:
            raise RuntimeError("longstep failed: %s" % res.stderr[-2000:])
        m = re.search(r"pme-reciprocal: (PME, alpha = \S+ 1/\S+, grid \S+, order \d+)",
                      res.stderr)
        pme_note("longstep", atoms, m.group(1) if m else "(not reported)")
        s = json.loads(res.stdout)
        return s["steps"] / s["wall_seconds"]


def longstep_grid(atoms):
    """The grid `longstep check` reports for the box's PME (the peers without a spacing rule
    use it): asked of longstep, so the script never keeps a copy of its grid rule."""
    res = sh([BIN, "check", PME.scenes[atoms], "--coulomb", "pme", "--pme-order",
              str(PME_ORDER)], cwd=ROOT)
    m = re.search(r"pme-reciprocal: PME, alpha = \S+ 1/\S+, grid (\d+)x\d+x\d+",
                  res.stdout + res.stderr)
    if res.returncode != 0 or not m:
        sys.exit("longstep check %s did not report its PME grid:\n%s" % (
            PME.scenes[atoms], (res.stderr or res.stdout)[-1500:]))
    return int(m.group(1))


PME_MDP = (MDP_HEAD + """coulombtype = PME
rcoulomb = 0.9
ewald-rtol = 1e-5
fourier-spacing = 0.12
pme-order = 4
""" + MDP_RUN + """nstlist = {nstlist}
""")
PME_MDP_MTS = """mts = yes
mts-levels = 2
mts-level2-forces = longrange-nonbonded
mts-level2-factor = {k}
"""


def run_gromacs_pme(atoms, h, k, steps, threads, precision, code="gromacs"):
    inner_steps = steps * k
    mdp = lambda nstlist: PME_MDP.format(nsteps=inner_steps, nstcalc=NSTCALCENERGY_DEFAULT,
                                         nstlist=nstlist) + (PME_MDP_MTS.format(k=k) if k > 1
                                                             else "")
    # The non-bonded pairs are on the fast level here: nstlist need not be a multiple of K.
    nstlist = tuned_nstlist((code, precision, "pme", atoms, k), mdp, 1, PME.gro[atoms],
                            PME.top[atoms])
    text = gromacs_mdrun(code, precision, mdp(nstlist), PME.gro[atoms], PME.top[atoms],
                         inner_steps, threads, extra=["-notunepme"])
    grid = [re.search(r"fourier-n%s\s*=\s*(\d+)" % a, text) for a in "xyz"]
    width = re.search(r"Gaussian width \(1/beta\) of ([0-9.eE+-]+) nm", text)
    order = re.search(r"pme-order\s*=\s*(\d+)", text)
    pme_note("%s %s" % (code, precision), atoms, "alpha = %s 1/A, grid %s, order %s" % (
        "%.6f" % (0.1 / float(width.group(1))) if width else "?",
        "x".join(g.group(1) if g else "?" for g in grid), order.group(1) if order else "?"))
    check_note("%s %s" % (code, precision), atoms, k, gromacs_log_note(text))
    return gromacs_outer_steps_per_s(text, h)


def run_gromacs_native_pme(atoms, h, k, steps, threads, precision):
    return run_gromacs_pme(atoms, h, k, steps, threads, precision, code=NATIVE)


def run_lammps_pme(atoms, h, k, steps, threads, precision):
    name, _, n = PME_SYSTEMS[atoms]
    grid = longstep_grid(atoms)
    with tempfile.TemporaryDirectory() as work:
        ff = open(os.path.join(PEERS, "systems", name + ".ff.lmp")).read().splitlines()
        ff = [line for line in ff if not line.startswith(("pair_style", "neigh_modify"))]
        deck = ["units real", "atom_style full", "boundary p p p",
                "read_data %s" % os.path.join(PEERS, "systems", name + ".data")]
        if n > 1:
            deck.append("replicate %d %d %d" % (n, n, n))
        deck += ["pair_style lj/cut/coul/long %g %g" % (PME_CUTOFF, PME_CUTOFF)] + ff + [
            "kspace_style pppm 1e-5",
            "kspace_modify gewald %.12g mesh %d %d %d order %d diff ad" % (
                pme_alpha(), grid, grid, grid, PME_ORDER),
            "neighbor 2.0 bin", "neigh_modify every 1 delay 0 check yes",
            "timestep %g" % h, "fix nve all nve", "thermo %d" % steps,
            "run_style respa 2 %d bond 1 angle 1 pair 1 kspace 2" % k if k > 1 else
            "run_style verlet",
            "run %d" % steps]
        deck_file = os.path.join(work, "in.pme")
        with open(deck_file, "w") as f:
            f.write("\n".join(deck) + "\n")
        log = os.path.join(work, "log")
        lmp = ["lmp", "-nocite", "-screen", "none", "-in", deck_file, "-log", log]
        if threads > 1:
            lmp = ["mpirun", "-np", str(threads), "--bind-to", "core"] + lmp
        env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
                   OMP_NUM_THREADS="1")
        res = sh(lmp, cwd=work, env=env, stdin=subprocess.DEVNULL)
        text = open(log).read() if os.path.exists(log) else ""
        if res.returncode != 0:
            raise RuntimeError("lmp failed: %s" % (res.stderr or res.stdout or text)[-2000:])
        g = re.search(r"G vector \(1/distance\) = ([0-9.eE+-]+)", text)
        mesh = re.search(r"grid = (\d+ \d+ \d+)", text)
        order = re.search(r"stencil order = (\d+)", text)
        acc = re.search(r"estimated relative force accuracy = ([0-9.eE+-]+)", text)
        pme_note("lammps", atoms, "alpha = %s 1/A, grid %s, order %s, relative force accuracy %s" % (
            g.group(1) if g else "?", mesh.group(1).replace(" ", "x") if mesh else "?",
            order.group(1) if order else "?", acc.group(1) if acc else "?"))
        loop = float(re.search(r"Loop time of ([0-9.eE+-]+) on", text).group(1))
        return steps / loop


def openmm_pme_system(p, n, k):
    """The kit's bonded terms and a PME NonbondedForce, for an n x n x n replica."""
    sys.path.insert(0, PEERS)
    import mdsys
    import openmm as mm
    if n > 1:
        p = replicate_params(p, n)
    system = mdsys.build_openmm_system(p, "identical")
    for index in reversed(range(system.getNumForces())):
        if system.getForce(index).getForceGroup() != 0:
            system.removeForce(index)
    _, charge = mdsys.per_atom_arrays(p)
    nb = mm.NonbondedForce()
    nb.setNonbondedMethod(mm.NonbondedForce.PME)
    nb.setCutoffDistance(PME_CUTOFF * mdsys.A2NM)
    grid = longstep_grid(p["n_atoms"])
    nb.setPMEParameters(pme_alpha() / mdsys.A2NM, grid, grid, grid)
    nb.setUseDispersionCorrection(False)
    nb.setUseSwitchingFunction(False)
    lj = p["nonbonded"]["lj"]["pair_coeffs"]
    for a in range(p["n_atoms"]):
        t = p["atom_type_of"][a]
        c = lj.get("%s-%s" % (t, t), {"epsilon": 0.0, "sigma": 1.0})
        nb.addParticle(float(charge[a]), c["sigma"] * mdsys.A2NM, c["epsilon"] * mdsys.KCAL)
    for i, j in p["exclusion_pairs"]:
        nb.addException(i, j, 0.0, 1.0, 0.0)
    nb.setForceGroup(1)
    if k > 1:
        nb.setReciprocalSpaceForceGroup(2)
    system.addForce(nb)
    return system, nb


def replicate_params(p, n):
    """The kit's system description for an n x n x n replica (atoms cell by cell, as
    replicate_box.py orders them)."""
    count = p["n_atoms"]
    q = dict(p)
    cells = n ** 3
    q["n_atoms"] = count * cells
    q["box"] = [b * n for b in p["box"]]
    q["atom_type_of"] = p["atom_type_of"] * cells
    shift = lambda rows, width: [[x + c * count for x in r[:width]] + list(r[width:])
                                 for c in range(cells) for r in rows]
    q["bonds"] = shift(p["bonds"], 2)
    q["angles"] = shift(p["angles"], 3)
    q["exclusion_pairs"] = shift(p["exclusion_pairs"], 2)
    return q


# (atoms, MTS?) -> (System, its NonbondedForce, the kit's parameters): built once a sitting.
OPENMM_SYSTEMS = {}


def run_openmm_pme(atoms, h, k, steps, threads, precision):
    sys.path.insert(0, PEERS)
    import mdsys
    import numpy as np
    import openmm as mm
    name, directory, n = PME_SYSTEMS[atoms]
    if (atoms, k > 1) not in OPENMM_SYSTEMS:
        p = mdsys.load_params(name)
        OPENMM_SYSTEMS[(atoms, k > 1)] = openmm_pme_system(p, n, k) + (p,)
    system, nb, p = OPENMM_SYSTEMS[(atoms, k > 1)]
    if k > 1:
        integ = mm.MTSIntegrator(h * 1e-3, [(2, 1), (1, k), (0, k)])
    else:
        integ = mm.VerletIntegrator(h * 1e-3)
    ctx = mm.Context(system, integ, mm.Platform.getPlatformByName("CPU"), {"Threads": str(threads)})
    x = mdsys.read_xyz(os.path.join(ROOT, directory, name + ".xyz"))[1]
    v = mdsys.read_xyz(os.path.join(ROOT, directory, name + ".vel.xyz"))[1]
    if n > 1:
        box = np.array(p["box"])
        x = np.concatenate([x + box * [i, j, kk] for i in range(n) for j in range(n)
                            for kk in range(n)])
        v = np.concatenate([v] * n ** 3)
    ctx.setPositions(x * mdsys.A2NM)
    ctx.setVelocities(v * mdsys.V_A_FS_TO_NM_PS)
    if ("openmm", atoms) not in PME_SEEN:
        source = "in the context"
        try:
            alpha, nx, ny, nz = nb.getPMEParametersInContext(ctx)
        except Exception:  # OpenMM 8.6's CPU platform fails here now and then (bad_cast)
            alpha, nx, ny, nz = nb.getPMEParameters()
            alpha, source = getattr(alpha, "_value", alpha), "as set"
        pme_note("openmm", atoms, "alpha = %.6f 1/A, grid %dx%dx%d, order 5 (%s)" % (
            alpha * mdsys.A2NM, nx, ny, nz, source))
    integ.step(2)  # first steps build the neighbour list and compile kernels
    start = time.perf_counter()
    integ.step(steps)
    ctx.getState(getEnergy=True)  # waits for the steps to finish
    return steps / (time.perf_counter() - start)


PME_RUNNERS = {"longstep": run_longstep_pme, "gromacs": run_gromacs_pme,
               NATIVE: run_gromacs_native_pme, "lammps": run_lammps_pme,
               "openmm": run_openmm_pme}
# Each code with the precisions it runs: GROMACS both (gmx, gmx_d), LAMMPS double only,
# OpenMM's CPU platform its own mixed precision only.
PRECISIONS = {"longstep": ["double", "mixed"], "gromacs": ["mixed", "double"],
              NATIVE: ["mixed"], "lammps": ["double"], "openmm": ["mixed"]}


def install(codes):
    """Install what is missing: OpenMM by pip, the rest by apt-get."""
    missing = []
    if "gromacs" in codes and not (shutil.which("gmx") and shutil.which("gmx_d")):
        missing.append("gromacs")
    if "lammps" in codes and not shutil.which("lmp"):
        missing.append("lammps")
    if "lammps" in codes and not shutil.which("mpirun"):
        missing.append("openmpi-bin")
    if missing:
        print("installing %s with apt-get" % " ".join(missing), flush=True)
        subprocess.run(["apt-get", "update", "-qq"], check=True)
        subprocess.run(["apt-get", "install", "-y", "-qq"] + missing, check=True)
    if "openmm" in codes:
        try:
            import openmm  # noqa: F401
        except ImportError:
            print("installing openmm with pip", flush=True)
            subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "openmm", "numpy"],
                           check=True)


def native_ready(build):
    """True when the native GROMACS is installed; builds it first when `build` (once, about
    12 minutes on 2 idle cores: scripts/build_gromacs_native.sh, its output on stderr)."""
    if os.access(native_gmx(), os.X_OK):
        return True
    if not build:
        print("no native GROMACS at %s (--no-build-native): its rows are left out; build it "
              "with scripts/build_gromacs_native.sh" % native_gmx(), flush=True)
        return False
    print("building the native GROMACS (scripts/build_gromacs_native.sh, once; about 12 "
          "minutes on 2 idle cores)", flush=True)
    res = subprocess.run(["bash", BUILD_NATIVE], stdout=subprocess.DEVNULL)
    if res.returncode != 0 or not os.access(native_gmx(), os.X_OK):
        sys.exit("scripts/build_gromacs_native.sh failed (exit %d)" % res.returncode)
    return True


def gromacs_version(gmx):
    """'GROMACS 2022.5-... (SIMD AVX_512)' from `gmx --version`."""
    line = sh([gmx, "--version"]).stdout
    m = re.search(r"GROMACS version:\s+(\S+)", line)
    simd = re.search(r"SIMD instructions:\s+(\S+)", line)
    return "GROMACS %s (SIMD %s)" % (m.group(1) if m else "?", simd.group(1) if simd else "?")


def versions(codes):
    out = []
    if NATIVE in codes:
        out.append("gromacs-native: " + gromacs_version(native_gmx()))
    if "gromacs" in codes:
        out.append("gromacs (Debian): " + gromacs_version("gmx"))
    if "lammps" in codes:
        m = re.search(r"Simulator - (.+)", sh(["lmp", "-h"]).stdout)
        out.append("LAMMPS %s" % (m.group(1) if m else "?"))
    if "openmm" in codes:
        import openmm
        out.append("OpenMM %s" % openmm.__version__)
    commit = sh(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT).stdout.strip()
    out.append("longstep %s" % (commit or "?"))
    return ", ".join(out)


def cpu_name():
    """The CPU's model name from /proc/cpuinfo."""
    return open("/proc/cpuinfo").read().split("model name")[1].split(":")[1].split("\n")[0].strip()


def configurations(args):
    for atoms in args.sizes:
        for threads in args.threads:
            for h in args.h:
                yield atoms, threads, h


def sitting(args):
    """Every configuration, codes interleaved within each repeat; returns the rows."""
    rows = []
    pme = args.coulomb == "pme"
    runners = PME_RUNNERS if pme else RUNNERS
    for atoms, threads, h in configurations(args):
        k = round(h / INNER)
        runs = [(c, p) for c in args.codes for p in PRECISIONS[c] if p in args.precisions]
        speeds = {r: [] for r in runs}
        for repeat in range(args.repeats):
            for code, precision in runs:
                if pme:
                    # The same simulated time for every scheme: PME_STEPS are inner steps.
                    steps = max(2, int(PME_STEPS[code][atoms] * args.steps_factor) // k)
                else:
                    steps = max(2 * k, int(STEPS[code][atoms] * args.steps_factor))
                try:
                    speed = runners[code](atoms, h, k, steps, threads, precision)
                except Exception as e:  # a failed run is reported; the sitting goes on
                    print("  %s %s failed: %s" % (code, precision, e), flush=True)
                    continue
                speeds[(code, precision)].append(speed)
                print("  %5d atoms  %d thr  %g/%g fs  %-8s %-6s run %d: %9.2f outer steps/s" % (
                    atoms, threads, h, INNER, code, precision, repeat + 1, speed), flush=True)
        for (code, precision), values in speeds.items():
            if values:
                rows.append({"atoms": atoms, "threads": threads, "h_fs": h, "inner_fs": INNER,
                             "code": code, "precision": precision, "runs": values,
                             "median": statistics.median(values), "coulomb": args.coulomb})
        report(rows, atoms, threads, h)
        if args.json:  # after every configuration, so that a cut-short sitting keeps its runs
            with open(args.json, "w") as f:
                json.dump(rows, f, indent=1)
    return rows


def report(rows, atoms, threads, h):
    here = [r for r in rows if (r["atoms"], r["threads"], r["h_fs"]) == (atoms, threads, h)]
    k = round(h / INNER)
    if here and here[0].get("coulomb") == "pme":
        scheme = ("PME, plain Verlet %g fs" % h if k == 1 else
                  "PME, MTS %g fs / %g fs (reciprocal sum every %d inner steps)" % (h, INNER, k))
    else:
        scheme = "impulse %g fs / %g fs" % (h, INNER)
    print("\n%d atoms, %d thread(s), %s: outer steps/s, median of %s" % (
        atoms, threads, scheme, "/".join(str(len(r["runs"])) for r in here)))
    for r in here:
        print("  %-8s %-6s %9.2f  (runs %s)  %7.1f ns/day  %6.3f us per atom and step" % (
            r["code"], r["precision"], r["median"], ", ".join("%.2f" % v for v in r["runs"]),
            r["median"] * h * 86400e-6, 1e6 / (r["median"] * atoms)))
    peers = [r for r in here if r["code"] != "longstep"]
    for ours in (r for r in here if r["code"] == "longstep"):
        ratios = ["%s %s %.2f" % (p["code"], p["precision"], ours["median"] / p["median"])
                  for p in peers]
        fastest = max(peers, key=lambda p: p["median"]) if peers else None
        print("  longstep %-6s / peer: %s%s" % (
            ours["precision"], ", ".join(ratios),
            "; / fastest (%s %s): %.2f" % (fastest["code"], fastest["precision"],
                                          ours["median"] / fastest["median"]) if fastest else ""))
    print(flush=True)


def markdown(rows):
    """The medians as a docs table: one row per size, threads and scheme, every run in
    brackets in repeat order."""
    columns = [("longstep", "double"), ("longstep", "mixed"), (NATIVE, "mixed"),
               ("gromacs", "mixed"), ("gromacs", "double"), ("lammps", "double"),
               ("openmm", "mixed")]
    fmt = lambda v: "%.0f" % v if v >= 100 else "%.3g" % v
    print("| atoms | threads | scheme | " + " | ".join("%s %s" % c for c in columns) + " |")
    print("|" + "---|" * (3 + len(columns)))
    keys = []
    for r in rows:
        key = (r["atoms"], r["threads"], r["h_fs"])
        if key not in keys:
            keys.append(key)
    for atoms, threads, h in keys:
        k = round(h / INNER)
        scheme = "Verlet %g" % h if k == 1 else "%g / %g" % (h, INNER)
        cells = []
        for code, precision in columns:
            found = [r for r in rows if (r["atoms"], r["threads"], r["h_fs"], r["code"],
                                         r["precision"]) == (atoms, threads, h, code, precision)]
            cells.append("%s (%s)" % (fmt(found[0]["median"]), ", ".join(
                fmt(v) for v in found[0]["runs"])) if found else "–")
        print("| {:,} | {} | {} | ".format(atoms, threads, scheme).replace(",", " ")
              + " | ".join(cells) + " |")


def scaling_summary(rows):
    """Cost per atom and outer step of longstep, 5184 against 648 atoms, and 2 threads against 1."""
    def median(atoms, threads, h, precision):
        for r in rows:
            if (r["code"], r["atoms"], r["threads"], r["h_fs"], r["precision"]) == (
                    "longstep", atoms, threads, h, precision):
                return r["median"]
        return None
    print("longstep summary")
    sizes = sorted({r["atoms"] for r in rows})
    for h in sorted({r["h_fs"] for r in rows}):
        for precision in ("double", "mixed"):
            for smaller, larger in zip(sizes, sizes[1:]):
                small, large = median(smaller, 1, h, precision), median(larger, 1, h, precision)
                if small and large:
                    print("  %g fs %-6s: cost per atom and step, %d / %d atoms: %.2f" % (
                        h, precision, larger, smaller, (small * smaller) / (large * larger)))
            for atoms in sizes:
                one, two = median(atoms, 1, h, precision), median(atoms, 2, h, precision)
                if one and two:
                    print("  %g fs %-6s: %5d atoms, 2 threads / 1 thread: %.2f" % (
                        h, precision, atoms, two / one))


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog=__doc__.split("\n", 1)[1])
    ints = lambda s: [int(x) for x in s.split(",")]
    floats = lambda s: [float(x) for x in s.split(",")]
    words = lambda s: s.split(",")
    ap.add_argument("--coulomb", choices=["dsf", "pme"], default="dsf",
                    help="the kit's shifted-force model (default) or PME (see below)")
    ap.add_argument("--sizes", type=ints, default=None,
                    help="atoms: 648 and/or 5184 (PME also 41472); default all")
    ap.add_argument("--threads", type=ints, default=[1, 2])
    ap.add_argument("--h", type=floats, default=None,
                    help="outer steps in fs (inner 0.5); default 4,2 (PME: 0.5,1,2)")
    ap.add_argument("--codes", type=words,
                    default=["longstep", NATIVE, "gromacs", "lammps", "openmm"],
                    help="default longstep,gromacs-native,gromacs,lammps,openmm")
    ap.add_argument("--precisions", type=words, default=["double", "mixed"])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--steps-factor", type=float, default=1.0,
                    help="scale every run's number of outer steps")
    ap.add_argument("--quick", action="store_true",
                    help="smoke test: one repeat, 1/20 of the steps")
    ap.add_argument("--no-install", dest="install", action="store_false")
    ap.add_argument("--no-build-native", dest="build_native", action="store_false",
                    help="do not build the native GROMACS when it is missing (its rows are "
                         "then left out)")
    ap.add_argument("--json", help="also write every run to this file")
    args = ap.parse_args()
    if args.quick:
        args.repeats, args.steps_factor = 1, args.steps_factor / 20.0
    pme = args.coulomb == "pme"
    known = PME_SYSTEMS if pme else SYSTEMS
    if args.sizes is None:
        args.sizes = sorted(known)
    if args.h is None:
        args.h = [0.5, 1.0, 2.0] if pme else [4.0, 2.0]
    for atoms in args.sizes:
        if atoms not in known:
            ap.error("--sizes: %d atoms is not one of %s" % (atoms, sorted(known)))
    for code in args.codes:
        if code not in RUNNERS:
            ap.error("--codes: unknown code %s (%s)" % (code, ", ".join(RUNNERS)))
    for h in args.h:
        if abs(h / INNER - round(h / INNER)) > 1e-9 or h < INNER:
            ap.error("--h: %g fs is not a whole number of %g fs inner steps" % (h, INNER))
    return args


def main():
    args = parse_args()
    if not os.path.exists(BIN):
        sys.exit("no release build at %s: run `cargo build --release` first" % BIN)
    if args.install:
        install(args.codes)
    if NATIVE in args.codes and not native_ready(args.build_native):
        args.codes = [c for c in args.codes if c != NATIVE]
    cpu = cpu_name()
    print("machine: %s, %d cores, load average %s; %s; %s" % (
        cpu, os.cpu_count(), " ".join("%.2f" % x for x in os.getloadavg()), versions(args.codes),
        time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())), flush=True)
    start = time.time()
    global PME
    if args.coulomb == "pme":
        PME = PmeInputs(args.sizes, args.codes)
        print("PME at GROMACS's defaults: r_c %g A, ewald-rtol %g (alpha %.6f 1/A), "
              "fourier-spacing %g A, order %d" % (PME_CUTOFF, PME_RTOL, pme_alpha(), PME_SPACING,
                                                  PME_ORDER), flush=True)
    try:
        rows = sitting(args)
    finally:
        if PME is not None:
            PME.close()
    scaling_summary(rows)
    print()
    markdown(rows)
    print("sitting took %.0f s" % (time.time() - start))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
