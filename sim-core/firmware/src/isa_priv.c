/*
 * Self-checking privileged-architecture program: CSRs, every exception the
 * core raises (illegal instruction, ecall from M and U, ebreak, load/store
 * access faults), user mode, mret, the machine timer interrupt with wfi,
 * the counters, and self-modifying code with fence.i. Prints a PASS/FAIL
 * summary; exit status = failures.
 */
#include "selfcheck.h"

#define CSRR(csr)                                          \
    ({                                                     \
        uint32_t v_;                                       \
        __asm__ volatile("csrr %0, " #csr : "=r"(v_));     \
        v_;                                                \
    })
#define CSRW(csr, v) __asm__ volatile("csrw " #csr ", %0" ::"r"(v))

#define MTIME_LO (*(volatile uint32_t *)0x0200bff8)
#define MTIMECMP_LO (*(volatile uint32_t *)0x02004000)
#define MTIMECMP_HI (*(volatile uint32_t *)0x02004004)

static volatile uint32_t trap_count, last_cause, last_tval, last_epc;

/* Records the trap; returns after the faulting instruction (2 or 4 bytes),
 * to machine mode after an ecall from user mode; silences the timer. */
__attribute__((interrupt("machine"), aligned(4))) static void handler(void)
{
    uint32_t cause = CSRR(mcause), epc = CSRR(mepc);
    trap_count++;
    last_cause = cause;
    last_tval = CSRR(mtval);
    last_epc = epc;
    if (cause & 0x80000000u) {
        MTIMECMP_HI = 0xffffffff;
        MTIMECMP_LO = 0xffffffff;
        return;
    }
    uint16_t first = *(volatile uint16_t *)epc;
    CSRW(mepc, epc + ((first & 3) == 3 ? 4 : 2));
    if (cause == 8) /* ecall from U: come back in M */
        __asm__ volatile("csrs mstatus, %0" ::"r"(3u << 11));
}

static void expect_trap(const char *name, uint32_t count_before, uint32_t cause)
{
    check(name, trap_count - count_before, 1);
    check(name, last_cause, cause);
}

static void csrs(void)
{
    check("misa", CSRR(misa), 0x40101104);
    /* 0 alone, 0x400 (gap_sdk's FC cluster id 32 << 5) beside a cluster
     * (DESIGN.md §12: `sim-core run-elf` attaches one by default). */
    uint32_t hart = CSRR(mhartid);
    check("mhartid", hart == 0 || hart == 0x400, 1);
    CSRW(mscratch, 0x12345678);
    check("mscratch", CSRR(mscratch), 0x12345678);
    uint32_t old;
    __asm__ volatile("csrrw %0, mscratch, %1" : "=r"(old) : "r"(7));
    check("csrrw old", old, 0x12345678);
    __asm__ volatile("csrrsi %0, mscratch, 8" : "=r"(old));
    __asm__ volatile("csrrci %0, mscratch, 1" : "=r"(old));
    check("csrrsi/csrrci", old, 15);
    check("csrrci new", CSRR(mscratch), 14);
    uint32_t a, b;
    __asm__ volatile("csrr %0, minstret\n\tcsrr %1, minstret" : "=r"(a), "=r"(b));
    check("minstret counts each instruction", b - a, 1);
    __asm__ volatile("rdcycle %0\n\tnop\n\trdcycle %1" : "=r"(a), "=r"(b));
    /* cycle is a 1-cycle CSR, nop 1 cycle (CV32E40P table). */
    check("cycle", b - a, 2);
    __asm__ volatile("rdtime %0" : "=r"(a));
    check("time is mtime", a <= MTIME_LO, 1);
    /* mepc ignores bit 0 (IALIGN = 16). */
    CSRW(mepc, 0x1001);
    check("mepc alignment", CSRR(mepc), 0x1000);
}

static void exceptions(void)
{
    uint32_t n = trap_count;
    __asm__ volatile(".option push\n\t.option norvc\n\tcsrr t0, 0x7ff\n\t.option pop" ::: "t0");
    expect_trap("illegal csr", n, 2);
    check("illegal csr mtval", last_tval, 0x7ff022f3);
    n = trap_count;
    __asm__ volatile(".2byte 0");
    expect_trap("illegal zero halfword", n, 2);
    n = trap_count;
    __asm__ volatile("csrw mvendorid, zero");
    expect_trap("write to read-only csr", n, 2);
    n = trap_count;
    __asm__ volatile("ecall");
    expect_trap("ecall from M", n, 11);
    n = trap_count;
    uint32_t where;
    __asm__ volatile(".option push\n\t.option norvc\n\t1: ebreak\n\tla %0, 1b\n\t.option pop"
                     : "=r"(where));
    expect_trap("ebreak", n, 3);
    check("ebreak epc", last_epc, where);
    n = trap_count;
    __asm__ volatile(".option push\n\t.option rvc\n\tc.ebreak\n\t.option pop");
    expect_trap("c.ebreak", n, 3);
    n = trap_count;
    uint32_t v;
    __asm__ volatile("lw %0, 0(%1)" : "=r"(v) : "r"(0x10));
    expect_trap("load access fault", n, 5);
    check("load fault mtval", last_tval, 0x10);
    n = trap_count;
    __asm__ volatile("sw zero, 0(%0)" ::"r"(0x20));
    expect_trap("store access fault", n, 7);
    check("store fault mtval", last_tval, 0x20);
}

static void user_mode(void)
{
    uint32_t n = trap_count;
    /* mret to user mode with MPP = U; in U, reading mstatus is illegal;
     * an ecall brings us back to M (the handler sets MPP = M). */
    __asm__ volatile("li t0, 3 << 11\n\t"
                     "csrc mstatus, t0\n\t"
                     "la t0, 1f\n\t"
                     "csrw mepc, t0\n\t"
                     "mret\n"
                     "1:\tcsrr t0, mstatus\n\t"
                     "ecall\n\t" ::
                         : "t0", "memory");
    check("user mode traps", trap_count - n, 2);
    check("ecall from U", last_cause, 8);
    n = trap_count;
    /* mret leaves MPP at the least-privileged mode, U. */
    check("mret clears MPP", (CSRR(mstatus) >> 11) & 3, 0);
    check("back in M: machine CSRs readable", trap_count - n, 0);
}

static void timer_interrupt(void)
{
    uint32_t n = trap_count;
    MTIMECMP_HI = 0;
    MTIMECMP_LO = MTIME_LO + 1000;
    __asm__ volatile("csrs mie, %0" ::"r"(1u << 7));
    __asm__ volatile("csrsi mstatus, 8");
    uint32_t before = MTIME_LO;
    __asm__ volatile("wfi");
    uint32_t after = MTIME_LO;
    __asm__ volatile("csrci mstatus, 8");
    check("timer interrupt taken", trap_count - n, 1);
    check("timer cause", last_cause, 0x80000007);
    check("wfi slept until the timer", after - before >= 900, 1);
    /* mcycle does not count while asleep (gated clock). */
}

/* Code written at run time: "li a0, imm; ret". */
static uint32_t code_buf[2] __attribute__((aligned(4)));

static uint32_t run_generated(int32_t imm)
{
    code_buf[0] = ((uint32_t)imm << 20) | (10 << 7) | 0x13; /* addi a0, zero, imm */
    code_buf[1] = 0x00008067;                                /* jalr zero, 0(ra) */
    __asm__ volatile("fence.i" ::: "memory");
    return ((uint32_t(*)(void))code_buf)();
}

int main(void)
{
    void (*h)(void) = handler;
    CSRW(mtvec, (uint32_t)h);
    csrs();
    exceptions();
    user_mode();
    timer_interrupt();
    check("generated code", run_generated(42), 42);
    check("regenerated code", run_generated(-7), (uint32_t)-7);
    return summary("isa_priv");
}
