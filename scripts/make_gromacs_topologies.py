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

    pip install parmed
    python3 scripts/make_gromacs_topologies.py
"""
import os

import parmed

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, ".."))
OUT = os.path.join(ROOT, "systems", "alanine-dipeptide-amber")
PROTEIN_OUT = os.path.join(ROOT, "systems", "protein-amber")


def main():
    for out, stem in ((OUT, "ala2"), (OUT, "ala2-solvated"), (PROTEIN_OUT, "trpcage")):
        structure = parmed.load_file(os.path.join(out, stem + ".prmtop"),
                                     os.path.join(out, stem + ".inpcrd"))
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
