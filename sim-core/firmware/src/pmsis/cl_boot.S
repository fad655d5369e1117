/*
 * Entry of every cluster core (CTRL.BOOT_ADDR, docs/CLUSTER.md): the core
 * starts with all registers zero. gp as the FC's start.S sets it, sp from
 * the table the FC filled in pi_cluster_open (__pi_cl_stack_top[core id]),
 * then C: __pi_cl_main(core id) never returns.
 */
    .file "cl_boot.S"
    .text
    .balign 4
    .globl __pi_cl_boot
    .type __pi_cl_boot, @function
__pi_cl_boot:
    .option push
    .option norelax
    la      gp, __global_pointer$
    .option pop
    csrr    a0, mhartid
    andi    a0, a0, 31
    la      t0, __pi_cl_stack_top
    slli    t1, a0, 2
    add     t0, t0, t1
    lw      sp, 0(t0)
    /* A trap on a cluster core ends the program as the FC's would. */
    la      t0, __default_trap
    csrw    mtvec, t0
    call    __pi_cl_main
1:  j       1b
    .size __pi_cl_boot, . - __pi_cl_boot
