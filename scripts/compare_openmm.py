#!/usr/bin/env python3
"""Compare longstep's energies and forces with OpenMM (and the peer kit's numpy reference).

For each scene: `longstep forces SCENE --parameters P.json` dumps every parameter of every
interaction (after longstep's table lookups); this script builds the same system in OpenMM
from that dump, evaluates both codes at the same coordinates (the scene's, randomly displaced
by up to DISPLACEMENT Å with a fixed seed so that bonds and angles are off their rest values)
and prints the energy difference per group and the force difference per level (bonded = fast,
non-bonded = slow) and in total: rel. RMS = rms(F_longstep - F_openmm) / rms(F_openmm).

OpenMM forms used: HarmonicBondForce, HarmonicAngleForce, PeriodicTorsionForce (same
conventions), CustomNonbondedForce for Lennard-Jones (per-type ε, σ tables, energy shift) and
for shifted-force / DSF and plain Coulomb, OpenMM's own NonbondedForce (CutoffPeriodic or
CutoffNonPeriodic) for reaction field, CustomBondForce for scaled 1-4 pairs.

    python3 scripts/compare_openmm.py                 # shipped molecules + water box
    python3 scripts/compare_openmm.py --platform CPU  # OpenMM's CPU platform (mixed precision)
    python3 scripts/compare_openmm.py --store         # (re)write tests/data/openmm-butane.*
    python3 scripts/compare_openmm.py --kit           # also the kit's reference_numpy.py

Needs `pip install openmm numpy` and a release build (`cargo build --release`).
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, ".."))
BIN = os.path.join(ROOT, "target", "release", "longstep")
KIT = os.path.abspath(os.path.join(ROOT, "..", "shared", "anchors", "md"))

# XYZ files are read as the peers' kit reads them (scripts/peers/mdsys.py): (elements, n × 3).
sys.path.insert(0, os.path.join(HERE, "peers"))
from mdsys import read_xyz  # noqa: E402

KCAL = 4.184  # kJ per kcal
A2NM = 0.1
GROUPS = ["bonds", "angles", "torsions", "lennard_jones", "coulomb"]
# OpenMM force groups: bonds 0, angles 1, torsions 2, LJ 3, Coulomb 4, LJ 1-4 5, Coulomb 1-4 6.
GROUP_SETS = {"bonds": {0}, "angles": {1}, "torsions": {2}, "lennard_jones": {3, 5}, "coulomb": {4, 6}}
BONDED = {0, 1, 2}
NONBONDED = {3, 4, 5, 6}

SCENES = [
    "systems/molecules/butane.toml",
    "systems/molecules/hexane.toml",
    "systems/molecules/alanine-dipeptide.toml",
    "systems/water-box/scene.toml",
    "systems/water-box/reaction-field.toml",
    "systems/polymer-melt/scene.toml",
]


def write_xyz(path, elements, x, comment):
    with open(path, "w") as f:
        f.write("%d\n%s\n" % (len(elements), comment))
        for e, r in zip(elements, x):
            f.write("%-2s %.10f %.10f %.10f\n" % (e, r[0], r[1], r[2]))


def scene_structure(scene):
    """The XYZ file a scene reads (its [structure] file)."""
    import tomllib
    with open(scene, "rb") as f:
        s = tomllib.load(f)
    return os.path.join(os.path.dirname(scene), s["structure"]["file"])


def longstep_forces(scene, positions, workdir):
    out = os.path.join(workdir, "forces.csv")
    params = os.path.join(workdir, "parameters.json")
    cmd = [BIN, "forces", scene, "--quiet", "--json", "--by-level", "--out", out,
           "--parameters", params, "--positions", positions]
    res = subprocess.run(cmd, check=True, capture_output=True, text=True, cwd=ROOT)
    report = json.loads(res.stdout)
    # Column names carry their unit in brackets (`fx[kcal/mol/angstrom]`): name by what
    # comes before it.
    with open(out) as f:
        names = [c.split("[")[0] for c in f.readline().strip().split(",")]
    data = np.genfromtxt(out, delimiter=",", skip_header=1, names=names, dtype=None,
                         encoding=None)
    total = np.stack([data["fx"], data["fy"], data["fz"]], axis=1)
    fast = np.stack([data["fx_fast"], data["fy_fast"], data["fz_fast"]], axis=1)
    slow = np.stack([data["fx_slow"], data["fy_slow"], data["fz_slow"]], axis=1)
    with open(params) as f:
        p = json.load(f)
    return report["energy"], {"total": total, "bonded": fast, "nonbonded": slow}, p


def build_openmm(p):
    import openmm as mm
    n = len(p["masses"])
    system = mm.System()
    for m in p["masses"]:
        system.addParticle(m)
    periodic = p["box"] is not None
    if periodic:
        L = np.array(p["box"]) * A2NM
        system.setDefaultPeriodicBoxVectors(mm.Vec3(L[0], 0, 0), mm.Vec3(0, L[1], 0), mm.Vec3(0, 0, L[2]))
    bf = mm.HarmonicBondForce()
    for i, j, k, r0 in p["bonds"]:
        bf.addBond(i, j, r0 * A2NM, k * KCAL / A2NM ** 2)
    af = mm.HarmonicAngleForce()
    for i, j, k, kth, th0 in p["angles"]:
        af.addAngle(i, j, k, th0, kth * KCAL)
    tf = mm.PeriodicTorsionForce()
    for atoms, series in p["torsions"]:
        for k, nper, phase in series:
            assert float(nper).is_integer()
            tf.addTorsion(*atoms, int(nper), phase, k * KCAL)
    for g, f in enumerate((bf, af, tf)):
        f.setUsesPeriodicBoundaryConditions(periodic)
        f.setForceGroup(g)
        system.addForce(f)

    nb = p["nonbonded"]
    rc = nb["cutoff"]
    method = (mm.CustomNonbondedForce.CutoffPeriodic if periodic else
              mm.CustomNonbondedForce.CutoffNonPeriodic) if rc else mm.CustomNonbondedForce.NoCutoff
    excluded = [tuple(e) for e in p["exclusions"]]
    nt = len(p["types"])
    eps = np.array(p["lj_epsilon"]) * KCAL
    sig = np.array(p["lj_sigma"]) * A2NM
    # Lennard-Jones: per-type-pair tables.
    expr = "4*e*((s/r)^12 - (s/r)^6)"
    if nb["lj_shift"]:
        expr += " - 4*e*((s/rc)^12 - (s/rc)^6); rc=%r" % (rc * A2NM)
    expr += "; e=eps(t1, t2); s=sig(t1, t2)"
    lj = mm.CustomNonbondedForce(expr)
    lj.addTabulatedFunction("eps", mm.Discrete2DFunction(nt, nt, list(eps.T.flatten())))
    lj.addTabulatedFunction("sig", mm.Discrete2DFunction(nt, nt, list(sig.T.flatten())))
    lj.addPerParticleParameter("t")
    for t in p["type_of"]:
        lj.addParticle([float(t)])
    forces = [lj]
    ke = nb["coulomb_constant"] * KCAL * A2NM
    q = p["charges"]
    if nb["coulomb"] in ("dsf", "plain"):
        if nb["coulomb"] == "plain":
            cexpr = "ke*q1*q2/r"
        elif not nb["dsf_alpha"]:
            cexpr = "ke*q1*q2*(1/r - 2/rc + r/(rc*rc)); rc=%r" % (rc * A2NM)
        else:
            a = nb["dsf_alpha"] / A2NM
            cexpr = ("ke*q1*q2*(erfc(a*r)/r - erfc(a*rc)/rc + (r - rc)*(erfc(a*rc)/(rc*rc) "
                     "+ 2*a/sqrt(pi)*exp(-a*a*rc*rc)/rc)); a=%r; rc=%r; pi=%r") % (a, rc * A2NM, np.pi)
        cexpr += "; ke=%r" % ke
        coul = mm.CustomNonbondedForce(cexpr)
        coul.addPerParticleParameter("q")
        for c in q:
            coul.addParticle([c])
        forces.append(coul)
    elif nb["coulomb"] == "reaction-field":
        coul = mm.NonbondedForce()
        coul.setNonbondedMethod(mm.NonbondedForce.CutoffPeriodic if periodic else mm.NonbondedForce.CutoffNonPeriodic)
        coul.setReactionFieldDielectric(nb["rf_dielectric"])
        coul.setUseDispersionCorrection(False)
        for c in q:
            coul.addParticle(c, 1.0, 0.0)
        for i, j in excluded:
            coul.addException(i, j, 0.0, 1.0, 0.0)
        forces.append(coul)
    for g, f in zip((3, 4), forces):
        if isinstance(f, mm.CustomNonbondedForce):
            f.setNonbondedMethod(method)
            if rc:
                f.setCutoffDistance(rc * A2NM)
            for i, j in excluded:
                f.addExclusion(i, j)
        else:
            f.setCutoffDistance(rc * A2NM)
        f.setForceGroup(g)
        system.addForce(f)
    # Scaled 1-4 pairs, no cutoff.
    if p["pairs_14"]:
        lj14 = mm.CustomBondForce("4*e*((s/r)^12 - (s/r)^6)")
        lj14.addPerBondParameter("e")
        lj14.addPerBondParameter("s")
        c14 = mm.CustomBondForce("qq/r")
        c14.addPerBondParameter("qq")
        for i, j in p["pairs_14"]:
            ti, tj = p["type_of"][i], p["type_of"][j]
            lj14.addBond(i, j, [p["scale_14_lj"] * eps[ti, tj], sig[ti, tj]])
            if nb["coulomb"] != "none":
                c14.addBond(i, j, [p["scale_14_coulomb"] * ke * q[i] * q[j]])
        for g, f in ((5, lj14), (6, c14)):
            f.setUsesPeriodicBoundaryConditions(periodic)
            f.setForceGroup(g)
            system.addForce(f)
    return system


def openmm_evaluate(system, x, platform):
    import openmm as mm
    import openmm.unit as u
    integ = mm.VerletIntegrator(0.001)
    props = {"Threads": "1"} if platform == "CPU" else {}
    ctx = mm.Context(system, integ, mm.Platform.getPlatformByName(platform), props)
    ctx.setPositions(x * A2NM)
    kj = u.kilojoule_per_mole

    def state(groups):
        st = ctx.getState(getEnergy=True, getForces=True, groups=groups)
        e = st.getPotentialEnergy().value_in_unit(kj) / KCAL
        f = st.getForces(asNumpy=True).value_in_unit(kj / u.nanometer) / (KCAL / A2NM)
        return e, np.array(f)

    energy = {g: state(s)[0] for g, s in GROUP_SETS.items()}
    e_b, f_b = state(BONDED)
    e_n, f_n = state(NONBONDED)
    energy["fast"], energy["slow"] = e_b, e_n
    energy["total"] = e_b + e_n
    return energy, {"total": f_b + f_n, "bonded": f_b, "nonbonded": f_n}


def rel_rms(a, b):
    ref = np.sqrt(np.mean(b ** 2))
    return np.sqrt(np.mean((a - b) ** 2)) / ref if ref > 0 else float("nan")


def compare(scene, platform, displacement, seed, workdir, store=None):
    import openmm
    elements, x0 = read_xyz(os.path.join(ROOT, scene_structure(scene)))
    rng = np.random.default_rng(seed)
    x = x0 + rng.uniform(-displacement, displacement, size=x0.shape)
    positions = os.path.join(workdir, "positions.xyz")
    write_xyz(positions, elements, x, "displaced by up to %g A, seed %d" % (displacement, seed))
    _, x = read_xyz(positions)  # exactly the numbers longstep reads
    e_ls, f_ls, p = longstep_forces(scene, positions, workdir)
    system = build_openmm(p)
    e_mm, f_mm = openmm_evaluate(system, x, platform)
    print("\n%s (%d atoms; OpenMM %s, %s platform; displaced ≤ %g Å)"
          % (scene, len(x), openmm.__version__, platform, displacement))
    print("  %-14s %20s %20s %12s" % ("energy", "longstep", "OpenMM", "difference"))
    for g in GROUPS + ["fast", "slow", "total"]:
        print("  %-14s %20.10f %20.10f %12.3e" % (g, e_ls[g], e_mm[g], e_ls[g] - e_mm[g]))
    worst = 0.0
    print("  %-14s %12s %12s" % ("forces", "rel. RMS", "max |dF|"))
    for part in ("bonded", "nonbonded", "total"):
        r = rel_rms(f_ls[part], f_mm[part])
        worst = max(worst, r if np.isfinite(r) else 0.0)
        print("  %-14s %12.3e %12.3e" % (part, r, np.max(np.abs(f_ls[part] - f_mm[part]))))
    if store:
        data_dir = os.path.join(ROOT, "tests", "data")
        os.makedirs(data_dir, exist_ok=True)
        write_xyz(os.path.join(data_dir, store + ".xyz"), elements, x,
                  "%s displaced by up to %g A (seed %d): positions of the OpenMM reference"
                  % (scene, displacement, seed))
        with open(os.path.join(data_dir, store + ".json"), "w") as f:
            json.dump({
                "scene": scene,
                "positions": "tests/data/%s.xyz" % store,
                "made_by": "python3 scripts/compare_openmm.py --store (OpenMM %s, %s platform, "
                           "double precision)" % (openmm.__version__, platform),
                "units": {"energy": "kcal/mol", "force": "kcal/mol/angstrom"},
                "energy": {g: e_mm[g] for g in GROUPS + ["fast", "slow", "total"]},
                "forces_total": f_mm["total"].tolist(),
                "forces_bonded": f_mm["bonded"].tolist(),
                "forces_nonbonded": f_mm["nonbonded"].tolist(),
            }, f, indent=1)
        print("  stored tests/data/%s.{json,xyz}" % store)
    return worst


def kit_numpy(workdir):
    """The kit's brute-force numpy reference on its water216 at the kit's coordinates."""
    sys.path.insert(0, KIT)
    import reference_numpy  # noqa: E402
    E, F = reference_numpy.evaluate("water216")
    positions = os.path.join(KIT, "systems", "water216.xyz")
    e_ls, f_ls, _ = longstep_forces("systems/water-box/scene.toml", positions, workdir)
    print("\nwater box vs the kit's reference_numpy.py (water216, kit coordinates)")
    for ours, theirs in (("fast", "bonded"), ("slow", "nonbonded"), ("lennard_jones", "lj"),
                         ("coulomb", "coul"), ("total", "total")):
        print("  %-14s %20.10f %20.10f %12.3e" % (ours, e_ls[ours], E[theirs], e_ls[ours] - E[theirs]))
    for k, part in enumerate(("total", "bonded", "nonbonded")):
        print("  forces %-9s rel. RMS %.3e" % (part, rel_rms(f_ls[part], F[k])))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scenes", nargs="*", default=SCENES)
    ap.add_argument("--platform", default="Reference", choices=["Reference", "CPU"])
    ap.add_argument("--displacement", type=float, default=0.05)
    ap.add_argument("--seed", type=int, default=6)
    ap.add_argument("--store", action="store_true",
                    help="write tests/data/openmm-butane.{json,xyz} (Reference platform)")
    ap.add_argument("--kit", action="store_true", help="also compare with the kit's numpy reference")
    args = ap.parse_args()
    worst = 0.0
    with tempfile.TemporaryDirectory() as workdir:
        for scene in args.scenes:
            store = None
            if args.store and scene.endswith("butane.toml"):
                store = "openmm-butane"
            worst = max(worst, compare(scene, args.platform, args.displacement, args.seed, workdir, store))
        if args.kit:
            kit_numpy(workdir)
    print("\nworst force rel. RMS: %.3e (requirement 1e-6): %s" % (worst, "PASS" if worst <= 1e-6 else "FAIL"))
    sys.exit(0 if worst <= 1e-6 else 1)


if __name__ == "__main__":
    main()
