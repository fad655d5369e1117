#!/usr/bin/env bash
# The system packages the tests and the firmware check need, installed when
# missing (one place for .ci/run and scripts/test-all.sh): GNU parallel, the
# RISC-V cross compiler and picolibc, clang-19 (CORE-V XCV, DESIGN.md §12),
# python3-venv, and for cfclient under Xvfb (python/tests/test_cfclient_keys.py,
# docs/CFLIB.md "cfclient") Xvfb, xdotool, scrot (scripts/cfclient-xvfb.sh's
# screenshots) and the libraries PyQt6's xcb platform loads. From apt-get (root, or sudo when there is one); with
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
command -v Xvfb >/dev/null 2>&1 || missing+=(xvfb)
command -v xdotool >/dev/null 2>&1 || missing+=(xdotool)
command -v scrot >/dev/null 2>&1 || missing+=(scrot)
for lib in libegl1 libxkbcommon-x11-0 libxcb-cursor0 libxcb-icccm4 libxcb-keysyms1 \
    libxcb-shape0 libxcb-randr0 libxcb-render-util0 libxcb-image0 libxcb-xinerama0 \
    libgl1 libfontconfig1 libdbus-1-3; do
  dpkg-query -W -f='${Status}' "$lib" 2>/dev/null | grep -q 'ok installed' || missing+=("$lib")
done
if [ ${#missing[@]} -gt 0 ]; then
  apt_install "${missing[@]}"
fi
parallel --version | head -n 1
