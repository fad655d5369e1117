#!/usr/bin/env bash
# Build upstream CoreMark (https://github.com/eembc/coremark, not vendored
# here) for the ISS benchmark of docs/ISS.md:
#
#   scripts/coremark.sh COREMARK_SRC_DIR [OUT_DIR] [ITERATIONS]
#
# writes OUT_DIR/coremark.elf (default out/coremark), RV32IMC, picolibc with
# semihosting, CoreMark's `simple` port (clock() = SYS_CLOCK, simulated time
# on our ISS), linked at 0x80000000 so that QEMU's `virt` machine runs the
# very same file (`sim-core run-elf` puts its RAM at the lowest loaded
# address). Then:
#
#   cosim bench iss --elf out/coremark/coremark.elf --qemu --repeat 3
set -euo pipefail
src=${1:?usage: scripts/coremark.sh COREMARK_SRC_DIR [OUT_DIR] [ITERATIONS]}
out=${2:-out/coremark}
iters=${3:-1000}
here=$(cd "$(dirname "$0")/.." && pwd)
mkdir -p "$out"
cat > "$out/virt.ld" <<'LD'
/* RAM at 0x80000000 (QEMU virt), the layout of sim-core/firmware/src/gap8.ld. */
__flash = 0x80000000;
__flash_size = 256K;
__ram = 0x80040000;
__ram_size = 256K;
__stack_size = 16K;
INCLUDE picolibc.ld
LD
riscv64-unknown-elf-gcc -march=rv32imc -misa-spec=2.2 -mabi=ilp32 -O2 \
  -ffunction-sections -fdata-sections --specs=picolibc.specs --oslib=semihost \
  -I"$src" -I"$src/simple" -DPERFORMANCE_RUN=1 -DITERATIONS="$iters" '-DFLAGS_STR="-O2"' \
  -nostartfiles -T "$out/virt.ld" -Wl,--gc-sections -o "$out/coremark.elf" \
  "$here/sim-core/firmware/src/start.S" \
  "$src"/core_list_join.c "$src"/core_main.c "$src"/core_matrix.c \
  "$src"/core_state.c "$src"/core_util.c "$src"/simple/core_portme.c
echo "$out/coremark.elf"
