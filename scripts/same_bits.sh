#!/usr/bin/env bash
# One comparison of the same-bits scripts (sourced, not run): `same_bits BEFORE AFTER WORK
# NAME THREADS ARGS…` runs `longstep run ARGS…` with both binaries at RAYON_NUM_THREADS =
# THREADS into WORK/NAME.{before,after} and compares their energy.csv byte for byte
# (`cmp`). Prints `same`, `DIFF` or `FAIL` (a run that failed, with its last lines) and
# returns 0 only for `same`.
same_bits() {
    local before=$1 after=$2 work=$3 name=$4 threads=$5
    shift 5
    local side bin out rows
    for side in before after; do
        bin=$before
        [ "$side" = after ] && bin=$after
        out="$work/$name.$side"
        rm -rf "$out"
        if ! RAYON_NUM_THREADS=$threads "$bin" run "$@" --quiet --out "$out" \
            >"$out.log" 2>&1; then
            echo "FAIL  $name ($side): $(tail -n 3 "$out.log")"
            return 1
        fi
    done
    rows=$(($(wc -l <"$work/$name.before/energy.csv") - 1))
    if cmp -s "$work/$name.before/energy.csv" "$work/$name.after/energy.csv"; then
        echo "same  $name ($rows rows, $threads thread(s))"
    else
        echo "DIFF  $name: $(cmp "$work/$name.before/energy.csv" "$work/$name.after/energy.csv")"
        return 1
    fi
}

# `same_bits_cases BEFORE AFTER WORK CASE…`: `same_bits` for each case `NAME|THREADS|ARGS`;
# returns 1 when any case is not `same`.
same_bits_cases() {
    local before=$1 after=$2 work=$3 status=0 case name threads args
    shift 3
    for case in "$@"; do
        IFS='|' read -r name threads args <<<"$case"
        # shellcheck disable=SC2086
        same_bits "$before" "$after" "$work" "$name" "$threads" $args || status=1
    done
    return $status
}
