#!/usr/bin/env python3
"""ns/day against outer step for the production study (docs/production.md), as SVG.

One chart per system from the committed data only: the timing sitting's runs
(docs/data/sittings/production-SYSTEM-DATE.csv, medians at one thread) and the study's verdicts
(docs/data/production/*-scan-DATE.csv). Each longstep row is a point at its outer step, marked
by what its study point says: filled when every decided criterion passes and none fails
(undecided criteria named in docs/production.md), a cross when a criterion fails, hollow when
not studied. The peers are horizontal lines at their medians (GROMACS solid, OpenMM dashed).

    python3 scripts/production_chart.py --date 2026-11-26 --sitting 2026-11-26-b --out docs/figures

Writes docs/figures/production-ala2.svg and production-trpcage.svg (not committed; `make
figures` does not run the sitting, so this script draws from the committed sitting).
"""
import argparse
import csv
import math
import os
import statistics

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DATA = os.path.join(ROOT, "docs", "data")

# Each longstep row of the sitting: its outer step (fs) and the study point that judges it,
# (scan file stem, configuration label, h in fs), per system; None where no study point is.
ROWS = {
    "verlet-hmr-5fs": (5, {"ala2": ("ala2-nve", "verlet-hmr", 5),
                           "trpcage": ("trp-nve", "verlet-hmr", 5)}),
    "impulse-recip-hmr-8fs": (8, {"ala2": ("ala2-nve", "impulse-recip-hmr", 8),
                                  "trpcage": ("trp-nve", "impulse-recip-hmr", 8)}),
    "langevin-hmr-4fs": (4, {"ala2": ("ala2-sampling-con", "langevin-respa-recip-hmr", 4),
                             "trpcage": ("trp-sampling-con", "langevin-hmr", 4)}),
    "langevin-respa-recip-hmr-12fs": (12, {
        "ala2": ("ala2-sampling-con", "langevin-respa-recip-hmr", 12),
        "trpcage": ("trp-sampling-con", "langevin-respa-recip-hmr", 12)}),
    "sinr-three-level-96fs": (96, {"ala2": ("ala2-sampling", "sinr-three-level", 96),
                                   "trpcage": ("trp-sampling-flex", "sinr-three-level", 96)}),
    "langevin-respa-split-hmr-12fs": (12, {
        "trpcage": ("trp-split-con", "langevin-respa-split-hmr", 12)}),
    "sinr-split-96fs": (96, {"trpcage": ("trp-split-flex", "sinr-three-level-split", 96)}),
}
PEERS = {"native-hbonds-2fs", "native-hmr-4fs", "native-mts-hmr-4fs", "native-mts-2fs",
         "gmx-hbonds-2fs", "gmx-hmr-4fs", "gmx-mts-hmr-4fs", "gmx-mts-2fs",
         "openmm-hbonds-2fs", "openmm-hmr-4fs", "openmm-mts-4fs"}


def medians(path, threads):
    runs = {}
    with open(path) as f:
        for r in csv.DictReader(f):
            if int(r["threads"]) == threads:
                runs.setdefault(r["row"], []).append(float(r["ns_day"]))
    return {row: statistics.median(v) for row, v in runs.items()}


def verdict(stem, date, label, h):
    path = os.path.join(DATA, "production", "%s-scan-%s.csv" % (stem, date))
    with open(path) as f:
        lines = [l for l in f if not l.startswith("#")]
    for r in csv.DictReader(lines):
        step = r["h"] if "h" in r else r["h[fs]"]  # tables since the units in headers
        if r.get("config") == label and abs(float(step) - h) < 1e-9:
            return r["status"]
    return None


def svg(title, points, peers):
    w, h, left, right, top, bottom = 720, 420, 70, 190, 40, 50
    xs = [p[1] for p in points] + [2, 100]
    ys = [p[2] for p in points] + list(peers.values())
    x0, x1 = math.log(min(xs) / 1.3), math.log(max(xs) * 1.3)
    y1 = max(ys) * 1.15
    px = lambda x: left + (math.log(x) - x0) / (x1 - x0) * (w - left - right)
    py = lambda y: top + (1 - y / y1) * (h - top - bottom)
    out = ['<svg xmlns="http://www.w3.org/2000/svg" width="%d" height="%d" '
           'font-family="sans-serif" font-size="11">' % (w, h),
           '<rect width="100%" height="100%" fill="white"/>',
           '<text x="%d" y="20" font-size="13">%s</text>' % (left, title)]
    out.append('<line x1="%d" y1="%d" x2="%d" y2="%d" stroke="black"/>' % (
        left, h - bottom, w - right, h - bottom))
    out.append('<line x1="%d" y1="%d" x2="%d" y2="%d" stroke="black"/>' % (
        left, top, left, h - bottom))
    for t in (2, 4, 8, 12, 24, 48, 96):
        out.append('<text x="%.1f" y="%d" text-anchor="middle">%g</text>' % (
            px(t), h - bottom + 15, t))
    out.append('<text x="%d" y="%d" text-anchor="middle">outer step h (fs, log)</text>' % (
        (left + w - right) // 2, h - 12))
    step = 10 ** math.floor(math.log10(y1 / 4))
    step *= 5 if y1 / step > 20 else 2 if y1 / step > 8 else 1
    for k in range(0, int(y1 / step) + 1):
        out.append('<text x="%d" y="%.1f" text-anchor="end">%g</text>' % (
            left - 5, py(k * step) + 4, k * step))
    out.append('<text x="15" y="%d" transform="rotate(-90 15 %d)" text-anchor="middle">'
               'ns/day, one thread</text>' % ((top + h - bottom) // 2, (top + h - bottom) // 2))
    for name, value in sorted(peers.items(), key=lambda kv: -kv[1]):
        dash = '' if name.startswith(("gmx", "native")) else ' stroke-dasharray="5,4"'
        out.append('<line x1="%d" y1="%.1f" x2="%d" y2="%.1f" stroke="grey"%s/>' % (
            left, py(value), w - right, py(value), dash))
        out.append('<text x="%d" y="%.1f">%s %.0f</text>' % (
            w - right + 5, py(value) + 4, name, value))
    for name, x, y, status in points:
        cx, cy = px(x), py(y)
        if status == "pass":
            out.append('<circle cx="%.1f" cy="%.1f" r="5" fill="black"/>' % (cx, cy))
        elif status in ("fail", "unstable"):
            out.append('<path d="M%.1f %.1fl8 8m0 -8l-8 8" stroke="black" stroke-width="2"/>'
                       % (cx - 4, cy - 4))
        else:
            out.append('<circle cx="%.1f" cy="%.1f" r="5" fill="white" stroke="black"/>' % (
                cx, cy))
        out.append('<text x="%.1f" y="%.1f">%s (%s)</text>' % (
            cx + 8, cy - 6, name, status or "not studied"))
    out.append('<text x="%d" y="%d">filled: passes; hollow: undecided; cross: fails</text>' % (
        left, top - 5))
    return "\n".join(out + ["</svg>"]) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--date", required=True, help="the study's date")
    ap.add_argument("--sitting", help="the sitting's tag, production-SYSTEM-TAG.csv "
                    "(default: the date)")
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "figures"))
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    for system in ("ala2", "trpcage"):
        tag = args.sitting or args.date
        sitting = os.path.join(DATA, "sittings", "production-%s-%s.csv" % (system, tag))
        if not os.path.exists(sitting):
            print("no sitting %s: skipped" % os.path.relpath(sitting, ROOT))
            continue
        med = medians(sitting, 1)
        points = []
        for row, (h, studies) in ROWS.items():
            if row in med and system in studies:
                stem, label, at = studies[system]
                points.append((row, h, med[row], verdict(stem, args.date, label, at)))
        peers = {row: v for row, v in med.items() if row in PEERS}
        path = os.path.join(args.out, "production-%s.svg" % system)
        with open(path, "w") as f:
            f.write(svg("%s: ns/day at one thread against the outer step" % system, points,
                        peers))
        print("wrote", os.path.relpath(path, ROOT))


if __name__ == "__main__":
    main()
