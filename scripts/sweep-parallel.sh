#!/usr/bin/env bash
# A `cosim sweep` spread by GNU parallel over this machine's cores or over
# ssh hosts, then merged (DESIGN.md §11; docs/COSIM.md, "Sweeps on a
# cluster"):
#
#   scripts/sweep-parallel.sh NAME [-j N] [--sshlogin HOSTS] [--shards N]
#                             [--out DIR] [-- COSIM-SWEEP-OPTIONS...]
#
# Each job is one shard, `cosim sweep NAME --shard K/N --jobs 1 --out DIR`;
# the options after `--` (--param, --set, --no-trace, --timeout ...) go to
# every shard and to the plan. --shards defaults to the number of runs (one
# run per job: parallel keeps every slot busy). -j is parallel's jobs per
# host (default: one per core). --sshlogin is parallel's (`host1,2/host2,:`;
# `:` is this machine). Then `cosim sweep --merge DIR --out DIR` writes
# DIR/sweep.csv, sweep.md and the plots. Exit code: the merge's (0 all runs
# completed, 1 some run failed, 2 the merge was refused: a shard missing).
#
# Over ssh every host must see the repository, the binaries and DIR at the
# same paths (a shared filesystem) and have GNU parallel's ssh access
# (keys, no password prompt). The binaries: $COSIM, default
# target/release/cosim beside this script (sim-core and world-server are
# taken from its directory); build them once: cargo build --release --workspace.
set -euo pipefail

usage() {
  sed -n '2,16p' "$0" | sed 's/^# \{0,1\}//' >&2
  exit 2
}

root=$(cd "$(dirname "$0")/.." && pwd)
cosim=${COSIM:-$root/target/release/cosim}
name=""
jobs=""
sshlogin=""
shards=""
out=""
extra=()
while [ $# -gt 0 ]; do
  case "$1" in
    -j|--jobs) jobs=${2:?-j needs a number}; shift 2 ;;
    --sshlogin|-S) sshlogin=${2:?--sshlogin needs hosts}; shift 2 ;;
    --shards) shards=${2:?--shards needs a number}; shift 2 ;;
    --out) out=${2:?--out needs a directory}; shift 2 ;;
    -h|--help) usage ;;
    --) shift; extra=("$@"); break ;;
    -*) echo "sweep-parallel: unknown option $1 (cosim options go after --)" >&2; exit 2 ;;
    *) if [ -n "$name" ]; then echo "sweep-parallel: two scenarios: $name and $1" >&2; exit 2; fi
       name=$1; shift ;;
  esac
done
[ -n "$name" ] || usage
if ! parallel --version 2>/dev/null | grep -q '^GNU parallel'; then
  echo "sweep-parallel: GNU parallel is not installed (apt-get install parallel)" >&2
  exit 2
fi
if [ ! -x "$cosim" ]; then
  echo "sweep-parallel: $cosim not found: cargo build --release --workspace, or set COSIM" >&2
  exit 2
fi

# The plan checks every run (a bad value fails here, before any job starts)
# and gives the number of runs.
runs=$("$cosim" sweep "$name" "${extra[@]}" --plan | wc -l)
shards=${shards:-$runs}
case "$shards" in ''|*[!0-9]*|0) echo "sweep-parallel: --shards must be a positive number" >&2; exit 2 ;; esac
# Absolute, so that remote jobs write into the same (shared) directory.
out=$(realpath -m "${out:-out/$(basename "$name" .toml)-sweep}")
mkdir -p "$out"

q() { printf '%q ' "$@"; }
cmd="cd $(q "$PWD")&& $(q "$cosim" sweep "$name" "${extra[@]}") --jobs 1 --out $(q "$out") --shard {}/$shards"
popts=(--tag --joblog "$out/parallel.joblog")
[ -n "$jobs" ] && popts+=(-j "$jobs")
[ -n "$sshlogin" ] && popts+=(--sshlogin "$sshlogin")
echo "sweep-parallel: $runs runs of $name in $shards shards -> $out" >&2

# A shard with a failed run exits 1; the run is still recorded, so the
# merge runs whatever parallel says and decides the exit code.
# parallel runs in the background so that a signal to this script is
# handled at once: GNU parallel stops starting jobs at the first TERM and
# kills the running ones at the second (each cosim then stops its own
# processes); then this script exits without merging.
set +e
parallel "${popts[@]}" "$cmd" ::: $(seq 1 "$shards") &
ppid=$!
stop() {
  kill -TERM "$ppid" 2>/dev/null
  sleep 1
  kill -TERM "$ppid" 2>/dev/null
  wait "$ppid"
  exit "$1"
}
trap 'stop 130' INT
trap 'stop 143' TERM
wait "$ppid"
prc=$?
trap - INT TERM
"$cosim" sweep --merge "$out" --out "$out"
mrc=$?
set -e
if [ "$mrc" -eq 2 ]; then
  echo "sweep-parallel: merge refused (parallel exit code $prc; see $out/parallel.joblog)" >&2
fi
exit "$mrc"
