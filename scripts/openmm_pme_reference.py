#!/usr/bin/env python3
"""OpenMM's smooth PME on the water box: the reference numbers of tests/ewald.rs.

Builds systems/water-box/ (216 flexible SPC/Fw waters, read from scene.toml and
water216.xyz: the same charges, Lennard-Jones, bonds and angles) as an OpenMM System with
NonbondedForce.PME at alpha = 0.347 / Å, grid 16 x 16 x 16 (OpenMM's order is 5), cutoff 9 Å,
every intramolecular pair excluded, no dispersion correction, no switch; Reference platform,
double precision. Writes tests/data/openmm-pme-water.json:

* forces per atom (kcal/mol/Å): total, and the electrostatic part alone (a second context
  with every epsilon zero);
* energies (kcal/mol): bonds, angles, electrostatics (real space + reciprocal + self +
  exclusion corrections), Lennard-Jones as OpenMM computes it (not shifted) and shifted as
  the scene's lj_shift = true computes it, and the totals with either.

OpenMM's Lennard-Jones is not shifted and the scene's is: the forces are the same, the energy
differs by n_pairs * V_LJ(r_c) over the O-O pairs within the cutoff. The script counts those
pairs (minimum image) and writes the shifted energy as OpenMM's minus that constant, so the
test compares like with like.

    pip install openmm numpy
    python3 scripts/openmm_pme_reference.py          # rewrites the JSON
"""
import json
import os
import sys
import tomllib

import numpy as np
import openmm
from openmm import unit

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, ".."))
SCENE = os.path.join(ROOT, "systems", "water-box", "scene.toml")
OUT = os.path.join(ROOT, "tests", "data", "openmm-pme-water.json")

KCAL = 4.184  # kJ per kcal
NM = 10.0  # Å per nm
ALPHA = 0.347  # 1/Å
GRID = 16


def read_xyz(path):
    with open(path) as f:
        lines = f.read().splitlines()
    n = int(lines[0])
    elements, positions = [], []
    for line in lines[2 : 2 + n]:
        parts = line.split()
        elements.append(parts[0])
        positions.append([float(x) for x in parts[1:4]])
    return elements, np.array(positions)


def model():
    with open(SCENE, "rb") as f:
        scene = tomllib.load(f)
    ff = scene["forcefield"]
    elements, positions = read_xyz(os.path.join(os.path.dirname(SCENE), scene["structure"]["file"]))
    if len(elements) % 3 or any(elements[i : i + 3] != ["O", "H", "H"] for i in range(0, len(elements), 3)):
        sys.exit("water216.xyz is not a list of O H H waters")
    return scene, ff, elements, positions


def minimum_image(d, box):
    return d - box * np.round(d / box)


def build_system(ff, elements, box, cutoff, lj_on=True):
    atoms = ff["atoms"]
    bond = ff["bonds"]["O-H"]
    angle = ff["angles"]["H-O-H"]
    system = openmm.System()
    system.setDefaultPeriodicBoxVectors(
        openmm.Vec3(box[0] / NM, 0, 0), openmm.Vec3(0, box[1] / NM, 0), openmm.Vec3(0, 0, box[2] / NM)
    )
    for e in elements:
        system.addParticle(atoms[e]["mass"])
    bonds = openmm.HarmonicBondForce()
    angles = openmm.HarmonicAngleForce()
    nonbonded = openmm.NonbondedForce()
    nonbonded.setNonbondedMethod(openmm.NonbondedForce.PME)
    nonbonded.setCutoffDistance(cutoff / NM)
    nonbonded.setPMEParameters(ALPHA * NM, GRID, GRID, GRID)
    nonbonded.setUseDispersionCorrection(False)
    nonbonded.setUseSwitchingFunction(False)
    for e in elements:
        a = atoms[e]
        epsilon = a["epsilon"] * KCAL if lj_on else 0.0
        nonbonded.addParticle(a["charge"], a["sigma"] / NM, epsilon)
    for o in range(0, len(elements), 3):
        for h in (o + 1, o + 2):
            bonds.addBond(o, h, bond["r0"] / NM, bond["k"] * KCAL * NM * NM)
        angles.addAngle(o + 1, o, o + 2, np.radians(angle["theta0"]), angle["k"] * KCAL)
        for i, j in ((o, o + 1), (o, o + 2), (o + 1, o + 2)):
            nonbonded.addException(i, j, 0.0, 1.0, 0.0)
    for group, force in enumerate((bonds, angles, nonbonded)):
        force.setForceGroup(group)
        system.addForce(force)
    return system


def evaluate(system, positions):
    integrator = openmm.VerletIntegrator(0.001)
    platform = openmm.Platform.getPlatformByName("Reference")
    context = openmm.Context(system, integrator, platform)
    context.setPositions(positions / NM)
    out = {}
    for name, groups in (("bonds", {0}), ("angles", {1}), ("nonbonded", {2}), ("total", {0, 1, 2})):
        state = context.getState(getEnergy=True, getForces=True, groups=groups)
        energy = state.getPotentialEnergy().value_in_unit(unit.kilojoule_per_mole) / KCAL
        forces = state.getForces(asNumpy=True).value_in_unit(unit.kilojoule_per_mole / unit.nanometer)
        out[name] = (energy, np.array(forces) / KCAL / NM)
    return out


def lj_shift(ff, elements, positions, box, cutoff):
    """n_pairs and n_pairs * V_LJ(r_c) over the O-O pairs within the cutoff."""
    o = ff["atoms"]["O"]
    eps, sig = o["epsilon"], o["sigma"]
    v_rc = 4 * eps * ((sig / cutoff) ** 12 - (sig / cutoff) ** 6)
    oxygens = positions[[i for i, e in enumerate(elements) if e == "O"]]
    pairs = 0
    for i in range(len(oxygens)):
        d = minimum_image(oxygens[i + 1 :] - oxygens[i], box)
        pairs += int(np.sum(np.sum(d * d, axis=1) < cutoff * cutoff))
    return pairs, pairs * v_rc


def main():
    scene, ff, elements, positions = model()
    box = np.array(scene["box"], dtype=float)
    cutoff = float(ff["cutoff"])
    # Molecules whole in the file: the exclusion corrections are then the same with or
    # without the minimum image.
    for o in range(0, len(elements), 3):
        for h in (o + 1, o + 2):
            d = positions[h] - positions[o]
            assert np.allclose(d, minimum_image(d, box)), f"water {o // 3} is split by the box"
    full = evaluate(build_system(ff, elements, box, cutoff), positions)
    coulomb = evaluate(build_system(ff, elements, box, cutoff, lj_on=False), positions)
    pairs, shift = lj_shift(ff, elements, positions, box, cutoff)
    e_coulomb = coulomb["nonbonded"][0]
    e_lj = full["nonbonded"][0] - e_coulomb
    report = {
        "doc": "OpenMM NonbondedForce.PME on systems/water-box (scripts/openmm_pme_reference.py); "
        "units kcal/mol, Å, kcal/mol/Å; forces[i] = [fx, fy, fz]; lennard_jones_shifted = "
        "lennard_jones_unshifted - shift_pairs * V_LJ(cutoff) (the scene's lj_shift)",
        "openmm_version": openmm.version.full_version,
        "platform": "Reference",
        "precision": "double",
        "alpha_per_angstrom": ALPHA,
        "grid": [GRID, GRID, GRID],
        "order": 5,
        "cutoff": cutoff,
        "box": box.tolist(),
        "shift_pairs": pairs,
        "energy": {
            "bonds": full["bonds"][0],
            "angles": full["angles"][0],
            "coulomb": e_coulomb,
            "lennard_jones_unshifted": e_lj,
            "lennard_jones_shift": shift,
            "lennard_jones_shifted": e_lj - shift,
            "total_unshifted": full["total"][0],
            "total_shifted": full["total"][0] - shift,
        },
        "forces": full["total"][1].tolist(),
        "forces_coulomb": coulomb["nonbonded"][1].tolist(),
    }
    os.makedirs(os.path.dirname(OUT), exist_ok=True)
    with open(OUT, "w") as f:
        json.dump(report, f, indent=1)
    print(json.dumps(report["energy"], indent=1))
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
