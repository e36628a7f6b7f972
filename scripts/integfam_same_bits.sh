#!/usr/bin/env bash
# Same bits before and after a refactor of the pseudo-energy schemes: runs pseudo-energy
# and async-pseudo-energy with two longstep binaries on spring chains (the 100-bead chain
# and the FPU chain, where every particle feels a fast spring and async falls back to the
# synchronous scheme; the slow-fast FPU chain, the asynchronous scheme proper) and on the
# water box (async falls back there too), and compares every energy.csv byte for byte.
# Exits 1 when any differs. (Async is not run on the 100-bead chain: the run's check of
# the asynchronous instability bands takes minutes on its 300 coordinates.)
#
#   scripts/integfam_same_bits.sh OLD_BINARY NEW_BINARY [THREADS]
#
# Run from the repository root. Runs are short (seconds each).
set -euo pipefail

if [ $# -lt 2 ]; then
    echo "usage: $0 OLD_BINARY NEW_BINARY [THREADS]" >&2
    exit 2
fi
old=$1
new=$2
threads=${3:-1}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

cases=(
    "chain-pe|$threads|systems/chain/scene.toml --method pseudo-energy --h 0.01 --t-end 0.5 --energy-every 1"
    "chain-pe-gl3|$threads|systems/chain/scene.toml --method pseudo-energy --h 0.01 --quadrature gl3 --t-end 0.5 --energy-every 1"
    "fpu-ape-sync|$threads|systems/fpu.toml --method async-pseudo-energy --h 0.01 --ratio 5 --t-end 5 --energy-every 1"
    "fpu-ape-sync-gl3|$threads|systems/fpu.toml --method async-pseudo-energy --h 0.01 --ratio 5 --quadrature gl3 --t-end 5 --energy-every 1"
    "fpu-ape|$threads|systems/fpu-slow-fast.toml --method async-pseudo-energy --h 0.01 --h-fast 0.001 --quadrature midpoint --t-end 5 --energy-every 1"
    "fpu-ape-gl5|$threads|systems/fpu-slow-fast.toml --method async-pseudo-energy --h 0.01 --h-fast 0.001 --t-end 5 --energy-every 1"
    "water-pe|$threads|systems/water-box/scene.toml --method pseudo-energy --h 0.5fs --t-end 10fs --energy-every 1"
    "water-ape|$threads|systems/water-box/scene.toml --method async-pseudo-energy --h 1fs --ratio 2 --t-end 10fs --energy-every 1"
)

# shellcheck source=scripts/same_bits.sh
. "$(dirname "$0")/same_bits.sh"
same_bits_cases "$old" "$new" "$work" "${cases[@]}"
