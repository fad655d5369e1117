/*
 * The generic network runtime (docs/NN_ONNX.md "On the deck"): the FC's
 * program. `cosim nn run` writes a model as data (model.h) into nn_l2 and
 * the HyperRAM, the input activation into its place in nn_l2, sets
 * nn_command and resumes; the FC walks the layers, one cluster task per
 * layer (kernels.c tiles it through L1), and stops at an ebreak
 * (host_stop.h) when done, or after every layer with nn_profile set.
 *
 * Weights flagged NN_F_W_L3 stream from the HyperRAM into two L2 stage
 * buffers in parts of whole output channels, one cluster task per part:
 * the read of the next part (of this layer or the next L3 layer) is
 * queued before the current part's task and waited for after it, so it
 * runs while the cluster computes (DORY's L3 double buffering, Burrello
 * et al. 2021, §III-C). nn_stats' fc_wait_cycles is what the FC waited
 * for L3 after the tasks: the reads the computation did not hide.
 */
#include <pmsis.h>

#include "../../host_stop.h"
#include "kernels.h"
#include "model.h"
#include "udma_regs.h"

#define NN_CMD_INFER 1u
#define NN_CMD_QUIT 2u

/* The L2 image: what the linker script (nn_run.ld) leaves beside the code,
 * the runtime's own data and the stack. */
#ifndef NN_L2_BYTES
#define NN_L2_BYTES (440u * 1024u)
#endif

uint8_t nn_l2[NN_L2_BYTES] __attribute__((aligned(8)));
__attribute__((used)) const uint32_t nn_l2_size = sizeof nn_l2;
volatile uint32_t nn_command;
volatile int32_t nn_status;
nn_layer_stats_t nn_stats[NN_MAX_LAYERS];
volatile uint32_t nn_profile;
volatile uint32_t nn_layer_done;
volatile uint32_t nn_event;

static struct pi_device cluster;
static struct pi_device ram;
static int ram_opened;
static nn_job_t job;

static inline uint32_t fc_now(void)
{
    uint32_t v;
    __asm__ volatile("csrr %0, time" : "=r"(v));
    return v;
}

static const nn_value_t *values(const nn_model_t *m)
{
    return (const nn_value_t *)(nn_l2 + m->values_off);
}

static const nn_layer_t *layers(const nn_model_t *m)
{
    return (const nn_layer_t *)(nn_l2 + m->layers_off);
}

/* [off, off + bytes) inside the image. */
static int inside(uint32_t off, uint64_t bytes)
{
    return off <= NN_L2_BYTES && bytes <= NN_L2_BYTES - off;
}

static uint32_t elems(const nn_value_t *v) { return v->c * v->h * v->w; }

/* Output channels of a CONV/DENSE layer and the bytes of one's weights. */
static uint32_t out_channels(const nn_model_t *m, const nn_layer_t *l)
{
    const nn_value_t *y = &values(m)[l->out];
    return l->kind == NN_DENSE ? elems(y) : y->c;
}

static uint32_t per_channel(const nn_model_t *m, const nn_layer_t *l)
{
    const nn_value_t *x = &values(m)[l->in[0]];
    if (l->kind == NN_DENSE)
        return elems(x);
    return l->kh * l->kw * (x->c / l->groups);
}

static int check_layer(const nn_model_t *m, const nn_layer_t *l)
{
    if (l->kind < NN_CONV || l->kind > NN_LUT || l->n_in < 1 || l->n_in > NN_MAX_IN ||
        l->out >= m->n_values || l->lo > l->hi)
        return -1;
    for (uint32_t k = 0; k < l->n_in; k++)
        if (l->in[k] >= m->n_values)
            return -1;
    const nn_value_t *x = &values(m)[l->in[0]], *y = &values(m)[l->out];
    int window = l->kind == NN_CONV || l->kind == NN_MAXPOOL || l->kind == NN_AVGPOOL;
    if (window && (l->kh < 1 || l->kw < 1 || l->sh < 1 || l->sw < 1 || l->pt >= l->kh ||
                   l->pl >= l->kw))
        return -1;
    switch (l->kind) {
    case NN_CONV:
    case NN_DENSE: {
        if (l->kind == NN_CONV &&
            (l->groups < 1 || x->c % l->groups || y->c % l->groups || l->n_in != 1))
            return -1;
        uint32_t cout = out_channels(m, l), per = per_channel(m, l);
        if ((uint64_t)cout * per != l->w_bytes || !inside(l->b_off, 4ull * cout) ||
            !inside(l->rq_off, 8ull * cout) || (l->b_off & 3) || (l->rq_off & 3))
            return -1;
        if (l->flags & NN_F_W_L3) {
            if (!l->part_oc || (uint64_t)l->part_oc * per > m->stage_bytes ||
                !inside(m->stage_off, 2ull * m->stage_bytes))
                return -1;
        } else if (!inside(l->w_off, l->w_bytes))
            return -1;
        return 0;
    }
    case NN_MAXPOOL:
        return x->c == y->c && inside(l->rq_off, 8) && !(l->rq_off & 3) ? 0 : -1;
    case NN_AVGPOOL:
        if (x->c != y->c)
            return -1;
        return !(l->flags & NN_F_POOL_RECORDS) ||
                       (inside(l->rq_off, 8ull * (l->kh * l->kw + 1)) && !(l->rq_off & 3))
                   ? 0
                   : -1;
    case NN_GAP:
        if (x->c != elems(y))
            return -1;
        return !(l->flags & NN_F_POOL_RECORDS) || (inside(l->rq_off, 8) && !(l->rq_off & 3))
                   ? 0
                   : -1;
    case NN_ADD:
        return l->n_in == 2 && elems(&values(m)[l->in[1]]) == elems(y) && elems(x) == elems(y) &&
                       inside(l->rq_off, 16) && !(l->rq_off & 3)
                   ? 0
                   : -1;
    case NN_CONCAT: {
        uint32_t c = 0;
        for (uint32_t k = 0; k < l->n_in; k++) {
            const nn_value_t *v = &values(m)[l->in[k]];
            if (v->h * v->w != y->h * y->w)
                return -1;
            c += v->c;
        }
        return c == y->c && inside(l->rq_off, 8ull * l->n_in) && !(l->rq_off & 3) ? 0 : -1;
    }
    case NN_REQUANT:
        return elems(x) == elems(y) && inside(l->rq_off, 8) && !(l->rq_off & 3) ? 0 : -1;
    case NN_LUT:
        return elems(x) == elems(y) && inside(l->lut_off, 256) ? 0 : -1;
    }
    return -1;
}

static int32_t check_model(const nn_model_t *m)
{
    if (m->magic != NN_MAGIC)
        return NN_E_MAGIC;
    if (m->version != NN_VERSION)
        return NN_E_VERSION;
    if (m->n_layers > NN_MAX_LAYERS || m->n_values == 0 || (m->values_off & 3) ||
        (m->layers_off & 3) || !inside(m->values_off, (uint64_t)m->n_values * sizeof(nn_value_t)) ||
        !inside(m->layers_off, (uint64_t)m->n_layers * sizeof(nn_layer_t)) ||
        m->input >= m->n_values || m->output >= m->n_values)
        return NN_E_HEADER;
    for (uint32_t i = 0; i < m->n_values; i++) {
        const nn_value_t *v = &values(m)[i];
        if (!v->c || !v->h || !v->w || (uint64_t)v->c * v->h * v->w > v->bytes ||
            !inside(v->off, v->bytes))
            return NN_E_VALUE;
    }
    for (uint32_t i = 0; i < m->n_layers; i++)
        if (check_layer(m, &layers(m)[i]) != 0) {
            nn_layer_done = i;
            return NN_E_LAYER;
        }
    return 0;
}

/* One cluster task: layer l, output channels [oc0, oc1), weights at w. */
static int32_t run_task(const nn_model_t *m, const nn_layer_t *l, nn_layer_stats_t *st,
                        const int8_t *w, uint32_t oc0, uint32_t oc1)
{
    job = (nn_job_t){.model = m, .l2 = nn_l2, .layer = l, .w = w, .oc_begin = oc0, .oc_end = oc1};
    struct pi_cluster_task task;
    pi_cluster_send_task_to_cl(&cluster, pi_cluster_task(&task, nn_layer_task, &job));
    st->cycles += job.cycles;
    st->dma_bytes += job.dma_bytes;
    return job.status;
}

/* ---- L3 parts ------------------------------------------------------------ */

typedef struct {
    uint32_t layer, oc0, oc1;
} part_t;

/* The L3 part after channel `oc` of layer i (i = n_layers: none yet
 * started, look from layer 0); 0 if none is left. */
static int next_part(const nn_model_t *m, uint32_t i, uint32_t oc, part_t *p)
{
    const nn_layer_t *L = layers(m);
    if (i >= m->n_layers) {
        i = 0;
        oc = 0;
    } else if (oc >= out_channels(m, &L[i])) {
        i++;
        oc = 0;
    }
    for (; i < m->n_layers; i++, oc = 0) {
        if (!(L[i].flags & NN_F_W_L3) || (L[i].kind != NN_CONV && L[i].kind != NN_DENSE))
            continue;
        uint32_t n = out_channels(m, &L[i]);
        p->layer = i;
        p->oc0 = oc;
        p->oc1 = oc + L[i].part_oc < n ? oc + L[i].part_oc : n;
        return 1;
    }
    return 0;
}

static int8_t *stage(const nn_model_t *m, int b)
{
    return (int8_t *)nn_l2 + m->stage_off + (uint32_t)b * m->stage_bytes;
}

static pi_task_t read_task;

/* Waits for an L3 read: the SDK's pi_task_wait_on, whose polling loop
 * on the µDMA's DONE count the ISS skips exactly. */
static void read_wait(pi_task_t *t) { pi_task_wait_on(t); }

static void start_read(const nn_model_t *m, const part_t *p, int b)
{
    const nn_layer_t *l = &layers(m)[p->layer];
    uint32_t per = per_channel(m, l), bytes = (p->oc1 - p->oc0) * per;
    pi_ram_read_async(&ram, l->w_off + p->oc0 * per, stage(m, b), bytes, &read_task);
    nn_stats[p->layer].l3_bytes += bytes;
}

static int32_t infer(void)
{
    const nn_model_t *m = (const nn_model_t *)nn_l2;
    int32_t st = check_model(m);
    if (st)
        return st;
    if (nn_l1_setup(&cluster, m->l1_budget) != 0)
        return NN_E_L1;
    for (uint32_t i = 0; i < m->n_layers; i++)
        nn_stats[i] = (nn_layer_stats_t){0, 0, 0, 0};
    if (m->l3_bytes && !ram_opened) {
        struct pi_hyperram_conf conf;
        pi_hyperram_conf_init(&conf);
        pi_open_from_conf(&ram, &conf);
        if (pi_ram_open(&ram) != 0)
            return NN_E_L3;
        ram_opened = 1;
    }
    /* The first L3 part's read, before anything runs. */
    part_t inflight;
    int have = next_part(m, m->n_layers, 0, &inflight), waited = 0, buf = 0;
    if (have)
        start_read(m, &inflight, buf);
    const nn_layer_t *L = layers(m);
    for (uint32_t i = 0; i < m->n_layers; i++) {
        const nn_layer_t *l = &L[i];
        nn_layer_stats_t *s = &nn_stats[i];
        int conv = l->kind == NN_CONV || l->kind == NN_DENSE;
        if (!conv || !(l->flags & NN_F_W_L3)) {
            st = run_task(m, l, s, conv ? (const int8_t *)nn_l2 + l->w_off : NULL, 0,
                          conv ? out_channels(m, l) : 0);
        } else {
            while (have && inflight.layer == i) {
                if (!waited) {
                    uint32_t t0 = fc_now();
                    read_wait(&read_task);
                    s->fc_wait_cycles += fc_now() - t0;
                }
                part_t cur = inflight;
                int b = buf;
                /* The next part's read runs while the cluster computes. */
                have = next_part(m, i, cur.oc1, &inflight);
                waited = 0;
                if (have) {
                    buf ^= 1;
                    start_read(m, &inflight, buf);
                }
                st = run_task(m, l, s, stage(m, b), cur.oc0, cur.oc1);
                if (have) {
                    uint32_t t0 = fc_now();
                    read_wait(&read_task);
                    s->fc_wait_cycles += fc_now() - t0;
                    waited = 1;
                }
                if (st)
                    break;
            }
        }
        nn_layer_done = i;
        if (st) {
            if (have && !waited)
                read_wait(&read_task);
            return st;
        }
        if (nn_profile) {
            nn_event = 1;
            host_stop();
        }
    }
    return 0;
}

int main(void)
{
    /* The host reads nn_l2_size; the reference keeps it from the linker's
     * garbage collection. */
    __asm__ volatile("" ::"r"(&nn_l2_size));
    struct pi_cluster_conf conf;
    pi_cluster_conf_init(&conf);
    pi_open_from_conf(&cluster, &conf);
    if (pi_cluster_open(&cluster) != 0) {
        nn_status = -100;
        return 1;
    }
    for (;;) {
        nn_event = 0;
        host_stop();
        if (nn_command != NN_CMD_INFER)
            break;
        nn_status = infer();
    }
    pi_cluster_close(&cluster);
    if (ram_opened)
        pi_ram_close(&ram);
    return 0;
}
