/*
 * Test macros for the CORE-V XCV assembly tests (riscv-tests style, on top
 * of ../rvtest.h): each checks one instruction's result in x14 against a
 * closed-form expectation from the CV32E40P manual and fails test n
 * otherwise. Operands: x11 = rs1, x12 = rs2, x14 = rD (preset to d for
 * instructions that read it).
 */
#include "../rvtest.h"

/* rvtest.h's trap vector reports an unexpected trap as a pass while a0 is
 * 0 (it only checks a0 after ecall): set a0 = 1 first, so that one fails
 * (tohost = 1337 << 1 | 1). RVTEST_PASS clears a0 itself. */
#define XCV_CODE_BEGIN \
    RVTEST_CODE_BEGIN  \
    li a0, 1

#define XCV_CHECK(n, result) \
    li x7, result;           \
    bne x14, x7, fail

/* rD = insn(rs1) */
#define TEST_R(n, insn, result, a) \
    li TESTNUM, n;                 \
    li x11, a;                     \
    insn x14, x11;                 \
    XCV_CHECK(n, result)
/* rD = insn(rs1, imm...) */
#define TEST_RI(n, insn, result, a, ...) \
    li TESTNUM, n;                       \
    li x11, a;                           \
    insn x14, x11, __VA_ARGS__;          \
    XCV_CHECK(n, result)
/* rD = insn(rD = d, rs1, imm...) */
#define TEST_DRI(n, insn, result, d, a, ...) \
    li TESTNUM, n;                           \
    li x14, d;                               \
    li x11, a;                               \
    insn x14, x11, __VA_ARGS__;              \
    XCV_CHECK(n, result)
/* rD = insn(rs1, rs2, imm...) */
#define TEST_RRI(n, insn, result, a, b, ...) \
    li TESTNUM, n;                           \
    li x11, a;                               \
    li x12, b;                               \
    insn x14, x11, x12, __VA_ARGS__;         \
    XCV_CHECK(n, result)
/* rD = insn(rD = d, rs1, rs2) */
#define TEST_DRR(n, insn, result, d, a, b) \
    li TESTNUM, n;                         \
    li x14, d;                             \
    li x11, a;                             \
    li x12, b;                             \
    insn x14, x11, x12;                    \
    XCV_CHECK(n, result)
/* rD = insn(rD = d, rs1, rs2, imm) */
#define TEST_DRRI(n, insn, result, d, a, b, i) \
    li TESTNUM, n;                             \
    li x14, d;                                 \
    li x11, a;                                 \
    li x12, b;                                 \
    insn x14, x11, x12, i;                     \
    XCV_CHECK(n, result)
/* Register x equals v (clobbers x7). */
#define CHECK_REG(x, v) \
    li x7, v;           \
    bne x, x7, fail

#define XCV_TEST_END \
    RVTEST_PASS;     \
fail:                \
    RVTEST_FAIL
