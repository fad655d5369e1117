/* Architecture-test style: results stored between begin_signature and
 * end_signature (dumped by --signature), then a pass through tohost.
 * Includes self-modifying code made visible with fence.i (Zifencei). */
#include "rvtest.h"

RVTEST_CODE_BEGIN
    la x1, sig
    li x12, 0x12345678
    li x13, 0x0f0f0f0f
    and x4, x12, x13
    sw x4, 0(x1)
    mul x5, x12, x13
    sw x5, 4(x1)
    srai x6, x12, 4
    sw x6, 8(x1)
    /* Patch "addi x7, x0, 1" into "addi x7, x0, 2" and run it. */
    la x8, patch
    lw x9, 0(x8)
    li x10, 0x00100000
    add x9, x9, x10
    sw x9, 0(x8)
    fence.i
    .option push
    .option norvc
patch:
    addi x7, x0, 1
    .option pop
    sw x7, 12(x1)
    RVTEST_PASS
fail:
    RVTEST_FAIL

RVTEST_DATA_BEGIN
sig:
    .fill 4, 4, 0xdeadbeef
RVTEST_DATA_END
