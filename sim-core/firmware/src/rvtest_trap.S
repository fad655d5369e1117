/* riscv-tests style: an unexpected trap (an illegal instruction) with
 * a0 = 0 must fail as test 1337, not pass (rvtest.h's trap vector). */
#include "rvtest.h"

RVTEST_CODE_BEGIN
    li a0, 0
    .word 0 /* all zeros: an illegal instruction */
    RVTEST_PASS

RVTEST_DATA_BEGIN
RVTEST_DATA_END
