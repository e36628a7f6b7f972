#!/usr/bin/env bash
# One interleaved sitting of thread scaling on the 5 184-atom water box: PME (GROMACS's
# defaults, order 4) with the mesh every 2 inner steps of 0.5 fs (impulse 1 fs / 2,
# --nonbonded-level 0 --pme-level 1), and the shifted-force model of the kit (impulse
# 4 fs / 8) for comparison. Every run is printed (case, threads, repeat, wall seconds of
# the run loop, outer steps); the rounds interleave thread counts and cases.
#
#   cargo build --release && bash scripts/thread_sitting.sh | tee out/threads.txt
#
# THREADS, REPEATS, T_END and BIN override the defaults.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${BIN:-target/release/longstep}
THREADS=${THREADS:-"1 2 4 8 16"}
REPEATS=${REPEATS:-3}
T_END=${T_END:-1ps}
SCENE=systems/water-box-1728/scene.toml
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
pme=(--coulomb pme --pme-order 4 --nonbonded-level 0 --pme-level 1 --method impulse --h 1fs --inner 2)
dsf=(--method impulse --h 4fs --inner 8)
echo "# $(uname -m) $(nproc) cores; $BIN; $SCENE; t_end $T_END"
echo "case threads repeat wall_seconds steps"
for repeat in $(seq "$REPEATS"); do
  for threads in $THREADS; do
    for case in pme dsf; do
      if [ "$case" = pme ]; then flags=("${pme[@]}"); else flags=("${dsf[@]}"); fi
      json=$(RAYON_NUM_THREADS=$threads "$BIN" run "$SCENE" "${flags[@]}" --t-end "$T_END" \
        --json --quiet --out "$OUT/$case-$threads-$repeat")
      wall=$(printf '%s\n' "$json" | sed -n 's/^ *"wall_seconds": *\([0-9.eE+-]*\).*/\1/p')
      steps=$(printf '%s\n' "$json" | sed -n 's/^ *"steps": *\([0-9]*\).*/\1/p' | head -1)
      echo "$case $threads $repeat $wall $steps"
    done
  done
done
