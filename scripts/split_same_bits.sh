#!/usr/bin/env bash
# Same bits before and after a change to the distance split (src/forces/distance_split*):
# runs each case below with two longstep binaries and compares their energy.csv byte for
# byte (`cmp`). The cases cover the split's loops: by molecule in one kind of water (the
# SIMD molecule blocks, one chunk at 648 atoms and four at 5184), by molecule in a mixed
# system (the solvated dipeptide: the row loop and the intramolecular atom pairs), by atom
# pair (the switched cluster kernel), Hessian-vector products of every level (structural-zd),
# PME with the bare short Coulomb, double and mixed precision, one and two threads.
#
#   scripts/split_same_bits.sh BEFORE AFTER [WORKDIR]
#
# Exit status 0 when every case is identical; each differing or failing case is named.
set -u
if [ $# -lt 2 ]; then
    echo "usage: $0 BEFORE_BINARY AFTER_BINARY [WORKDIR]" >&2
    exit 2
fi
before=$1 after=$2
work=${3:-$(mktemp -d)}
mkdir -p "$work"
water=systems/water-box
dipeptide=systems/alanine-dipeptide-amber/ala2-solvated-pme.toml
impulse3="--method impulse --h 2fs --level-steps 2,2 --t-end 600fs --energy-every 5"
impulse_lc="--method impulse --h 1fs --level-steps 1,2 --t-end 100fs --energy-every 1"
cases=(
    "three-level|1|$water/three-level.toml $impulse3"
    "three-level-t2|2|$water/three-level.toml $impulse3"
    "three-level-mixed|1|$water/three-level.toml $impulse3 --precision mixed"
    "three-level-mixed-t2|2|$water/three-level.toml $impulse3 --precision mixed"
    "three-level-pme|1|$water/three-level.toml $impulse3 --coulomb pme"
    "three-level-pme-mixed-t2|2|$water/three-level.toml $impulse3 --coulomb pme --precision mixed"
    "three-level-sinr|1|$water/three-level.toml --method sinr --h 20fs --level-steps 10,4 --thermostats 4 --tau 5fs --t-end 1ps --energy-every 1 --seed 7 --temperature 300K"
    "three-level-structural|1|$water/three-level.toml --method structural-zd --block 2 --h 1fs --t-end 40fs --energy-every 1"
    "long-cutoff-three-level|1|$water/long-cutoff-three-level.toml $impulse_lc"
    "long-cutoff-three-level-t2|2|$water/long-cutoff-three-level.toml $impulse_lc"
    "long-cutoff-three-level-mixed-t2|2|$water/long-cutoff-three-level.toml $impulse_lc --precision mixed"
    "long-cutoff-three-level-wide|2|$water/long-cutoff-three-level-wide.toml $impulse_lc"
    "long-cutoff-15-three-level-wide|2|$water/long-cutoff-15-three-level-wide.toml $impulse_lc"
    "dipeptide-atom|1|$dipeptide --split r_in=5,r_out=6,short_level=0,remainder_level=1 --method impulse --h 2fs --inner 2 --t-end 200fs --energy-every 1"
    "dipeptide-atom-mixed-t2|2|$dipeptide --split r_in=5,r_out=6,short_level=0,remainder_level=1 --method impulse --h 2fs --inner 2 --t-end 200fs --energy-every 1 --precision mixed"
    "dipeptide-molecule|1|$dipeptide --split r_in=5,r_out=6,by=molecule,short_level=0,remainder_level=1 --method impulse --h 2fs --inner 2 --t-end 200fs --energy-every 1"
    "dipeptide-molecule-t2|2|$dipeptide --split r_in=5,r_out=6,by=molecule,short_level=0,remainder_level=1 --method impulse --h 2fs --inner 2 --t-end 200fs --energy-every 1"
    "dipeptide-molecule-structural|1|$dipeptide --split r_in=5,r_out=6,by=molecule,short_level=0,remainder_level=1 --method structural-zd --block 2 --h 1fs --t-end 10fs --energy-every 1"
)
# shellcheck source=scripts/same_bits.sh
. "$(dirname "$0")/same_bits.sh"
same_bits_cases "$before" "$after" "$work" "${cases[@]}"
