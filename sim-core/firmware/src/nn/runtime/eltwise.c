/*
 * The element-wise kinds: REQUANT and LUT (one input byte to one output
 * byte: a 256-entry table in L1), ADD (two inputs, 64-bit arithmetic),
 * CONCAT (each input's channels requantized into their place of the
 * output's pixels). ADD, REQUANT and LUT see their values as flat byte
 * arrays (the output keeps the input's storage order), in chunks.
 */
#include "rt.h"

/* ---- Flat chunks: REQUANT, LUT, ADD ------------------------------------ */

typedef struct {
    rt_pipe_t p;
    int n_in;         /* 1 (table) or 2 (ADD) */
    uint32_t total, chunk, set_bytes;
    const int8_t *in[2];
    int8_t *out;
    int32_t za, zb, zy, lo, hi;
    int32_t m0, m1;
    uint32_t shift;
    const int8_t *tab;
} flat_t;

static uint32_t chunk_len(const flat_t *c, int t)
{
    uint32_t at = (uint32_t)t * c->chunk;
    return c->total - at < c->chunk ? c->total - at : c->chunk;
}

static void flat_load(rt_pipe_t *p, int t, int b)
{
    flat_t *c = (flat_t *)p;
    int8_t *set = nn_l1_tiles + b * c->set_bytes;
    for (int i = 0; i < c->n_in; i++)
        rt_load(p, c->in[i] + t * c->chunk, set + i * a4(c->chunk), chunk_len(c, t));
}

static void flat_store(rt_pipe_t *p, int t, int b)
{
    flat_t *c = (flat_t *)p;
    int8_t *set = nn_l1_tiles + b * c->set_bytes;
    rt_store(p, c->out + t * c->chunk, set + c->n_in * a4(c->chunk), chunk_len(c, t));
}

static void map_compute(void *arg)
{
    const flat_t *c = arg;
    const int8_t *set = nn_l1_tiles + c->p.b * c->set_bytes;
    const int8_t *in = set, *tab = c->tab + 128;
    int8_t *out = (int8_t *)set + a4(c->chunk);
    int first, last;
    rt_share((int)chunk_len(c, c->p.t), &first, &last);
    for (int i = first; i < last; i++)
        out[i] = tab[in[i]];
}

static void add_compute(void *arg)
{
    const flat_t c = *(const flat_t *)arg;
    const int8_t *set = nn_l1_tiles + c.p.b * c.set_bytes;
    const int8_t *a = set, *bb = set + a4(c.chunk);
    int8_t *out = (int8_t *)set + 2 * a4(c.chunk);
    int first, last;
    rt_share((int)chunk_len(&c, c.p.t), &first, &last);
    if (c.shift - 33u < 30u) {
        /* |acc| < 2^40: its high word plus the rounding fits int32 (rt.h
         * rt_rq). */
        for (int i = first; i < last; i++) {
            int64_t acc = (int64_t)(a[i] - c.za) * c.m0 + (int64_t)(bb[i] - c.zb) * c.m1;
            int32_t hi = (int32_t)(acc >> 32);
            int32_t v = (hi + (1 << (c.shift - 33))) >> (c.shift - 32);
            out[i] = (int8_t)rt_clamp(c.zy + v, c.lo, c.hi);
        }
    } else {
        for (int i = first; i < last; i++) {
            int64_t acc = (int64_t)(a[i] - c.za) * c.m0 + (int64_t)(bb[i] - c.zb) * c.m1;
            out[i] = (int8_t)rt_clamp(c.zy + rt_round_shift64(acc, c.shift), c.lo, c.hi);
        }
    }
}

typedef struct {
    const nn_record_t *r; /* REQUANT; NULL: LUT */
    const int8_t *lut;
    int32_t zx, zy, lo, hi;
    int8_t *tab;
} table_job_t;

static void table_entry(void *arg)
{
    const table_job_t *t = arg;
    if (t->r) {
        rt_table_share(t->tab, t->r, t->zx, t->zy, t->lo, t->hi);
        return;
    }
    int first, last;
    rt_share(256, &first, &last);
    for (int k = first; k < last; k++)
        t->tab[k] = (int8_t)rt_clamp(t->lut[k], t->lo, t->hi);
}

static int flat_plan(flat_t *c)
{
    /* Two sets of n_in + 1 arrays of one chunk each; one set when a
     * single chunk of everything fits only once. */
    uint32_t arrays = (uint32_t)c->n_in + 1;
    uint32_t chunk = (nn_l1_tiles_bytes / (2 * arrays)) & ~3u;
    c->p.nbuf = 2;
    if (c->total > chunk && arrays * a4(c->total) <= nn_l1_tiles_bytes) {
        chunk = c->total;
        c->p.nbuf = 1;
    }
    if (chunk == 0)
        return NN_E_L1;
    c->chunk = chunk < c->total ? chunk : c->total;
    c->set_bytes = arrays * a4(c->chunk);
    c->p.n_tiles = (int)((c->total + c->chunk - 1) / c->chunk);
    c->p.load = flat_load;
    c->p.store = flat_store;
    return 0;
}

int rt_map(nn_job_t *j)
{
    const nn_layer_t *l = j->layer;
    const nn_value_t *xv = rt_value(j, l->in[0]), *yv = rt_value(j, l->out);
    flat_t cs = {0}, *c = &cs;
    c->n_in = 1;
    c->total = xv->c * xv->h * xv->w;
    c->in[0] = rt_at(j, xv->off);
    c->out = rt_at(j, yv->off);
    table_job_t t = {NULL, NULL, xv->zp, yv->zp, l->lo, l->hi, nn_l1_scratch};
    if (l->kind == NN_REQUANT)
        t.r = (const nn_record_t *)rt_at(j, l->rq_off);
    else
        t.lut = rt_at(j, l->lut_off);
    pi_cl_team_fork(0, table_entry, &t);
    c->tab = nn_l1_scratch;
    int st = flat_plan(c);
    if (st)
        return st;
    c->p.compute = map_compute;
    rt_pipe_run(&c->p);
    j->dma_bytes += c->p.dma_bytes;
    return 0;
}

int rt_add(nn_job_t *j)
{
    const nn_layer_t *l = j->layer;
    const nn_value_t *av = rt_value(j, l->in[0]), *bv = rt_value(j, l->in[1]);
    const nn_value_t *yv = rt_value(j, l->out);
    const nn_record_t *r = (const nn_record_t *)rt_at(j, l->rq_off);
    flat_t cs = {0}, *c = &cs;
    c->n_in = 2;
    c->total = yv->c * yv->h * yv->w;
    c->in[0] = rt_at(j, av->off);
    c->in[1] = rt_at(j, bv->off);
    c->out = rt_at(j, yv->off);
    c->za = av->zp;
    c->zb = bv->zp;
    c->zy = yv->zp;
    c->lo = l->lo;
    c->hi = l->hi;
    c->m0 = r[0].mult;
    c->m1 = r[1].mult;
    c->shift = r[0].shift;
    int st = flat_plan(c);
    if (st)
        return st;
    c->p.compute = add_compute;
    rt_pipe_run(&c->p);
    j->dma_bytes += c->p.dma_bytes;
    return 0;
}

/* ---- CONCAT ------------------------------------------------------------ */

typedef struct {
    rt_pipe_t p;
    int n_in, C;
    int c_in[NN_MAX_IN];
    const int8_t *in[NN_MAX_IN];
    int8_t *out;
    uint32_t P, tp, set_bytes;
    uint32_t o_in[NN_MAX_IN + 1]; /* the inputs' arrays, then the output's */
} cat_t;

static uint32_t cat_pixels(const cat_t *c, int t)
{
    uint32_t at = (uint32_t)t * c->tp;
    return c->P - at < c->tp ? c->P - at : c->tp;
}

static void cat_load(rt_pipe_t *p, int t, int b)
{
    cat_t *c = (cat_t *)p;
    int8_t *set = nn_l1_tiles + b * c->set_bytes;
    uint32_t n = cat_pixels(c, t);
    for (int i = 0; i < c->n_in; i++)
        rt_load(p, c->in[i] + t * c->tp * c->c_in[i], set + c->o_in[i], n * c->c_in[i]);
}

static void cat_store(rt_pipe_t *p, int t, int b)
{
    cat_t *c = (cat_t *)p;
    int8_t *set = nn_l1_tiles + b * c->set_bytes;
    rt_store(p, c->out + t * c->tp * c->C, set + c->o_in[c->n_in], cat_pixels(c, t) * c->C);
}

static void cat_compute(void *arg)
{
    const cat_t *c = arg;
    const int8_t *set = nn_l1_tiles + c->p.b * c->set_bytes;
    int8_t *out = (int8_t *)set + c->o_in[c->n_in];
    int first, last, C = c->C;
    rt_share((int)cat_pixels(c, c->p.t), &first, &last);
    int off = 0;
    for (int i = 0; i < c->n_in; i++) {
        const int8_t *tab = nn_l1_scratch + 256 * i + 128;
        int ci = c->c_in[i];
        const int8_t *in = set + c->o_in[i] + first * ci;
        for (int px = first; px < last; px++) {
            int8_t *o = out + px * C + off;
            for (int ch = 0; ch < ci; ch++)
                o[ch] = tab[*in++];
        }
        off += ci;
    }
}

typedef struct {
    const nn_job_t *j;
    int32_t zy, lo, hi;
} cat_tables_t;

static void cat_tables(void *arg)
{
    const cat_tables_t *t = arg;
    const nn_layer_t *l = t->j->layer;
    const nn_record_t *r = (const nn_record_t *)rt_at(t->j, l->rq_off);
    for (uint32_t i = 0; i < l->n_in; i++)
        rt_table_share(nn_l1_scratch + 256 * i, &r[i], rt_value(t->j, l->in[i])->zp, t->zy,
                       t->lo, t->hi);
}

int rt_concat(nn_job_t *j)
{
    const nn_layer_t *l = j->layer;
    const nn_value_t *yv = rt_value(j, l->out);
    cat_t cs = {0}, *c = &cs;
    c->n_in = (int)l->n_in;
    c->C = (int)yv->c;
    c->P = yv->h * yv->w;
    c->out = rt_at(j, yv->off);
    for (int i = 0; i < c->n_in; i++) {
        const nn_value_t *v = rt_value(j, l->in[i]);
        c->c_in[i] = (int)v->c;
        c->in[i] = rt_at(j, v->off);
    }
    cat_tables_t t = {j, yv->zp, l->lo, l->hi};
    pi_cl_team_fork(0, cat_tables, &t);
    /* Pixels per tile: two sets of the inputs' and the output's arrays. */
    uint32_t tp = c->P;
    for (;;) {
        uint32_t at = 0;
        for (int i = 0; i < c->n_in; i++) {
            c->o_in[i] = at;
            at += a4(tp * c->c_in[i]);
        }
        c->o_in[c->n_in] = at;
        at += a4(tp * c->C);
        c->set_bytes = at;
        if (2 * at <= nn_l1_tiles_bytes) {
            c->p.nbuf = 2;
            break;
        }
        if (at <= nn_l1_tiles_bytes && tp == c->P) {
            c->p.nbuf = 1;
            break;
        }
        /* Scale down to what fits, then step. */
        uint32_t next = (uint32_t)((uint64_t)tp * nn_l1_tiles_bytes / (2 * at));
        tp = next < tp ? next : tp - 1;
        if (tp == 0)
            return NN_E_L1;
    }
    c->tp = tp;
    c->p.n_tiles = (int)((c->P + tp - 1) / tp);
    c->p.load = cat_load;
    c->p.compute = cat_compute;
    c->p.store = cat_store;
    rt_pipe_run(&c->p);
    j->dma_bytes += c->p.dma_bytes;
    return 0;
}
