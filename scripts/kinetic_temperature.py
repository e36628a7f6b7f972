#!/usr/bin/env python3
"""Mean kinetic temperature of a run with a block-averaging standard error.

Reads a run's energy.csv (column `kinetic`, or another given by --column; kcal/mol in a real
scene), converts each row to T = 2 K / (N_f k_B) with N_f = 3 × atoms (a Langevin run does not conserve momentum,
so no degree of freedom is removed), drops rows before --skip (time, in the file's unit), cuts the
rest into blocks of --block (time) and reports the mean, the standard error of the mean from
the block means, and how far the mean is from --target in standard errors. It also prints the
standard error for a range of block lengths, so one can see that it has stopped growing at
the chosen length (blocks longer than the correlation time).

    python3 scripts/kinetic_temperature.py out/lr50/energy.csv --atoms 648 --block 5000 \
        --target 300

For SIN(R) pass --factor L/(L+1) (its kinetic temperature is L/(L+1) T by construction).
With BAOAB inner steps the step-end momenta of a stiff harmonic mode are cold by (ω dt)²/4
(LM13): about 1 % for flexible water at dt = 0.5 fs. Standard library only.
"""
import argparse
import csv
import math

BOLTZMANN_KCAL_PER_K = 1.380649e-23 * 6.02214076e23 / 4184.0


def block_error(values, length):
    """Mean of `values` and the standard error from consecutive blocks of `length` rows."""
    blocks = len(values) // length
    means = [sum(values[b * length:(b + 1) * length]) / length for b in range(blocks)]
    mean = sum(means) / blocks
    variance = sum((m - mean) ** 2 for m in means) / (blocks - 1)
    return mean, math.sqrt(variance / blocks), blocks


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("csv")
    parser.add_argument("--atoms", type=int, required=True)
    parser.add_argument("--block", type=float, required=True, help="block length (time)")
    parser.add_argument("--skip", type=float, default=0.0, help="drop rows before this time")
    parser.add_argument("--target", type=float, help="expected temperature (K)")
    parser.add_argument("--column", default="kinetic", help="kinetic energy column")
    parser.add_argument("--factor", type=float, default=1.0,
                        help="expected kinetic T / T (SIN(R): L/(L+1))")
    args = parser.parse_args()
    with open(args.csv, newline="") as f:
        rows = [r for r in csv.DictReader(f) if float(r["t"]) >= args.skip]
    times = [float(r["t"]) for r in rows]
    dof = 3 * args.atoms
    temperature = [2.0 * float(r[args.column]) / (dof * BOLTZMANN_KCAL_PER_K) for r in rows]
    spacing = times[1] - times[0]
    length = max(1, round(args.block / spacing))
    mean, error, blocks = block_error(temperature, length)
    print(f"rows {len(rows)} from t = {times[0]:g} to {times[-1]:g}, every {spacing:g}")
    print(f"mean kinetic T ({args.column}) = {mean:.3f} K, block SE = {error:.3f} K "
          f"({blocks} blocks of {length * spacing:g})")
    if args.target is not None:
        expected = args.target * args.factor
        print(f"expected {expected:.3f} K: off by {(mean - expected) / error:+.2f} SE")
    print("SE against block length (should level off):")
    for factor in (0.05, 0.1, 0.2, 0.5, 1.0, 2.0):
        k = max(1, round(length * factor))
        if len(temperature) // k >= 4:
            _, e, n = block_error(temperature, k)
            print(f"  block {k * spacing:g}: SE {e:.3f} K ({n} blocks)")


if __name__ == "__main__":
    main()
