#!/usr/bin/env bash
# Bitcraze's cfclient against the simulator, headless (docs/CFLIB.md,
# "cfclient"): Xvfb, `cosim run cflib-lab`, cfclient connected to
# udp://127.0.0.1:19859, a flight by its command-based flight buttons
# (take off, up, down, forward, back, left, right, land: xdotool clicks;
# each moves 0.5 m in 1 s) and screenshots (scrot) of the flight, console
# and plotter tabs.
#
#   scripts/cfclient-xvfb.sh [OUT_DIR]      # default out/cfclient-shots
#   scripts/cfclient-xvfb.sh --keys [OUT_DIR]
#       # flown with the keyboard instead: cfclient's ZMQ input device and
#       # scripts/cfclient-keys.py pushing scripted keys (take off, forward,
#       # left, turn, land; docs/CFLIB.md, "cfclient flown with the keyboard")
#
# Needs: cfclient in its venv (CFCLIENT, default target/cfclient-venv/bin/cfclient,
# made by scripts/test-all.sh), Xvfb, xdotool, scrot and the libraries
# PyQt6 loads (scripts/install-deps.sh), and the release binaries
# (cargo build --release). Everything it starts is stopped when it ends,
# however it ends.
#
# The clicks are at the widgets' places in cfclient 2026.8.1's default
# layout on a 1600x1000 window (set in the throw-away config written below).
set -euo pipefail

ROOT=$(cd "$(dirname "$0")/.." && pwd)
KEYS=0
if [ "${1:-}" = --keys ]; then
    KEYS=1
    shift
fi
OUT=${1:-$ROOT/out/cfclient-shots}
CFCLIENT=${CFCLIENT:-$ROOT/target/cfclient-venv/bin/cfclient}
DISPLAY_NR=${DISPLAY_NR:-:77}
# The last port of cfclient's scan range (19850-19859), so that other runs
# on the first ports are not in the way; preselected below.
PORT=${PORT:-19859}

die() { echo "cfclient-xvfb: $*" >&2; exit 1; }
[ -x "$CFCLIENT" ] || die "no cfclient at $CFCLIENT: make its venv with python3 -m venv target/cfclient-venv && target/cfclient-venv/bin/pip install cfclient==2026.8.1 (or set CFCLIENT)"
for tool in Xvfb xdotool scrot; do
    command -v "$tool" >/dev/null 2>&1 || die "$tool is missing: run scripts/install-deps.sh"
done
[ -x "$ROOT/target/release/cosim" ] || die "no $ROOT/target/release/cosim: run cargo build --release"

mkdir -p "$OUT"
HOME_DIR=$(mktemp -d)
mkdir -p "$HOME_DIR/.config/cfclient"
# The URI preselected (cfclient scans 19850-19859 at start and lists the
# simulator), the tabs shown, the window's size; for the buttons no ZMQ
# input device (with an input device cfclient disables its command-based
# flight buttons), for the keys its ZMQ input selected, in Hover mode (3).
if [ "$KEYS" = 1 ]; then
    ZMQ='"enable_zmq_input": true, "input_device": "ZMQ@tcp://127.0.0.1:1212", "assistedControl": 3'
else
    ZMQ='"enable_zmq_input": false'
fi
cat > "$HOME_DIR/.config/cfclient/config.json" <<EOF
{
  "link_uri": "udp://127.0.0.1:$PORT",
  "open_tabs": "Flight Control,Console,Plotter,Log TOC,Parameters",
  "window_size": [1600, 1000],
  $ZMQ
}
EOF

# A plotter log block of this platform: the height and the battery's
# current (the power network's) through take-off, climb and descent.
mkdir -p "$HOME_DIR/.config/cfclient/log"
cat > "$HOME_DIR/.config/cfclient/log/aa_height_power.json" <<EOF
{"logconfig": {"logblock": {"name": "Height and battery current", "period": 50, "variables": [
  {"name": "stateEstimate.z", "type": "TOC", "stored_as": "float", "fetch_as": "float"},
  {"name": "power.iBattery", "type": "TOC", "stored_as": "float", "fetch_as": "float"}]}}}
EOF

# Everything started below is stopped on every way out (an error, Ctrl-C,
# SIGTERM): cosim stops its own world-server and sim-core.
pids=()
cleanup() {
    for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
    for p in "${pids[@]}"; do
        for _ in $(seq 50); do kill -0 "$p" 2>/dev/null || break; sleep 0.1; done
        kill -9 "$p" 2>/dev/null || true
    done
    rm -rf "$HOME_DIR"
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

Xvfb "$DISPLAY_NR" -screen 0 1600x1000x24 >"$OUT/xvfb.log" 2>&1 &
pids+=($!)
export DISPLAY=$DISPLAY_NR
"$ROOT/target/release/cosim" run cflib-lab --out "$OUT/run" --no-plots --quiet --no-build \
    --set crtp=udp:127.0.0.1:$PORT --set crtp_idle_s=10 >"$OUT/cosim.log" 2>&1 &
cosim=$!
pids+=("$cosim")
sleep 3
HOME=$HOME_DIR "$CFCLIENT" --debug info >"$OUT/cfclient.log" 2>&1 &
pids+=($!)
sleep 10

click() { xdotool mousemove "$1" "$2" click 1; }
tab() { # the tabs' row
    case $1 in
        flight) click 74 145 ;; console) click 184 145 ;; plotter) click 267 145 ;;
        toc) click 351 145 ;; params) click 455 145 ;;
    esac
}
shot() { scrot --overwrite "$OUT/$1.png"; }

click 304 47 # Connect
sleep 6
shot cfclient-connected
if [ "$KEYS" = 1 ]; then
    # The keys (wall seconds from now): take off to cfclient's 0.4 m, up
    # 1 s (0.3 m/s), forward 2 s, left 1.5 s, turn left 1 s, land.
    "$(dirname "$CFCLIENT")/python" "$ROOT/scripts/cfclient-keys.py" \
        --script "t@0, r@4:1, up@6:2, left@9:1.5, q@11.5:1, l@14" >"$OUT/keys.log" 2>&1 &
    keys=$!
    pids+=("$keys")
    sleep 10.5
    shot cfclient-keys
    wait "$keys"
    shot cfclient-keys-landed
    click 304 47 # Disconnect
    wait "$cosim"
    echo "screenshots in $OUT; the run in $OUT/run"
    exit 0
fi
tab plotter
sleep 1
click 795 182 # the plotter's log block list
sleep 1
shot cfclient-plotter-list
xdotool key Home Return
tab flight
sleep 1
click 1343 783 # Take off (0.5 m in 1 s)
sleep 4
click 1438 866 # Up 0.5 m (in 1 s)
sleep 2
shot cfclient-flight
sleep 1
click 1522 866 # Down 0.5 m
sleep 3
# The arrows: forward, back, left, right, 0.5 m in 1 s each (docs/CFLIB.md,
# "cfclient's moves").
click 1485 779 # Forward
sleep 3
click 1485 832 # Back
sleep 3
click 1439 805 # Left
sleep 3
shot cfclient-moves
click 1531 805 # Right
sleep 3
tab plotter
sleep 2
shot cfclient-plotter
tab console
sleep 1
shot cfclient-console
tab flight
click 1343 828 # Land
sleep 4
shot cfclient-landed
click 304 47 # Disconnect
wait "$cosim"
echo "screenshots in $OUT; the run in $OUT/run"
