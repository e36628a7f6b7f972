#!/usr/bin/env python3
"""OpenMM on the solvated alanine dipeptide with constraints: the yardsticks of issue 28.

The system is OpenMM's own reading of the shipped topology
(systems/alanine-dipeptide-amber/ala2-solvated.prmtop, .inpcrd; app.AmberPrmtopFile) with
the settings of longstep's scene ala2-solvated.toml: CutoffPeriodic at 9 Å (the reaction
field, ε_rf = 78.3), LJ neither shifted nor switched, no dispersion correction, no
centre-of-mass motion remover, bonds to hydrogen constrained and rigid water
(constraints=HBonds, rigidWater=True), optionally hydrogenMass (HMR). Reference platform
(double precision). The start: the file's positions put on the constraints, Maxwell-Boltzmann
velocities at 300 K (seeded) projected onto them.

Three modes, each printing its figures and writing a JSON file (--out):

* `langevin`: LangevinMiddleIntegrator (BAOAB-type: B, A, O, A) at --h, --temperature,
  --friction for --t-end ps. Every --every steps it records the potential and kinetic
  energies; after --skip ps it reports the mean potential energy with the standard error of
  --blocks block means, and the kinetic temperature over 3N − N_c degrees of freedom (no
  motion remover, so the centre of mass is thermalized too). At every --bias-every-th record
  it also measures `⟨F_c·M⁻¹F_c⟩`, the force projected onto the constraints' tangent space
  (M⁻¹-orthogonally to the constraint gradients), which sets BAOAB's step-end kinetic
  temperature bias to leading order in h (docs/thermostats.md: each harmonic mode's
  step-end kinetic energy is kT/2 · (1 − (ω h)²/4), and Σ ω² kT = ⟨F·M⁻¹F⟩):
      T_kin / T = 1 − h² ⟨F_c·M⁻¹F_c⟩ / (4 N_f kT).
* `nve`: VerletIntegrator at --h for --t-end ps, the total energy every --every steps, and
  its drift by a least-squares line from --skip ps on, in kT/ns per degree of freedom with
  kT = 2⟨K⟩/N_f (as longstep's run reports it: slope / 2⟨K⟩), with the residual rms.
* `compare`: longstep's `langevin-respa` run at the same settings (--run DIR, its
  energy.csv) against the `langevin` JSON (--openmm): the difference of the mean potential
  energies in combined standard errors, and longstep's kinetic temperature over 3N − N_c
  against the BAOAB expectation above; verdicts: pass |z| ≤ 2, fail |z| > 3, undecided
  between.

    python3 scripts/openmm_constrained_peptide.py langevin --t-end 100 --skip 10 \
        --out docs/data/constraints/openmm-langevin-middle-ala2.json
    python3 scripts/openmm_constrained_peptide.py nve --h 4 --hmr 3 --t-end 100 --skip 5 \
        --out docs/data/constraints/openmm-nve-ala2-hmr-4fs.json

Needs `pip install openmm numpy`. Times: --h in fs, --t-end and --skip in ps.
"""
import argparse
import json
import math
import os
import time

import numpy as np
import openmm
from openmm import app, unit

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, ".."))
SYSTEMS = os.path.join(ROOT, "systems", "alanine-dipeptide-amber")
KCAL = 4.184  # kJ per kcal
BOLTZMANN_KCAL = 1.380649e-23 * 6.02214076e23 / 4184.0  # kcal/mol/K
EPSILON_RF = 78.3
CUTOFF_NM = 0.9


def build(hmr):
    prmtop = app.AmberPrmtopFile(os.path.join(SYSTEMS, "ala2-solvated.prmtop"))
    inpcrd = app.AmberInpcrdFile(os.path.join(SYSTEMS, "ala2-solvated.inpcrd"))
    kwargs = {"hydrogenMass": hmr * unit.amu} if hmr else {}
    system = prmtop.createSystem(nonbondedMethod=app.CutoffPeriodic,
                                 nonbondedCutoff=CUTOFF_NM * unit.nanometer,
                                 constraints=app.HBonds, rigidWater=True,
                                 removeCMMotion=False, **kwargs)
    for force in system.getForces():
        if isinstance(force, openmm.NonbondedForce):
            force.setUseDispersionCorrection(False)
            force.setUseSwitchingFunction(False)
            force.setReactionFieldDielectric(EPSILON_RF)
    rigid = add_hh_constraints(system, prmtop.topology)
    assert rigid == 423, f"{rigid} waters made rigid"
    return system, inpcrd


def add_hh_constraints(system, topology):
    """The H–H constraint each water needs for SETTLE, at 2 r_OH sin(θ₀/2).

    OpenMM's AMBER reader makes water rigid only through the H–H bond a tleap prmtop lists;
    this ParmEd-written prmtop has none, so rigidWater=True leaves the H–O–H angle flexible.
    Each water gets the H–H distance from its O–H constraint and H–O–H rest angle, as
    longstep builds it (docs/molecules.md); the angle term stays (constant at rest, as in
    longstep), so the potential energies compare term for term."""
    waters = {r.index: [a.index for a in r.atoms()] for r in topology.residues()
              if r.name == "HOH"}
    constrained = {}
    for k in range(system.getNumConstraints()):
        i, j, d = system.getConstraintParameters(k)
        constrained[(min(i, j), max(i, j))] = d.value_in_unit(unit.nanometer)
    (angles,) = [f for f in system.getForces() if isinstance(f, openmm.HarmonicAngleForce)]
    rest = {}
    for k in range(angles.getNumAngles()):
        i, j, m, theta, _ = angles.getAngleParameters(k)
        rest[(j, min(i, m), max(i, m))] = theta.value_in_unit(unit.radian)
    for o, h1, h2 in waters.values():
        r_oh = constrained[(min(o, h1), max(o, h1))]
        system.addConstraint(h1, h2, 2.0 * r_oh * math.sin(0.5 * rest[(o, min(h1, h2), max(h1, h2))]))
    return len(waters)


def start(system, inpcrd, integrator, args):
    integrator.setConstraintTolerance(args.tolerance)
    platform = openmm.Platform.getPlatformByName(args.platform)
    context = openmm.Context(system, integrator, platform)
    context.setPeriodicBoxVectors(*inpcrd.boxVectors)
    context.setPositions(inpcrd.positions)
    context.applyConstraints(args.tolerance)
    context.setVelocitiesToTemperature(args.temperature * unit.kelvin, args.seed)
    context.applyVelocityConstraints(args.tolerance)
    return context


def energies(context):
    s = context.getState(getEnergy=True)
    return (s.getPotentialEnergy().value_in_unit(unit.kilojoule_per_mole) / KCAL,
            s.getKineticEnergy().value_in_unit(unit.kilojoule_per_mole) / KCAL)


def block_error(values, blocks):
    """Mean and standard error of the mean from `blocks` consecutive block means."""
    n = len(values) // blocks
    means = np.array([np.mean(values[b * n:(b + 1) * n]) for b in range(blocks)])
    return float(np.mean(values[:blocks * n])), float(np.std(means, ddof=1) / math.sqrt(blocks))


class Projector:
    """Projects forces onto the constraints' tangent space, M⁻¹-orthogonally."""

    def __init__(self, system):
        self.pairs = np.array([system.getConstraintParameters(k)[:2]
                               for k in range(system.getNumConstraints())])
        self.inverse_mass = np.array([1.0 / system.getParticleMass(i).value_in_unit(unit.dalton)
                                      for i in range(system.getNumParticles())])

    def norm(self, positions_nm, forces_kj_nm):
        """F_c·M⁻¹F_c in (kcal/mol)²/(Å² amu), from positions (nm) and forces (kJ/mol/nm)."""
        x = positions_nm * 10.0
        f = forces_kj_nm / KCAL / 10.0
        i, j = self.pairs[:, 0], self.pairs[:, 1]
        d = x[i] - x[j]
        n, c = len(x), len(self.pairs)
        g = np.zeros((c, 3 * n))
        rows = np.arange(c)
        for axis in range(3):
            g[rows, 3 * i + axis] = d[:, axis]
            g[rows, 3 * j + axis] = -d[:, axis]
        w = np.repeat(self.inverse_mass, 3)
        flat = f.reshape(-1)
        gw = g * w
        lam = np.linalg.solve(gw @ g.T, gw @ flat)
        projected = flat - g.T @ lam
        return float(np.sum(projected * projected * w))


# 1 kcal/mol = 418.4 amu Å²/ps² = 4.184e-4 amu Å²/fs²: F·M⁻¹F [(kcal/mol)²/(Å² amu)] · h² [fs²]
# / kT [kcal/mol] is in kcal/mol/(Å² amu) · fs² = 4.184e-4.
CONVERSION = 4.184e-4


def records(integrator, context, args, keep_at_skip):
    """Steps `integrator` `args.every` steps at a time to `args.t_end` and yields (time in fs,
    potential, kinetic) after each batch that ends past `args.skip` (or at it, when
    `keep_at_skip`)."""
    steps = round(args.t_end * 1000.0 / args.h)
    skip = round(args.skip * 1000.0 / args.h)
    for step in range(0, steps, args.every):
        integrator.step(args.every)
        end = step + args.every
        if end < skip or (end == skip and not keep_at_skip):
            continue
        pe, ke = energies(context)
        yield end * args.h, pe, ke


def langevin(args):
    system, inpcrd = build(args.hmr)
    dt = args.h * unit.femtoseconds
    integrator = openmm.LangevinMiddleIntegrator(args.temperature * unit.kelvin,
                                                 args.friction / unit.picosecond, dt)
    integrator.setRandomNumberSeed(args.seed)
    context = start(system, inpcrd, integrator, args)
    projector = Projector(system)
    potential, kinetic, norms = [], [], []
    clock = time.time()
    for _, pe, ke in records(integrator, context, args, keep_at_skip=False):
        potential.append(pe)
        kinetic.append(ke)
        if len(potential) % args.bias_every == 0:
            s = context.getState(getPositions=True, getForces=True)
            norms.append(projector.norm(
                s.getPositions(asNumpy=True).value_in_unit(unit.nanometer),
                s.getForces(asNumpy=True).value_in_unit(unit.kilojoule_per_mole / unit.nanometer)))
    wall = time.time() - clock
    dof = 3 * system.getNumParticles() - system.getNumConstraints()
    kt = BOLTZMANN_KCAL * args.temperature
    temperature = [2.0 * k / (dof * BOLTZMANN_KCAL) for k in kinetic]
    pe_mean, pe_error = block_error(potential, args.blocks)
    t_mean, t_error = block_error(temperature, args.blocks)
    norm_mean, norm_error = block_error(norms, min(args.blocks, len(norms) // 2))
    per_h2 = norm_mean * CONVERSION / (4.0 * dof * kt)  # relative bias per fs²
    result = {
        "doc": "OpenMM LangevinMiddleIntegrator on ala2-solvated (prmtop, CutoffPeriodic 9 A, "
               "eps_rf 78.3, HBonds + rigidWater, platform in settings); energies kcal/mol; "
               "made by scripts/openmm_constrained_peptide.py langevin",
        "openmm": openmm.__version__,
        "settings": vars(args),
        "constraints": system.getNumConstraints(),
        "degrees_of_freedom": dof,
        "samples": len(potential),
        "potential_mean": pe_mean,
        "potential_error": pe_error,
        "kinetic_temperature_openmm": t_mean,
        "kinetic_temperature_openmm_error": t_error,
        "projected_force_norm_mean": norm_mean,
        "projected_force_norm_error": norm_error,
        "projected_force_samples": len(norms),
        "baoab_relative_bias_per_fs2": -per_h2,
        "wall_seconds": wall,
    }
    print(json.dumps({k: v for k, v in result.items() if k != "settings"}, indent=1))
    for h in (1.0, 2.0, 4.0):
        print(f"BAOAB step-end kinetic T at h = {h:g} fs: "
              f"{args.temperature * (1.0 - per_h2 * h * h):.2f} K (bias {-per_h2 * h * h:+.4%})")
    return result


def nve(args):
    system, inpcrd = build(args.hmr)
    integrator = openmm.VerletIntegrator(args.h * unit.femtoseconds)
    context = start(system, inpcrd, integrator, args)
    times, total, kinetic = [], [], []
    clock = time.time()
    for t, pe, ke in records(integrator, context, args, keep_at_skip=True):
        times.append(t)
        total.append(pe + ke)
        kinetic.append(ke)
    wall = time.time() - clock
    t, e = np.array(times), np.array(total)
    slope, intercept = np.polyfit(t, e, 1)
    residual = float(np.std(e - (slope * t + intercept), ddof=2))
    rate = slope / (2.0 * np.mean(kinetic)) * 1e6  # kT/ns/dof: slope per fs, 1e6 fs per ns
    dof = 3 * system.getNumParticles() - system.getNumConstraints() - 3
    result = {
        "doc": "OpenMM VerletIntegrator on ala2-solvated (prmtop, CutoffPeriodic 9 A, eps_rf "
               "78.3, HBonds + rigidWater), platform in settings; drift slope/(2<K>) in "
               "kT/ns/dof; made by scripts/openmm_constrained_peptide.py nve",
        "openmm": openmm.__version__,
        "settings": vars(args),
        "rows": len(t),
        "fit_from_fs": float(t[0]),
        "fit_to_fs": float(t[-1]),
        "drift_kt_per_ns_per_dof": float(rate),
        "fitted_change_kcal": float(slope * (t[-1] - t[0])),
        "residual_rms_kcal": residual,
        "mean_kinetic_temperature": float(2.0 * np.mean(kinetic) / (dof * BOLTZMANN_KCAL)),
        "wall_seconds": wall,
    }
    print(json.dumps({k: v for k, v in result.items() if k != "settings"}, indent=1))
    return result


def compare(args):
    """longstep's langevin-respa run (its energy.csv) against the stored OpenMM result."""
    import csv
    with open(args.openmm) as f:
        reference = json.load(f)
    with open(os.path.join(args.run, "energy.csv"), newline="") as f:
        rows = [r for r in csv.DictReader(f) if float(r["t[fs]"]) >= args.skip * 1000.0]
    dof = reference["degrees_of_freedom"]  # 3N − N_c: the Langevin run thermalizes the centre
    potential = [float(r["potential[kcal/mol]"]) for r in rows]
    temperature = [2.0 * float(r["kinetic[kcal/mol]"]) / (dof * BOLTZMANN_KCAL) for r in rows]
    pe, pe_error = block_error(potential, args.blocks)
    t, t_error = block_error(temperature, args.blocks)
    difference = pe - reference["potential_mean"]
    sigma = math.hypot(pe_error, reference["potential_error"])
    z = abs(difference) / sigma
    verdict = "pass" if z <= 2.0 else ("fail" if z > 3.0 else "undecided")
    h = reference["settings"]["h"]
    expected = args.temperature * (1.0 + reference["baoab_relative_bias_per_fs2"] * h * h)
    bias_error = (args.temperature * h * h * abs(reference["baoab_relative_bias_per_fs2"])
                  * reference["projected_force_norm_error"]
                  / reference["projected_force_norm_mean"])
    t_sigma = math.hypot(t_error, bias_error)
    t_z = abs(t - expected) / t_sigma
    t_verdict = "pass" if t_z <= 2.0 else ("fail" if t_z > 3.0 else "undecided")
    result = {
        "doc": "longstep langevin-respa with constraints against OpenMM LangevinMiddleIntegrator "
               "on ala2-solvated; made by scripts/openmm_constrained_peptide.py compare. "
               "Verdicts: pass |z| <= 2, fail |z| > 3, undecided between.",
        "run": args.run,
        "from_ps": args.skip,
        "blocks": args.blocks,
        "samples": len(rows),
        "longstep_potential_mean": pe,
        "longstep_potential_error": pe_error,
        "openmm_potential_mean": reference["potential_mean"],
        "openmm_potential_error": reference["potential_error"],
        "potential_difference": difference,
        "potential_combined_sigma": sigma,
        "potential_z": z,
        "potential_verdict": verdict,
        "degrees_of_freedom": dof,
        "longstep_kinetic_temperature": t,
        "longstep_kinetic_temperature_error": t_error,
        "baoab_expected_kinetic_temperature": expected,
        "baoab_expected_error": bias_error,
        "temperature_z": t_z,
        "temperature_verdict": t_verdict,
    }
    print(json.dumps({k: v for k, v in result.items() if k != "doc"}, indent=1))
    return result


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("mode", choices=["langevin", "nve", "compare"])
    parser.add_argument("--run", help="compare: longstep's run directory (energy.csv)")
    parser.add_argument("--openmm", help="compare: the JSON file the langevin mode wrote")
    parser.add_argument("--h", type=float, default=2.0, help="step (fs)")
    parser.add_argument("--hmr", type=float, default=0.0, help="hydrogen mass (amu); 0: none")
    parser.add_argument("--t-end", type=float, default=100.0, help="ps")
    parser.add_argument("--skip", type=float, default=10.0, help="ps left out at the start")
    parser.add_argument("--temperature", type=float, default=300.0, help="K")
    parser.add_argument("--friction", type=float, default=1.0, help="1/ps")
    parser.add_argument("--seed", type=int, default=2013)
    parser.add_argument("--every", type=int, default=10, help="steps between records")
    parser.add_argument("--bias-every", type=int, default=25,
                        help="records between projected-force samples")
    parser.add_argument("--blocks", type=int, default=10)
    parser.add_argument("--tolerance", type=float, default=1e-8, help="constraint tolerance")
    parser.add_argument("--platform", default="Reference")
    parser.add_argument("--out", help="JSON file to write")
    args = parser.parse_args()
    result = {"langevin": langevin, "nve": nve, "compare": compare}[args.mode](args)
    if args.out:
        os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
        with open(args.out, "w") as f:
            json.dump(result, f, indent=1)
        print("wrote", args.out)


if __name__ == "__main__":
    main()
