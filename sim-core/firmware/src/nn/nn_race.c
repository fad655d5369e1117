/*
 * The race flown on what the network sees (DESIGN.md §13,
 * docs/NN.md "nn-race"): the FC grabs each looked-at camera frame into L2
 * (as vision_race.c does), averages it to the network's input (frame.c),
 * sends the network to the cluster (network.c), decodes the head
 * (decode.c) and turns the gate's pixel and distance into a position in
 * the body frame; the flying (turns, standoff points, the running mean of
 * accepted sightings, the STM32's target) is ../guidance/guidance.c's,
 * shared with the classical detector's race.
 *
 * Temporal filtering (docs/NN.md "nn-race"): the network misses 12 % of
 * the gates and reports 9 % false ones (held-out), with a 17 px mean
 * centre error and 0.42 m distance error, frame by frame. So a sighting is
 * used only (1) at a plausible range, (2) within nn_accept_mm of the
 * course's nominal waypoint, (3) once nn_track_min sightings of this gate
 * were accepted, within nn_track_mm of their mean (a jump is a false
 * detection, not the gate moving); the target is the mean of the accepted
 * sightings, so single errors average out, and it is held (the last
 * target, or the nominal waypoint before any sighting) across misses.
 * The target lies nn_through_mm beyond the mean, along the approach: a
 * distance error that places the gate short of its plane would otherwise
 * stop the drone in front of it.
 *
 * The cluster is powered up for each inference and down after it
 * (pi_cluster_open ... pi_cluster_close, GAP8's cluster power gating): it
 * works about 3.5 ms of every 120 ms, and an open idle cluster would leak
 * the rest of the time (8.6 times the cluster's energy over the race with
 * nn_keep_open = 1, docs/NN.md "Power gating"). The power-up, the cores'
 * boot and the L1 allocation are in the latency, not in the cluster
 * cycles of the network (network.c measures from the input's DMA).
 *
 * Inference time: the FC's time CSR (it counts while the FC waits for the
 * cluster) from the capture's end to the decoded head, rounded up to whole
 * ms, is the ITER_ADVANCE the world advances by (guidance.c).
 *
 * The figures the run's summary reports (§13's `nn` block) are read by
 * sim-core from `nn_race_stats` at the end (sim-core/src/kernel/nn_stats.rs).
 */
#include <pmsis.h>
#include <stdint.h>
#include <stdio.h>

#include "../cosim_regs.h"
#include "../guidance/guidance.h"
#include "../vision/gate_detect.h"
#include "decode.h"
#include "frame.h"
#include "network.h"
#include "net.h"

/* The network's input is the camera's whole image (DESIGN.md §5: 320x320). */
#if NN_CAMERA != GATE_IMAGE_WIDTH || NN_CAMERA != GATE_IMAGE_HEIGHT
#error "weights.h's NN_CAMERA is not the camera's image size"
#endif

/* The tunables, globals so that a scenario may set them (`firmware.NAME`,
 * RunConfig::firmware_params) without a rebuild. */
/* A network on every nn_look_every-th camera frame while approaching a
 * gate: vision_race's cadence (LOOK_EVERY 5), so that the two detectors
 * are compared at the same rate. A frame is the 16 ms capture, the
 * inference's ITER_ADVANCE and the PID step on the platform's clock: 5
 * gives 8.1 inferences per second (3: 13), within PULP-DroNet's 6-18 fps
 * on the AI deck, and keeps the ISS's work (about 18 ms of host CPU per
 * inference) within the 10x-real-time budget (docs/NN.md "nn-race"). */
int32_t nn_look_every = 5;
/* 0: the cluster is powered for each inference only (see the top); 1: it
 * is opened at the first look and kept open, its cores asleep between
 * inferences: `--set firmware.nn_keep_open=1` measures what the power
 * gating saves (docs/NN.md "Power gating"). In .data although 0, since a
 * scenario sets it in the ELF's image (kernel/firmware_params.rs). */
__attribute__((section(".data"))) int32_t nn_keep_open = 0;
/* Sightings are used from nn_min_range_mm to nn_max_range_mm: the training
 * images' poses were 0.8-7 m from a gate (docs/NN.md "The data"), the
 * distance error grows with the distance. */
int32_t nn_min_range_mm = 900;
int32_t nn_max_range_mm = 5000;
/* Gating against the course (mm): a perturbed gate moves up to 0.45 m, the
 * network's distance error is 0.42 m on average. */
int32_t nn_accept_mm = 900;
int32_t nn_accept_dz_mm = 400;
/* Gating against the tracked gate (mm, sightings). */
int32_t nn_track_mm = 600;
int32_t nn_track_min = 3;
/* The target beyond the gate (mm). */
int32_t nn_through_mm = 300;

/* Indices of nn_race_stats (sim-core/src/kernel/nn_stats.rs reads them). */
enum {
    NN_RS_VERSION,          /* NN_RS_FORMAT */
    NN_RS_INFERENCES,       /* networks run */
    NN_RS_MACS,             /* MACs per inference (weights.h) */
    NN_RS_CL_CYCLES_LO,     /* cluster cycles, input DMA to head in L2, sum */
    NN_RS_CL_CYCLES_HI,
    NN_RS_CL_CYCLES_MAX,
    NN_RS_LATENCY_LO,       /* FC time-CSR cycles, frame copy to decoded head, sum */
    NN_RS_LATENCY_HI,
    NN_RS_LATENCY_MAX,
    NN_RS_PERIOD_LO,        /* FC cycles between consecutive looks of the cadence, sum */
    NN_RS_PERIOD_HI,
    NN_RS_PERIODS,          /* ... and their number */
    NN_RS_VISIBLE,          /* heads that report a gate */
    NN_RS_USED,             /* sightings the guidance used */
    NN_RS_STATUS,           /* 0, or the cluster's failure */
    NN_RS_WORDS
};
#define NN_RS_FORMAT 1u
uint32_t nn_race_stats[NN_RS_WORDS];

static uint8_t frame[NN_CAMERA * NN_CAMERA] __attribute__((aligned(4)));
static int8_t input[NN_INPUT_PADDED_BYTES] __attribute__((aligned(4)));
static int16_t head[NN_GRID * NN_GRID * NN_HEAD_CHANNELS] __attribute__((aligned(4)));
static struct pi_device cluster;
/* The camera model: focal length and the camera's place on the body. */
static const gate_config_t camera = GATE_CONFIG_DEFAULT;

static uint32_t fc_now(void)
{
    uint32_t v;
    __asm__ volatile("csrr %0, time" : "=r"(v));
    return v;
}

static void add64(int lo, uint64_t v)
{
    uint64_t s = ((uint64_t)nn_race_stats[lo + 1] << 32 | nn_race_stats[lo]) + v;
    nn_race_stats[lo] = (uint32_t)s;
    nn_race_stats[lo + 1] = (uint32_t)(s >> 32);
}

/* The image into L2, a word at a time (the window composes unaligned words
 * from bytes, docs/VISION.md "What the flight integration needs" 1). */
static void copy_frame(void)
{
    const volatile uint8_t *src = &REG8(CAMERA_IMAGE_OFFSET);
    uint32_t *dst = (uint32_t *)frame;
    for (int i = 0; i < NN_CAMERA * NN_CAMERA / 4; i++)
        dst[i] = *(const volatile uint32_t *)(src + 4 * i);
}

/* The gate's centre in the body frame (mm) from its pixel (1/16 px) and
 * its distance from the optical centre (mm): the pinhole ray through the
 * pixel (x forward, y left, z up), scaled to the distance, plus the
 * camera's place on the body. */
static void body_from_pixel(const nn_output_t *o, int32_t body[3])
{
    int64_t f = camera.focal_q8 / 16; /* q4 px */
    int64_t du = o->u_q4 - NN_CAMERA / 2 * 16, dv = NN_CAMERA / 2 * 16 - o->v_q4;
    int64_t norm = gate_isqrt64((uint64_t)(f * f + du * du + dv * dv));
    int64_t d = o->distance_mm;
    body[0] = camera.cam_x_mm + (int32_t)(d * f / norm);
    body[1] = camera.cam_y_mm - (int32_t)(d * du / norm);
    body[2] = camera.cam_z_mm + (int32_t)(d * dv / norm);
}

static void look(int wp, guidance_sighting_t *s)
{
    static nn_job_t job;
    static uint32_t last_t0, last_captured;
    uint32_t t0 = fc_now();
    copy_frame();
    nn_downsample(frame, input);
    /* The cluster is powered for the inference only (see the top), unless
     * nn_keep_open. */
    static int open;
    if (!open) {
        struct pi_cluster_conf conf;
        pi_cluster_conf_init(&conf);
        pi_open_from_conf(&cluster, &conf);
        if (pi_cluster_open(&cluster) != 0) {
            printf("[nn] cannot open the cluster\n");
            nn_race_stats[NN_RS_STATUS] = 1;
            return;
        }
        open = 1;
    }
    job = (nn_job_t){.cluster = &cluster, .input = input, .head = head};
    struct pi_cluster_task task;
    pi_cluster_send_task_to_cl(&cluster, pi_cluster_task(&task, nn_network_run, &job));
    if (!nn_keep_open) {
        pi_cluster_close(&cluster);
        nn_network_release(); /* the next open's L1 heap is new */
        open = 0;
    }
    nn_output_t o;
    nn_decode(head, &o);
    uint32_t latency = fc_now() - t0;

    nn_race_stats[NN_RS_INFERENCES]++;
    add64(NN_RS_CL_CYCLES_LO, job.cycles);
    if (job.cycles > nn_race_stats[NN_RS_CL_CYCLES_MAX])
        nn_race_stats[NN_RS_CL_CYCLES_MAX] = job.cycles;
    add64(NN_RS_LATENCY_LO, latency);
    if (latency > nn_race_stats[NN_RS_LATENCY_MAX])
        nn_race_stats[NN_RS_LATENCY_MAX] = latency;
    /* The inference period: between two looks of the cadence in a row
     * (not across a turn or a hold at a gate, when the network rests). */
    uint32_t captured = guidance_stats.captured;
    if (nn_race_stats[NN_RS_INFERENCES] > 1 && captured - last_captured == (uint32_t)nn_look_every) {
        add64(NN_RS_PERIOD_LO, t0 - last_t0);
        nn_race_stats[NN_RS_PERIODS]++;
    }
    last_t0 = t0;
    last_captured = captured;
    if (job.status != 0) {
        nn_race_stats[NN_RS_STATUS] = (uint32_t)job.status;
        return;
    }

    s->found = o.visible;
    if (!o.visible)
        return;
    nn_race_stats[NN_RS_VISIBLE]++;
    s->usable = wp >= 0 && wp < GUIDANCE_WAYPOINTS - 1 && o.distance_mm >= nn_min_range_mm &&
                o.distance_mm <= nn_max_range_mm;
    body_from_pixel(&o, s->body_mm);
#ifdef VISION_TRACE
    printf("[nn] wp %d u %d v %d d %d score %d body %d %d %d\n", wp + 1, (int)(o.u_q4 / 16),
           (int)(o.v_q4 / 16), (int)o.distance_mm, (int)o.score, (int)s->body_mm[0],
           (int)s->body_mm[1], (int)s->body_mm[2]);
#endif
}

int main(void)
{
    printf("[nn] race with the network on the cluster in the loop\n");
    nn_race_stats[NN_RS_VERSION] = NN_RS_FORMAT;
    nn_race_stats[NN_RS_MACS] = NN_MACS;
    if (nn_look_every < 1)
        nn_look_every = 1;
    const guidance_config_t g = {
        .look = look,
        .time_csr = 1,
        .look_every = nn_look_every,
        .accept_mm = nn_accept_mm,
        .accept_dz_mm = nn_accept_dz_mm,
        .track_mm = nn_track_mm,
        .track_min = (uint32_t)nn_track_min,
        .through_mm = nn_through_mm,
        .tag = "[nn]",
    };
    guidance_fly(&g);
    const guidance_stats_t *s = &guidance_stats;
    nn_race_stats[NN_RS_USED] = s->used;
    uint32_t n = nn_race_stats[NN_RS_INFERENCES];
    uint64_t cl = (uint64_t)nn_race_stats[NN_RS_CL_CYCLES_HI] << 32 | nn_race_stats[NN_RS_CL_CYCLES_LO];
    printf("[nn] captured %u, inferences %u, gate seen in %u, used %u, rejected by tracking %u, retargets %u, inference %u ms\n",
           (unsigned)s->captured, (unsigned)n, (unsigned)s->found, (unsigned)s->used,
           (unsigned)s->rejected, (unsigned)s->retargets, (unsigned)s->infer_ms_sum);
    printf("[nn] waypoints %d, standoff points %u, target moves %u\n", GUIDANCE_WAYPOINTS,
           (unsigned)s->standoffs, (unsigned)s->retargets);
    printf("[nn] cluster cycles per inference: mean %u, max %u; FC clock %u cycles/ms\n",
           (unsigned)(n ? cl / n : 0), (unsigned)nn_race_stats[NN_RS_CL_CYCLES_MAX],
           (unsigned)s->cycles_per_ms);
    guidance_print_simul_time();
    return nn_race_stats[NN_RS_STATUS] != 0;
}
