#!/usr/bin/env python3
"""Store OpenMM's constrained velocity Verlet on the rigid water box, for tests/constraints.rs.

The system is longstep's own (`longstep forces --parameters` dumps every parameter; the
OpenMM system is built from it by compare_openmm.build_openmm) with every water made rigid
as OpenMM's rigidWater does: O-H at the bond's rest length, H-H = 2 r0 sin(theta0/2) from the
H-O-H rest angle (OpenMM solves these three-constraint clusters by SETTLE). From the water
box's file positions and velocities OpenMM applies the constraints (to 1e-12), then takes
STEPS steps of VerletIntegrator at 2 fs (constraint tolerance 1e-12) on the Reference
platform (double precision). The start and the end state go into
tests/data/openmm-constrained-water.json: positions in Å, velocities in Å/fs.

    python3 scripts/openmm_constrained.py          # prints, and writes the JSON

Needs `pip install openmm numpy` and a release build (`cargo build --release`).
"""
import json
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from compare_openmm import A2NM, BIN, KCAL, ROOT, build_openmm, read_xyz  # noqa: E402

SCENE = "systems/water-box/scene.toml"
STEPS = 50
H_FS = 2.0
TOLERANCE = 1e-12
OUT = os.path.join(ROOT, "tests", "data", "openmm-constrained-water.json")


def parameters(workdir):
    path = os.path.join(workdir, "parameters.json")
    subprocess.run([BIN, "forces", SCENE, "--quiet", "--json", "--parameters", path],
                   check=True, capture_output=True, text=True, cwd=ROOT)
    with open(path) as f:
        return json.load(f)


def add_rigid_water(system, p):
    """Three constraints per water (an O bonded to exactly two H, nothing else)."""
    elements = p["elements"]
    bonded = {}
    for i, j, _k, r0 in p["bonds"]:
        bonded.setdefault(i, {})[j] = r0
        bonded.setdefault(j, {})[i] = r0
    theta = {(a[1], min(a[0], a[2]), max(a[0], a[2])): a[4] for a in p["angles"]}
    waters = 0
    for o, around in sorted(bonded.items()):
        hs = sorted(around)
        if elements[o] != "O" or len(hs) != 2 or any(elements[h] != "H" for h in hs):
            continue
        if any(set(bonded[h]) - {o} for h in hs):
            continue
        r0 = around[hs[0]]
        hh = 2.0 * r0 * math.sin(0.5 * theta[(o, hs[0], hs[1])])
        system.addConstraint(o, hs[0], r0 * A2NM)
        system.addConstraint(o, hs[1], r0 * A2NM)
        system.addConstraint(hs[0], hs[1], hh * A2NM)
        waters += 1
    return waters


def main():
    import openmm as mm
    import openmm.unit as u
    with tempfile.TemporaryDirectory() as workdir:
        p = parameters(workdir)
    system = build_openmm(p)
    waters = add_rigid_water(system, p)
    _, x = read_xyz(os.path.join(ROOT, "systems", "water-box", "water216.xyz"))
    _, v = read_xyz(os.path.join(ROOT, "systems", "water-box", "water216.vel.xyz"))
    integrator = mm.VerletIntegrator(H_FS * u.femtoseconds)
    integrator.setConstraintTolerance(TOLERANCE)
    platform = mm.Platform.getPlatformByName("Reference")
    context = mm.Context(system, integrator, platform)
    context.setPositions(x * A2NM)
    context.setVelocities(v * A2NM * 1000.0)  # Å/fs → nm/ps
    context.applyConstraints(TOLERANCE)
    context.applyVelocityConstraints(TOLERANCE)

    def state():
        s = context.getState(getPositions=True, getVelocities=True, getEnergy=True)
        pos = s.getPositions(asNumpy=True).value_in_unit(u.nanometer) / A2NM
        vel = s.getVelocities(asNumpy=True).value_in_unit(u.nanometer / u.picosecond) / (A2NM * 1000.0)
        energy = (s.getKineticEnergy().value_in_unit(u.kilojoule_per_mole)
                  + s.getPotentialEnergy().value_in_unit(u.kilojoule_per_mole)) / KCAL
        return pos, vel, energy

    x0, v0, e0 = state()
    integrator.step(STEPS)
    x1, v1, e1 = state()
    print("OpenMM %s: %d rigid waters, %d steps of %g fs: E %.10f → %.10f kcal/mol"
          % (mm.__version__, waters, STEPS, H_FS, e0, e1))
    data = {
        "doc": "OpenMM VerletIntegrator with rigid water (SETTLE) on longstep's water box, "
               "Reference platform; made by scripts/openmm_constrained.py. Positions in "
               "angstrom, velocities in angstrom/fs, energies kcal/mol.",
        "openmm": mm.__version__,
        "scene": SCENE,
        "steps": STEPS,
        "h_fs": H_FS,
        "constraint_tolerance": TOLERANCE,
        "rigid_waters": waters,
        "positions_start": x0.tolist(),
        "velocities_start": v0.tolist(),
        "positions_end": x1.tolist(),
        "velocities_end": v1.tolist(),
        "energy_start": e0,
        "energy_end": e1,
    }
    with open(OUT, "w") as f:
        json.dump(data, f)
    print("wrote", os.path.relpath(OUT, ROOT))


if __name__ == "__main__":
    main()
