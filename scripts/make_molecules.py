#!/usr/bin/env python3
"""Make the small-molecule structures and scenes in systems/molecules/ (needs RDKit:
`pip install rdkit`). Not needed to build or test longstep: its outputs are committed.

For each molecule: 3-D coordinates from RDKit (ETKDG embedding with a fixed seed, then an
MMFF94 minimisation), hydrogens explicit, written as XYZ with 10 decimals; Gasteiger partial
charges (RDKit), written into the scene as the per-atom `charges` list. Bonds are not written:
longstep perceives them with chemfiles. The scenes use longstep's built-in bond, angle and
Lennard-Jones tables and generic torsions (AMBER-like X-C-C-X n=3, X-C-N-X n=2), in vacuum
(no box, no cutoff, plain Coulomb, AMBER 1-4 scaling).

    python3 scripts/make_molecules.py
"""
import os

from rdkit import Chem
from rdkit.Chem import AllChem

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "..", "systems", "molecules")

MOLECULES = [
    ("butane", "CCCC", "n-butane C4H10"),
    ("hexane", "CCCCCC", "n-hexane C6H14"),
    ("alanine-dipeptide", "CC(=O)NC(C)C(=O)NC", "alanine dipeptide (Ace-Ala-NMe) C6H12N2O2"),
]

SCENE = """# {title}: {n} atoms in vacuum, from {name}.xyz (RDKit ETKDG + MMFF94 geometry,
# scripts/make_molecules.py). Bonds perceived by chemfiles; bond, angle and Lennard-Jones
# constants from longstep's built-in generic tables (the run prints which); rest lengths and
# angles from the geometry; generic torsions; Gasteiger charges (RDKit) with plain Coulomb
# (no cutoff), 1-2 and 1-3 pairs excluded, 1-4 pairs scaled 0.5 (LJ) and 1/1.2 (Coulomb).
# Not a validated force field: a molecule to try the methods on.
version = 1
name = "{name}"
description = "{title} in vacuum, generic force field"
dim = 3
units = "real"

[structure]
file = "{name}.xyz"

[forcefield]
coulomb = "plain"
charges = [{charges}]

[forcefield.torsions]
"X-C-C-X" = [{{ k = 0.15556, n = 3, phase = 0.0 }}]
"X-C-N-X" = [{{ k = 2.5, n = 2, phase = 180.0 }}]

[run]
method = "impulse"
h = "2fs"
inner_steps = 4
t_end = "10ps"

[output]
energy_every = 10
trajectory_every = 100
"""


def main():
    os.makedirs(OUT, exist_ok=True)
    for name, smiles, title in MOLECULES:
        mol = Chem.AddHs(Chem.MolFromSmiles(smiles))
        params = AllChem.ETKDGv3()
        params.randomSeed = 42
        AllChem.EmbedMolecule(mol, params)
        AllChem.MMFFOptimizeMolecule(mol, maxIters=2000)
        AllChem.ComputeGasteigerCharges(mol)
        charges = [a.GetDoubleProp("_GasteigerCharge") for a in mol.GetAtoms()]
        # Make the total exactly zero to 1e-10 (Gasteiger sums are neutral up to round-off).
        shift = sum(charges) / len(charges)
        charges = [round(c - shift, 10) for c in charges]
        conf = mol.GetConformer()
        with open(os.path.join(OUT, name + ".xyz"), "w") as f:
            f.write("%d\n%s (RDKit ETKDG seed 42 + MMFF94), angstrom\n" % (mol.GetNumAtoms(), title))
            for a in mol.GetAtoms():
                p = conf.GetAtomPosition(a.GetIdx())
                f.write("%-2s %.10f %.10f %.10f\n" % (a.GetSymbol(), p.x, p.y, p.z))
        with open(os.path.join(OUT, name + ".toml"), "w") as f:
            f.write(SCENE.format(title=title, n=mol.GetNumAtoms(), name=name,
                                 charges=", ".join("%.10f" % c for c in charges)))
        print(name, mol.GetNumAtoms(), "atoms")


if __name__ == "__main__":
    main()
