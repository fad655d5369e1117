/*
 * Start file for the GAP8-like map (gap8.ld): the job of picolibc's crt0,
 * plus a default trap handler so that a stray trap ends the program with a
 * clear exit status (128 + mcause) instead of looping.
 */
    /* A fixed file name: the default is a temporary file (not reproducible). */
    .file "start.S"
    .section .text.init.enter, "ax"
    .globl _start
    .type _start, @function
_start:
    .option push
    .option norelax
    la      gp, __global_pointer$
    .option pop
    la      sp, __stack
    la      t0, __default_trap
    csrw    mtvec, t0
    /* .data is loaded in place by our loaders; the copy keeps the image
     * correct for a loader that only writes the load addresses. */
    la      a0, __data_start
    la      a1, __data_source
    la      a2, __data_size
    call    memcpy
    la      a0, __bss_start
    li      a1, 0
    la      a2, __bss_size
    call    memset
    la      a0, __tls_base
    call    _set_tls
    call    __libc_init_array
    li      a0, 0
    li      a1, 0
    call    main
    call    exit
1:  j       1b
    .size _start, . - _start

    .text
    .balign 4
    .weak __default_trap
    .type __default_trap, @function
__default_trap:
    csrr    a0, mcause
    andi    a0, a0, 0x7f
    addi    a0, a0, 128
    call    _exit
2:  j       2b
    .size __default_trap, . - __default_trap
