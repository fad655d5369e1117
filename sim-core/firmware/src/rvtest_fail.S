/* riscv-tests style: test 2 passes, test 3 fails (tohost = 7, exit 3). */
#include "rvtest.h"

RVTEST_CODE_BEGIN
    TEST_RR(2, add, 3, 1, 2)
    TEST_RR(3, add, 4, 1, 2)
    RVTEST_PASS
fail:
    RVTEST_FAIL

RVTEST_DATA_BEGIN
RVTEST_DATA_END
