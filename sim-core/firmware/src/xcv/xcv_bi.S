/* xcvbi (CV32E40P manual, "Immediate Branching Operations"): cv.beqimm /
 * cv.bneimm compare rs1 with a sign-extended 5-bit immediate. */
#include "xcvtest.h"

XCV_CODE_BEGIN
    li TESTNUM, 2
    li x11, -16
    cv.beqimm x11, -16, 1f
    j fail
1:  li TESTNUM, 3
    cv.beqimm x11, 15, fail
    li TESTNUM, 4
    cv.bneimm x11, -16, fail
    li TESTNUM, 5
    li x11, 15
    cv.bneimm x11, -16, 2f
    j fail
2:  li TESTNUM, 6
    /* A counted loop closed by cv.bneimm: 5 iterations. */
    li x11, 0
    li x12, 0
3:  addi x12, x12, 3
    addi x11, x11, 1
    cv.bneimm x11, 5, 3b
    CHECK_REG(x12, 15)
    XCV_TEST_END

RVTEST_DATA_BEGIN
RVTEST_DATA_END
