#!/bin/bash
# `make test-slurm`: the Slurm job array of docs/studies.md ("Scans larger than one machine")
# on a real Slurm. Installs Debian's slurm-wlm and munge when missing (apt-get, as root),
# starts munged and a single-node Slurm (slurmctld + slurmd) on this machine under a scratch
# folder, submits the documented array script for a small scan, waits for every task,
# merges the shards with `longstep merge`, and checks the merged scan.csv (and every other
# file both write, but the wall-clock timing.csv) equals an unsharded scan's byte for byte.
# Stops what it started on exit. Not part of `make test` (it needs root and a few minutes).
#
#   make test-slurm            # or: scripts/test_slurm.sh [path/to/longstep]
set -euo pipefail

REPO=$(cd "$(dirname "$0")/.." && pwd)
BIN=$(realpath "${1:-$REPO/target/release/longstep}")
SHARDS=4
# The small scan: GSS98's three-spring system, ten outer steps, two methods.
SCAN="$REPO/systems/three-spring.toml --methods impulse,long-average --h 0.1:1:0.1 --inner 10 --t-end 20 --repeats 0"

die() { echo "test-slurm: $*" >&2; exit 1; }
[ -x "$BIN" ] || die "no longstep binary at $BIN (cargo build --release)"
[ "$(id -u)" = 0 ] || die "needs root (it installs packages and starts daemons)"

missing=()
for tool in slurmctld slurmd sbatch squeue sinfo munged; do
    command -v "$tool" >/dev/null || missing+=("$tool")
done
if [ ${#missing[@]} -gt 0 ]; then
    echo "test-slurm: ${missing[*]} missing: installing slurm-wlm and munge from Debian" >&2
    command -v apt-get >/dev/null || die "no apt-get to install slurm-wlm and munge with"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
        slurm-wlm munge >/dev/null
    for tool in "${missing[@]}"; do
        command -v "$tool" >/dev/null || die "$tool still missing after installing slurm-wlm"
    done
fi

WORK=$(mktemp -d /tmp/longstep-slurm.XXXXXX)
chmod 755 "$WORK"
PIDS=()
cleanup() {
    for pid in "${PIDS[@]}"; do kill "$pid" 2>/dev/null || true; done
    for file in "$WORK"/slurmd.pid "$WORK"/slurmctld.pid "$WORK"/munge/munged.pid; do
        [ -f "$file" ] && kill "$(cat "$file")" 2>/dev/null || true
    done
}
trap cleanup EXIT

# munge: a fresh key and socket under the scratch folder.
mkdir -p "$WORK/munge"
dd if=/dev/urandom of="$WORK/munge/munge.key" bs=1024 count=1 status=none
chown -R munge:munge "$WORK/munge"
chmod 711 "$WORK/munge"
chmod 400 "$WORK/munge/munge.key"
SOCKET="$WORK/munge/munge.socket"
runuser -u munge -- munged --key-file="$WORK/munge/munge.key" --socket="$SOCKET" \
    --pid-file="$WORK/munge/munged.pid" --log-file="$WORK/munge/munged.log" \
    --seed-file="$WORK/munge/munged.seed"
for _ in $(seq 50); do [ -S "$SOCKET" ] && break; sleep 0.1; done
[ -S "$SOCKET" ] || die "munged did not start ($WORK/munge/munged.log)"

# A single-node cluster: this host, its cores (at least the 2 the script asks a task for).
HOST=$(hostname -s)
CPUS=$(nproc)
[ "$CPUS" -ge 2 ] || CPUS=2
mkdir -p "$WORK/state" "$WORK/spool"
export SLURM_CONF="$WORK/slurm.conf"
cat >"$SLURM_CONF" <<EOF
ClusterName=longstep-test
SlurmctldHost=$HOST
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$SOCKET
CredType=cred/munge
StateSaveLocation=$WORK/state
SlurmdSpoolDir=$WORK/spool
SlurmctldPidFile=$WORK/slurmctld.pid
SlurmdPidFile=$WORK/slurmd.pid
SlurmctldLogFile=$WORK/slurmctld.log
SlurmdLogFile=$WORK/slurmd.log
SlurmctldPort=16817
SlurmdPort=16818
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SlurmdParameters=config_overrides
ReturnToService=2
MpiDefault=none
NodeName=$HOST CPUs=$CPUS State=UNKNOWN
PartitionName=debug Nodes=$HOST Default=YES MaxTime=INFINITE State=UP
EOF
slurmctld -i
slurmd
for _ in $(seq 100); do
    sinfo -h -o %t 2>/dev/null | grep -qE '^(idle|mix|alloc)' && break
    sleep 0.2
done
sinfo -h -o %t | grep -qE '^(idle|mix|alloc)' || die "the node did not come up ($WORK/slurmd.log)"

# The array script of docs/studies.md, as written there, for the small scan: the same
# #SBATCH lines and --shard/--out pattern, SHARDS tasks, this build of longstep.
SCRIPT=$(awk '/With a Slurm job array:/ {found = 1} found && /^```sh/ {inside = 1; next}
              inside && /^```/ {exit} inside {print}' "$REPO/docs/studies.md")
[ -n "$SCRIPT" ] || die "no Slurm array script found in docs/studies.md"
echo "$SCRIPT" |
    sed -e "s|--array=1-16|--array=1-$SHARDS|" \
        -e "s|/16 |/$SHARDS |" \
        -e "s|^longstep |$BIN |" \
        -e "s|systems/water-box/scene.toml --methods impulse,long-average|$SCAN|" \
        -e "s|--h 1fs:10fs:0.25fs --dt 0.5fs --t-end 2ps ||" >"$WORK/array.sh"
grep -q -- "--shard \${SLURM_ARRAY_TASK_ID}/$SHARDS" "$WORK/array.sh" ||
    die "docs/studies.md's script changed shape: $(cat "$WORK/array.sh")"
echo "test-slurm: submitting" >&2
cat "$WORK/array.sh" >&2

START=$(date +%s)
JOB=$(sbatch --parsable --chdir="$WORK" --output="$WORK/slurm-%A_%a.out" "$WORK/array.sh")
while squeue -h -j "$JOB" 2>/dev/null | grep -q .; do
    [ $(($(date +%s) - START)) -lt 600 ] || die "job $JOB still queued or running after 600 s"
    sleep 1
done
for k in $(seq "$SHARDS"); do
    [ -f "$WORK/scan-$k/scan.csv" ] ||
        die "task $k wrote no scan.csv: $(cat "$WORK"/slurm-*_"$k".out 2>/dev/null)"
done

# shellcheck disable=SC2086 # $SCAN is a list of arguments
(cd "$WORK" && "$BIN" merge scan-* --out scan >/dev/null &&
    "$BIN" scan steps $SCAN --quiet --out single >/dev/null)
cmp "$WORK/scan/scan.csv" "$WORK/single/scan.csv" ||
    die "the merged scan.csv differs from the unsharded one ($WORK)"
compared=0
for file in "$WORK"/single/*; do
    name=$(basename "$file")
    [ "$name" = timing.csv ] && continue
    [ -f "$WORK/scan/$name" ] || continue
    cmp "$file" "$WORK/scan/$name" || die "merged $name differs from the unsharded one"
    compared=$((compared + 1))
done
echo "test-slurm: pass: $SHARDS array tasks on Slurm $(sinfo -V | cut -d' ' -f2), merged:" \
    "$compared files equal to the unsharded scan's byte for byte" \
    "($(($(date +%s) - START)) s; $WORK)"
