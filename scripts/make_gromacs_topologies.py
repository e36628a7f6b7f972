#!/usr/bin/env python3
"""Write the shipped AMBER systems (alanine dipeptide, Trp-cage) also as GROMACS top/gro.

Reads systems/alanine-dipeptide-amber/{ala2,ala2-solvated}.prmtop/.inpcrd and
systems/protein-amber/trpcage.prmtop/.inpcrd (made by scripts/make_topologies.py) and
writes ala2.top/.gro, ala2-solvated.top/.gro and trpcage.top/.gro beside them: ParmEd's `save(..., format="gromacs")` with every parameter inline (no #include, no
GROMACS installation needed). ParmEd writes a water molecule as `[settles]` with its
flexible `[bonds]`/`[angles]` under `#ifdef FLEXIBLE`: the solvated system is flexible like
its prmtop when read with FLEXIBLE defined (longstep: `[topology] defines = ["FLEXIBLE"]`;
OpenMM: GromacsTopFile(defines={"FLEXIBLE": True})). The vacuum system has no box: ParmEd
writes its bounding box on the .gro's last line, which this script sets to 0 0 0 (no box).

ParmEd gives [ defaults ] one fudgeLJ, 1/SCNB when every 1-4 pair has the same SCNB and
1.0 otherwise — and then writes [ pairs ] without parameters, so mixed SCNB would double
the 1-4 Lennard-Jones. The Trp-cage prmtop (ParmEd's reading of OpenMM's System) has SCNB
2.0 for its 801 1-4 pairs with Lennard-Jones and 1e10 for 11 pairs with a hydroxyl H (ε = 0:
no 1-4 LJ whatever the scale); uniform_scnb sets those 11 to 2.0, which changes no energy
and lets ParmEd write fudgeLJ 0.5.

    pip install parmed
    python3 scripts/make_gromacs_topologies.py
"""
import os

import parmed

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, ".."))
OUT = os.path.join(ROOT, "systems", "alanine-dipeptide-amber")
PROTEIN_OUT = os.path.join(ROOT, "systems", "protein-amber")


def uniform_scnb(structure):
    """SCNB 2.0 for the 1-4 pairs whose Lennard-Jones is zero (an end with ε = 0)."""
    for dihedral in structure.dihedrals:
        zero = dihedral.atom1.epsilon == 0.0 or dihedral.atom4.epsilon == 0.0
        if not dihedral.ignore_end and dihedral.type.scnb != 2.0 and zero:
            dihedral.type.scnb = 2.0


def main():
    for out, stem in ((OUT, "ala2"), (OUT, "ala2-solvated"), (PROTEIN_OUT, "trpcage")):
        structure = parmed.load_file(os.path.join(out, stem + ".prmtop"),
                                     os.path.join(out, stem + ".inpcrd"))
        uniform_scnb(structure)
        top = os.path.join(out, stem + ".top")
        gro = os.path.join(out, stem + ".gro")
        structure.save(top, format="gromacs", overwrite=True)
        structure.save(gro, format="gro", overwrite=True)
        if structure.box is None:
            with open(gro) as f:
                lines = f.read().splitlines()
            lines[-1] = "   0.00000   0.00000   0.00000"
            with open(gro, "w") as f:
                f.write("\n".join(lines) + "\n")
        print(top, gro, len(structure.atoms), "atoms")


if __name__ == "__main__":
    main()
