#!/usr/bin/env python3
"""The criteria of `longstep analyze … --reference REF --json` as a Markdown table: one row
per criterion, one column per run (difference ± combined standard error, verdict), the
bound beside; an undecided criterion with the run length that would decide it (`~T`), or,
when the reference's own error is too wide for any run of the point, how many times longer
both would have to be (`both ×f`, the difference assumed to stay).

    longstep analyze MODEL RUN… --reference REF --temperature 300K --json > verdicts.json
    python3 scripts/verdict_table.py verdicts.json [--labels A,B]
"""
import argparse
import json
import sys


def cell(c, time_unit):
    if c["difference"] is None:
        return c["verdict"]
    d, e = c["difference"], c["error"]
    digits = 3 if abs(e) < 1 else 1
    text = f"{d:+.{digits}f} ± {e:.{digits}f}"
    verdict = c["verdict"]
    if verdict == "fail":
        text = f"**{text}**"
    if verdict == "undecided" and c.get("decide_at"):
        verdict += f" (~{c['decide_at'] / 1000:.0f} ps)" if time_unit == "fs" else \
            f" (~{c['decide_at']:.3g} {time_unit})"
    elif verdict == "undecided" and c.get("kind") != "basin":
        # (A basin's error is that of its dwells, not 1/√T before many transitions.)
        verdict += f" (both ×{both_longer(d, e, c['bound']):.0f})"
    return f"{text} {verdict}"


def both_longer(d, e, bound):
    """How many times longer the run and the reference both must be to decide, when the
    reference's error alone is too wide for the run to: the 2σ interval must clear the
    bound by the gap ||d| − bound|, and σ shrinks as 1/√T in both (the difference assumed to
    stay where it is)."""
    gap = abs(abs(d) - bound)
    return (2.0 * e / gap) ** 2 if gap > 0 else float("inf")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("json")
    parser.add_argument("--labels", help="column labels, comma-separated")
    args = parser.parse_args()
    with open(args.json) as f:
        runs = json.load(f)
    labels = args.labels.split(",") if args.labels else [r["label"] for r in runs]
    if len(labels) != len(runs):
        sys.exit(f"--labels gives {len(labels)} labels for {len(runs)} runs")
    time_unit = runs[0]["units"]["time"]
    print("| criterion | bound | " + " | ".join(labels) + " |")
    print("|---|---|" + "---|" * len(runs))
    for k, first in enumerate(runs[0]["criteria"]):
        unit = f" ({first['unit']})" if first["unit"] else ""
        bound = first["bound"]
        bound = "" if bound is None else f"{bound:.3g}"
        cells = [cell(r["criteria"][k], time_unit) for r in runs]
        print(f"| {first['name']}{unit} | {bound} | " + " | ".join(cells) + " |")
    print("| **verdict** | | " + " | ".join(f"**{r['verdict']}**" for r in runs) + " |")


if __name__ == "__main__":
    main()
