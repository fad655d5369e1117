#!/bin/sh
# The co-simulation launched by hand: what `cosim run` does, as a plain
# script to read and adapt (the thesis's users start both simulators from a
# script, §5.1). It runs the thesis race by default.
#
#   scripts/cosim.sh [OUT_DIR]
#
# Settings come from the environment (defaults: the thesis race of §5.1):
#   WORLD     world file               (scenarios/worlds/thesis-course.toml)
#   FIRMWARE  firmware ELF             (sim-core/firmware/bin/race.elf)
#   TIMESTEP  basicTimeStep in ms      (32)
#   SETS      run keys for sim-core    ("power_model=empirical battery=lipol250")
#   BIN       directory of the binaries (target/release; build them first with
#             `cargo build --release --workspace`)
#   WORLD_CMD another world server, e.g. "python3 examples/python-world/world.py"
#             (it gets --socket PATH and --timestep MS)
#
# Outputs in OUT_DIR (default out/script-run): summary.json, power.csv, the
# three motor CSVs, console.log, trajectory.csv and both traces. The plots
# are drawn by `cosim run`; this script only runs the pair.
set -eu

ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:-out/script-run}
WORLD=${WORLD:-$ROOT/scenarios/worlds/thesis-course.toml}
FIRMWARE=${FIRMWARE:-$ROOT/sim-core/firmware/bin/race.elf}
TIMESTEP=${TIMESTEP:-32}
SETS=${SETS:-"power_model=empirical battery=lipol250"}
BIN=${BIN:-$ROOT/target/release}

need="$BIN/sim-core"
[ -n "${WORLD_CMD:-}" ] || need="$need $BIN/world-server"
for b in $need; do
    if [ ! -x "$b" ]; then
        echo "cosim.sh: $b not found; run: cargo build --release --workspace" >&2
        exit 2
    fi
done
mkdir -p "$OUT"

# A private directory (mode 0700) for the socket: no other user can connect
# and two runs never collide.
SOCKDIR=$(mktemp -d "${TMPDIR:-/tmp}/cosim-XXXXXX")
SOCKET=$SOCKDIR/world.sock
WORLD_PID=
SIM_PID=
cleanup() {
    [ -n "$SIM_PID" ] && kill "$SIM_PID" 2>/dev/null || true
    [ -n "$WORLD_PID" ] && kill "$WORLD_PID" 2>/dev/null || true
    rm -rf "$SOCKDIR"
}
# On every way out; a signal ends the script (a handler alone would let it
# go on where it was interrupted).
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

# Every line a program prints is prefixed so the two logs can be told apart.
# The output goes through a FIFO (not a pipe) so that $! is the program's
# own PID and `wait` returns its exit status.
logged() {
    name=$1
    shift
    mkfifo "$SOCKDIR/$name.log"
    sed -u "s/^/[$name] /" <"$SOCKDIR/$name.log" &
    "$@" >"$SOCKDIR/$name.log" 2>&1 &
}

# 1. The world first: it listens on the socket.
if [ -n "${WORLD_CMD:-}" ]; then
    # shellcheck disable=SC2086 # WORLD_CMD is a command line on purpose
    logged world $WORLD_CMD --socket "$SOCKET" --timestep "$TIMESTEP"
else
    logged world "$BIN/world-server" --socket "$SOCKET" --world "$WORLD" \
        --timestep "$TIMESTEP" --trajectory "$OUT/trajectory.csv" --trace "$OUT/world.trace"
fi
WORLD_PID=$!

# 2. Wait until the socket exists (sim-core would also retry on its own).
i=0
while [ ! -S "$SOCKET" ]; do
    i=$((i + 1))
    if [ $i -gt 300 ] || ! kill -0 "$WORLD_PID" 2>/dev/null; then
        echo "cosim.sh: the world did not start" >&2
        exit 1
    fi
    sleep 0.1
done

# 3. The platform: runs the firmware until it exits, then sends STOP.
set --
for kv in $SETS; do set -- "$@" --set "$kv"; done
logged sim-core "$BIN/sim-core" --socket "$SOCKET" --firmware "$FIRMWARE" --out "$OUT" \
    --trace "$OUT/platform.trace" --no-progress "$@"
SIM_PID=$!

# 4. Wait for both; if the platform fails, the world is stopped by cleanup.
status=0
wait "$SIM_PID" || status=$?
SIM_PID=
if [ "$status" -ne 0 ]; then
    echo "cosim.sh: sim-core failed (exit $status); stopping the world" >&2
    exit "$status"
fi
wait "$WORLD_PID" || status=$?
WORLD_PID=
wait # the log forwarders
echo "cosim.sh: done (exit $status); outputs in $OUT (summary.json, power.csv, ...)"
exit "$status"
