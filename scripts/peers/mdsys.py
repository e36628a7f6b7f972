"""Copied from the peers' comparison kit (shared/anchors/md/mdsys.py, 2026-11-24) so that
scripts/head_to_head.py runs from a clone; only this header was added.

Shared helpers: read a benchmark system (JSON + XYZ + velocities) and
build the corresponding OpenMM System.

All files in systems/ use LAMMPS 'real'-style units:
  length angstrom, energy kcal/mol, mass g/mol, time fs, charge e,
  velocity angstrom/fs, force kcal/mol/angstrom.
OpenMM works in nm, ps, kJ/mol; conversions are done here only.

Force groups (for MTS):
  group 0 = bonded (harmonic bonds + harmonic angles)   -> inner (fast) level
  group 1 = nonbonded (LJ + Coulomb, cutoff, exclusions) -> outer (slow) level
  group 2 = (native variants only) energy-only correction term, never
            integrated (see build_openmm_system).
"""
import json
import os

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
SYSDIR = os.path.join(HERE, "systems")

KCAL = 4.184          # kJ per kcal (exact)
A2NM = 0.1            # nm per angstrom
# angstrom/fs -> nm/ps
V_A_FS_TO_NM_PS = 100.0
# force kcal/mol/A -> kJ/mol/nm
F_KCALA_TO_KJNM = KCAL / A2NM


def sys_path(name, ext):
    return os.path.join(SYSDIR, name + ext)


def load_params(name):
    with open(sys_path(name, ".json")) as f:
        return json.load(f)


def read_xyz(path):
    with open(path) as f:
        lines = f.read().splitlines()
    n = int(lines[0].split()[0])
    elems = []
    xyz = np.zeros((n, 3))
    for i in range(n):
        p = lines[2 + i].split()
        elems.append(p[0])
        xyz[i] = [float(p[1]), float(p[2]), float(p[3])]
    return elems, xyz


def write_xyz(path, elems, xyz, comment):
    with open(path, "w") as f:
        f.write("%d\n%s\n" % (len(elems), comment))
        for e, r in zip(elems, xyz):
            f.write("%-3s %.10f %.10f %.10f\n" % (e, r[0], r[1], r[2]))


def load_positions(name):
    return read_xyz(sys_path(name, ".xyz"))[1]


def load_velocities(name):
    # same XYZ layout, but columns are vx vy vz in angstrom/fs
    return read_xyz(sys_path(name, ".vel.xyz"))[1]


def per_atom_arrays(p):
    types = p["atom_type_of"]
    tt = p["atom_types"]
    mass = np.array([tt[t]["mass"] for t in types])
    charge = np.array([tt[t]["charge"] for t in types])
    return mass, charge


def n_dof(p):
    return 3 * p["n_atoms"] - 3


def build_openmm_system(p, variant="identical"):
    """variant:
      'identical' : exactly the model in the JSON (CustomNonbondedForce).
      'native'    : polymer: NonbondedForce (same forces) + an energy-only
                    CustomNonbondedForce in group 2 that adds the LJ energy
                    shift, so energies are also identical to the model.
                    water: NonbondedForce CutoffPeriodic = OpenMM's built-in
                    reaction field (eps_rf=78.3) -> a DIFFERENT electrostatic
                    model, used only as a speed reference.
    """
    import openmm as mm
    import openmm.unit as u

    nb = p["nonbonded"]
    L = np.array(p["box"]) * A2NM
    system = mm.System()
    system.setDefaultPeriodicBoxVectors(mm.Vec3(L[0], 0, 0), mm.Vec3(0, L[1], 0), mm.Vec3(0, 0, L[2]))
    mass, charge = per_atom_arrays(p)
    for m in mass:
        system.addParticle(m)

    # ---- bonded: group 0 -----------------------------------------------
    bf = mm.HarmonicBondForce()
    for i, j, t in p["bonds"]:
        bt = p["bond_types"][t]
        # JSON: E = 0.5*k*(r-r0)^2, k in kcal/mol/A^2 ; OpenMM uses the same 0.5 convention
        bf.addBond(i, j, bt["r0"] * A2NM, bt["k"] * KCAL / A2NM**2)
    bf.setForceGroup(0)
    system.addForce(bf)
    if p["angles"]:
        af = mm.HarmonicAngleForce()
        for i, j, k, t in p["angles"]:
            at = p["angle_types"][t]
            af.addAngle(i, j, k, np.deg2rad(at["theta0_deg"]), at["k"] * KCAL)
        af.setForceGroup(0)
        system.addForce(af)

    # ---- nonbonded: group 1 --------------------------------------------
    rc = float(nb["cutoff"] * A2NM)
    types = p["atom_type_of"]
    tnames = sorted(p["atom_types"].keys())
    tindex = {t: i for i, t in enumerate(tnames)}
    nt = len(tnames)
    excl = p["exclusion_pairs"]
    has_coul = nb["coulomb"] is not None and np.any(charge != 0)

    if variant == "identical":
        # per type-pair LJ tables (epsilon, sigma) exactly as listed in the JSON
        eps_tab = np.zeros((nt, nt))
        sig_tab = np.ones((nt, nt))
        for key, c in nb["lj"]["pair_coeffs"].items():
            a, b = key.split("-")
            for x, y in ((a, b), (b, a)):
                eps_tab[tindex[x], tindex[y]] = c["epsilon"] * KCAL
                sig_tab[tindex[x], tindex[y]] = c["sigma"] * A2NM
        # if only one type pair has LJ, use scalars (faster JIT expression)
        lj_pairs = [(i, j) for i in range(nt) for j in range(nt) if eps_tab[i, j] != 0]
        expr_parts = []
        if nb["lj"].get("shift", False):
            ljexpr = "4*eps*(sr6*sr6-sr6) - 4*eps*(src6*src6-src6); sr6=(sig/r)^6; src6=(sig/rc)^6"
        else:
            ljexpr = "4*eps*(sr6*sr6-sr6); sr6=(sig/r)^6"
        if len(lj_pairs) == 0:
            ljexpr = None
        cf = None
        if has_coul:
            ke = nb["coulomb"]["ke"] * KCAL * A2NM  # kJ/mol nm / e^2
            form = nb["coulomb"]["form_id"]
            assert form == "shifted_force", form
            cexpr = "ke*q1*q2*(1/r - 2/rc + r/(rc*rc))"
        else:
            cexpr = None
        if len(lj_pairs) == 1 or (nt == 1 and ljexpr):
            # scalar eps/sig applied only when both atoms are of the LJ type pair
            i0, j0 = lj_pairs[0]
            assert i0 == j0, "single heteropair LJ not supported in fast path"
            lj_body = ljexpr.split(";")[0]
            lj_defs = ";".join(ljexpr.split(";")[1:])
            if nt == 1:
                body = "(%s)" % lj_body
            else:
                body = "ljon1*ljon2*(%s)" % lj_body
            parts = [body]
            if cexpr:
                parts.append(cexpr)
            full = " + ".join(parts) + ";" + lj_defs + "; eps=%r; sig=%r; rc=%r" % (
                float(eps_tab[i0, j0]), float(sig_tab[i0, j0]), float(rc))
            if cexpr:
                full += "; ke=%r" % float(ke)
            cf = mm.CustomNonbondedForce(full)
            if nt > 1:
                cf.addPerParticleParameter("ljon")
            if cexpr:
                cf.addPerParticleParameter("q")
            for a in range(p["n_atoms"]):
                prm = []
                if nt > 1:
                    prm.append(1.0 if tindex[types[a]] == i0 else 0.0)
                if cexpr:
                    prm.append(float(charge[a]))
                cf.addParticle(prm)
        else:
            parts = []
            if ljexpr:
                parts.append(ljexpr.split(";")[0])
            if cexpr:
                parts.append(cexpr)
            defs = ";".join(ljexpr.split(";")[1:]) if ljexpr else ""
            full = " + ".join(parts) + ";" + defs + "; eps=epstab(t1,t2); sig=sigtab(t1,t2); rc=%r" % float(rc)
            if cexpr:
                full += "; ke=%r" % float(ke)
            cf = mm.CustomNonbondedForce(full)
            cf.addTabulatedFunction("epstab", mm.Discrete2DFunction(nt, nt, list(eps_tab.T.flatten())))
            cf.addTabulatedFunction("sigtab", mm.Discrete2DFunction(nt, nt, list(sig_tab.T.flatten())))
            cf.addPerParticleParameter("t")
            if cexpr:
                cf.addPerParticleParameter("q")
            for a in range(p["n_atoms"]):
                prm = [float(tindex[types[a]])]
                if cexpr:
                    prm.append(float(charge[a]))
                cf.addParticle(prm)
        cf.setNonbondedMethod(mm.CustomNonbondedForce.CutoffPeriodic)
        cf.setCutoffDistance(rc)
        cf.setUseSwitchingFunction(False)
        cf.setUseLongRangeCorrection(False)
        for i, j in excl:
            cf.addExclusion(i, j)
        cf.setForceGroup(1)
        system.addForce(cf)
    elif variant == "native":
        nbf = mm.NonbondedForce()
        nbf.setNonbondedMethod(mm.NonbondedForce.CutoffPeriodic)
        nbf.setCutoffDistance(rc)
        nbf.setUseDispersionCorrection(False)
        nbf.setUseSwitchingFunction(False)
        if has_coul:
            nbf.setReactionFieldDielectric(78.3)
        # native NonbondedForce uses Lorentz-Berthelot per-particle params; the
        # benchmark systems only have like-type LJ (water: O-O; polymer: one type)
        lj = nb["lj"]["pair_coeffs"]
        for a in range(p["n_atoms"]):
            t = types[a]
            c = lj.get("%s-%s" % (t, t), {"epsilon": 0.0, "sigma": 1.0})
            nbf.addParticle(float(charge[a]), c["sigma"] * A2NM, c["epsilon"] * KCAL)
        for i, j in excl:
            nbf.addException(i, j, 0.0, 1.0, 0.0)
        nbf.setForceGroup(1)
        system.addForce(nbf)
        if nb["lj"].get("shift", False) and not has_coul:
            # energy-only term: -E_LJ(rc) for every LJ pair inside the cutoff;
            # zero force, never integrated (group 2)
            assert nt == 1
            c = lj["%s-%s" % (tnames[0], tnames[0])]
            e = c["epsilon"] * KCAL
            s = c["sigma"] * A2NM
            shift = 4 * e * ((s / rc) ** 12 - (s / rc) ** 6)
            sf = mm.CustomNonbondedForce("-(%r)" % float(shift))
            sf.setNonbondedMethod(mm.CustomNonbondedForce.CutoffPeriodic)
            sf.setCutoffDistance(rc)
            for a in range(p["n_atoms"]):
                sf.addParticle([])
            for i, j in excl:
                sf.addExclusion(i, j)
            sf.setForceGroup(2)
            system.addForce(sf)
    else:
        raise ValueError(variant)
    return system


def openmm_positions(p, xyz_A):
    return xyz_A * A2NM
