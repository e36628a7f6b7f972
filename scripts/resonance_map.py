#!/usr/bin/env python3
"""The resonance map of docs/production.md ("Which mode binds") as one SVG.

Reads the `longstep modes --lanczos` tables in docs/data/modes/*.txt and draws, for each
configuration, every listed mode's T/3, T/2 and T (fs) as ticks on the outer-step axis, with
the `scan steps` verdicts of docs/production.md at their steps. Run from the repository root:

    python3 scripts/resonance_map.py            # writes docs/data/modes/resonance-map.svg
"""
import re
import sys
from pathlib import Path

DATA = Path("docs/data/modes")
# (label, modes table, [(h fs, verdict, method)]) — verdicts from docs/production.md; for
# langevin-respa "pass" is the configurational criteria (PE, O–O peak) with basins undecided.
ROWS = [
    ("dipeptide, HMR, bonded + real space", "ala2-hmr-realspace.txt",
     [(8, "pass", "impulse"), (12, "fail", "impulse"), (16, "fail", "impulse")]),
    ("dipeptide, h-bonds, bonded + real space", "ala2-hbonds-realspace.txt",
     [(4, "pass", "impulse"), (6, "undecided", "impulse"), (8, "fail", "impulse")]),
    ("Trp-cage, HMR, bonded + real space", "trpcage-hmr-realspace.txt",
     [(8, "undecided", "impulse"), (12, "fail", "impulse"),
      (8, "pass", "langevin-respa"), (12, "pass", "langevin-respa")]),
    ("Trp-cage, HMR, split 5-6 Å", "trpcage-hmr-split.txt",
     [(8, "fail", "impulse"), (12, "fail", "impulse"),
      (8, "undecided", "langevin-respa"), (12, "pass", "langevin-respa"),
      (16, "fail", "langevin-respa")]),
    ("Trp-cage, h-bonds, bonded + real space", "trpcage-hbonds-realspace.txt",
     [(4, "pass", "impulse"), (6, "fail", "impulse")]),
]
MODE = re.compile(r"^\s+\d+\s+([\d.]+)\s+\S+\s+([\d.]+)\s+[\d.]+\s+[-\d.]+\s+")
H_MAX, LEFT, WIDTH, ROW = 24.0, 300, 720, 70
COLOURS = {"T/3": "#999999", "T/2": "#c0392b", "T": "#2c6fbb"}


def periods(name):
    text = (DATA / name).read_text()
    return [float(m.group(2)) for line in text.splitlines() if (m := MODE.match(line))]


def x(h):
    return LEFT + WIDTH * h / H_MAX


def main():
    height = 90 + ROW * len(ROWS)
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{LEFT + WIDTH + 40}" '
           f'height="{height}" font-family="sans-serif" font-size="12">',
           '<rect width="100%" height="100%" fill="white"/>',
           f'<text x="{LEFT}" y="20" font-size="14">Fast-level modes (ticks: T/3 grey, T/2 red, '
           'T blue) and scan steps verdicts</text>',
           f'<text x="{LEFT}" y="38">filled circle: pass; hollow: undecided; cross: fail or '
           'unstable; upper row impulse, lower langevin-respa</text>']
    for k, (label, table, verdicts) in enumerate(ROWS):
        y = 60 + ROW * k
        out.append(f'<text x="{LEFT - 8}" y="{y + 30}" text-anchor="end">{label}</text>')
        out.append(f'<line x1="{x(0)}" y1="{y + ROW - 8}" x2="{x(H_MAX)}" y2="{y + ROW - 8}" '
                   'stroke="#dddddd"/>')
        for period in periods(table):
            for name, h in (("T/3", period / 3), ("T/2", period / 2), ("T", period)):
                if h <= H_MAX:
                    out.append(f'<line x1="{x(h):.1f}" y1="{y}" x2="{x(h):.1f}" y2="{y + 24}" '
                               f'stroke="{COLOURS[name]}" stroke-opacity="0.6"/>')
        for h, verdict, method in verdicts:
            cy = y + (36 if method == "impulse" else 52)
            if verdict == "fail":
                d = 5
                out.append(f'<path d="M{x(h) - d},{cy - d}L{x(h) + d},{cy + d}M{x(h) - d},'
                           f'{cy + d}L{x(h) + d},{cy - d}" stroke="black" stroke-width="2"/>')
            else:
                fill = "black" if verdict == "pass" else "white"
                out.append(f'<circle cx="{x(h)}" cy="{cy}" r="5" fill="{fill}" stroke="black"/>')
    axis = 60 + ROW * len(ROWS)
    out.append(f'<line x1="{x(0)}" y1="{axis}" x2="{x(H_MAX)}" y2="{axis}" stroke="black"/>')
    for h in range(0, int(H_MAX) + 1, 2):
        out.append(f'<line x1="{x(h)}" y1="{axis}" x2="{x(h)}" y2="{axis + 5}" stroke="black"/>')
        out.append(f'<text x="{x(h)}" y="{axis + 18}" text-anchor="middle">{h}</text>')
    out.append(f'<text x="{x(H_MAX / 2)}" y="{axis + 26 + 8}" text-anchor="middle">'
               'outer step h (fs)</text></svg>')
    path = DATA / "resonance-map.svg"
    path.write_text("\n".join(out) + "\n")
    print(path)


if __name__ == "__main__":
    sys.exit(main())
