#!/usr/bin/env python3
"""Short trajectories of the solvated alanine dipeptide written by GROMACS (.xtc) and OpenMM
(.dcd), for the tests of `longstep analyze` on another engine's trajectory (tests/analyze_peers.rs).

Both start from systems/alanine-dipeptide-amber/ala2-solvated-300K.xyz (the 300 K start),
with the model of ala2-solvated-pme.toml: Amber ff14SB from the prmtop (GROMACS: its .top
with FLEXIBLE), flexible TIP3P, PME with a 9 Å cut, no constraints; Langevin at 300 K,
friction 1/ps, 0.5 fs steps, a frame every 100 steps (50 fs), 8 frames. They are small on
purpose (about 100 KB each): enough frames to read and judge, not to sample.

* GROMACS: `gmx grompp` + `gmx mdrun`, integrator sd, written at compressed-x-precision 10000
  (0.0001 nm: the default 1000 rounds positions to 0.001 nm, which biases bond and angle
  energies by several kelvin of equipartition temperature; docs/studies.md).
* OpenMM: LangevinMiddleIntegrator, DCDReporter (float32 positions). The script also
  evaluates OpenMM's bond, angle and torsion energies (Reference platform, double) at each
  frame's positions as written (rounded to float32), into ala2-openmm-terms.json, so the test
  compares longstep's recomputed terms with OpenMM's at the same positions.

    apt-get install gromacs; pip install openmm
    python3 scripts/make_peer_trajectories.py     # rewrites tests/data/peer-trajectories/
"""
import json
import os
import shutil
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, ".."))
SYSTEM = os.path.join(ROOT, "systems", "alanine-dipeptide-amber")
OUT = os.path.join(ROOT, "tests", "data", "peer-trajectories")

FRAMES = 8
EVERY = 100  # steps between frames
DT_PS = 0.0005
TEMPERATURE = 300.0
SEED = 7

MDP = f"""define = -DFLEXIBLE
integrator = sd
dt = {DT_PS}
nsteps = {FRAMES * EVERY}
tc-grps = System
tau-t = 1.0
ref-t = {TEMPERATURE}
ld-seed = {SEED}
pcoupl = no
cutoff-scheme = Verlet
coulombtype = PME
rcoulomb = 0.9
ewald-rtol = 1e-5
fourier-spacing = 0.12
pme-order = 4
vdwtype = Cut-off
vdw-modifier = None
rvdw = 0.9
DispCorr = no
constraints = none
continuation = no
gen-vel = yes
gen-temp = {TEMPERATURE}
gen-seed = {SEED}
nstcalcenergy = 100
nstenergy = {EVERY}
nstlog = 0
nstxout-compressed = {EVERY}
compressed-x-precision = 10000
"""


def read_xyz(path):
    with open(path) as f:
        lines = f.read().splitlines()
    n = int(lines[0])
    return [[float(x) for x in line.split()[1:4]] for line in lines[2 : 2 + n]]


def start_gro(work, positions):
    """ala2-solvated.gro's names with the 300 K start's positions (Å -> nm)."""
    with open(os.path.join(SYSTEM, "ala2-solvated.gro")) as f:
        lines = f.read().splitlines()
    n = int(lines[1])
    assert n == len(positions), "the 300 K start and the .gro differ in atom count"
    out = lines[:2]
    for line, (x, y, z) in zip(lines[2 : 2 + n], positions):
        out.append(line[:20] + "%8.3f%8.3f%8.3f" % (x / 10, y / 10, z / 10))
    out.append(lines[2 + n])
    path = os.path.join(work, "start.gro")
    with open(path, "w") as f:
        f.write("\n".join(out) + "\n")
    return path


def gromacs(positions):
    with tempfile.TemporaryDirectory() as work:
        gro = start_gro(work, positions)
        mdp = os.path.join(work, "run.mdp")
        with open(mdp, "w") as f:
            f.write(MDP)
        run = lambda args: subprocess.run(args, cwd=work, check=True, capture_output=True)
        run(["gmx", "grompp", "-f", mdp, "-c", gro, "-p",
             os.path.join(SYSTEM, "ala2-solvated.top"), "-o", "run.tpr", "-maxwarn", "0"])
        run(["gmx", "mdrun", "-s", "run.tpr", "-ntmpi", "1", "-ntomp", "1", "-deffnm", "run"])
        shutil.copy(os.path.join(work, "run.xtc"), os.path.join(OUT, "ala2-gromacs.xtc"))


def openmm_run(positions):
    import numpy as np
    import openmm
    from openmm import app, unit

    prmtop = app.AmberPrmtopFile(os.path.join(SYSTEM, "ala2-solvated.prmtop"))
    system = prmtop.createSystem(nonbondedMethod=app.PME, nonbondedCutoff=0.9 * unit.nanometer,
                                 constraints=None, rigidWater=False, ewaldErrorTolerance=1e-5)
    groups = {"bonds": openmm.HarmonicBondForce, "angles": openmm.HarmonicAngleForce,
              "torsions": openmm.PeriodicTorsionForce}
    for force in system.getForces():
        for k, kind in enumerate(groups.values()):
            if isinstance(force, kind):
                force.setForceGroup(k + 1)
    integrator = openmm.LangevinMiddleIntegrator(TEMPERATURE * unit.kelvin, 1 / unit.picosecond,
                                                 DT_PS * unit.picosecond)
    integrator.setRandomNumberSeed(SEED)
    simulation = app.Simulation(prmtop.topology, system, integrator,
                                openmm.Platform.getPlatformByName("CPU"))
    simulation.context.setPositions(np.array(positions) * 0.1)
    simulation.context.setVelocitiesToTemperature(TEMPERATURE * unit.kelvin, SEED)
    dcd = os.path.join(OUT, "ala2-openmm.dcd")
    simulation.reporters.append(app.DCDReporter(dcd, EVERY))
    reference = openmm.Context(system, openmm.VerletIntegrator(0.001),
                               openmm.Platform.getPlatformByName("Reference"))
    frames = []
    for _ in range(FRAMES):
        simulation.step(EVERY)
        state = simulation.context.getState(getPositions=True)
        q = state.getPositions(asNumpy=True).value_in_unit(unit.angstrom)
        reference.setPositions(q.astype(np.float32).astype(np.float64) * 0.1 * unit.nanometer)
        reference.setPeriodicBoxVectors(*state.getPeriodicBoxVectors())
        energies = {}
        for k, name in enumerate(groups):
            e = reference.getState(getEnergy=True, groups={k + 1}).getPotentialEnergy()
            energies[name] = e.value_in_unit(unit.kilocalorie_per_mole)
        frames.append(energies)
    with open(os.path.join(OUT, "ala2-openmm-terms.json"), "w") as f:
        json.dump({"about": "OpenMM (Reference platform) energies in kcal/mol of each frame of "
                            "ala2-openmm.dcd at its float32 positions; torsions holds the "
                            "proper and improper dihedrals together. Written by "
                            "scripts/make_peer_trajectories.py.",
                   "frames": frames}, f, indent=1)
        f.write("\n")


def main():
    os.makedirs(OUT, exist_ok=True)
    positions = read_xyz(os.path.join(SYSTEM, "ala2-solvated-300K.xyz"))
    which = sys.argv[1:] or ["gromacs", "openmm"]
    if "gromacs" in which:
        gromacs(positions)
    if "openmm" in which:
        openmm_run(positions)
    for name in sorted(os.listdir(OUT)):
        print(name, os.path.getsize(os.path.join(OUT, name)), "bytes")


if __name__ == "__main__":
    main()
