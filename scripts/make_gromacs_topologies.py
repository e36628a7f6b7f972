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

Explicit 1-4 parameters, as ParmEd writes a Structure made from an OpenMM System (whose
NonbondedForce exceptions become ParmEd "adjusts") and as acpype writes: `gen-pairs no`,
`fudgeLJ 1` and each pair's own σ/ε (already scaled). explicit_pairs() writes the vacuum
dipeptide three ways into tests/data/: gromacs-pairs-inline.top (σ/ε on each [ pairs ]
line), gromacs-pairs-types.top (σ/ε in [ pairtypes ], the pairs bare) and
gromacs-pairs-genpairs.top (the latter with `gen-pairs yes`, `fudgeLJ 0.5` and every other
[ pairtypes ] line removed, so those pairs are generated from the atom types × 0.5, which
for Amber's SCNB 2 is the same energy), with gromacs-pairs.gro (box 0 0 0: vacuum).

    pip install parmed openmm
    python3 scripts/make_gromacs_topologies.py [--only-explicit-pairs]
"""
import os
import re
import sys

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


DATA = os.path.join(ROOT, "tests", "data")


def sections(text):
    """The top as [(directive or None for the lines before the first, [lines])]."""
    out = [(None, [])]
    for line in text.splitlines():
        m = re.match(r"\s*\[\s*(\w+)\s*\]", line)
        if m:
            out.append((m.group(1), [line]))
        else:
            out[-1][1].append(line)
    return out


def pairs_to_pairtypes(text):
    """The inline top with each pair's σ/ε moved into one [ pairtypes ] line per type pair
    (after [ atomtypes ]); asserts that a type pair has one σ/ε."""
    parts = sections(text)
    types = {}
    for name, lines in parts:
        if name == "atoms":
            for line in lines[1:]:
                f = line.split(";")[0].split()
                if f:
                    types[f[0]] = f[1]
    table = {}
    for k, (name, lines) in enumerate(parts):
        if name != "pairs":
            continue
        bare = [lines[0]]
        for line in lines[1:]:
            f = line.split(";")[0].split()
            if len(f) < 5:
                bare.append(line)
                continue
            key = tuple(sorted((types[f[0]], types[f[1]])))
            assert table.setdefault(key, (f[3], f[4])) == (f[3], f[4]), key
            bare.append(f"{f[0]:>7} {f[1]:>6} {f[2]:>5}")
        parts[k] = (name, bare)
    rows = ["[ pairtypes ]", "; i j   func    sigma1-4    epsilon1-4"]
    rows += [f"{a:<5} {b:<5}  1  {s} {e}" for (a, b), (s, e) in sorted(table.items())]
    at = next(k for k, (name, _) in enumerate(parts) if name == "atomtypes")
    parts.insert(at + 1, ("pairtypes", rows + [""]))
    return "\n".join(line for _, lines in parts for line in lines) + "\n"


def explicit_pairs():
    """The vacuum dipeptide with explicit 1-4 σ/ε: inline, in [ pairtypes ], gen-pairs yes."""
    from openmm import app

    prmtop = app.AmberPrmtopFile(os.path.join(OUT, "ala2.prmtop"))
    inpcrd = app.AmberInpcrdFile(os.path.join(OUT, "ala2.inpcrd"))
    system = prmtop.createSystem(nonbondedMethod=app.NoCutoff, constraints=None,
                                 rigidWater=False)
    structure = parmed.openmm.load_topology(prmtop.topology, system, xyz=inpcrd.positions)
    assert structure.adjusts, "no explicit 1-4 pairs to write"
    inline = os.path.join(DATA, "gromacs-pairs-inline.top")
    gro = os.path.join(DATA, "gromacs-pairs.gro")
    structure.save(inline, format="gromacs", overwrite=True)
    structure.save(gro, format="gro", overwrite=True)
    with open(gro) as f:
        lines = f.read().splitlines()
    lines[-1] = "   0.00000   0.00000   0.00000"
    with open(gro, "w") as f:
        f.write("\n".join(lines) + "\n")
    with open(inline) as f:
        text = pairs_to_pairtypes(f.read())
    with open(os.path.join(DATA, "gromacs-pairs-types.top"), "w") as f:
        f.write(text)
    defaults = re.search(r"^1 +2 +no +1 +(\S+)", text, re.M)
    assert defaults, "ParmEd's [ defaults ] line changed"
    text = text.replace(defaults.group(0), f"1  2  yes  0.5  {defaults.group(1)}")
    head, rest = text.split("[ pairtypes ]\n", 1)
    table, tail = rest.split("\n\n", 1)
    rows = table.splitlines()
    kept = [r for k, r in enumerate(rows) if r.startswith(";") or k % 2 == 0]
    with open(os.path.join(DATA, "gromacs-pairs-genpairs.top"), "w") as f:
        f.write(head + "[ pairtypes ]\n" + "\n".join(kept) + "\n\n" + tail)
    print(inline, "and -types, -genpairs;", gro, len(structure.adjusts), "pairs")


def main():
    if "--only-explicit-pairs" in sys.argv[1:]:
        explicit_pairs()
        return
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
    explicit_pairs()


if __name__ == "__main__":
    main()
