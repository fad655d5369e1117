/*
 * Segmentation for the gate detector (docs/VISION.md, "Algorithm", step 1):
 * every row is cut into runs of "gate" pixels (grey within the band), and
 * runs touching between rows (8-connected) are joined by union-find into
 * components: one per frame in view (a frame and its legs are one).
 */
#include "gate_internal.h"

run_t gate_runs[MAX_RUNS];
/* Union-find parent of each run (always a smaller index), then its
 * component label. */
uint16_t gate_run_link[MAX_RUNS];
uint16_t gate_row_start[H + 1];
region_t gate_comps[MAX_COMPONENTS];

/* --- union-find over run indices; the root is the smallest index --- */

static uint32_t uf_find(uint16_t *link, uint32_t i)
{
    while (link[i] != i) {
        link[i] = link[link[i]]; /* path halving */
        i = link[i];
    }
    return i;
}

void gate_uf_union(uint16_t *link, uint32_t a, uint32_t b)
{
    a = uf_find(link, a);
    b = uf_find(link, b);
    if (a < b)
        link[b] = (uint16_t)a;
    else if (b < a)
        link[a] = (uint16_t)b;
}

/* Turns parents into labels 0, 1, ... in order of first run (NONE past
 * `max`); returns the number of labels. Works in place because a parent
 * always precedes its children. */
uint32_t gate_uf_label(uint16_t *link, uint32_t n, uint32_t max)
{
    uint32_t labels = 0;
    for (uint32_t i = 0; i < n; i++) {
        if (link[i] == i)
            link[i] = labels < max ? (uint16_t)labels++ : NONE;
        else
            link[i] = link[link[i]];
    }
    return labels;
}

void gate_region_add(region_t *r, uint32_t x0, uint32_t x1, uint32_t y)
{
    if (r->area == 0) {
        r->x0 = (uint16_t)x0;
        r->x1 = (uint16_t)x1;
        r->y0 = r->y1 = (uint16_t)y;
    } else {
        if (x0 < r->x0)
            r->x0 = (uint16_t)x0;
        if (x1 > r->x1)
            r->x1 = (uint16_t)x1;
        r->y1 = (uint16_t)y; /* rows come in order */
    }
    r->area += x1 - x0 + 1;
}

/* --- 1. segmentation --- */

/* Per byte of w: 0x80 if (byte - lo) mod 256 >= lim, i.e. outside the
 * band, else 0 (lim = 128 - (span + 1), span < 128). SWAR: the byte-wise
 * difference without borrows between bytes (Hacker's Delight 2-18), then
 * a compare by a 7-bit sum that cannot carry into the next byte. */
#define HIGH 0x80808080u
#define LOW7 0x7f7f7f7fu
static inline uint32_t out_of_band(uint32_t w, uint32_t lo7, uint32_t nlo4, uint32_t lim4)
{
    uint32_t d = ((w | HIGH) - lo7) ^ ((w ^ nlo4) & HIGH);
    return (((d & LOW7) + lim4) | d) & HIGH;
}

static uint32_t n_runs_;

/* Appends run [x0, x1]; 0 when the buffer is full. */
static inline int add_run(uint32_t x0, uint32_t x1)
{
    if (n_runs_ == MAX_RUNS)
        return 0;
    gate_runs[n_runs_].x0 = (uint16_t)x0;
    gate_runs[n_runs_].x1 = (uint16_t)x1;
    gate_run_link[n_runs_] = (uint16_t)n_runs_;
    n_runs_++;
    return 1;
}

/* Runs of one row, a pixel at a time (images not 4-byte aligned). */
static int row_runs_bytes(const uint8_t *p, uint8_t lo, uint8_t span)
{
    uint32_t x = 0;
    for (;;) {
        while (x < W && (uint8_t)(p[x] - lo) > span)
            x++;
        if (x == W)
            return 1;
        uint32_t start = x;
        while (x < W && (uint8_t)(p[x] - lo) <= span)
            x++;
        if (!add_run(start, x - 1))
            return 0;
    }
}

/* Runs of one row, four pixels per load: outside a run, a word with no
 * pixel in the band costs one test; inside, a word with all four in it.
 * Only words with an edge are looked at pixel by pixel. This loop is most
 * of the detector's time (docs/VISION.md, "Cycles"). */
static int row_runs_words(const uint32_t *p, uint32_t lo7, uint32_t nlo4, uint32_t lim4)
{
    const uint32_t *end = p + W / 4;
    const uint32_t *row = p;
    uint32_t in_run = 0, start = 0, m = 0;
    for (;;) {
        /* Two words per test (one branch for eight pixels), then one. */
        if (!in_run) {
            while (p + 2 <= end &&
                   (out_of_band(p[0], lo7, nlo4, lim4) & out_of_band(p[1], lo7, nlo4, lim4)) == HIGH)
                p += 2;
            while (p < end && (m = out_of_band(*p, lo7, nlo4, lim4)) == HIGH)
                p++;
        } else {
            while (p + 2 <= end &&
                   (out_of_band(p[0], lo7, nlo4, lim4) | out_of_band(p[1], lo7, nlo4, lim4)) == 0)
                p += 2;
            while (p < end && (m = out_of_band(*p, lo7, nlo4, lim4)) == 0)
                p++;
        }
        if (p == end)
            return in_run ? add_run(start, W - 1) : 1;
        /* An edge in this word: pixel by pixel (little endian: byte k is
         * pixel x + k). */
        uint32_t x = (uint32_t)(p - row) * 4;
        for (uint32_t k = 0; k < 4; k++) {
            uint32_t b = ((m >> (8 * k + 7)) & 1u) ^ 1u;
            if (b == in_run)
                continue;
            in_run = b;
            if (b)
                start = x + k;
            else if (!add_run(start, x + k - 1))
                return 0;
        }
        p++;
    }
}

/* Cuts the image into runs of pixels p with lo <= p <= lo + span.
 * Returns the number of runs; sets GATE_OVERFLOW when they do not fit. */
static uint32_t scan_runs(const uint8_t *image, uint8_t lo, uint8_t span, uint32_t *flags)
{
    uint32_t y;
    /* Word loads need aligned rows (W is a multiple of 4) and a band of at
     * most 128 values. */
    int words = ((uintptr_t)image & 3u) == 0 && span < 128;
    uint32_t lo4 = lo * 0x01010101u, lim4 = (128u - (span + 1u)) * 0x01010101u;
    uint32_t lo7 = lo4 & LOW7, nlo4 = ~lo4;
    n_runs_ = 0;
    for (y = 0; y < H; y++) {
        gate_row_start[y] = (uint16_t)n_runs_;
        const uint8_t *p = image + y * W;
        int ok = words ? row_runs_words((const uint32_t *)(const void *)p, lo7, nlo4, lim4)
                       : row_runs_bytes(p, lo, span);
        if (!ok) {
            *flags |= GATE_OVERFLOW;
            break;
        }
    }
    /* Rows not reached hold no runs. */
    for (y = y < H ? y + 1 : H; y <= H; y++)
        gate_row_start[y] = (uint16_t)n_runs_;
    return n_runs_;
}

/* Joins the runs of consecutive rows that touch, diagonals included. */
static void join_runs(void)
{
    for (uint32_t y = 1; y < H; y++) {
        uint32_t i = gate_row_start[y - 1], i1 = gate_row_start[y];
        uint32_t j = gate_row_start[y], j1 = gate_row_start[y + 1];
        while (i < i1 && j < j1) {
            if (gate_runs[i].x1 + 1 < gate_runs[j].x0) {
                i++;
            } else if (gate_runs[j].x1 + 1 < gate_runs[i].x0) {
                j++;
            } else {
                gate_uf_union(gate_run_link, i, j);
                if (gate_runs[i].x1 < gate_runs[j].x1)
                    i++;
                else
                    j++;
            }
        }
    }
}

uint32_t gate_segment(const uint8_t *image, uint8_t lo, uint8_t span, uint32_t *flags,
                      uint32_t *scan_cycles)
{
    uint32_t t0 = gate_mcycle();
    uint32_t n = scan_runs(image, lo, span, flags);
    *scan_cycles = gate_mcycle() - t0;
    join_runs();
    uint32_t nc = gate_uf_label(gate_run_link, n, MAX_COMPONENTS);
    for (uint32_t c = 0; c < nc; c++)
        gate_comps[c].area = 0;
    for (uint32_t y = 0; y < H; y++)
        for (uint32_t i = gate_row_start[y]; i < gate_row_start[y + 1]; i++)
            if (gate_run_link[i] != NONE)
                gate_region_add(&gate_comps[gate_run_link[i]], gate_runs[i].x0, gate_runs[i].x1, y);
    return nc;
}
