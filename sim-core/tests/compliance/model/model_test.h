/* Our target for the RISC-V architecture tests (riscv-arch-test 2.7.4):
 * sim-core run-elf halts on a write to `tohost` and dumps the words between
 * begin_signature and end_signature (--signature). */
#ifndef COSIM_MODEL_TEST_H
#define COSIM_MODEL_TEST_H
#define RVMODEL_DATA_SECTION \
  .pushsection .tohost, "aw", @progbits; \
  .align 8; .global tohost; tohost: .dword 0; \
  .align 8; .global fromhost; fromhost: .dword 0; \
  .popsection; \
  .align 8; .global begin_regstate; begin_regstate: .word 128; \
  .align 8; .global end_regstate; end_regstate: .word 4;
#define RVMODEL_HALT \
  li t0, 1; la t1, tohost; sw t0, 0(t1); sw zero, 4(t1); \
  cosim_halt: j cosim_halt;
#define RVMODEL_BOOT
#define RVMODEL_DATA_BEGIN .align 4; .global begin_signature; begin_signature:
#define RVMODEL_DATA_END .align 4; .global end_signature; end_signature: RVMODEL_DATA_SECTION
#define RVMODEL_IO_INIT
#define RVMODEL_IO_WRITE_STR(_R, _STR)
#define RVMODEL_IO_CHECK()
#define RVMODEL_IO_ASSERT_GPR_EQ(_S, _R, _I)
#define RVMODEL_IO_ASSERT_SFPR_EQ(_F, _R, _I)
#define RVMODEL_IO_ASSERT_DFPR_EQ(_D, _R, _I)
#define RVMODEL_SET_MSW_INT
#define RVMODEL_CLEAR_MSW_INT
#define RVMODEL_CLEAR_MTIMER_INT
#define RVMODEL_CLEAR_MEXT_INT
#endif
