#!/usr/bin/env bash
# Same output before and after a change to the shared geometry (the minimum image of
# src/forces/periodic_box.rs, the cell list of src/forces/cell_list.rs, the switch, the
# scalar Lennard-Jones pair) where scripts/split_same_bits.sh does not reach: runs with two
# longstep binaries and compares byte for byte (`cmp`)
# - SETTLE-rigid water (the lane loop's minimum image): energy.csv of impulse runs of the
#   solvated dipeptide with --rigid-water, one and two threads;
# - g(r) (the cell list): `analyze` of one trajectory, written once by BEFORE, with O-O,
#   O-H and H-H pairs, intra- and intermolecular, at three ranges (half the 24 Å box: one
#   cell per axis; 6 Å: 3 cells; 3.9 Å: 6 cells): rdf.csv, summary.json and stdout;
# - the energy per group and the per-atom forces of `forces` on the water box split by
#   distance (by molecule and by atom pair: the switch, the pair's energy parts).
#
#   scripts/geometry_same_output.sh BEFORE AFTER [WORKDIR]
#
# Exit status 0 when every case is the same; each differing or failing case is named.
set -u
if [ $# -lt 2 ]; then
    echo "usage: $0 BEFORE_BINARY AFTER_BINARY [WORKDIR]" >&2
    exit 2
fi
before=$1 after=$2
work=${3:-$(mktemp -d)}
mkdir -p "$work"
status=0
solvated=systems/alanine-dipeptide-amber/ala2-solvated-pme.toml
rigid="$solvated --rigid-water --method impulse --h 2fs --inner 2 --t-end 200fs --energy-every 1"
# shellcheck source=scripts/same_bits.sh
. "$(dirname "$0")/same_bits.sh"
same_bits_cases "$before" "$after" "$work" \
    "settle|1|$rigid" "settle-t2|2|$rigid" || status=1

# One trajectory for every g(r) case, from BEFORE.
run="$work/trajectory"
if [ ! -f "$run/energy.csv" ]; then
    "$before" run $solvated --method langevin-respa --inner 1 --h 1fs --friction 50/ps \
        --temperature 300K --trajectory-every 10 --t-end 0.3ps --quiet --out "$run" \
        >"$work/trajectory.log" 2>&1 || { echo "FAIL  trajectory: $(tail -n 3 "$work/trajectory.log")"; exit 1; }
fi
# name|analyze flags
rdf_cases=(
    "rdf-oo|--pairs O-O"
    "rdf-all|--pairs O-O,O-H,H-H --r-max 6 --bin 0.05"
    "rdf-short|--pairs O-O,O-H --r-max 3.9 --bin 0.05"
    "rdf-intra|--pairs O-H,H-H --intramolecular --bin 0.01"
)
for case in "${rdf_cases[@]}"; do
    IFS='|' read -r name flags <<<"$case"
    diffs=""
    for side in before after; do
        bin=$before
        [ "$side" = after ] && bin=$after
        out="$work/$name.$side"
        rm -rf "$out"
        # shellcheck disable=SC2086
        if ! RAYON_NUM_THREADS=2 "$bin" analyze $solvated "$run" $flags --out "$out" \
            >"$out.stdout" 2>"$out.stderr"; then
            echo "FAIL  $name ($side): $(tail -n 3 "$out.stderr")"
            diffs=" failed"
        fi
    done
    b="$work/$name.before" a="$work/$name.after"
    if [ -z "$diffs" ]; then
        for file in $(cd "$b" && find . -name 'rdf.csv' -o -name 'summary.json'); do
            cmp -s "$b/$file" "$a/$file" || diffs+=" $file"
        done
        # stdout names the output paths, which differ: masked.
        cmp -s <(sed "s|$b|OUT|g" "$b.stdout") <(sed "s|$a|OUT|g" "$a.stdout") || diffs+=" stdout"
    fi
    if [ -z "$diffs" ]; then
        echo "same  $name ($(cd "$b" && find . -name rdf.csv | wc -l) rdf.csv)"
    else
        echo "DIFF  $name:$diffs"
        status=1
    fi
done

# name|forces arguments
force_cases=(
    "forces-molecule|systems/water-box/three-level.toml"
    "forces-atom-pair|$solvated --split r_in=5,r_out=6,short_level=0,remainder_level=1"
    "forces-dipeptide-molecule|$solvated --split r_in=5,r_out=6,by=molecule,short_level=0,remainder_level=1"
)
for case in "${force_cases[@]}"; do
    IFS='|' read -r name args <<<"$case"
    diffs=""
    for side in before after; do
        bin=$before
        [ "$side" = after ] && bin=$after
        out="$work/$name.$side"
        # shellcheck disable=SC2086
        if ! "$bin" forces $args --by-level --out "$out.csv" >"$out.stdout" 2>"$out.stderr"; then
            echo "FAIL  $name ($side): $(tail -n 3 "$out.stderr")"
            diffs=" failed"
        fi
    done
    b="$work/$name.before" a="$work/$name.after"
    if [ -z "$diffs" ]; then
        cmp -s "$b.csv" "$a.csv" || diffs+=" forces.csv"
        # stdout names the output paths, which differ: masked.
        cmp -s <(sed "s|$b|OUT|g" "$b.stdout") <(sed "s|$a|OUT|g" "$a.stdout") || diffs+=" stdout"
    fi
    if [ -z "$diffs" ]; then
        echo "same  $name ($(($(wc -l <"$b.csv") - 1)) atoms)"
    else
        echo "DIFF  $name:$diffs"
        status=1
    fi
done
exit $status
