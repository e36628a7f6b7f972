#!/usr/bin/env python3
"""The topology scenes' pair-list skin against ns/day, in one interleaved sitting.

For each system (the solvated dipeptide and Trp-cage PME scenes) and each skin, a copy of
the scene with `skin = S` in its [topology] table (paths made absolute, in a temporary
folder), run in turn with one configuration, `--repeats` times; ns/day from longstep's
summary (the stepping loop only). Prints per system and skin the median with its range and
writes every run to --csv. Needs a release build (`cargo build --release`).

    RAYON_NUM_THREADS=1 python3 scripts/skin_sitting.py --skins 2,3,4,5 --repeats 5 \\
        --csv docs/data/sittings/topology-skin-2026-11-26.csv
"""

import argparse
import csv
import re
import statistics
import subprocess
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SYSTEMS = {
    "ala2": ("systems/alanine-dipeptide-amber/ala2-solvated-pme.toml",
             "systems/alanine-dipeptide-amber/ala2-solvated-300K.xyz", "10ps"),
    "trpcage": ("systems/protein-amber/trpcage-pme.toml",
                "systems/protein-amber/trpcage-300K.xyz", "2ps"),
}
CONFIGS = {
    "baoab-hmr-4fs": "--method langevin-respa --inner 1 --h 4fs --friction 1/ps "
                     "--constraints h-bonds --rigid-water --hydrogen-mass 3amu",
    "verlet-flexible-1fs": "--method verlet --h 1fs",
}


def scene_copy(scene, skin, folder):
    """The scene with `skin = S` and absolute file paths, written into `folder`."""
    source = ROOT / scene
    text = source.read_text()
    text = re.sub(r'^(file|coordinates) = "([^"]+)"',
                  lambda m: '%s = "%s"' % (m.group(1), source.parent / m.group(2)),
                  text, flags=re.M)
    text = text.replace("[topology]\n", "[topology]\nskin = %s\n" % skin, 1)
    path = Path(folder) / ("%s-skin%s.toml" % (source.stem, skin))
    path.write_text(text)
    return path


def ns_per_day(scene, start, t_end, config):
    args = ([str(ROOT / "target/release/longstep"), "run", str(scene), "--start", str(ROOT / start),
             "--t-end", t_end, "--temperature", "300K", "--seed", "1", "--energy-every", "100",
             "--precision", "mixed", "--out", tempfile.mkdtemp()] + config.split())
    out = subprocess.run(args, capture_output=True, text=True, check=True).stdout
    m = re.search(r"^wall time\s+\S+ s \(([0-9.eE+-]+) ns/day\)", out, re.M)
    if not m:
        raise SystemExit("no wall time line in:\n" + out)
    return float(m.group(1))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--skins", default="2,3,4,5")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--configs", default=",".join(CONFIGS))
    parser.add_argument("--csv", required=True)
    a = parser.parse_args()
    skins = a.skins.split(",")
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for system, (scene, start, t_end) in SYSTEMS.items():
            copies = {s: scene_copy(scene, s, folder) for s in skins}
            for config in a.configs.split(","):
                for repeat in range(a.repeats):
                    for skin in skins:
                        value = ns_per_day(copies[skin], start, t_end, CONFIGS[config])
                        rows.append((system, config, skin, repeat, value))
                        print("%-8s %-20s skin %-3s repeat %d: %.2f ns/day"
                              % (system, config, skin, repeat, value), flush=True)
    with open(a.csv, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["system", "config", "skin_angstrom", "repeat", "ns_per_day"])
        w.writerows(rows)
    print("\nsystem   config               skin  median ns/day [min-max]  ratio to skin %s"
          % skins[0])
    for system in SYSTEMS:
        for config in a.configs.split(","):
            values = {s: [r[4] for r in rows if r[:3] == (system, config, s)] for s in skins}
            base = statistics.median(values[skins[0]])
            for s in skins:
                v = values[s]
                print("%-8s %-20s %-5s %7.2f [%.2f-%.2f]  %.3f" % (
                    system, config, s, statistics.median(v), min(v), max(v),
                    statistics.median(v) / base))


if __name__ == "__main__":
    main()
