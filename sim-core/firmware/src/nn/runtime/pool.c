/*
 * MAXPOOL and AVGPOOL in bands of output rows (all channels), and GAP in
 * bands of input rows. Taps outside the input are skipped, as the
 * reference does (scenarios/src/nn/onnx/reference.rs `pool`): a band holds
 * only the input's own rows and columns, no pad.
 */
#include "rt.h"

typedef struct {
    rt_pipe_t p;
    int H, W, C, Ho, Wo, kh, kw, sh, sw, pt, pl;
    int toh, avg, count_pad, records;
    int32_t zx, zy, lo, hi;
    const int8_t *x;
    int8_t *y;
    const nn_record_t *rec; /* AVGPOOL records, copied to the scratch */
    const int8_t *tab;      /* MAXPOOL: the requantization as a table */
    uint32_t o_out, set_bytes;
} pool_t;

static void band_rows(const pool_t *c, int t, int *oy0, int *r, int *iy0, int *iy1)
{
    *oy0 = t * c->toh;
    *r = c->Ho - *oy0 < c->toh ? c->Ho - *oy0 : c->toh;
    int a = *oy0 * c->sh - c->pt, b = (*oy0 + *r - 1) * c->sh - c->pt + c->kh;
    *iy0 = a < 0 ? 0 : a;
    *iy1 = b > c->H ? c->H : b;
}

static void pool_load(rt_pipe_t *p, int t, int b)
{
    pool_t *c = (pool_t *)p;
    int oy0, r, iy0, iy1;
    band_rows(c, t, &oy0, &r, &iy0, &iy1);
    if (iy1 > iy0)
        rt_load(p, c->x + iy0 * c->W * c->C, nn_l1_tiles + b * c->set_bytes,
                (uint32_t)((iy1 - iy0) * c->W * c->C));
}

static void pool_store(rt_pipe_t *p, int t, int b)
{
    pool_t *c = (pool_t *)p;
    int oy0, r, iy0, iy1;
    band_rows(c, t, &oy0, &r, &iy0, &iy1);
    rt_store(p, c->y + oy0 * c->Wo * c->C, nn_l1_tiles + b * c->set_bytes + c->o_out,
             (uint32_t)(r * c->Wo * c->C));
}

static void pool_compute(void *arg)
{
    const pool_t c = *(const pool_t *)arg;
    int oy0, r, iy0, iy1;
    band_rows(&c, c.p.t, &oy0, &r, &iy0, &iy1);
    const int8_t *band = nn_l1_tiles + c.p.b * c.set_bytes;
    int8_t *out = (int8_t *)band + c.o_out;
    int first, last;
    rt_share(r * c.Wo, &first, &last);
    const int row = c.W * c.C;
    for (int pix = first; pix < last; pix++) {
        int oy = oy0 + pix / c.Wo, ox = pix % c.Wo;
        int ya = oy * c.sh - c.pt, xa = ox * c.sw - c.pl;
        int y0 = ya < 0 ? 0 : ya, y1 = ya + c.kh > c.H ? c.H : ya + c.kh;
        int x0 = xa < 0 ? 0 : xa, x1 = xa + c.kw > c.W ? c.W : xa + c.kw;
        int count = (y1 - y0) * (x1 - x0);
        const int8_t *win = band + (y0 - iy0) * row + x0 * c.C;
        int8_t *o = out + pix * c.C;
        /* The window's taps inside the input, as offsets from its first. */
        int taps[16], nt = 0;
        if (count <= 16)
            for (int y = 0; y < y1 - y0; y++)
                for (int x = 0; x < x1 - x0; x++)
                    taps[nt++] = y * row + x * c.C;
        if (!c.avg) {
            for (int ch = 0; ch < c.C; ch++) {
                int32_t m = -128;
                const int8_t *q = win + ch;
                if (count <= 16) {
                    for (int k = 0; k < nt; k++) {
                        int32_t v = q[taps[k]];
                        m = v > m ? v : m;
                    }
                } else {
                    for (int y = y0; y < y1; y++, q += row)
                        for (int x = 0; x < x1 - x0; x++) {
                            int32_t v = q[x * c.C];
                            m = v > m ? v : m;
                        }
                }
                o[ch] = count ? c.tab[m + 128] : c.tab[c.zx + 128];
            }
            continue;
        }
        int n = c.count_pad ? c.kh * c.kw : count;
        nn_record_t rec = c.records ? c.rec[n] : (nn_record_t){0, 0};
        for (int ch = 0; ch < c.C; ch++) {
            int32_t s = 0;
            const int8_t *q = win + ch;
            if (count <= 16) {
                for (int k = 0; k < nt; k++)
                    s += q[taps[k]];
            } else {
                for (int y = y0; y < y1; y++, q += row)
                    for (int x = 0; x < x1 - x0; x++)
                        s += q[x * c.C];
            }
            s -= count * c.zx;
            int32_t v = c.records ? rt_rq(s, rec.mult, rec.shift) : n ? rt_div_rhe(s, n) : 0;
            o[ch] = (int8_t)rt_clamp(c.zy + v, c.lo, c.hi);
        }
    }
}

typedef struct {
    const nn_record_t *r;
    int32_t zx, zy, lo, hi;
} table_job_t;

static void table_entry(void *arg)
{
    const table_job_t *t = arg;
    rt_table_share(nn_l1_scratch, t->r, t->zx, t->zy, t->lo, t->hi);
}

int rt_pool(nn_job_t *j)
{
    const nn_layer_t *l = j->layer;
    const nn_value_t *xv = rt_value(j, l->in[0]), *yv = rt_value(j, l->out);
    pool_t cs = {0}, *c = &cs;
    c->H = (int)xv->h;
    c->W = (int)xv->w;
    c->C = (int)xv->c;
    c->Ho = (int)yv->h;
    c->Wo = (int)yv->w;
    c->kh = (int)l->kh;
    c->kw = (int)l->kw;
    c->sh = (int)l->sh;
    c->sw = (int)l->sw;
    c->pt = (int)l->pt;
    c->pl = (int)l->pl;
    c->avg = l->kind == NN_AVGPOOL;
    c->count_pad = (l->flags & NN_F_COUNT_PAD) != 0;
    c->records = (l->flags & NN_F_POOL_RECORDS) != 0;
    c->zx = xv->zp;
    c->zy = yv->zp;
    c->lo = l->lo;
    c->hi = l->hi;
    c->x = rt_at(j, xv->off);
    c->y = rt_at(j, yv->off);
    if (c->avg) {
        if (c->records) {
            uint32_t n = (l->kh * l->kw + 1) * sizeof(nn_record_t);
            const nn_record_t *src = (const nn_record_t *)rt_at(j, l->rq_off);
            if (n <= NN_SCRATCH_BYTES) {
                nn_record_t *dst = (nn_record_t *)nn_l1_scratch;
                for (uint32_t i = 0; i < l->kh * l->kw + 1; i++)
                    dst[i] = src[i];
                c->rec = dst;
            } else
                c->rec = src;
        }
    } else {
        table_job_t t = {(const nn_record_t *)rt_at(j, l->rq_off), c->zx, c->zy, c->lo, c->hi};
        pi_cl_team_fork(0, table_entry, &t);
        c->tab = nn_l1_scratch;
    }
    int toh0 = (int)l->tile_oh, toh;
    toh0 = toh0 < 1 || toh0 > c->Ho ? c->Ho : toh0;
    for (toh = toh0;; toh--) {
        if (toh < 1)
            return NN_E_L1;
        uint32_t band = a4((uint32_t)(((toh - 1) * c->sh + c->kh) * c->W * c->C));
        uint32_t set = band + a4((uint32_t)(toh * c->Wo * c->C));
        int tiles = (c->Ho + toh - 1) / toh;
        c->o_out = band;
        c->set_bytes = set;
        if (2 * set <= nn_l1_tiles_bytes) {
            c->p.nbuf = 2;
            break;
        }
        if (set <= nn_l1_tiles_bytes && tiles == 1) {
            c->p.nbuf = 1;
            break;
        }
    }
    c->toh = toh;
    c->p.n_tiles = (c->Ho + toh - 1) / toh;
    c->p.load = pool_load;
    c->p.compute = pool_compute;
    c->p.store = pool_store;
    rt_pipe_run(&c->p);
    j->dma_bytes += c->p.dma_bytes;
    return 0;
}

/* ---- GAP --------------------------------------------------------------- */

typedef struct {
    rt_pipe_t p;
    int H, W, C, toh, records;
    int32_t zx, zy, lo, hi;
    nn_record_t rec;
    const int8_t *x;
    int8_t *y;
    int32_t *sums; /* L1, before the sets */
    int8_t *out;
    int8_t *sets;
    uint32_t set_bytes;
} gap_t;

static void gap_load(rt_pipe_t *p, int t, int b)
{
    gap_t *c = (gap_t *)p;
    int y0 = t * c->toh, r = c->H - y0 < c->toh ? c->H - y0 : c->toh;
    rt_load(p, c->x + y0 * c->W * c->C, c->sets + b * c->set_bytes, (uint32_t)(r * c->W * c->C));
}

static void gap_store(rt_pipe_t *p, int t, int b)
{
    (void)b;
    gap_t *c = (gap_t *)p;
    if (t == p->n_tiles - 1)
        rt_store(p, c->y, c->out, (uint32_t)c->C);
}

static void gap_compute(void *arg)
{
    const gap_t *c = arg;
    int t = c->p.t, y0 = t * c->toh, r = c->H - y0 < c->toh ? c->H - y0 : c->toh;
    const int8_t *band = c->sets + c->p.b * c->set_bytes;
    int first, last, C = c->C, n = r * c->W;
    rt_share(C, &first, &last);
    for (int ch = first; ch < last; ch++) {
        int32_t s = 0;
        const int8_t *q = band + ch;
        for (int i = 0; i < n; i++, q += C)
            s += *q;
        s -= n * c->zx;
        s += t == 0 ? 0 : c->sums[ch];
        c->sums[ch] = s;
        if (t == c->p.n_tiles - 1) {
            int32_t v = c->records ? rt_rq(s, c->rec.mult, c->rec.shift)
                                   : rt_div_rhe(s, c->H * c->W);
            c->out[ch] = (int8_t)rt_clamp(c->zy + v, c->lo, c->hi);
        }
    }
}

int rt_gap(nn_job_t *j)
{
    const nn_layer_t *l = j->layer;
    const nn_value_t *xv = rt_value(j, l->in[0]), *yv = rt_value(j, l->out);
    gap_t cs = {0}, *c = &cs;
    c->H = (int)xv->h;
    c->W = (int)xv->w;
    c->C = (int)xv->c;
    c->records = (l->flags & NN_F_POOL_RECORDS) != 0;
    if (c->records)
        c->rec = *(const nn_record_t *)rt_at(j, l->rq_off);
    c->zx = xv->zp;
    c->zy = yv->zp;
    c->lo = l->lo;
    c->hi = l->hi;
    c->x = rt_at(j, xv->off);
    c->y = rt_at(j, yv->off);
    uint32_t fixed = 4u * c->C + a4((uint32_t)c->C);
    if (fixed >= nn_l1_tiles_bytes)
        return NN_E_L1;
    c->sums = (int32_t *)nn_l1_tiles;
    c->out = nn_l1_tiles + 4 * c->C;
    c->sets = nn_l1_tiles + fixed;
    uint32_t avail = nn_l1_tiles_bytes - fixed;
    int toh0 = (int)l->tile_oh, toh;
    toh0 = toh0 < 1 || toh0 > c->H ? c->H : toh0;
    for (toh = toh0;; toh--) {
        if (toh < 1)
            return NN_E_L1;
        c->set_bytes = a4((uint32_t)(toh * c->W * c->C));
        if (2 * c->set_bytes <= avail) {
            c->p.nbuf = 2;
            break;
        }
        if (c->set_bytes <= avail && toh == c->H) {
            c->p.nbuf = 1;
            break;
        }
    }
    c->toh = toh;
    c->p.n_tiles = (c->H + toh - 1) / toh;
    c->p.load = gap_load;
    c->p.compute = gap_compute;
    c->p.store = gap_store;
    rt_pipe_run(&c->p);
    j->dma_bytes += c->p.dma_bytes;
    return 0;
}
