#!/usr/bin/env bash
# The README's test command: every test, Rust and Python, on a fresh machine
# with the Rust toolchain. Installs what the tests need when
# it is missing, then runs them:
#   - GNU parallel (tests/tests/sweep_shards.rs, scripts/sweep-parallel.sh);
#   - the RISC-V cross compiler and picolibc, clang-19 (firmware
#     builds: `make -C sim-core/firmware check`, the cluster's kernels);
#   - a Python venv in target/py-venv with python/requirements-test.txt
#     (pytest, numpy, gymnasium, pandas, cflib) for python/tests and training/tests;
#   - Bitcraze's cfclient in its own venv, target/cfclient-venv (PyQt6; the
#     cfclient test flies it under Xvfb: python/tests/test_cfclient_keys.py).
# System packages come from apt-get through scripts/install-deps.sh (root,
# or sudo when there is one); set
# COSIM_NO_INSTALL=1 to only check and fail with what is missing.
# Usage: scripts/test-all.sh [extra `cargo test` arguments]
set -euo pipefail
cd "$(dirname "$0")/.."

step() { printf '\n=== %s (%ss)\n' "$1" "$SECONDS"; }

step "system packages"
"$(dirname "$0")/install-deps.sh"

step "Python venv (target/py-venv, python/requirements-test.txt)"
venv=target/py-venv
req=python/requirements-test.txt
# What the venv was made from: reinstall when the requirements or the
# package's metadata change.
stamp=$venv/.installed-from
want=$(cat "$req" python/pyproject.toml 2>/dev/null || true)
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
if [ "$want" != "$(cat "$stamp" 2>/dev/null || true)" ]; then
  "$venv/bin/python" -m pip install -q --upgrade pip
  "$venv/bin/python" -m pip install -q -r "$req"
  # The package itself, when the checkout has it (pure Python; editable, so
  # the tests see the checkout's sources).
  if [ -f python/pyproject.toml ]; then
    "$venv/bin/python" -m pip install -q -e ./python
  fi
  printf '%s' "$want" > "$stamp"
fi

step "cfclient venv (target/cfclient-venv)"
cfvenv=target/cfclient-venv
if [ ! -x "$cfvenv/bin/cfclient" ]; then
  python3 -m venv "$cfvenv"
  "$cfvenv/bin/python" -m pip install -q --upgrade pip
  # The version docs/CFLIB.md was measured with.
  "$cfvenv/bin/python" -m pip install -q "cfclient==2026.8.1"
fi
export CFCLIENT="$PWD/$cfvenv/bin/cfclient"

step "cargo test --workspace"
cargo test --workspace "$@"

if [ -d python/tests ]; then
  step "python -m pytest python/tests"
  # The Python tests start our binaries: release builds, as a user runs them.
  cargo build --release -q -p world-server -p sim-core -p scenarios
  COSIM_WORLD_SERVER="$PWD/target/release/world-server" \
    "$venv/bin/python" -m pytest -q python/tests
fi

if [ -d training/tests ]; then
  step "python -m pytest training/tests (the gate network's int8 export and reference, numpy only)"
  "$venv/bin/python" -m pytest -q training/tests
fi

step "done"
