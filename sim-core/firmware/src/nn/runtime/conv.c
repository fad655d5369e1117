/*
 * CONV (regular, grouped, depthwise) and DENSE (a 1x1 convolution of a
 * 1x1 input of `in` channels) through L1, in tiles of output rows x
 * output channels (model.h's plan). A tile's set in L1:
 *   band    its input rows, every column of the windows, the channels of
 *           its groups; pad rows and columns hold the input's zero point
 *           (the biases have it folded in: the sum runs over raw inputs);
 *   weights its channels' [kh][kw][cin/groups] bytes (the fast kernel's
 *           rows padded to whole words, the spare bytes zero);
 *   bias, records, output (HWC, the tile's channels).
 * Three kernels: the fast one (groups 1, or every tile inside one group),
 * 2 output pixels x 4 channels per item with cv.sdotsp.b (PULP-NN's 4x2
 * register blocking, Garofalo et al. 2020, §4) over whole window rows,
 * which are contiguous in the HWC band and in the weights; the depthwise
 * 3x3 one, a channel's output row per item; the generic one, a pixel x
 * channel item over the taps (words when cin/groups allows).
 */
#include "rt.h"

#include "../../xcv.h"

typedef struct {
    const int8_t *band;
    int band_row, pix, ystep;
    const int8_t *w;
    int wch, row_w, kh, kw, skip;
    int nch, cin_g, cout_g, oc0, ci0, words;
    const int32_t *bias;
    const nn_record_t *rec;
    int8_t *out;
    int n, P, Wo;
    int32_t zy, lo, hi;
} kargs_t;

typedef struct {
    rt_pipe_t p;
    nn_job_t *j;
    int H, W, cin, Ho, Wo, kh, kw, sh, sw, pt, pl, groups, cin_g, cout_g, cout;
    int BW;
    int32_t zx, zy, lo, hi;
    const int8_t *x;
    int8_t *y;
    const int8_t *w;
    const int32_t *bias;
    const nn_record_t *rec;
    int oc_begin, noc;
    int toh, toc, n_r, n_c, rows_inner;
    int per, row_b, row_w, wch, fast, nch_max, dw3x3;
    uint32_t o_w, o_b, o_r, o_out, set_bytes;
    int in_key[2], w_key[2], w_repack[2];
    kargs_t k;
} conv_t;

typedef struct {
    int oy0, r, oc0, n, ci0, nch;
} ctile_t;

static void tile_at(const conv_t *c, int t, ctile_t *ti)
{
    int ri, ci;
    if (c->rows_inner) {
        ci = t / c->n_r;
        ri = t - ci * c->n_r;
    } else {
        ri = t / c->n_c;
        ci = t - ri * c->n_c;
    }
    ti->oy0 = ri * c->toh;
    ti->r = c->Ho - ti->oy0 < c->toh ? c->Ho - ti->oy0 : c->toh;
    ti->oc0 = c->oc_begin + ci * c->toc;
    int end = c->oc_begin + c->noc;
    ti->n = end - ti->oc0 < c->toc ? end - ti->oc0 : c->toc;
    if (c->groups == 1) {
        ti->ci0 = 0;
        ti->nch = c->cin;
    } else {
        int g0 = ti->oc0 / c->cout_g, g1 = (ti->oc0 + ti->n - 1) / c->cout_g;
        ti->ci0 = g0 * c->cin_g;
        ti->nch = (g1 - g0 + 1) * c->cin_g;
    }
}

/* For tiles of toc channels: the most band channels a tile takes, and
 * whether every tile lies in one group (the fast kernel's condition). */
static void channel_plan(conv_t *c, int toc, int *nch_max, int *one_group)
{
    if (c->groups == 1) {
        *nch_max = c->cin;
        *one_group = 1;
        return;
    }
    int m = 0, one = 1, end = c->oc_begin + c->noc;
    for (int oc0 = c->oc_begin; oc0 < end; oc0 += toc) {
        int n = end - oc0 < toc ? end - oc0 : toc;
        int g0 = oc0 / c->cout_g, g1 = (oc0 + n - 1) / c->cout_g;
        int nch = (g1 - g0 + 1) * c->cin_g;
        m = nch > m ? nch : m;
        one &= g0 == g1;
    }
    *nch_max = m;
    *one_group = one;
}

/* Lays out one set for tiles of toh x toc; returns its bytes. */
static uint32_t layout(conv_t *c, int toh, int toc)
{
    int one;
    channel_plan(c, toc, &c->nch_max, &one);
    c->fast = one;
    /* Depthwise 3x3 over several groups: conv_dw3x3. */
    c->dw3x3 = !one && c->cin_g == 1 && c->cout_g == 1 && c->kh == 3 && c->kw == 3;
    c->row_w = (c->row_b + 3) / 4;
    c->wch = c->fast ? c->kh * c->row_w * 4 : c->per;
    uint32_t rows_in = (uint32_t)((toh - 1) * c->sh + c->kh);
    uint32_t band = a4(rows_in * c->BW * c->nch_max);
    c->o_w = band;
    c->o_b = c->o_w + a4((uint32_t)(toc * c->wch));
    c->o_r = c->o_b + 4u * toc;
    c->o_out = c->o_r + 8u * toc;
    return c->o_out + a4((uint32_t)(toh * c->Wo * toc));
}

static int8_t *set_base(const conv_t *c, int b) { return nn_l1_tiles + b * c->set_bytes; }

static void conv_load(rt_pipe_t *p, int t, int b)
{
    conv_t *c = (conv_t *)p;
    ctile_t ti;
    tile_at(c, t, &ti);
    int8_t *set = set_base(c, b);
    int in_key = ti.oy0 * 65536 + ti.ci0;
    if (c->in_key[b] != in_key) {
        c->in_key[b] = in_key;
        int rows_in = (ti.r - 1) * c->sh + c->kh;
        int iy0 = ti.oy0 * c->sh - c->pt;
        int nch = ti.nch, bwn = c->BW * nch;
        int xs = c->BW - c->pl < c->W ? c->BW - c->pl : c->W;
        int right = c->BW - c->pl - xs;
        int8_t zx = (int8_t)c->zx;
        /* Rows of every column in one command when the band is the
         * input's own rows (no pad column, no column dropped). */
        int whole = c->pl == 0 && right == 0 && xs == c->W;
        int run = -1; /* first data row of a run not yet queued */
        for (int jr = 0; jr <= rows_in; jr++) {
            int iy = iy0 + jr;
            int data = jr < rows_in && iy >= 0 && iy < c->H;
            if (whole) {
                if (data && run < 0)
                    run = jr;
                if (!data && run >= 0) {
                    int y0 = iy0 + run;
                    rt_load_2d(p, c->x + (y0 * c->W) * c->cin + ti.ci0, set + run * bwn,
                               (uint32_t)((jr - run) * bwn), (uint32_t)c->cin, (uint32_t)nch);
                    run = -1;
                }
            }
            if (jr == rows_in)
                break;
            int8_t *dst = set + jr * bwn;
            if (!data) {
                rt_fill(dst, zx, (uint32_t)bwn);
                continue;
            }
            if (whole)
                continue;
            if (c->pl)
                rt_fill(dst, zx, (uint32_t)(c->pl * nch));
            if (right)
                rt_fill(dst + (c->pl + xs) * nch, zx, (uint32_t)(right * nch));
            rt_load_2d(p, c->x + (iy * c->W) * c->cin + ti.ci0, dst + c->pl * nch,
                       (uint32_t)(xs * nch), (uint32_t)c->cin, (uint32_t)nch);
        }
    }
    if (c->w_key[b] != ti.oc0) {
        c->w_key[b] = ti.oc0;
        rt_load(p, c->w + (ti.oc0 - c->oc_begin) * c->per, set + c->o_w, (uint32_t)(ti.n * c->per));
        rt_load(p, c->bias + ti.oc0, set + c->o_b, 4u * ti.n);
        rt_load(p, c->rec + ti.oc0, set + c->o_r, 8u * ti.n);
        c->w_repack[b] = c->fast && c->wch != c->per;
    }
}

/* The fast kernel's weight rows padded to whole words, in place from the
 * last row back (a row's new place is never below its old one). */
static void conv_ready(rt_pipe_t *p, int t, int b)
{
    conv_t *c = (conv_t *)p;
    if (!c->w_repack[b])
        return;
    c->w_repack[b] = 0;
    ctile_t ti;
    tile_at(c, t, &ti);
    int8_t *w = set_base(c, b) + c->o_w;
    int rb = c->row_b, rw = c->row_w * 4;
    for (int row = ti.n * c->kh - 1; row >= 0; row--) {
        int8_t *src = w + row * rb, *dst = w + row * rw;
        for (int k = rw - 1; k >= rb; k--)
            dst[k] = 0;
        for (int k = rb - 1; k >= 0; k--)
            dst[k] = src[k];
    }
}

static void conv_store(rt_pipe_t *p, int t, int b)
{
    conv_t *c = (conv_t *)p;
    ctile_t ti;
    tile_at(c, t, &ti);
    int8_t *out = set_base(c, b) + c->o_out;
    rt_store_2d(p, c->y + ti.oy0 * c->Wo * c->cout + ti.oc0, out,
                (uint32_t)(ti.r * c->Wo * ti.n), (uint32_t)c->cout, (uint32_t)ti.n);
}

/* ---- The fast kernel ---------------------------------------------------- */

#define STEP_2x4()                                                             \
    do {                                                                       \
        uint32_t v0 = xcv_lw_inc(x0, 4), v1 = xcv_lw_inc(x1, 4);               \
        uint32_t q0 = xcv_lw_inc(k0, 4), q1 = xcv_lw_inc(k1, 4);               \
        uint32_t q2 = xcv_lw_inc(k2, 4), q3 = xcv_lw_inc(k3, 4);               \
        a0 = xcv_sdotsp_b(a0, v0, q0);                                         \
        a1 = xcv_sdotsp_b(a1, v0, q1);                                         \
        a2 = xcv_sdotsp_b(a2, v0, q2);                                         \
        a3 = xcv_sdotsp_b(a3, v0, q3);                                         \
        a4_ = xcv_sdotsp_b(a4_, v1, q0);                                       \
        a5 = xcv_sdotsp_b(a5, v1, q1);                                         \
        a6 = xcv_sdotsp_b(a6, v1, q2);                                         \
        a7 = xcv_sdotsp_b(a7, v1, q3);                                         \
    } while (0)

#define STEP_1x4()                                                             \
    do {                                                                       \
        uint32_t v0 = xcv_lw_inc(x0, 4);                                       \
        uint32_t q0 = xcv_lw_inc(k0, 4), q1 = xcv_lw_inc(k1, 4);               \
        uint32_t q2 = xcv_lw_inc(k2, 4), q3 = xcv_lw_inc(k3, 4);               \
        a0 = xcv_sdotsp_b(a0, v0, q0);                                         \
        a1 = xcv_sdotsp_b(a1, v0, q1);                                         \
        a2 = xcv_sdotsp_b(a2, v0, q2);                                         \
        a3 = xcv_sdotsp_b(a3, v0, q3);                                         \
    } while (0)

static inline void put(const kargs_t *k, int pix, int ch, int32_t acc)
{
    k->out[pix * k->n + ch] = (int8_t)rt_out(acc + k->bias[ch], &k->rec[ch], k->zy, k->lo, k->hi);
}

/* Channel ch of two pixels (the second only if has1): the channel's bias
 * and record read once, both outputs computed before either is stored. */
static inline void put2(const kargs_t *k, int p0, int has1, int ch, int32_t a, int32_t b)
{
    const int32_t bias = k->bias[ch];
    const nn_record_t r = k->rec[ch];
    int32_t va, vb;
    if (r.shift - 33u < 30u) {
        int32_t rnd = 1 << (r.shift - 33), sh = (int32_t)r.shift - 32;
        va = ((int32_t)(((int64_t)(a + bias) * r.mult) >> 32) + rnd) >> sh;
        vb = ((int32_t)(((int64_t)(b + bias) * r.mult) >> 32) + rnd) >> sh;
    } else {
        va = rt_rq_slow(a + bias, r.mult, r.shift);
        vb = rt_rq_slow(b + bias, r.mult, r.shift);
    }
    va = rt_clamp(k->zy + va, k->lo, k->hi);
    vb = rt_clamp(k->zy + vb, k->lo, k->hi);
    k->out[p0 * k->n + ch] = (int8_t)va;
    if (has1)
        k->out[(p0 + 1) * k->n + ch] = (int8_t)vb;
}

/* Items run channel quad by channel quad (item = quad * pairs + pair), so
 * a core's range walks the pixel pairs of one quad at a time: the quad's
 * weight rows, biases and records are set up once per run instead of
 * once per item. Requantization is most of a 1x1 layer's work when its
 * input has few channels (32 channels: 8 dot products per output, beside
 * the 64-bit product, rounding, clamp and store), so the records are
 * decoded here, once per quad, into the high word's shift s = shift - 32
 * and one constant added before it: the rounding term plus the output
 * zero point shifted up, as (h + r) >> s plus zp equals (h + r + zp *
 * 2^s) >> s while the sum stays in int32 (|h| < 2^30, rt_rq; s <= 22
 * keeps |zp * 2^s| <= 2^29). Other records take put2. */
static void fast_2x4(const kargs_t *k, int first, int last)
{
    const int pairs = (k->P + 1) / 2;
    int quad = first / pairs, pair = first - quad * pairs;
    const int rw = k->row_w, kh = k->kh, skip = k->skip, last_c = k->n - 1;
    const int32_t zy = k->zy, lo = k->lo, hi = k->hi;
    const int n = k->n;
    int it = first;
    while (it < last) {
        const int c = 4 * quad;
        int stop = it + (pairs - pair);
        stop = stop < last ? stop : last;
        const int8_t *w = k->w;
        const uint32_t *w0 = (const uint32_t *)(w + c * k->wch);
        const uint32_t *w1 = (const uint32_t *)(w + (c + 1 > last_c ? last_c : c + 1) * k->wch);
        const uint32_t *w2 = (const uint32_t *)(w + (c + 2 > last_c ? last_c : c + 2) * k->wch);
        const uint32_t *w3 = (const uint32_t *)(w + (c + 3 > last_c ? last_c : c + 3) * k->wch);
        /* The quad's records when all four take rt_rq's one-mulh form
         * with s in 1..22. */
        int quick = c + 3 <= last_c;
        int32_t bs[4], ml[4], rn[4], sh[4];
        for (int j = 0; j < 4 && quick; j++) {
            const nn_record_t r = k->rec[c + j];
            quick = r.shift - 33u < 22u;
            bs[j] = k->bias[c + j];
            ml[j] = r.mult;
            sh[j] = (int32_t)r.shift - 32;
            rn[j] = quick ? (1 << (sh[j] - 1)) + (int32_t)((uint32_t)zy << sh[j]) : 0;
        }
        int y = 2 * pair / k->Wo, x = 2 * pair - y * k->Wo;
        for (; it < stop; it++) {
            int p0 = 2 * pair, has1 = p0 + 1 < k->P;
            int i0 = y * k->ystep + x * k->pix;
            int i1 = x + 1 < k->Wo ? i0 + k->pix : (y + 1) * k->ystep;
            if (!has1)
                i1 = i0;
            const uint32_t *k0 = w0, *k1 = w1, *k2 = w2, *k3 = w3;
            const uint32_t *x0 = (const uint32_t *)(k->band + i0);
            const uint32_t *x1 = (const uint32_t *)(k->band + i1);
            int32_t a0 = 0, a1 = 0, a2 = 0, a3 = 0, a4_ = 0, a5 = 0, a6 = 0, a7 = 0;
            for (int ky = 0; ky < kh; ky++) {
                if ((rw & 3) == 0) {
                    for (int i = rw >> 2; i > 0; i--) {
                        STEP_2x4();
                        STEP_2x4();
                        STEP_2x4();
                        STEP_2x4();
                    }
                } else {
                    if (rw & 1)
                        STEP_2x4();
                    for (int i = rw >> 1; i > 0; i--) {
                        STEP_2x4();
                        STEP_2x4();
                    }
                }
                x0 = (const uint32_t *)((const int8_t *)x0 + skip);
                x1 = (const uint32_t *)((const int8_t *)x1 + skip);
            }
            if (quick && has1) {
                int8_t *o = k->out + p0 * n + c;
#define RQ(acc, j) rt_clamp(((int32_t)(((int64_t)((acc) + bs[j]) * ml[j]) >> 32) + rn[j]) >> sh[j], lo, hi)
                o[0] = (int8_t)RQ(a0, 0);
                o[1] = (int8_t)RQ(a1, 1);
                o[2] = (int8_t)RQ(a2, 2);
                o[3] = (int8_t)RQ(a3, 3);
                o += n;
                o[0] = (int8_t)RQ(a4_, 0);
                o[1] = (int8_t)RQ(a5, 1);
                o[2] = (int8_t)RQ(a6, 2);
                o[3] = (int8_t)RQ(a7, 3);
#undef RQ
            } else {
                put2(k, p0, has1, c, a0, a4_);
                if (c + 1 <= last_c)
                    put2(k, p0, has1, c + 1, a1, a5);
                if (c + 2 <= last_c)
                    put2(k, p0, has1, c + 2, a2, a6);
                if (c + 3 <= last_c)
                    put2(k, p0, has1, c + 3, a3, a7);
            }
            pair++;
            x += 2;
            if (x >= k->Wo) {
                x -= k->Wo;
                y++;
            }
        }
        quad++;
        pair = 0;
    }
}

/* One output pixel (DENSE, or a 1x1 output): items are channel quads. */
static void fast_1x4(const kargs_t *k, int first, int last)
{
    const int rw = k->row_w, kh = k->kh, skip = k->skip, last_c = k->n - 1;
    for (int quad = first; quad < last; quad++) {
        int c = 4 * quad;
        const int8_t *w = k->w;
        const uint32_t *k0 = (const uint32_t *)(w + c * k->wch);
        const uint32_t *k1 = (const uint32_t *)(w + (c + 1 > last_c ? last_c : c + 1) * k->wch);
        const uint32_t *k2 = (const uint32_t *)(w + (c + 2 > last_c ? last_c : c + 2) * k->wch);
        const uint32_t *k3 = (const uint32_t *)(w + (c + 3 > last_c ? last_c : c + 3) * k->wch);
        const uint32_t *x0 = (const uint32_t *)k->band;
        int32_t a0 = 0, a1 = 0, a2 = 0, a3 = 0;
        for (int ky = 0; ky < kh; ky++) {
            if (rw & 1)
                STEP_1x4();
            for (int i = rw >> 1; i > 0; i--) {
                STEP_1x4();
                STEP_1x4();
            }
            x0 = (const uint32_t *)((const int8_t *)x0 + skip);
        }
        put(k, 0, c, a0);
        if (c + 1 <= last_c)
            put(k, 0, c + 1, a1);
        if (c + 2 <= last_c)
            put(k, 0, c + 2, a2);
        if (c + 3 <= last_c)
            put(k, 0, c + 3, a3);
    }
}

static void conv_fast(void *arg)
{
    const kargs_t k = ((const conv_t *)arg)->k;
    int first, last;
    if (k.P == 1) {
        rt_share((k.n + 3) / 4, &first, &last);
        fast_1x4(&k, first, last);
    } else {
        rt_share((k.P + 1) / 2 * ((k.n + 3) / 4), &first, &last);
        fast_2x4(&k, first, last);
    }
}

/* ---- The generic kernel ------------------------------------------------- */

static void conv_generic(void *arg)
{
    const kargs_t k = ((const conv_t *)arg)->k;
    int first, last;
    rt_share(k.P * k.n, &first, &last);
    if (first >= last)
        return;
    int pix = first / k.n, ch = first - pix * k.n;
    int y = pix / k.Wo, x = pix - y * k.Wo;
    const int per = k.kh * k.kw * k.cin_g;
    /* Channel ch's group, walked without dividing: its input channels'
     * offset in the band and its place within the group. */
    const int g0 = k.oc0 / k.cout_g, r0 = k.oc0 - g0 * k.cout_g;
    const int choff0 = g0 * k.cin_g - k.ci0;
    int oc = k.oc0 + ch, g = oc / k.cout_g;
    int gpos = oc - g * k.cout_g, choff = g * k.cin_g - k.ci0;
    const int8_t *base = k.band + y * k.ystep + x * k.pix;
    for (int it = first; it < last; it++) {
        const int8_t *wp = k.w + ch * per;
        const int8_t *in = base + choff;
        int32_t acc = 0;
        if (k.cin_g == 1) {
            /* Depthwise: one input channel, a tap per byte. */
            for (int ky = 0; ky < k.kh; ky++) {
                const int8_t *ip = in + ky * k.band_row;
                for (int kx = 0; kx < k.kw; kx++, ip += k.nch)
                    acc += *ip * *wp++;
            }
        } else {
            for (int ky = 0; ky < k.kh; ky++) {
                const int8_t *ip = in + ky * k.band_row;
                for (int kx = 0; kx < k.kw; kx++, ip += k.nch) {
                    if (k.words) {
                        const uint32_t *iw = (const uint32_t *)ip, *ww = (const uint32_t *)wp;
                        for (int i = k.cin_g >> 2; i > 0; i--)
                            acc = xcv_sdotsp_b(acc, *iw++, *ww++);
                        wp += k.cin_g;
                    } else {
                        for (int i = 0; i < k.cin_g; i++)
                            acc += ip[i] * *wp++;
                    }
                }
            }
        }
        put(&k, pix, ch, acc);
        if (++gpos == k.cout_g) {
            gpos = 0;
            choff += k.cin_g;
        }
        if (++ch == k.n) {
            ch = 0;
            gpos = r0;
            choff = choff0;
            pix++;
            if (++x == k.Wo) {
                x = 0;
                y++;
                base = k.band + y * k.ystep;
            } else
                base += k.pix;
        }
    }
}

/* A depthwise 3x3 layer (one input channel per output channel): an item
 * is one output row of one channel, so the channel's nine weights, bias
 * and record stay in registers along the row; each tap a load and a
 * cv.mac. */
/* A signed byte load that advances the pointer by a register. */
#define LB_INC(p, inc)                                                         \
    ({                                                                         \
        int32_t lb_v_;                                                         \
        __asm__ volatile("cv.lb %0, (%1), %2" : "=r"(lb_v_), "+r"(p) : "r"(inc) : "memory"); \
        lb_v_;                                                                 \
    })

static void conv_dw3x3(void *arg)
{
    const kargs_t k = ((const conv_t *)arg)->k;
    const int rows = k.P / k.Wo;
    int first, last;
    rt_share(k.n * rows, &first, &last);
    if (first >= last)
        return;
    int ch = first / rows, y = first - ch * rows;
    const int br = k.band_row, nch = k.nch, pix = k.pix;
    for (int it = first; it < last; it++) {
        const int8_t *w = k.w + 9 * ch;
        const int32_t w0 = w[0], w1 = w[1], w2 = w[2], w3 = w[3], w4 = w[4], w5 = w[5];
        const int32_t w6 = w[6], w7 = w[7], w8 = w[8];
        const int32_t bias = k.bias[ch];
        const nn_record_t rec = k.rec[ch];
        const int8_t *r0 = k.band + y * k.ystep + (k.oc0 + ch - k.ci0);
        int8_t *o = k.out + y * k.Wo * k.n + ch;
        /* One pointer walks the window: two steps of a pixel (nch) along
         * a row, then down to the next row's start (jump), with
         * post-increment loads (cv.lb rd, (rs1), rs2). */
        const int jump = br - 2 * nch;
        for (int x = k.Wo; x > 0; x--) {
            const int8_t *q = r0;
            int32_t acc = bias;
            acc = xcv_mac(acc, LB_INC(q, nch), w0);
            acc = xcv_mac(acc, LB_INC(q, nch), w1);
            acc = xcv_mac(acc, LB_INC(q, jump), w2);
            acc = xcv_mac(acc, LB_INC(q, nch), w3);
            acc = xcv_mac(acc, LB_INC(q, nch), w4);
            acc = xcv_mac(acc, LB_INC(q, jump), w5);
            acc = xcv_mac(acc, LB_INC(q, nch), w6);
            acc = xcv_mac(acc, LB_INC(q, nch), w7);
            acc = xcv_mac(acc, *q, w8);
            *o = (int8_t)rt_out(acc, &rec, k.zy, k.lo, k.hi);
            o += k.n;
            r0 += pix;
        }
        if (++y == rows) {
            y = 0;
            ch++;
        }
    }
}

/* Core 0 before the fork: the tile's kernel arguments. */
static void conv_compute_args(conv_t *c, int t, int b)
{
    ctile_t ti;
    tile_at(c, t, &ti);
    int8_t *set = set_base(c, b);
    kargs_t *k = &c->k;
    k->band = set;
    k->band_row = c->BW * ti.nch;
    k->pix = c->sw * ti.nch;
    k->ystep = c->sh * k->band_row;
    k->w = set + c->o_w;
    k->wch = c->wch;
    k->row_w = c->row_w;
    k->kh = c->kh;
    k->kw = c->kw;
    k->skip = k->band_row - 4 * c->row_w;
    k->nch = ti.nch;
    k->cin_g = c->cin_g;
    k->cout_g = c->cout_g;
    k->oc0 = ti.oc0;
    k->ci0 = ti.ci0;
    k->words = (c->cin_g & 3) == 0;
    k->bias = (const int32_t *)(set + c->o_b);
    k->rec = (const nn_record_t *)(set + c->o_r);
    k->out = set + c->o_out;
    k->n = ti.n;
    k->P = ti.r * c->Wo;
    k->Wo = c->Wo;
    k->zy = c->zy;
    k->lo = c->lo;
    k->hi = c->hi;
}

static void conv_compute(void *arg)
{
    conv_t *c = arg;
    if (c->fast)
        conv_fast(arg);
    else if (c->dw3x3)
        conv_dw3x3(arg);
    else
        conv_generic(arg);
}

/* The pipeline's compute hook runs on every core: core 0 fills the tile's
 * arguments in its `ready` step instead (below). */
static void conv_ready_args(rt_pipe_t *p, int t, int b)
{
    conv_ready(p, t, b);
    conv_compute_args((conv_t *)p, t, b);
}

int rt_conv(nn_job_t *j)
{
    const nn_layer_t *l = j->layer;
    const nn_value_t *xv = rt_value(j, l->in[0]), *yv = rt_value(j, l->out);
    /* On core 0's stack, in L1: the team copies the tile's kargs from it. */
    conv_t cs = {0};
    conv_t *c = &cs;
    c->j = j;
    if (l->kind == NN_DENSE) {
        c->H = c->W = 1;
        c->cin = (int)(xv->c * xv->h * xv->w);
        c->Ho = c->Wo = 1;
        c->kh = c->kw = c->sh = c->sw = 1;
        c->groups = 1;
        c->cout = (int)(yv->c * yv->h * yv->w);
    } else {
        c->H = (int)xv->h;
        c->W = (int)xv->w;
        c->cin = (int)xv->c;
        c->Ho = (int)yv->h;
        c->Wo = (int)yv->w;
        c->kh = (int)l->kh;
        c->kw = (int)l->kw;
        c->sh = (int)l->sh;
        c->sw = (int)l->sw;
        c->pt = (int)l->pt;
        c->pl = (int)l->pl;
        c->groups = (int)l->groups;
        c->cout = (int)yv->c;
    }
    c->cin_g = c->cin / c->groups;
    c->cout_g = c->cout / c->groups;
    c->BW = (c->Wo - 1) * c->sw + c->kw;
    c->zx = xv->zp;
    c->zy = yv->zp;
    c->lo = l->lo;
    c->hi = l->hi;
    c->x = rt_at(j, xv->off);
    c->y = rt_at(j, yv->off);
    c->w = j->w;
    c->bias = (const int32_t *)rt_at(j, l->b_off);
    c->rec = (const nn_record_t *)rt_at(j, l->rq_off);
    c->oc_begin = (int)j->oc_begin;
    c->noc = (int)(j->oc_end - j->oc_begin);
    c->per = c->kh * c->kw * c->cin_g;
    c->row_b = c->kw * c->cin_g;
    if (c->noc <= 0)
        return 0;

    /* The host's tile, shrunk if this L1 holds less than it planned. */
    int toh0 = l->kind == NN_DENSE ? 1 : (int)l->tile_oh;
    int toc = (int)l->tile_oc;
    toh0 = toh0 < 1 || toh0 > c->Ho ? c->Ho : toh0;
    toc = toc < 1 || toc > c->noc ? c->noc : toc;
    int toh = toh0;
    uint32_t avail = nn_l1_tiles_bytes;
    for (;;) {
        uint32_t set = layout(c, toh, toc);
        int tiles = ((c->Ho + toh - 1) / toh) * ((c->noc + toc - 1) / toc);
        if (2 * set <= avail) {
            c->p.nbuf = 2;
            c->set_bytes = set;
            break;
        }
        if (set <= avail && tiles == 1) {
            c->p.nbuf = 1;
            c->set_bytes = set;
            break;
        }
        if (toh > 1)
            toh--;
        else if (toc > 1) {
            toc = toc > 4 ? ((toc / 2 + 3) & ~3) : toc - 1;
            toh = toh0;
        } else
            return NN_E_L1;
    }
    c->toh = toh;
    c->toc = toc;
    c->n_r = (c->Ho + toh - 1) / toh;
    c->n_c = (c->noc + toc - 1) / toc;
    /* Rows inside channel chunks keeps a chunk's weights in L1 across its
     * row tiles; channel chunks inside rows keeps the band. The order that
     * moves fewer bytes: the weights once plus the input n_c times, or the
     * input once plus the weights n_r times. */
    uint32_t in_bytes = (uint32_t)(c->H * c->W * c->cin), w_bytes = (uint32_t)(c->noc * c->per);
    c->rows_inner = (uint64_t)in_bytes * c->n_c + w_bytes <= (uint64_t)w_bytes * c->n_r + in_bytes;
    c->in_key[0] = c->in_key[1] = -1;
    c->w_key[0] = c->w_key[1] = -1;
    c->p.n_tiles = c->n_r * c->n_c;
    c->p.load = conv_load;
    c->p.ready = conv_ready_args;
    c->p.compute = conv_compute;
    c->p.store = conv_store;
    rt_pipe_run(&c->p);
    j->dma_bytes += c->p.dma_bytes;
    return 0;
}
