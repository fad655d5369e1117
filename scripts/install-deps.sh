#!/usr/bin/env bash
# The system packages the tests and the firmware check need, installed when
# missing (one place for .ci/run and scripts/test-all.sh): GNU parallel, the
# RISC-V cross compiler and picolibc, clang-19 (CORE-V XCV, DESIGN.md §12),
# python3-venv. From apt-get (root, or sudo when there is one); with
# COSIM_NO_INSTALL=1 it only checks and fails with what is missing.
set -euo pipefail

apt_install() {
  if [ "${COSIM_NO_INSTALL:-0}" = 1 ]; then
    echo "install-deps: missing: $* (COSIM_NO_INSTALL=1: not installing)" >&2
    exit 1
  fi
  local sudo=()
  if [ "$(id -u)" != 0 ]; then
    command -v sudo >/dev/null 2>&1 || {
      echo "install-deps: missing: $*; install them (apt-get install $*) or run as root" >&2
      exit 1
    }
    sudo=(sudo)
  fi
  echo "install-deps: installing $*"
  export DEBIAN_FRONTEND=noninteractive
  "${sudo[@]}" apt-get update -qq
  "${sudo[@]}" apt-get install -y -qq "$@" >/dev/null
}

missing=()
# moreutils ships another program called parallel: check for GNU's.
parallel --version 2>/dev/null | grep -q '^GNU parallel' || missing+=(parallel)
command -v riscv64-unknown-elf-gcc >/dev/null 2>&1 || missing+=(gcc-riscv64-unknown-elf)
[ -f /usr/lib/picolibc/riscv64-unknown-elf/picolibc.specs ] || missing+=(picolibc-riscv64-unknown-elf)
command -v clang-19 >/dev/null 2>&1 || missing+=(clang-19)
python3 -c 'import venv, ensurepip' 2>/dev/null || missing+=(python3-venv)
if [ ${#missing[@]} -gt 0 ]; then
  apt_install "${missing[@]}"
fi
parallel --version | head -n 1
