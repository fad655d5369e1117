#!/usr/bin/env bash
# The README's test command: every test, Rust and Python, on a fresh machine
# with the Rust toolchain. Installs what the tests need when it is missing,
# then runs them:
#   - GNU parallel (the sweep-shards end-to-end test, scripts/sweep-parallel.sh);
#   - the RISC-V cross compiler and picolibc, clang-19 (firmware
#     builds: `make -C sim-core/firmware check`, the cluster's kernels);
#   - a Python venv in target/py-venv with python/requirements-test.txt
#     (pytest, numpy, gymnasium, pandas, cflib) for python/tests and
#     training/tests, and JAX + optax for the training tests that train
#     (skipped, and said so in the summary, when JAX cannot be installed);
#   - Bitcraze's cfclient in its own venv, target/cfclient-venv (PyQt6; the
#     cfclient test flies it under Xvfb: python/tests/test_cfclient_keys.py).
# System packages come from apt-get through scripts/install-deps.sh (root,
# or sudo when there is one); set COSIM_NO_INSTALL=1 to only check and fail
# with what is missing.
#
# What it costs, and why it is ordered so:
#   - The workspace is built ONCE, in the debug profile (our code at
#     opt-level 1, dependencies at 3: Cargo.toml). The three binaries the
#     end-to-end and the Python tests start (cosim, sim-core, world-server)
#     are built first, with the features the test build resolves (`--examples`
#     turns the dev-dependencies' features on as the tests do; built apart
#     with other features, the shared dependencies and the workspace would be
#     compiled a second time). Both kinds of tests take them from
#     $COSIM_BIN_DIR.
#   - The Python tests mostly wait on the wall clock (cflib and the lab
#     guides fly paced to it; about 1.5 minutes of CPU in 5 of wall time),
#     so they run three test files at a time, but alone: a paced client
#     starved of CPU by a build or by the Rust tests loses its link or its
#     timing (guide 3's radar rule is a race against the Python process's
#     reaction time: beside the Rust tests' build, two of its drones met in
#     the airway), and a Rust test waits on the wall clock too (a CRTP
#     client's replies within 300 ms).
#
# Usage: scripts/test-all.sh [extra `cargo test` arguments]
# Logs: target/test-all/. The last lines are a summary: the tests passed,
# failed and skipped per suite, and why any were skipped.
set -euo pipefail
cd "$(dirname "$0")/.."
# Each background job in its own process group, so that one kill stops it
# with its children (pytest's world servers, cfclient under Xvfb).
set -m

logs=target/test-all
mkdir -p "$logs"
started=$SECONDS
timings=()
step() {
  printf '\n=== %s (%ss)\n' "$1" "$SECONDS"
  timings+=("$(printf '%6ss  %s' "$SECONDS" "$1")")
}
background=()
stop_background() {
  for pid in "${background[@]}"; do
    kill -TERM -- "-$pid" 2>/dev/null || true
  done
}
trap stop_background EXIT

step "system packages"
"$(dirname "$0")/install-deps.sh"

venv=target/py-venv
cfvenv=target/cfclient-venv
make_venvs() {
  req=python/requirements-test.txt
  # What the venv was made from: reinstall when the requirements or the
  # package's metadata change.
  stamp=$venv/.installed-from
  want=$(cat "$req" python/pyproject.toml 2>/dev/null || true; echo "+ jax optax")
  if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
  fi
  if [ "$want" != "$(cat "$stamp" 2>/dev/null || true)" ]; then
    "$venv/bin/python" -m pip install -q --upgrade pip
    "$venv/bin/python" -m pip install -q -r "$req"
    # The package itself, when the checkout has it (pure Python; editable,
    # so the tests see the checkout's sources).
    if [ -f python/pyproject.toml ]; then
      "$venv/bin/python" -m pip install -q -e ./python
    fi
    # Training (training/train.py) needs JAX and optax: six training tests
    # train with them. Not in the requirements file: where no JAX wheel
    # exists the other tests still run, and the summary says why six are
    # skipped.
    "$venv/bin/python" -m pip install -q jax optax ||
      echo "test-all: JAX could not be installed: the training tests that train are skipped"
    printf '%s' "$want" > "$stamp"
  fi
  if [ ! -x "$cfvenv/bin/cfclient" ]; then
    python3 -m venv "$cfvenv"
    "$cfvenv/bin/python" -m pip install -q --upgrade pip
    # The version docs/CFLIB.md was measured with.
    "$cfvenv/bin/python" -m pip install -q "cfclient==2026.8.1"
  fi
}
step "Python venvs: target/py-venv, target/cfclient-venv (in the background: $logs/venvs.log)"
make_venvs > "$logs/venvs.log" 2>&1 &
venvs=$!
background+=("$venvs")

step "build (debug): cosim, sim-core, world-server and the libraries"
cargo build --workspace --bins --examples
export COSIM_BIN_DIR="$PWD/target/debug"

step "wait for the Python venvs"
if ! wait "$venvs"; then
  cat "$logs/venvs.log" >&2
  echo "test-all: making the Python venvs failed (log above)" >&2
  exit 1
fi
export CFCLIENT="$PWD/$cfvenv/bin/cfclient"

step "build (debug): every test"
cargo build --workspace --tests

python_status=0
if [ -d python/tests ]; then
  step "python -m pytest python/tests"
  COSIM_WORLD_SERVER="$COSIM_BIN_DIR/world-server" COSIM="$COSIM_BIN_DIR/cosim" \
    "$venv/bin/python" -m pytest -q -rs -n 3 --dist loadfile python/tests 2>&1 |
    tee "$logs/python-tests.log" || python_status=$?
fi

step "cargo test --workspace"
cargo test --workspace "$@" 2>&1 | tee "$logs/cargo-test.log"

if [ -d training/tests ]; then
  step "python -m pytest training/tests (the gate network: int8 export and reference, training with JAX)"
  "$venv/bin/python" -m pytest -q -rs training/tests 2>&1 | tee "$logs/training-tests.log"
fi

step "done"
# pytest's last line, e.g. "85 passed, 2 skipped in 190.32s".
pytest_line() { grep -E '^(=+ )?[0-9]+ (passed|failed|skipped|error)' "$1" | tail -n 1 | sed 's/^=* //; s/ =*$//'; }
printf '\n=== summary (%ss in all)\n' "$((SECONDS - started))"
printf '%s\n' "${timings[@]}"
# cargo's "test result: ok. 12 passed; 0 failed; 1 ignored; ..." lines, summed.
awk '/^test result:/ { b++; p += $4; f += $6; i += $8 }
     END { printf "cargo test --workspace: %d passed, %d failed, %d ignored (%d test binaries and doc-test sets)\n", p, f, i, b }' \
  "$logs/cargo-test.log"
for suite in python training; do
  log=$logs/$suite-tests.log
  [ -f "$log" ] || continue
  echo "$suite/tests: $(pytest_line "$log")"
  # Every skip with its reason (pytest -rs), so that none goes unnoticed.
  grep '^SKIPPED' "$log" | sed 's/^/  /' || true
done
exit "$python_status"
