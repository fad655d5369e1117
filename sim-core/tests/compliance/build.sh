#!/usr/bin/env bash
# Rebuilds the committed compliance ELFs from the upstream suites' sources
# (not vendored) and checks they are byte-identical to the committed ones
# (the firmware's `make check` rule: committed artifacts are checked for
# reproducibility, not rebuilt in CI).
#
#   sim-core/tests/compliance/build.sh RISCV_TESTS ARCH_TEST [--write]
#
# RISCV_TESTS: a checkout of github.com/riscv-software-src/riscv-tests at
#   34e6b6d1e7936b526075432fb730d89148623484 with its env submodule
#   (github.com/riscv/riscv-test-env) at 6de71edb142be36319e380ce782c3d1830c65d68.
# ARCH_TEST: a checkout of github.com/riscv-non-isa/riscv-arch-test at tag
#   2.7.4 (96e3589a867955e94c95ba098822da54d3ae39c0), the last release that
#   ships reference signatures (later ones generate them with Sail).
# Compiler: riscv64-unknown-elf-gcc (Debian's gcc-riscv64-unknown-elf,
#   13.2.0), as the firmware's Makefile uses.
# --write replaces the committed files instead of comparing.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
rt=$(cd "$1" && pwd); at=$(cd "$2" && pwd); write=${3:-}
out=$(mktemp -d); trap 'rm -rf "$out"' EXIT
cc=riscv64-unknown-elf-gcc
strip=riscv64-unknown-elf-strip
opts=(-mabi=ilp32 -static -mcmodel=medany -fvisibility=hidden -nostdlib -nostartfiles
      -ffile-prefix-map="$rt"=riscv-tests -ffile-prefix-map="$at"=riscv-arch-test -g0)

# riscv-tests, physical-memory ("p") environment, M mode. Left out:
# rv32mi pmpaddr (the CV32E40P has no PMP; the test fails by design
# without one: "If a7 is 0 ... this test does not support" it).
mkdir -p "$out/riscv-tests"
for suite in rv32ui rv32um rv32uc rv32mi; do
  tests=$(make -s -C "$rt/isa" -f - <<MK
include $suite/Makefrag
all:
	@echo \$(${suite}_sc_tests)
MK
)
  for t in $tests; do
    [ "$suite/$t" = rv32mi/pmpaddr ] && continue
    "$cc" -march=rv32imc_zicsr_zifencei "${opts[@]}" -I"$rt/env/p" -I"$rt/isa/macros/scalar" \
      -T"$rt/env/p/link.ld" "$rt/isa/$suite/$t.S" -o "$out/riscv-tests/$suite-p-$t.elf"
    # The local symbols name gcc's temporary files: drop them (tohost and
    # the signature bounds are global).
    "$strip" --strip-debug --discard-all "$out/riscv-tests/$suite-p-$t.elf"
  done
done

# The architecture tests with our model (model/): RV32I, M, C, Zifencei
# and the privilege tests, each built for the ISA its RVTEST_ISA names
# (the reference signatures were made so). Left out: misalign-{lh,lhu,lw,
# sh,sw}: their references assume misaligned loads and stores trap
# (hw_data_misaligned_support False); the CV32E40P performs them in
# hardware, as its manual says, so RISCOF would not select them.
for s in I M C Zifencei privilege; do
  mkdir -p "$out/arch-test/$s"
  march=rv32i; [ $s = M ] && march=rv32im; [ $s = C ] && march=rv32ic
  for src in "$at/riscv-test-suite/rv32i_m/$s/src/"*.S; do
    t=$(basename "$src" .S)
    case $t in misalign-lh-01|misalign-lhu-01|misalign-lw-01|misalign-sh-01|misalign-sw-01) continue;; esac
    defs=(-DXLEN=32)
    [ $s = privilege ] && defs+=(-Drvtest_mtrap_routine=True)
    "$cc" -march=${march}_zicsr_zifencei "${opts[@]}" "${defs[@]}" -I"$here/model" \
      -I"$at/riscv-test-suite/env" -T"$here/model/link.ld" "$src" -o "$out/arch-test/$s/$t.elf" 2>/dev/null
    "$strip" --strip-debug --discard-all "$out/arch-test/$s/$t.elf"
    cp "$at/riscv-test-suite/rv32i_m/$s/references/$t.reference_output" "$out/arch-test/$s/"
  done
done

if [ "$write" = --write ]; then
  rm -rf "$here/riscv-tests" "$here/arch-test"
  cp -r "$out/riscv-tests" "$out/arch-test" "$here/"
  echo "compliance: wrote $(find "$out" -name '*.elf' | wc -l) ELFs"
else
  if diff -r "$out/riscv-tests" "$here/riscv-tests" && diff -r "$out/arch-test" "$here/arch-test"; then
    echo "compliance: all $(find "$out" -name '*.elf' | wc -l) ELFs reproduce"
  else
    echo "compliance: the committed ELFs differ from a rebuild" >&2
    exit 1
  fi
fi
