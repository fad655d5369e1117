/*
 * Idle-skipping workload: the register protocol of thesis Listing 4.6
 * (write an opcode to a control register, poll the status register until it
 * shows the same code, clear both) against a test device at the start of the
 * peripheral window, polled with byte and masked-word loads, and a wfi sleep
 * until the machine timer. sim-core's tests run it with idle skipping on and
 * off and compare.
 */
#include <stdint.h>

#define CTRL (*(volatile uint8_t *)0x20000000)
#define STAT (*(volatile uint8_t *)0x20000001)
#define WORD0 (*(volatile uint32_t *)0x20000000)
#define MTIME_LO (*(volatile uint32_t *)0x0200bff8)
#define MTIMECMP_LO (*(volatile uint32_t *)0x02004000)
#define MTIMECMP_HI (*(volatile uint32_t *)0x02004004)

static void perform(uint8_t op)
{
    CTRL = op;
    while (STAT != op)
        ;
    STAT = 0;
    CTRL = 0;
}

static void perform_word(uint8_t op)
{
    CTRL = op;
    while ((WORD0 & 0xff00u) != ((uint32_t)op << 8))
        ;
    STAT = 0;
    CTRL = 0;
}

int main(void)
{
    uint32_t work = 0;
    for (uint8_t op = 1; op <= 3; op++) {
        perform(op);
        for (int i = 0; i < 100; i++)
            work = work * 31u + i;
    }
    perform_word(4);
    /* Sleep until the timer: wfi wakes on a pending enabled interrupt even
     * with mstatus.MIE clear, so no handler runs. */
    MTIMECMP_HI = 0;
    MTIMECMP_LO = MTIME_LO + 12345;
    __asm__ volatile("csrs mie, %0" ::"r"(1u << 7));
    __asm__ volatile("wfi");
    __asm__ volatile("csrc mie, %0" ::"r"(1u << 7));
    perform(5);
    return (int)(work & 0x7f);
}
