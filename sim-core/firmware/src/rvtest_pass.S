/* riscv-tests style: a few RV32I/M/C checks that all pass (tohost = 1). */
#include "rvtest.h"

RVTEST_CODE_BEGIN
    TEST_RR(2, add, 0x80000000, 0x7fffffff, 1)
    TEST_RR(3, sub, 0xffffffff, 0, 1)
    TEST_RR(4, mulhu, 0xfffffffe, 0xffffffff, 0xffffffff)
    TEST_RR(5, div, 0x80000000, 0x80000000, -1)
    TEST_RR(6, remu, 5, 5, 0)
    li TESTNUM, 7
    la x10, scratch
    li x11, 0x11223344
    sw x11, 0(x10)
    lhu x12, 2(x10)
    li x7, 0x1122
    bne x12, x7, fail
    li TESTNUM, 8
    .option push
    .option rvc
    c.li x8, 5
    c.addi x8, -7
    .option pop
    li x7, -2
    bne x8, x7, fail
    RVTEST_PASS
fail:
    RVTEST_FAIL

RVTEST_DATA_BEGIN
scratch: .word 0
RVTEST_DATA_END
