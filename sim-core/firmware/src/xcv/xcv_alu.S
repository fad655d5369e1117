/* xcvalu (CV32E40P manual, "ALU" / "General ALU operations"): expected
 * values from the manual's formulas, including the clip bounds and the
 * rounding normalisations. sim-core/tests/iss_xcv.rs runs it. */
#include "xcvtest.h"

XCV_CODE_BEGIN
    TEST_R(2, cv.abs, 5, -5)
    TEST_R(3, cv.abs, 0x80000000, 0x80000000)
    TEST_RR(4, cv.slet, 1, -1, 0)
    TEST_RR(5, cv.slet, 1, 7, 7)
    TEST_RR(6, cv.sletu, 0, -1, 0)
    TEST_RR(7, cv.min, -1, -1, 1)
    TEST_RR(8, cv.minu, 1, -1, 1)
    TEST_RR(9, cv.max, 1, -1, 1)
    TEST_RR(10, cv.maxu, -1, -1, 1)
    TEST_R(11, cv.exths, 0xffff8000, 0x12348000)
    TEST_R(12, cv.exthz, 0x8000, 0x12348000)
    TEST_R(13, cv.extbs, 0xffffff80, 0x180)
    TEST_R(14, cv.extbz, 0x80, 0x180)
    /* cv.clip rD, rs1, Is2: [-2^(Is2-1), 2^(Is2-1)-1]; Is2 = 0: [-1, 0]. */
    TEST_RI(15, cv.clip, 127, 1000, 8)
    TEST_RI(16, cv.clip, -128, -1000, 8)
    TEST_RI(17, cv.clip, 100, 100, 8)
    TEST_RI(18, cv.clip, 0, 5, 0)
    TEST_RI(19, cv.clip, -1, -5, 0)
    TEST_RI(20, cv.clip, 0xc0000000, 0x80000000, 31)
    TEST_RI(21, cv.clipu, 0, -5, 8)
    TEST_RI(22, cv.clipu, 127, 1000, 8)
    TEST_RR(23, cv.clipr, 100, 300, 100)
    TEST_RR(24, cv.clipr, -101, -300, 100)
    TEST_RR(25, cv.clipur, 100, 300, 0x80000064)
    TEST_RR(26, cv.clipur, 0, -300, 100)
    /* (rs1 +- rs2 [+ 2^(Is3-1)]) >>> or >> Is3, on 32 bits. */
    TEST_RRI(27, cv.addn, 4, 7, 2, 1)
    TEST_RRI(28, cv.addrn, 5, 7, 2, 1)
    TEST_RRI(29, cv.addun, 0x7fffffff, -2, 0, 1)
    TEST_RRI(30, cv.addurn, 4, 3, 4, 1)
    TEST_RRI(31, cv.subn, -2, 0, 32, 4)
    TEST_RRI(32, cv.subun, 0x0ffffffe, 0, 32, 4)
    TEST_RRI(33, cv.subrn, -1, 0, 3, 1)
    TEST_RRI(34, cv.suburn, 4, 10, 3, 1)
    TEST_RRI(35, cv.addn, 0, 0xffffffff, 1, 0)
    /* rD = (rD +- rs1 [+ 2^(rs2-1)]) >> rs2[4:0]. */
    TEST_DRR(36, cv.addnr, 7, 10, 5, 1)
    TEST_DRR(37, cv.addrnr, 8, 10, 5, 1)
    TEST_DRR(38, cv.addunr, 0x7fffffff, -2, 0, 33)
    TEST_DRR(39, cv.addurnr, 8, 10, 5, 1)
    TEST_DRR(40, cv.subnr, -10, 10, 30, 1)
    TEST_DRR(41, cv.subunr, 0x7ffffff6, 10, 30, 1)
    TEST_DRR(42, cv.subrnr, -5, 10, 30, 2)
    TEST_DRR(43, cv.suburnr, 0x3ffffffb, 10, 30, 2)
    XCV_TEST_END

RVTEST_DATA_BEGIN
RVTEST_DATA_END
