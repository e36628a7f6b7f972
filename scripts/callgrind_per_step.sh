#!/bin/sh
# Instructions per outer step of a `longstep run`, counted by callgrind: the difference of
# two runs of N1 and N2 outer steps divided by N2 − N1, so setup, scene loading and output
# cancel. One thread (RAYON_NUM_THREADS=1), so the count is deterministic.
#
#   scripts/callgrind_per_step.sh SCENE H N1 N2 [longstep run options…]
#   scripts/callgrind_per_step.sh systems/water-box/scene.toml 4 10 30 --method impulse --inner 8
#
# H is the outer step in the scene's time unit (fs for real scenes). Needs valgrind and a
# release build (cargo build --release).
set -eu
if [ $# -lt 4 ]; then
    echo "usage: $0 SCENE H N1 N2 [longstep run options...]" >&2
    exit 2
fi
scene=$1 h=$2 n1=$3 n2=$4
shift 4
bin=${LONGSTEP:-target/release/longstep}
unit=""
grep -q '^units *= *"real"' "$scene" && unit=fs
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
count() {
    n=$1
    shift
    t_end=$(awk "BEGIN { print $h * $n }")
    if ! RAYON_NUM_THREADS=1 valgrind --tool=callgrind --callgrind-out-file="$work/cg.$n" \
        "$bin" run "$scene" --h "$h$unit" --t-end "$t_end$unit" --energy-every 1000000 \
        --quiet --out "$work/out.$n" "$@" >/dev/null 2>"$work/log.$n"; then
        cat "$work/log.$n" >&2
        return 1
    fi
    callgrind_annotate "$work/cg.$n" 2>/dev/null | awk '/PROGRAM TOTALS/ { gsub(",", "", $1); print $1 }'
}
a=$(count "$n1" "$@") || exit 1
b=$(count "$n2" "$@") || exit 1
awk "BEGIN { printf \"%.0f instructions per outer step\\n\", ($b - $a) / ($n2 - $n1) }"
