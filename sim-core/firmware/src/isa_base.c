/*
 * Self-checking ISA program: every RV32I, M and C computational, branch,
 * jump, load and store instruction, with expected values worked out by hand
 * from the ISA manual. Prints a PASS/FAIL summary; exit status = failures.
 */
#include "selfcheck.h"

#define RR(insn, a, b)                                                                  \
    ({                                                                                  \
        uint32_t r_;                                                                    \
        __asm__ volatile(insn " %0, %1, %2" : "=r"(r_) : "r"(opaque(a)), "r"(opaque(b))); \
        r_;                                                                             \
    })
#define RI(insn, a, imm)                                                              \
    ({                                                                                \
        uint32_t r_;                                                                  \
        __asm__ volatile(insn " %0, %1, " #imm : "=r"(r_) : "r"(opaque(a)));          \
        r_;                                                                           \
    })
/* 1 if the branch is taken. */
#define BR(insn, a, b)                                                                 \
    ({                                                                                 \
        uint32_t r_;                                                                   \
        __asm__ volatile("li %0, 1\n\t" insn " %1, %2, 1f\n\tli %0, 0\n1:"             \
                         : "=&r"(r_)                                                   \
                         : "r"(opaque(a)), "r"(opaque(b)));                            \
        r_;                                                                            \
    })

static void alu(void)
{
    check("add", RR("add", 0x7fffffff, 1), 0x80000000);
    check("sub", RR("sub", 0, 1), 0xffffffff);
    check("sll", RR("sll", 1, 31), 0x80000000);
    check("sll uses 5 bits", RR("sll", 1, 33), 2);
    check("slt", RR("slt", 0xffffffff, 1), 1);
    check("sltu", RR("sltu", 0xffffffff, 1), 0);
    check("xor", RR("xor", 0xf0f0f0f0, 0xff00ff00), 0x0ff00ff0);
    check("srl", RR("srl", 0x80000000, 31), 1);
    check("sra", RR("sra", 0x80000000, 31), 0xffffffff);
    check("or", RR("or", 0xf0f0f0f0, 0x0f0f0f0f), 0xffffffff);
    check("and", RR("and", 0xf0f0f0f0, 0xff00ff00), 0xf000f000);
    check("addi", RI("addi", 0, -1), 0xffffffff);
    check("slti", RI("slti", 0xffffffff, -1), 0);
    check("sltiu", RI("sltiu", 0, -1), 1);
    check("xori", RI("xori", 0x00ff00ff, -1), 0xff00ff00);
    check("ori", RI("ori", 0x100, 0xff), 0x1ff);
    check("andi", RI("andi", 0xffffffff, 0x7ff), 0x7ff);
    check("slli", RI("slli", 3, 4), 0x30);
    check("srli", RI("srli", 0x80000000, 4), 0x08000000);
    check("srai", RI("srai", 0x80000000, 4), 0xf8000000);
    uint32_t r, l;
    __asm__ volatile("lui %0, 0x12345" : "=r"(r));
    check("lui", r, 0x12345000);
    __asm__ volatile("1: auipc %0, 0\n\tla %1, 1b" : "=r"(r), "=r"(l));
    check("auipc", r, l);
}

static void muldiv(void)
{
    check("mul", RR("mul", 0x12345678, 0x9abcdef0), 0x242d2080);
    check("mulhu", RR("mulhu", 0x12345678, 0x9abcdef0), 0x0b00ea4e);
    check("mulhsu", RR("mulhsu", 0xedcba988, 0x9abcdef0), 0xf4ff15b1);
    check("mulh", RR("mulh", 0xedcba988, 0x9abcdef0), 0x07336c29);
    check("mulhu max", RR("mulhu", 0xffffffff, 0xffffffff), 0xfffffffe);
    check("div", RR("div", -7, 2), (uint32_t)-3);
    check("rem", RR("rem", -7, 2), (uint32_t)-1);
    check("divu", RR("divu", 7, 2), 3);
    check("remu", RR("remu", 7, 2), 1);
    check("div by 0", RR("div", 5, 0), 0xffffffff);
    check("rem by 0", RR("rem", 5, 0), 5);
    check("divu by 0", RR("divu", 5, 0), 0xffffffff);
    check("remu by 0", RR("remu", 5, 0), 5);
    check("div overflow", RR("div", 0x80000000, -1), 0x80000000);
    check("rem overflow", RR("rem", 0x80000000, -1), 0);
}

static void branches(void)
{
    check("beq taken", BR("beq", 1, 1), 1);
    check("beq not taken", BR("beq", 1, 2), 0);
    check("bne", BR("bne", 1, 1), 0);
    check("blt", BR("blt", -1, 1), 1);
    check("bge", BR("bge", -1, 1), 0);
    check("bltu", BR("bltu", -1, 1), 0);
    check("bgeu", BR("bgeu", -1, 1), 1);
    uint32_t link, want;
    __asm__ volatile(".option push\n\t.option norvc\n\t"
                     "jal %0, 1f\n2:\n1:\n\tla %1, 2b\n\t.option pop"
                     : "=r"(link), "=r"(want));
    check("jal link", link, want);
    __asm__ volatile(".option push\n\t.option norvc\n\t"
                     "la t0, 1f\n\tjalr %0, 0(t0)\n2:\n1:\n\tla %1, 2b\n\t.option pop"
                     : "=r"(link), "=r"(want)
                     :
                     : "t0");
    check("jalr link", link, want);
}

static volatile uint8_t mem[16] __attribute__((aligned(4)));

static void loads_stores(void)
{
    volatile uint32_t *w = (volatile uint32_t *)mem;
    w[0] = 0x80ff7f01;
    w[1] = 0;
    w[2] = 0;
    check("lb", (uint32_t)(int32_t)(int8_t)mem[1], 0x7f);
    int8_t sb;
    __asm__ volatile("lb %0, 2(%1)" : "=r"(sb) : "r"(mem));
    check("lb sign", (uint32_t)(int32_t)sb, 0xffffffff);
    uint32_t r;
    __asm__ volatile("lbu %0, 3(%1)" : "=r"(r) : "r"(mem));
    check("lbu", r, 0x80);
    __asm__ volatile("lh %0, 2(%1)" : "=r"(r) : "r"(mem));
    check("lh", r, 0xffff80ff);
    __asm__ volatile("lhu %0, 2(%1)" : "=r"(r) : "r"(mem));
    check("lhu", r, 0x80ff);
    __asm__ volatile("lw %0, 0(%1)" : "=r"(r) : "r"(mem));
    check("lw", r, 0x80ff7f01);
    __asm__ volatile("sb %0, 4(%1)" ::"r"(0x1234), "r"(mem) : "memory");
    __asm__ volatile("sh %0, 6(%1)" ::"r"(0xabcd5678), "r"(mem) : "memory");
    check("sb/sh", w[1], 0x56780034);
    /* Misaligned accesses are done in hardware (RI5CY). */
    __asm__ volatile("sw %0, 5(%1)" ::"r"(0xdeadbeef), "r"(mem) : "memory");
    check("misaligned sw", w[1], 0xadbeef34);
    check("misaligned sw tail", w[2], 0x000000de);
    __asm__ volatile("lw %0, 5(%1)" : "=r"(r) : "r"(mem));
    check("misaligned lw", r, 0xdeadbeef);
    __asm__ volatile("lh %0, 7(%1)" : "=r"(r) : "r"(mem));
    check("misaligned lh", r, 0xffffdead);
}

/* Compressed instructions, each compared with the value its expansion gives. */
static void compressed(void)
{
    uint32_t r;
    __asm__ volatile(".option push\n\t.option rvc\n\t"
                     "li a0, 0\n\t"
                     "c.li a0, -5\n\t"
                     "c.addi a0, 3\n\t"
                     "c.slli a0, 4\n\t"
                     "mv %0, a0\n\t.option pop"
                     : "=r"(r)
                     :
                     : "a0");
    check("c.li/c.addi/c.slli", r, (uint32_t)-32);
    __asm__ volatile(".option push\n\t.option rvc\n\t"
                     "c.lui a0, 0x1f\n\t"
                     "c.srli a0, 4\n\t"
                     "mv %0, a0\n\t.option pop"
                     : "=r"(r)
                     :
                     : "a0");
    check("c.lui/c.srli", r, 0x1f000 >> 4);
    __asm__ volatile(".option push\n\t.option rvc\n\t"
                     "c.lui a0, 0xfffe0\n\t"
                     "c.srai a0, 8\n\t"
                     "c.andi a0, -16\n\t"
                     "mv %0, a0\n\t.option pop"
                     : "=r"(r)
                     :
                     : "a0");
    check("c.lui/c.srai/c.andi", r, 0xfffffe00); /* 0xfffe0000 >> 8 */
    __asm__ volatile(".option push\n\t.option rvc\n\t"
                     "li a0, 0x0ff0\n\tli a1, 0x00ff\n\t"
                     "c.mv a2, a0\n\t"
                     "c.sub a2, a1\n\t"  /* 0x0ef1 */
                     "c.mv a3, a0\n\t"
                     "c.xor a3, a1\n\t"  /* 0x0f0f */
                     "c.add a2, a3\n\t"  /* 0x1e00 */
                     "c.mv a3, a0\n\t"
                     "c.or a3, a1\n\t"   /* 0x0fff */
                     "c.add a2, a3\n\t"  /* 0x2dff */
                     "c.and a0, a1\n\t"  /* 0x00f0 */
                     "c.add a2, a0\n\t"  /* 0x2eef */
                     "mv %0, a2\n\t.option pop"
                     : "=r"(r)
                     :
                     : "a0", "a1", "a2", "a3");
    check("c.mv/c.sub/c.xor/c.or/c.and/c.add", r, 0x2eef);
    __asm__ volatile(".option push\n\t.option rvc\n\t"
                     "mv a1, sp\n\t"
                     "c.addi16sp sp, -32\n\t"
                     "c.addi4spn a0, sp, 8\n\t"
                     "li a2, 0x5a5a\n\t"
                     "c.sw a2, 4(a0)\n\t"
                     "c.lwsp a3, 12(sp)\n\t"
                     "c.swsp a3, 16(sp)\n\t"
                     "c.lw a4, 8(a0)\n\t"
                     "c.addi16sp sp, 32\n\t"
                     "sub a1, a1, sp\n\t"
                     "add %0, a4, a1\n\t.option pop"
                     : "=r"(r)
                     :
                     : "a0", "a1", "a2", "a3", "a4", "memory");
    check("c.addi16sp/c.addi4spn/c.sw/c.lw/c.lwsp/c.swsp", r, 0x5a5a);
    __asm__ volatile(".option push\n\t.option rvc\n\t"
                     "li a0, 0\n\t"
                     "c.beqz a0, 1f\n\t"
                     "c.li a0, 9\n"
                     "1:\tc.bnez a0, 2f\n\t"
                     "c.li a0, 1\n"
                     "2:\tc.j 3f\n\t"
                     "c.li a0, 7\n"
                     "3:\tmv %0, a0\n\t.option pop"
                     : "=r"(r)
                     :
                     : "a0");
    check("c.beqz/c.bnez/c.j", r, 1);
    uint32_t link, want;
    __asm__ volatile(".option push\n\t.option rvc\n\t"
                     "mv t0, ra\n\t"
                     "c.jal 1f\n2:\n1:\tmv %0, ra\n\t"
                     "la %1, 2b\n\t"
                     "la a0, 3f\n\t"
                     "c.jalr a0\n3:\n\t"
                     "la a1, 3b\n\t"
                     "sub %0, %0, %1\n\t"
                     "sub a1, a1, ra\n\t"
                     "or %0, %0, a1\n\t"
                     "la a0, 4f\n\t"
                     "c.jr a0\n\t"
                     "li %0, 99\n"
                     "4:\tmv ra, t0\n\t.option pop"
                     : "=&r"(link), "=&r"(want)
                     :
                     : "a0", "a1", "t0", "ra");
    check("c.jal/c.jalr/c.jr", link, 0);
}

int main(void)
{
    alu();
    muldiv();
    branches();
    loads_stores();
    compressed();
    return summary("isa_base");
}
