/* Tiny self-checking harness shared by the ISA programs. */
#ifndef SELFCHECK_H
#define SELFCHECK_H
#include <stdint.h>
#include <stdio.h>

static int checks, failures;

static void check(const char *name, uint32_t got, uint32_t want)
{
    checks++;
    if (got != want) {
        failures++;
        printf("FAIL %s: got %08lx, want %08lx\n", name, (unsigned long)got, (unsigned long)want);
    }
}

/* Prints the summary; the exit status is the number of failures. */
static int summary(const char *program)
{
    printf("%s: %d checks, %d failures: %s\n", program, checks, failures,
           failures ? "FAIL" : "PASS");
    return failures;
}

/* Keep the compiler from folding constants: launder through a register. */
static inline uint32_t opaque(uint32_t x)
{
    __asm__ volatile("" : "+r"(x));
    return x;
}
#endif
