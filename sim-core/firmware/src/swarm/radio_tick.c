/*
 * A drone that only uses its UWB radio, alone in the world: the platform's
 * clock ticker moves its clock (docs/SWARM.md §4.1). It sends three frames at
 * chosen times and sleeps in wfi until each TX_DONE, printing for each the
 * cycle at which it started the frame, the frame's TX stamp and the cycle at
 * which it woke up. sim-core's kernel test (tests/kernel_ticker.rs) checks
 * them against the clock bookkeeping; the program then ends with the world
 * session open, so the platform sends STOP for it.
 */
#include <stdint.h>
#include <stdio.h>

#include "../radio/radio.h"

#define CYCLES_PER_MS 250000ull

int main(void)
{
    radio_t uwb = RADIO_UWB;
    radio_init(&uwb);
    uint64_t t0 = radio_now_cycles();
    static const uint8_t payload[10] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10};
    for (int i = 0; i < 3; i++) {
        /* Start the frame 3.3 ms apart, off the 1 ms grid of the ticks. */
        uint64_t at = t0 + (uint64_t)i * 3300 * CYCLES_PER_MS / 1000 + 1250 * CYCLES_PER_MS / 1000;
        radio_set_timer(at);
        __asm__ volatile("csrs mie, %0" ::"r"(1u << 7));
        while (radio_now_cycles() < at)
            __asm__ volatile("wfi");
        __asm__ volatile("csrc mie, %0" ::"r"(1u << 7));
        uint64_t sent = radio_now_cycles();
        radio_send(&uwb, payload, sizeof payload);
        uint8_t s = radio_wait(&uwb, RADIO_TX_DONE, sent + 100 * CYCLES_PER_MS);
        uint64_t woke = radio_now_cycles();
        if (!s) {
            printf("no TX_DONE\n");
            return 1;
        }
        radio_clear(&uwb, RADIO_TX_DONE);
        printf("frame %d sent %llu stamp %llu woke %llu\n", i, (unsigned long long)sent,
               (unsigned long long)radio_tx_stamp(&uwb), (unsigned long long)woke);
    }
    return 0;
}
