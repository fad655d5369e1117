/* xcvmac (CV32E40P manual, "Multiply-Accumulate"): 32-bit MACs wrapping
 * at 2^32, the 16-bit multiplies and MACs with shift and rounding, at the
 * edges (-32768 * -32768, 0xffff * 0xffff). */
#include "xcvtest.h"

XCV_CODE_BEGIN
    TEST_DRR(2, cv.mac, 1, 1, 0x80000000, 2)
    TEST_DRR(3, cv.mac, -2, 10, -3, 4)
    TEST_DRR(4, cv.mac, 0x80000000, 0x7fffffff, 1, 1)
    TEST_DRR(5, cv.msu, -1, 5, 2, 3)
    TEST_DRR(6, cv.msu, 0, 0, 0x10000, 0x10000)
    TEST_RRI(7, cv.mulsn, 0x40000000, 0x8000, 0x8000, 0)
    TEST_RR(8, cv.muls, -6, 0x70002, 0x5fffd)
    TEST_RR(9, cv.mulhhs, 0x40000000, 0x80000000, 0x80000000)
    TEST_RRI(10, cv.mulun, 0xfffe0001, 0xffff, 0xffff, 0)
    TEST_RR(11, cv.mulhhu, 0xfffe0001, 0xffff0000, 0xffff0000)
    TEST_RRI(12, cv.mulsn, -125, 100, 0xfffb, 2)
    TEST_RRI(13, cv.mulsrn, -62, 100, 0xfffb, 3)
    TEST_RRI(14, cv.mulurn, 0xfffe, 0xffff, 0xffff, 16)
    TEST_RRI(15, cv.mulhhsrn, -1, 0x30000, 0xfffb0000, 4)
    TEST_RRI(16, cv.mulhhun, 0x1fffc, 0xffff0000, 0xffff0000, 15)
    TEST_RRI(17, cv.mulhhurn, 0x1fffc, 0xffff0000, 0xffff0000, 15)
    TEST_DRRI(18, cv.macsn, 13, 4, 3, 3, 0)
    TEST_DRRI(19, cv.macsrn, 7, 4, 3, 3, 1)
    TEST_DRRI(20, cv.macun, 0x7fffffff, 0x1fffe, 0xffff, 0xffff, 1)
    TEST_DRRI(21, cv.machhsn, -6, 0, 0x20000, 0xfffd0000, 0)
    TEST_DRRI(22, cv.machhsrn, -3, 0, 0x20000, 0xfffd0000, 1)
    TEST_DRRI(23, cv.macurn, 5, 1, 3, 3, 1)
    TEST_DRRI(24, cv.machhun, 0x80000000, 0x7fffffff, 0x10000, 0x10000, 0)
    TEST_DRRI(25, cv.machhurn, 2, 1, 0x10000, 0x20000, 1)
    XCV_TEST_END

RVTEST_DATA_BEGIN
RVTEST_DATA_END
