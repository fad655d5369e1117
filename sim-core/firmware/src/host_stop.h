/* The host's stop for programs driven frame by frame from the host
 * (`cosim nn eval`, the gate detector's test harness): a plain 4-byte
 * ebreak (not compressed, no semihosting markers around it), so the ISS
 * stops at it (`ebreak_stops`) and the host resumes at pc + 4. */
#ifndef HOST_STOP_H
#define HOST_STOP_H

static inline void host_stop(void)
{
    __asm__ volatile(".option push\n.option norvc\nebreak\n.option pop" ::: "memory");
}

#endif
