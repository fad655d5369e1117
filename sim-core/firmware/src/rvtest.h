/*
 * A minimal riscv-tests "-p-" environment (same conventions as
 * riscv-test-env/p/riscv_test.h, written from its documented behaviour):
 * machine-mode reset code that drops to user mode with mret, test number in
 * gp (x3), ecall to finish; the trap vector writes tohost = 1 (pass) or
 * (gp << 1) | 1 (fail of test gp) and spins; any other trap is a failure
 * (test 1337), whatever a0 holds.
 */
#define TESTNUM gp

#define RVTEST_CODE_BEGIN                  \
    .file __FILE__; /* not the temporary name: reproducible */ \
    .section .text.init;                   \
    .align 6;                              \
    .globl _start;                         \
_start:                                    \
    la t0, trap_vector;                    \
    csrw mtvec, t0;                        \
    li TESTNUM, 0;                         \
    /* satp does not exist: the access     \
     * traps, the handler skips it */      \
    la t0, 1f;                             \
    csrw mtvec, t0;                        \
    csrwi satp, 0;                         \
    .align 2;                              \
1:  la t0, trap_vector;                    \
    csrw mtvec, t0;                        \
    csrwi mstatus, 0;                      \
    la t0, user_start;                     \
    csrw mepc, t0;                         \
    mret;                                  \
    .align 2;                              \
trap_vector:                               \
    csrr t5, mcause;                       \
    li t6, 8; /* ecall from U */           \
    beq t5, t6, write_tohost_result;       \
    li t6, 11; /* ecall from M */          \
    beq t5, t6, write_tohost_result;       \
    /* an unexpected trap fails, whatever a0 \
     * holds: test 1337 */                 \
    li TESTNUM, (1337 << 1) | 1;           \
    j write_tohost;                        \
write_tohost_result:                       \
    sll TESTNUM, TESTNUM, 1;               \
    or TESTNUM, TESTNUM, 1;                \
    beqz a0, 2f;                           \
    j write_tohost;                        \
2:  li TESTNUM, 1;                         \
write_tohost:                              \
    sw TESTNUM, tohost, t5;                \
    j write_tohost;                        \
    .text;                                 \
user_start:

/* a0 = 0 means pass (as riscv-tests' RVTEST_PASS), a0 = 1 fail. */
#define RVTEST_PASS \
    fence;          \
    li a0, 0;       \
    ecall
#define RVTEST_FAIL \
    fence;          \
    li a0, 1;       \
    ecall

#define RVTEST_DATA_BEGIN      \
    .pushsection .tohost, "aw", @progbits; \
    .align 6;                  \
    .globl tohost;             \
tohost: .dword 0;              \
    .align 6;                  \
    .globl fromhost;           \
fromhost: .dword 0;            \
    .popsection;               \
    .data;                     \
    .align 4;                  \
    .globl begin_signature;    \
begin_signature:

#define RVTEST_DATA_END        \
    .align 4;                  \
    .globl end_signature;      \
end_signature:

/* TEST_RR(n, insn, result, a, b): fail test n unless insn(a, b) == result. */
#define TEST_RR(n, insn, result, a, b) \
    li TESTNUM, n;                     \
    li x11, a;                         \
    li x12, b;                         \
    insn x14, x11, x12;                \
    li x7, result;                     \
    bne x14, x7, fail
