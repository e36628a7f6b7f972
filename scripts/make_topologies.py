#!/usr/bin/env python3
"""Build the shipped AMBER topologies (alanine dipeptide, Trp-cage) with OpenMM + ParmEd.

Writes, under systems/alanine-dipeptide-amber/:

* ala2.prmtop, ala2.inpcrd: in vacuum, Amber ff14SB (OpenMM's amber14-all.xml; ff14SB has
  no CMAP), no box;
* ala2-solvated.prmtop, ala2-solvated.inpcrd: the same peptide in a cubic 24 Å box of TIP3P
  water (OpenMM Modeller.addSolvent, amber14/tip3p.xml), written as flexible water: the O-H
  bonds and the H-O-H angle are harmonic terms of the topology (rigidWater=False), no
  constraints and no SHAKE flag.

The coordinates are those of systems/molecules/alanine-dipeptide.xyz (RDKit ETKDG + MMFF94,
scripts/make_molecules.py), given PDB names, mirrored if needed so that the alpha carbon is
L, and relaxed by OpenMM's local energy minimiser in ff14SB (vacuum), then solvated and
relaxed again (solvated). Nothing is downloaded.

And under systems/protein-amber/:

* trpcage.prmtop, trpcage.inpcrd: the Trp-cage miniprotein (NLYIQWLKDGGPSSGRPPPS, 20
  residues, charged termini, net charge +1) in a cubic 42 Å box of flexible TIP3P water with
  one Cl- ion, Amber ff14SB. The structure is built, not experimental: PeptideBuilder lays
  the backbone from the (phi, psi) of PROTEIN_PHI_PSI (a helix 2-9, a 3_10 turn 12-14,
  polyproline 16-19, roughly the fold of Trp-cage), Modeller adds the hydrogens (pH 7),
  the solvent and the ion, and OpenMM's local minimiser relaxes it in vacuum, then solvated.

    pip install openmm parmed PeptideBuilder
    python3 scripts/make_topologies.py
"""
import os

import numpy as np
import openmm
import parmed
from openmm import app, unit

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, ".."))
OUT = os.path.join(ROOT, "systems", "alanine-dipeptide-amber")
XYZ = os.path.join(ROOT, "systems", "molecules", "alanine-dipeptide.xyz")
BOX_NM = 2.4  # cubic box edge: a cutoff of 9 Å needs more than 18 Å
PROTEIN_OUT = os.path.join(ROOT, "systems", "protein-amber")
PROTEIN_SEQUENCE = "NLYIQWLKDGGPSSGRPPPS"  # Trp-cage TC5b
# (phi, psi) in degrees per residue: an alpha helix for residues 2-9, a turn at 10-11, a 3_10
# helix 12-14, a left-handed turn at G15, polyproline II for 16-19 (the termini's dihedrals
# are free). Not the NMR structure's angles: a compact start that minimises.
PROTEIN_PHI_PSI = ([(-60, 140)] + [(-60, -45)] * 8 + [(-90, 0), (90, 10), (-70, 140)]
                   + [(-60, -30)] * 3 + [(80, 10)] + [(-70, 150)] * 4)
PROTEIN_BOX_NM = 4.2  # about 1 nm of water around the 22 Å peptide

# Row of alanine-dipeptide.xyz -> (residue, PDB atom name), in the order RDKit wrote them
# (SMILES CC(=O)NC(C)C(=O)NC, then the hydrogens in the order of their heavy atoms).
NAMES = [
    ("ACE", "CH3"), ("ACE", "C"), ("ACE", "O"),
    ("ALA", "N"), ("ALA", "CA"), ("ALA", "CB"), ("ALA", "C"), ("ALA", "O"),
    ("NME", "N"), ("NME", "C"),
    ("ACE", "H1"), ("ACE", "H2"), ("ACE", "H3"),
    ("ALA", "H"), ("ALA", "HA"), ("ALA", "HB1"), ("ALA", "HB2"), ("ALA", "HB3"),
    ("NME", "H"), ("NME", "H1"), ("NME", "H2"), ("NME", "H3"),
]
ORDER = {"ACE": ["H1", "CH3", "H2", "H3", "C", "O"],
         "ALA": ["N", "H", "CA", "HA", "CB", "HB1", "HB2", "HB3", "C", "O"],
         "NME": ["N", "H", "C", "H1", "H2", "H3"]}


def read_xyz(path):
    with open(path) as f:
        lines = f.read().splitlines()
    n = int(lines[0].split()[0])
    return np.array([[float(v) for v in line.split()[1:4]] for line in lines[2:2 + n]])


def is_l_alanine(x):
    """CORN rule: seen from HA, CO -> R (CB) -> N runs clockwise."""
    ca, c, cb, n, ha = x[4], x[6], x[5], x[3], x[14]
    a, b, d = c - ca, cb - ca, n - ca
    turn = np.cross(a, b) + np.cross(b, d) + np.cross(d, a)
    return float(np.dot(turn, ha - ca)) < 0.0


def pdb_text(x):
    rows = {res: {} for res in ORDER}
    for (res, name), pos in zip(NAMES, x):
        rows[res][name] = pos
    lines, serial = [], 1
    for number, res in enumerate(["ACE", "ALA", "NME"], start=1):
        for name in ORDER[res]:
            p = rows[res][name]
            element = name[0]
            lines.append("ATOM  %5d %-4s %3s A%4d    %8.3f%8.3f%8.3f  1.00  0.00          %2s"
                         % (serial, name if len(name) == 4 else " " + name, res, number,
                            p[0], p[1], p[2], element))
            serial += 1
    lines.append("TER")
    lines.append("END")
    return "\n".join(lines) + "\n"


def minimise(topology, system, positions):
    integrator = openmm.VerletIntegrator(0.001)
    platform = openmm.Platform.getPlatformByName("Reference")
    context = openmm.Context(system, integrator, platform)
    context.setPositions(positions)
    openmm.LocalEnergyMinimizer.minimize(context, 1.0, 2000)
    return context.getState(getPositions=True).getPositions(asNumpy=True)


def save(topology, system, positions, stem, box=None, out=OUT):
    structure = parmed.openmm.load_topology(topology, system, xyz=positions)
    if box is not None:
        structure.box = box
    prmtop = os.path.join(out, stem + ".prmtop")
    inpcrd = os.path.join(out, stem + ".inpcrd")
    structure.save(prmtop, format="amber", overwrite=True)
    structure.save(inpcrd, format="rst7", overwrite=True)
    print("wrote", prmtop, inpcrd, len(structure.atoms), "atoms")


def built_peptide():
    """The Trp-cage backbone and side chains from PROTEIN_PHI_PSI (PeptideBuilder's ideal
    geometry), with the C-terminal OXT, as an OpenMM PDBFile without hydrogens."""
    import io

    import PeptideBuilder
    from Bio.PDB import PDBIO
    from PeptideBuilder import Geometry

    assert len(PROTEIN_PHI_PSI) == len(PROTEIN_SEQUENCE)
    geometries = []
    for i, letter in enumerate(PROTEIN_SEQUENCE):
        geometry = Geometry.geometry(letter)
        geometry.phi = PROTEIN_PHI_PSI[i][0]
        geometry.psi_im1 = PROTEIN_PHI_PSI[i - 1][1] if i > 0 else 0.0
        geometries.append(geometry)
    structure = PeptideBuilder.make_structure_from_geos(geometries)
    PeptideBuilder.add_terminal_OXT(structure)
    text = io.StringIO()
    writer = PDBIO()
    writer.set_structure(structure)
    writer.save(text)
    return app.PDBFile(io.StringIO(text.getvalue()))


def make_protein(ff, options):
    pdb = built_peptide()
    modeller = app.Modeller(pdb.topology, pdb.positions)
    modeller.addHydrogens(ff, pH=7.0)
    system = ff.createSystem(modeller.topology, nonbondedMethod=app.NoCutoff, **options)
    positions = minimise(modeller.topology, system, modeller.positions)
    modeller = app.Modeller(modeller.topology, positions)
    box = openmm.Vec3(PROTEIN_BOX_NM, PROTEIN_BOX_NM, PROTEIN_BOX_NM) * unit.nanometer
    modeller.addSolvent(ff, model="tip3p", boxSize=box, neutralize=True)
    system = ff.createSystem(modeller.topology, nonbondedMethod=app.CutoffPeriodic,
                             nonbondedCutoff=0.9 * unit.nanometer, **options)
    positions = minimise(modeller.topology, system, modeller.positions)
    edge = PROTEIN_BOX_NM * 10.0
    os.makedirs(PROTEIN_OUT, exist_ok=True)
    save(modeller.topology, system, positions, "trpcage", box=[edge, edge, edge, 90, 90, 90],
         out=PROTEIN_OUT)


def main():
    x = read_xyz(XYZ)
    if not is_l_alanine(x):
        x[:, 0] *= -1.0  # a mirror image keeps every internal coordinate, flips chirality
    assert is_l_alanine(x)
    path = os.path.join(OUT, "ala2-start.pdb")
    os.makedirs(OUT, exist_ok=True)
    with open(path, "w") as f:
        f.write(pdb_text(x))
    pdb = app.PDBFile(path)
    os.remove(path)
    ff = app.ForceField("amber14-all.xml", "amber14/tip3p.xml")
    options = dict(constraints=None, rigidWater=False)

    system = ff.createSystem(pdb.topology, nonbondedMethod=app.NoCutoff, **options)
    positions = minimise(pdb.topology, system, pdb.positions)
    save(pdb.topology, system, positions, "ala2")

    modeller = app.Modeller(pdb.topology, positions)
    modeller.addSolvent(ff, model="tip3p", boxSize=openmm.Vec3(BOX_NM, BOX_NM, BOX_NM) * unit.nanometer)
    system = ff.createSystem(modeller.topology, nonbondedMethod=app.CutoffPeriodic,
                             nonbondedCutoff=0.9 * unit.nanometer, **options)
    positions = minimise(modeller.topology, system, modeller.positions)
    edge = BOX_NM * 10.0
    save(modeller.topology, system, positions, "ala2-solvated", box=[edge, edge, edge, 90, 90, 90])
    make_protein(ff, options)


if __name__ == "__main__":
    main()
