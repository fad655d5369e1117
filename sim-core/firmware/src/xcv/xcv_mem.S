/* xcvmem (CV32E40P manual, "Post-Incrementing Load & Store Instructions
 * and Register-Register Load & Store Instructions"): every form, with
 * positive and negative increments, register increments and offsets, a
 * misaligned post-increment load, and rD = rs1 (the loaded value wins). */
#include "xcvtest.h"

/* Load x14 with the instruction (the last arguments), then check x14 = v and the base x11 = base + inc. */
#define TEST_LD(n, v, off, inc, ...) \
    li TESTNUM, n;                    \
    la x15, data;                     \
    addi x11, x15, off;               \
    __VA_ARGS__;                      \
    CHECK_REG(x14, v);                \
    addi x7, x15, off + inc;          \
    bne x11, x7, fail

XCV_CODE_BEGIN
    /* Post-increment by an immediate. */
    TEST_LD(2, -128, 0, 1, cv.lb x14, (x11), 1)
    TEST_LD(3, 0x80, 0, 1, cv.lbu x14, (x11), 1)
    TEST_LD(4, 0xffff8001, 4, 2, cv.lh x14, (x11), 2)
    TEST_LD(5, 0x8001, 4, -2, cv.lhu x14, (x11), -2)
    TEST_LD(6, 0xdeadbeef, 8, -8, cv.lw x14, (x11), -8)
    /* Misaligned: bytes data+2..data+5. */
    TEST_LD(7, 0x80011122, 2, 4, cv.lw x14, (x11), 4)
    /* Post-increment by a register. */
    li x12, 8
    TEST_LD(8, 0x11223380, 0, 8, cv.lw x14, (x11), x12)
    li x12, -1
    TEST_LD(9, 0xef, 8, -1, cv.lbu x14, (x11), x12)
    li x12, -4
    TEST_LD(10, 0xffffbeef, 8, -4, cv.lh x14, (x11), x12)
    TEST_LD(11, 0xffffffef, 8, -4, cv.lb x14, (x11), x12)
    TEST_LD(12, 0xbeef, 8, -4, cv.lhu x14, (x11), x12)
    /* Register offset: the base is unchanged. */
    li x12, 4
    TEST_LD(13, 1, 0, 0, cv.lb x14, x12(x11))
    li x12, 6
    TEST_LD(14, -1, 0, 0, cv.lh x14, x12(x11))
    TEST_LD(15, 0xffff, 0, 0, cv.lhu x14, x12(x11))
    li x12, -8
    TEST_LD(16, 0xdeadbeef, 16, 0, cv.lw x14, x12(x11))
    li x12, 3
    TEST_LD(17, 0x11, 0, 0, cv.lbu x14, x12(x11))
    /* rD = rs1: the loaded value, not the incremented address. */
    li TESTNUM, 18
    la x11, data
    cv.lw x11, (x11), 4
    CHECK_REG(x11, 0x11223380)

    /* Stores into scratch (16 zero bytes); x13 = data. */
    li TESTNUM, 19
    la x11, scratch
    li x13, 0xab
    cv.sb x13, (x11), 1          /* scratch[0] = ab, x11 = +1 */
    li x12, 2
    li x13, 0xcd
    cv.sb x13, (x11), x12        /* scratch[1] = cd, x11 = +3 */
    li x12, -3
    li x13, 0xee
    cv.sb x13, x12(x11)          /* scratch[0]: ee over ab */
    la x7, scratch + 3
    bne x11, x7, fail
    li TESTNUM, 20
    la x11, scratch + 6
    li x13, 0x1234
    cv.sh x13, (x11), -2         /* scratch[6..8] = 34 12, x11 = +4 */
    li x12, 4
    li x13, 0x5678
    cv.sh x13, (x11), x12        /* scratch[4..6] = 78 56, x11 = +8 */
    li x12, -6
    li x13, 0x9abc
    cv.sh x13, x12(x11)          /* scratch[2..4] = bc 9a */
    la x7, scratch + 8
    bne x11, x7, fail
    li TESTNUM, 21
    li x13, 0xcafef00d
    cv.sw x13, (x11), 4          /* scratch[8..12], x11 = +12 */
    li x12, -12
    li x13, 0x55667788
    cv.sw x13, (x11), x12        /* scratch[12..16], x11 = +0 */
    li x12, 12
    li x13, 0x01020304
    cv.sw x13, x12(x11)          /* scratch[12..16] again */
    la x7, scratch
    bne x11, x7, fail
    li TESTNUM, 22
    lw x14, 0(x11)
    CHECK_REG(x14, 0x9abccdee)
    lw x14, 4(x11)
    CHECK_REG(x14, 0x12345678)
    lw x14, 8(x11)
    CHECK_REG(x14, 0xcafef00d)
    lw x14, 12(x11)
    CHECK_REG(x14, 0x01020304)
    XCV_TEST_END

RVTEST_DATA_BEGIN
data:
    .word 0x11223380, 0xffff8001, 0xdeadbeef, 0
scratch:
    .word 0, 0, 0, 0
RVTEST_DATA_END
