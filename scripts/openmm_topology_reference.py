#!/usr/bin/env python3
"""OpenMM's per-term energies and per-atom forces for the shipped AMBER topologies.

For each system, OpenMM's own AMBER reader (app.AmberPrmtopFile, app.AmberInpcrdFile) builds
the system exactly as a user of OpenMM would (no constraints, flexible water), on the
Reference platform (double precision), and this script writes
tests/data/openmm-<name>.json with, in longstep's units (kcal/mol, kcal/mol/Å):

* "energy": per group — "bonds" (HarmonicBondForce), "angles" (HarmonicAngleForce),
  "torsions" (PeriodicTorsionForce: proper and improper dihedrals together, as OpenMM holds
  them), "lj" and "coulomb" (NonbondedForce's pairs, 1-4 pairs and exclusions left out),
  "lj_14" and "coulomb_14" (NonbondedForce's exceptions: the scaled 1-4 pairs), "total";
* "forces": per-atom forces, n × 3: "bonded" (bonds, angles, torsions), "nonbonded" (the
  whole NonbondedForce, 1-4 pairs included) and "total". At a minimised structure the total
  is a small difference of large bonded and non-bonded forces, so a test compares each part
  on its own scale.

The non-bonded parts come from copies of the NonbondedForce, each in its own force group:
charges zeroed (LJ only) or ε zeroed (Coulomb only), with the exceptions zeroed (pairs only)
or the particles zeroed (exceptions only); the script checks that the four parts add up to
the unsplit force's energy.

Settings: vacuum — NoCutoff (plain Coulomb, every pair); solvated — CutoffPeriodic at 9 Å,
which in OpenMM is the reaction field (k_rf = (ε_rf − 1)/((2ε_rf + 1) r_c³),
c_rf = 1/r_c + k_rf r_c², applied to the pairs within the cutoff; exclusions and 1-4
exceptions get plain Coulomb and no reaction field), ε_rf = 78.3 (OpenMM's default), LJ
neither shifted nor switched, no long-range dispersion correction — the conventions of
longstep's forces/nonbonded/mod.rs.

A second tool chain: the shipped systems are ParmEd's writing of OpenMM's ForceField; with
--other and openmmtools installed, its alanine dipeptide prmtop (made by tleap, AMBER's own
tool) is copied next to them as ala2-tleap.prmtop/.inpcrd and checked the same way
(tests/data/openmm-ala2-tleap.json).

The same systems as GROMACS top/gro (scripts/make_gromacs_topologies.py) go through OpenMM's
GROMACS reader (app.GromacsTopFile with FLEXIBLE defined, so the water is flexible;
app.GromacsGroFile: positions as the .gro prints them, 1e-3 nm) into
tests/data/openmm-<name>-gromacs.json, in the same groups.

The solvated Trp-cage of systems/protein-amber/ (6920 atoms) is written the same way, from
the prmtop and from the top, with reaction field and with PME, into
tests/data/openmm-trpcage*.json — but its per-atom forces only for a fixed subset of atoms
(every protein atom, the ions, and every PROTEIN_WATER_STRIDE-th water atom: all forces
would make 1 MB files), with the RMS over all atoms of each part of the forces
("forces_rms") beside them.

Explicit 1-4 parameters: the vacuum dipeptide as ParmEd writes it from an OpenMM System
(gen-pairs no, fudgeLJ 1, σ/ε inline or in [ pairtypes ], and a gen-pairs yes variant:
scripts/make_gromacs_topologies.py --only-explicit-pairs wrote tests/data/gromacs-pairs-*)
through GromacsTopFile into tests/data/openmm-gromacs-pairs-*.json, in the same groups
(--only-explicit-pairs writes only these).

GROMACS dihedral functions 2 (harmonic improper) and 3 (Ryckaert-Bellemans): the hand-made
tests/data/gromacs-dihedral-types.top/.gro through GromacsTopFile (which builds them as a
CustomTorsionForce and an RBTorsionForce) into tests/data/openmm-gromacs-dihedral-types.json:
the energy and per-atom forces of each of the two forces and of the whole system.

    pip install openmm parmed
    python3 scripts/openmm_topology_reference.py
    pip install --no-deps openmmtools && python3 scripts/openmm_topology_reference.py --other
"""
import argparse
import json
import os
import shutil

import numpy as np
import openmm
from openmm import app, unit

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, ".."))
SYSTEMS = os.path.join(ROOT, "systems", "alanine-dipeptide-amber")
DATA = os.path.join(ROOT, "tests", "data")
KCAL = 4.184  # kJ per kcal
EPSILON_RF = 78.3
CUTOFF_NM = 0.9
# PME of the solvated system: alpha, grid and order given explicitly (OpenMM's order is 5).
PME_ALPHA_PER_NM = 3.5
PME_GRID = 24
PROTEIN = os.path.join(ROOT, "systems", "protein-amber")
# PME of the solvated protein: the box is 42 Å; alpha as the scene's erfc(alpha r_c) = 1e-5
# would give (3.47 / nm), rounded; a 36³ grid (1.17 Å spacing).
PROTEIN_PME_ALPHA_PER_NM = 3.5
PROTEIN_PME_GRID = 36
PROTEIN_WATER_STRIDE = 16

# name -> (prmtop, inpcrd, nonbonded method: "vacuum", "reaction-field" or "pme")
SHIPPED = {
    "ala2": ("ala2.prmtop", "ala2.inpcrd", "vacuum"),
    "ala2-solvated": ("ala2-solvated.prmtop", "ala2-solvated.inpcrd", "reaction-field"),
    "ala2-solvated-pme": ("ala2-solvated.prmtop", "ala2-solvated.inpcrd", "pme"),
}

GROUPS = {"bonds": 0, "angles": 1, "torsions": 2, "lj": 3, "coulomb": 4, "lj_14": 5, "coulomb_14": 6}
FULL_NONBONDED = 7


def nonbonded_copy(force, charges, lj, pairs, exceptions):
    """A copy of `force` keeping the charges and/or LJ, of the pairs and/or exceptions."""
    copy = openmm.XmlSerializer.deserialize(openmm.XmlSerializer.serialize(force))
    for i in range(copy.getNumParticles()):
        q, sigma, eps = copy.getParticleParameters(i)
        copy.setParticleParameters(i, q if (charges and pairs) else 0.0, sigma,
                                   eps if (lj and pairs) else 0.0)
    for k in range(copy.getNumExceptions()):
        i, j, qq, sigma, eps = copy.getExceptionParameters(k)
        copy.setExceptionParameters(k, i, j, qq if (charges and exceptions) else 0.0, sigma,
                                    eps if (lj and exceptions) else 0.0)
    return copy


# name -> (top, gro, nonbonded method)
SHIPPED_GROMACS = {
    "ala2-gromacs": ("ala2.top", "ala2.gro", "vacuum"),
    "ala2-solvated-gromacs": ("ala2-solvated.top", "ala2-solvated.gro", "reaction-field"),
}


def build(prmtop, method, pme=(PME_ALPHA_PER_NM, PME_GRID)):
    if method == "pme":
        system = prmtop.createSystem(nonbondedMethod=app.PME,
                                     nonbondedCutoff=CUTOFF_NM * unit.nanometer,
                                     constraints=None, rigidWater=False)
    elif method == "reaction-field":
        system = prmtop.createSystem(nonbondedMethod=app.CutoffPeriodic,
                                     nonbondedCutoff=CUTOFF_NM * unit.nanometer,
                                     constraints=None, rigidWater=False)
    else:
        system = prmtop.createSystem(nonbondedMethod=app.NoCutoff, constraints=None,
                                     rigidWater=False)
    kinds = {}
    for force in system.getForces():
        kinds.setdefault(type(force).__name__, []).append(force)
    unknown = set(kinds) - {"HarmonicBondForce", "HarmonicAngleForce", "PeriodicTorsionForce",
                            "NonbondedForce", "CMMotionRemover"}
    empty = {k for k in unknown if all(getattr(f, "getNumTorsions", lambda: 1)() == 0
                                       for f in kinds[k])}
    for name in empty:  # GromacsTopFile adds an RBTorsionForce even when it has no terms
        for force in kinds[name]:
            system.removeForce(list(system.getForces()).index(force))
    unknown -= empty
    assert not unknown, f"forces this script does not split: {unknown}"
    (nb,) = kinds["NonbondedForce"]
    nb.setUseDispersionCorrection(False)
    nb.setUseSwitchingFunction(False)
    if method == "reaction-field":
        nb.setReactionFieldDielectric(EPSILON_RF)
    if method == "pme":
        nb.setPMEParameters(pme[0], pme[1], pme[1], pme[1])
    for name, group in [("HarmonicBondForce", 0), ("HarmonicAngleForce", 1),
                        ("PeriodicTorsionForce", 2)]:
        for force in kinds.get(name, []):
            force.setForceGroup(group)
    parts = {
        "lj": nonbonded_copy(nb, False, True, True, False),
        "coulomb": nonbonded_copy(nb, True, False, True, False),
        "lj_14": nonbonded_copy(nb, False, True, False, True),
        "coulomb_14": nonbonded_copy(nb, True, False, False, True),
    }
    nb.setForceGroup(FULL_NONBONDED)
    for name, force in parts.items():
        force.setForceGroup(GROUPS[name])
        system.addForce(force)
    return system


def evaluate(prmtop_path, inpcrd_path, method, pme=(PME_ALPHA_PER_NM, PME_GRID)):
    periodic = method != "vacuum"
    if prmtop_path.endswith(".top"):
        gro = app.GromacsGroFile(inpcrd_path)
        box = gro.getPeriodicBoxVectors() if periodic else None
        prmtop = app.GromacsTopFile(prmtop_path, periodicBoxVectors=box,
                                    defines={"FLEXIBLE": True})
        positions, box_vectors = gro.positions, box
    else:
        prmtop = app.AmberPrmtopFile(prmtop_path)
        inpcrd = app.AmberInpcrdFile(inpcrd_path)
        positions, box_vectors = inpcrd.positions, inpcrd.boxVectors
    system = build(prmtop, method, pme)
    platform = openmm.Platform.getPlatformByName("Reference")
    context = openmm.Context(system, openmm.VerletIntegrator(0.001), platform)
    if periodic:
        context.setPeriodicBoxVectors(*box_vectors)
    context.setPositions(positions)

    def energy(groups):
        state = context.getState(getEnergy=True, groups=groups)
        return state.getPotentialEnergy().value_in_unit(unit.kilojoule_per_mole) / KCAL

    energies = {name: energy({group}) for name, group in GROUPS.items()}
    full = energy({FULL_NONBONDED})
    split = sum(energies[k] for k in ("lj", "coulomb", "lj_14", "coulomb_14"))
    assert abs(split - full) <= 1e-9 * max(1.0, abs(full)), (split, full)
    def forces(groups):
        state = context.getState(getForces=True, groups=groups)
        return np.asarray(state.getForces(asNumpy=True).value_in_unit(
            unit.kilojoule_per_mole / unit.angstrom) / KCAL)

    bonded = {GROUPS["bonds"], GROUPS["angles"], GROUPS["torsions"]}
    split_forces = {"bonded": forces(bonded), "nonbonded": forces({FULL_NONBONDED}),
                    "total": forces(bonded | {FULL_NONBONDED})}
    energies["total"] = sum(energies.values())
    return energies, split_forces


NONBONDED = {
    "vacuum": {"method": "NoCutoff"},
    "reaction-field": {"method": "CutoffPeriodic (reaction field)", "cutoff": CUTOFF_NM * 10.0,
                       "epsilon_rf": EPSILON_RF},
    "pme": {"method": "PME", "cutoff": CUTOFF_NM * 10.0, "alpha": PME_ALPHA_PER_NM / 10.0,
            "grid": [PME_GRID] * 3, "order": 5},
}


def write(name, prmtop, inpcrd, method, source, folder=SYSTEMS, pme=None, subset=None):
    """`subset`: the atoms whose forces are written (all when None); `pme`: (alpha per nm,
    grid) when not the dipeptide's."""
    pme = pme or (PME_ALPHA_PER_NM, PME_GRID)
    energies, forces = evaluate(os.path.join(folder, prmtop), os.path.join(folder, inpcrd),
                                method, pme)
    nonbonded = dict(NONBONDED[method])
    if method == "pme":
        nonbonded.update(alpha=pme[0] / 10.0, grid=[pme[1]] * 3)
    where = os.path.relpath(folder, ROOT)
    record = {
        "system": name,
        ("top" if prmtop.endswith(".top") else "prmtop"): f"{where}/{prmtop}",
        ("gro" if inpcrd.endswith(".gro") else "inpcrd"): f"{where}/{inpcrd}",
        "source": source,
        "openmm": openmm.__version__,
        "platform": "Reference",
        "nonbonded": nonbonded,
        "dispersion_correction": False,
        "units": {"energy": "kcal/mol", "forces": "kcal/mol/angstrom"},
        "energy": energies,
    }
    if subset is None:
        record["forces"] = {k: v.tolist() for k, v in forces.items()}
    else:
        record["n_atoms"] = len(forces["total"])
        record["force_atoms"] = subset
        record["forces"] = {k: v[subset].tolist() for k, v in forces.items()}
        record["forces_rms"] = {k: float(np.sqrt(np.mean(v * v))) for k, v in forces.items()}
    path = os.path.join(DATA, f"openmm-{name}.json")
    with open(path, "w") as f:
        json.dump(record, f)
        f.write("\n")
    print(path, {k: round(v, 6) for k, v in energies.items()})


def other_tool():
    """openmmtools' alanine dipeptide (a tleap-made prmtop), when installed; only its data
    files are used (`pip install --no-deps openmmtools` is enough)."""
    import importlib.util
    spec = importlib.util.find_spec("openmmtools")
    if spec is None:
        print("openmmtools is not installed: no prmtop of another tool to check")
        return
    data = os.path.join(os.path.dirname(spec.origin), "data", "alanine-dipeptide-gbsa")
    for ext, target in (("prmtop", "prmtop"), ("crd", "inpcrd")):
        shutil.copy(os.path.join(data, f"alanine-dipeptide.{ext}"),
                    os.path.join(SYSTEMS, f"ala2-tleap.{target}"))
    write("ala2-tleap", "ala2-tleap.prmtop", "ala2-tleap.inpcrd", "vacuum",
          "openmmtools 'data/alanine-dipeptide-gbsa' (made by tleap), copied unchanged; "
          "evaluated in vacuum (its GBSA radii are not used)")


def protein_subset():
    """Every protein atom, the ions, and every PROTEIN_WATER_STRIDE-th water atom."""
    topology = app.AmberPrmtopFile(os.path.join(PROTEIN, "trpcage.prmtop")).topology
    subset, water = [], 0
    for atom in topology.atoms():
        if atom.residue.name != "HOH":
            subset.append(atom.index)
        else:
            if water % PROTEIN_WATER_STRIDE == 0:
                subset.append(atom.index)
            water += 1
    return subset


def protein():
    subset = protein_subset()
    pme = (PROTEIN_PME_ALPHA_PER_NM, PROTEIN_PME_GRID)
    amber = ("scripts/make_topologies.py (PeptideBuilder backbone, OpenMM Modeller, "
             "amber14-all.xml + amber14/tip3p.xml, written by ParmEd)")
    gromacs = ("scripts/make_gromacs_topologies.py (ParmEd's GROMACS writing of the "
               "shipped prmtop), read by OpenMM's GromacsTopFile with FLEXIBLE")
    for suffix, method in (("", "reaction-field"), ("-pme", "pme")):
        write("trpcage" + suffix, "trpcage.prmtop", "trpcage.inpcrd", method, amber,
              folder=PROTEIN, pme=pme, subset=subset)
        write("trpcage-gromacs" + suffix, "trpcage.top", "trpcage.gro", method, gromacs,
              folder=PROTEIN, pme=pme, subset=subset)


def dihedral_types():
    """OpenMM's energies and forces of the hand-made top's RB and harmonic dihedrals."""
    top = os.path.join(DATA, "gromacs-dihedral-types.top")
    gro = app.GromacsGroFile(os.path.join(DATA, "gromacs-dihedral-types.gro"))
    system = app.GromacsTopFile(top).createSystem(nonbondedMethod=app.NoCutoff)
    groups = {"RBTorsionForce": 1, "CustomTorsionForce": 2}
    names = {1: "ryckaert_bellemans", 2: "harmonic_dihedrals"}
    for force in system.getForces():
        force.setForceGroup(groups.get(type(force).__name__, 0))
    found = {type(f).__name__ for f in system.getForces()}
    assert set(groups) <= found, found
    context = openmm.Context(system, openmm.VerletIntegrator(0.001),
                             openmm.Platform.getPlatformByName("Reference"))
    context.setPositions(gro.positions)
    record = {"top": "tests/data/gromacs-dihedral-types.top",
              "gro": "tests/data/gromacs-dihedral-types.gro",
              "openmm": openmm.__version__, "platform": "Reference",
              "units": {"energy": "kcal/mol", "forces": "kcal/mol/angstrom"},
              "energy": {}, "forces": {}}
    for label, group_set in [(names[1], {1}), (names[2], {2}), ("total", {0, 1, 2})]:
        state = context.getState(getEnergy=True, getForces=True, groups=group_set)
        record["energy"][label] = state.getPotentialEnergy().value_in_unit(
            unit.kilojoule_per_mole) / KCAL
        record["forces"][label] = (np.asarray(state.getForces(asNumpy=True).value_in_unit(
            unit.kilojoule_per_mole / unit.angstrom)) / KCAL).tolist()
    path = os.path.join(DATA, "openmm-gromacs-dihedral-types.json")
    with open(path, "w") as f:
        json.dump(record, f, indent=1)
        f.write("\n")
    print(path, record["energy"])


def explicit_pairs():
    """The vacuum dipeptide's tops with explicit 1-4 σ/ε (inline, [ pairtypes ], gen-pairs yes)."""
    for variant in ("inline", "types", "genpairs"):
        write(f"gromacs-pairs-{variant}", f"gromacs-pairs-{variant}.top", "gromacs-pairs.gro",
              "vacuum", "scripts/make_gromacs_topologies.py --only-explicit-pairs (ParmEd's "
              "GROMACS writing of OpenMM's System of ala2.prmtop), read by GromacsTopFile",
              folder=DATA)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--other", action="store_true",
                        help="also the prmtop of another tool (openmmtools, if installed)")
    parser.add_argument("--only-dihedral-types", action="store_true",
                        help="only the hand-made top of GROMACS dihedral functions 2 and 3")
    parser.add_argument("--only-explicit-pairs", action="store_true",
                        help="only the tops with explicit 1-4 parameters (tests/data)")
    args = parser.parse_args()
    if args.only_explicit_pairs:
        explicit_pairs()
        return
    dihedral_types()
    if args.only_dihedral_types:
        return
    for name, (prmtop, inpcrd, method) in SHIPPED.items():
        write(name, prmtop, inpcrd, method, "scripts/make_topologies.py (OpenMM ForceField "
              "amber14-all.xml + amber14/tip3p.xml, written by ParmEd)")
    for name, (top, gro, method) in SHIPPED_GROMACS.items():
        write(name, top, gro, method, "scripts/make_gromacs_topologies.py (ParmEd's GROMACS "
              "writing of the shipped prmtop), read by OpenMM's GromacsTopFile with FLEXIBLE")
    protein()
    explicit_pairs()
    if args.other:
        other_tool()


if __name__ == "__main__":
    main()
