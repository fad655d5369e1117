/* xcvbitmanip (CV32E40P manual, "Bit Manipulation operations"), with the
 * manual's own cv.bitrev examples. */
#include "xcvtest.h"

XCV_CODE_BEGIN
    TEST_RI(2, cv.extract, -1, 0xf00, 3, 8)
    TEST_RI(3, cv.extractu, 15, 0xf00, 3, 8)
    TEST_RI(4, cv.extract, 7, 0x700, 3, 8)
    TEST_RI(5, cv.extractu, 0xf, 0xf0000000, 31, 28)
    TEST_RR(6, cv.extractr, -1, 0xf00, 0x68)
    TEST_RR(7, cv.extractur, 15, 0xf00, 0x68)
    TEST_DRI(8, cv.insert, 0xfffffabf, 0xffffffff, 0xab, 7, 4)
    TEST_DRR(9, cv.insertr, 0xab0, 0, 0xab, 0xe4)
    TEST_RI(10, cv.bclr, 0xffffff0f, 0xffffffff, 3, 4)
    TEST_RI(11, cv.bset, 0xf0, 0, 3, 4)
    TEST_RR(12, cv.bclrr, 0x0fffffff, 0xffffffff, 0x3fc)
    TEST_RR(13, cv.bsetr, 0xffffffff, 0, 0x3e0)
    TEST_R(14, cv.ff1, 32, 0)
    TEST_R(15, cv.ff1, 31, 0x80000000)
    TEST_R(16, cv.ff1, 4, 0x50)
    TEST_R(17, cv.fl1, 0, 1)
    TEST_R(18, cv.fl1, 32, 0)
    TEST_R(19, cv.fl1, 6, 0x50)
    TEST_R(20, cv.clb, 0, 0)
    TEST_R(21, cv.clb, 30, 1)
    TEST_R(22, cv.clb, 31, -1)
    TEST_R(23, cv.clb, 3, 0xf0000000)
    TEST_R(24, cv.cnt, 9, 0xf0f00001)
    TEST_RR(25, cv.ror, 0x80000000, 1, 1)
    TEST_RR(26, cv.ror, 0x81234567, 0x12345678, 36)
    TEST_RI(27, cv.bitrev, 0x0cc9a526, 0xc64a5933, 0, 4)
    TEST_RI(28, cv.bitrev, 0x0cc65a19, 0xc64a5933, 1, 4)
    TEST_RI(29, cv.bitrev, 0x216b244b, 0xc64a5933, 2, 4)
    XCV_TEST_END

RVTEST_DATA_BEGIN
RVTEST_DATA_END
