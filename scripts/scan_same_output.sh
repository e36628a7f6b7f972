#!/usr/bin/env bash
# Same output of `longstep scan steps` before and after a change to the studies
# (src/studies/, src/cli/scan_steps.rs): runs each case below with two longstep binaries and
# compares, byte for byte (`cmp`), the scan's table (scan.csv), its stdout (the safe-step
# table), its stderr without the last line (run time, which no two runs share) and, under
# the sampling criterion, every point's energy.csv. With timings (--repeats 1) timing.csv
# is compared without its wall-clock columns, and the safe-step table with its speeds
# masked. The cases cover the drift criterion on a method list, a shard, --until-decided,
# --starts, a study file, timings, and the sampling criterion with its reference and
# backbone basins.
#
#   scripts/scan_same_output.sh BEFORE AFTER [WORKDIR]
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
spring=systems/three-spring.toml
ala2=systems/alanine-dipeptide-amber/ala2.toml
solvated=systems/alanine-dipeptide-amber/ala2-solvated-pme.toml
drift="$spring --methods impulse,short-average,long-average --h 0.1:0.7:0.05 --inner 40 --t-end 100"
cat >"$work/study.toml" <<'EOF'
[[config]]
label = "impulse-fine"
method = "impulse"
h = "0.1:0.5:0.1"
inner_steps = 40

[[config]]
label = "long-average-coarse"
method = "long-average"
h = [0.2, 0.4, 0.6]
inner_steps = 10
EOF
# The sampling criterion's reference: one run, shared by both binaries.
reference="$work/reference"
if [ ! -f "$reference/energy.csv" ]; then
    "$before" run $solvated --method langevin-respa --inner 1 --h 1fs --friction 50/ps \
        --temperature 300K --trajectory-every 20 --t-end 0.4ps --quiet --out "$reference" \
        >"$work/reference.log" 2>&1 || { echo "FAIL  reference: $(tail -n 3 "$work/reference.log")"; exit 1; }
fi
cases=(
    "drift|$drift --repeats 0"
    "drift-shard|$drift --repeats 0 --shard 2/3"
    "until-decided|$drift --repeats 0 --drift-bound 1e-5 --until-decided 4"
    "starts|$ala2 --method verlet --h 0.5fs,1fs --t-end 200fs --temperature 300K --starts 3 --repeats 0"
    "study|$spring --study $work/study.toml --t-end 50 --repeats 0"
    "timings|$spring --methods impulse --h 0.1:0.3:0.1 --inner 10 --t-end 20 --repeats 1"
    "sampling|$solvated --method langevin-respa --inner 1 --friction 50/ps --h 1fs,2fs --t-end 0.4ps --discard 0.2ps --temperature 300K --criterion sampling --reference $reference --frames 20 --blocks 4 --repeats 0"
)
status=0
for case in "${cases[@]}"; do
    IFS='|' read -r name args <<<"$case"
    failed=0
    for side in before after; do
        bin=$before
        [ "$side" = after ] && bin=$after
        out="$work/$name.$side"
        rm -rf "$out"
        # shellcheck disable=SC2086
        if ! "$bin" scan steps $args --out "$out" >"$out.stdout" 2>"$out.stderr"; then
            echo "FAIL  $name ($side): $(tail -n 3 "$out.stderr")"
            failed=1
        fi
        head -n -1 "$out.stderr" >"$out.stderr-head"
        if [ -f "$out/timing.csv" ]; then
            # method,h,threads,repeats (and a study's config) without the wall times.
            awk -F, 'NR == 1 { print; next } { print $1 "," $2 "," $3 "," $4 }' \
                "$out/timing.csv" >"$out.timing"
        fi
    done
    [ $failed = 1 ] && { status=1; continue; }
    b="$work/$name.before" a="$work/$name.after"
    diffs=""
    cmp -s "$b/scan.csv" "$a/scan.csv" || diffs+=" scan.csv"
    if [ -f "$b.timing" ]; then
        # The safe-step table's speed columns are wall-clock: numbers of six or more
        # digits (the per-day rates of a dimensionless scene) are masked.
        for side in "$b" "$a"; do sed -E 's/ +[0-9]{6,}/ N/g' "$side.stdout" >"$side.stdout-masked"; done
        cmp -s "$b.stdout-masked" "$a.stdout-masked" || diffs+=" stdout"
    else
        cmp -s "$b.stdout" "$a.stdout" || diffs+=" stdout"
    fi
    cmp -s "$b.stderr-head" "$a.stderr-head" || diffs+=" stderr"
    if [ -f "$b.timing" ] || [ -f "$a.timing" ]; then
        cmp -s "$b.timing" "$a.timing" || diffs+=" timing.csv"
    fi
    if [ -d "$b/runs" ]; then
        for run in "$b"/runs/*/; do
            run=$(basename "$run")
            cmp -s "$b/runs/$run/energy.csv" "$a/runs/$run/energy.csv" || diffs+=" runs/$run"
        done
    fi
    rows=$(($(wc -l <"$b/scan.csv") - 2))
    if [ -z "$diffs" ]; then
        echo "same  $name ($rows points)"
    else
        echo "DIFF  $name:$diffs"
        status=1
    fi
done
exit $status
