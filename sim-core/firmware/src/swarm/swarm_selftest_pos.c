/*
 * Self-test of the positioning half (seed 003 §5.3.2, §6.8, §7.3): the
 * coordinate system on known triangles and tetrahedra, the Kalman filter's
 * convergence and §7.3's drift, and the cost of the soft-float arithmetic.
 */
#include <math.h>
#include <string.h>

#include "selftest_util.h"
#include "swarm.h"

static void vsub(float *o, const float *a, const float *b)
{
    for (int k = 0; k < 3; k++)
        o[k] = a[k] - b[k];
}
static float vdot(const float *a, const float *b)
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static float vdist(const float *a, const float *b)
{
    float d[3];
    vsub(d, a, b);
    return sqrtf(vdot(d, d));
}

/* Expected coordinates of q in the seed's frame of p[0..3], by
 * Gram-Schmidt (independent of coords.c's formulas). */
static void seed_frame(const float p[][3], int planar, const float *q, float *out)
{
    float ex[3], ey[3], ez[3], v[3];
    vsub(ex, p[1], p[0]);
    float n = sqrtf(vdot(ex, ex));
    for (int k = 0; k < 3; k++)
        ex[k] /= n;
    vsub(v, p[2], p[0]);
    float d = vdot(v, ex);
    for (int k = 0; k < 3; k++)
        ey[k] = v[k] - d * ex[k];
    n = sqrtf(vdot(ey, ey));
    for (int k = 0; k < 3; k++)
        ey[k] /= n;
    ez[0] = ex[1] * ey[2] - ex[2] * ey[1];
    ez[1] = ex[2] * ey[0] - ex[0] * ey[2];
    ez[2] = ex[0] * ey[1] - ex[1] * ey[0];
    if (!planar) {
        vsub(v, p[3], p[0]);
        if (vdot(v, ez) < 0.0f)
            for (int k = 0; k < 3; k++)
                ez[k] = -ez[k];
    }
    vsub(v, q, p[0]);
    out[0] = vdot(v, ex);
    out[1] = vdot(v, ey);
    out[2] = vdot(v, ez);
}

static float err3(const swarm_vec3_t *a, const float *b)
{
    float d[3] = {a->x - b[0], a->y - b[1], a->z - b[2]};
    return sqrtf(vdot(d, d));
}

/* Frame and trilateration of five points, 3D or planar; returns the worst
 * error in metres. */
static float frame_case(const float p[5][3], int planar)
{
    float d[5][5];
    for (int i = 0; i < 5; i++)
        for (int j = 0; j < 5; j++)
            d[i][j] = vdist(p[i], p[j]);
    swarm_vec3_t f[5];
    f[0] = (swarm_vec3_t){0, 0, 0};
    int rc = swarm_frame_p2(d[0][1], &f[1]);
    rc |= swarm_frame_p3(d[0][1], d[0][2], d[1][2], &f[2]);
    int n = 3;
    if (!planar) {
        rc |= swarm_frame_p4(d[0][1], &f[2], d[0][3], d[1][3], d[2][3], &f[3]);
        n = 4;
    }
    CHECK(rc == SWARM_COORDS_OK, "frame status %d", rc);
    float dist[4] = {d[4][0], d[4][1], d[4][2], d[4][3]};
    rc = swarm_trilaterate(f, dist, n, planar, &f[4]);
    CHECK(rc == SWARM_COORDS_OK, "trilateration status %d", rc);
    float worst = 0.0f;
    for (int i = 0; i < 5; i++) {
        if (planar && i == 3)
            continue;
        float want[3];
        seed_frame(p, planar, p[i], want);
        float e = err3(&f[i], want);
        worst = e > worst ? e : worst;
    }
    /* The conventions themselves. */
    CHECK(f[1].x > 0 && f[1].y == 0 && f[1].z == 0, "P2 on +X");
    CHECK(f[2].y >= 0 && f[2].z == 0, "P3 in XY, +Y");
    CHECK(planar || f[3].z >= 0, "P4 on +Z");
    return worst;
}

static void coords(void)
{
    /* The 3-4-5 triangle. */
    swarm_vec3_t p;
    CHECK(swarm_frame_p3(3, 4, 5, &p) == 0 && fabsf(p.x) < 1e-6f && fabsf(p.y - 4) < 1e-6f,
          "3-4-5: P3 = (%d, %d) mm", (int)(p.x * 1000), (int)(p.y * 1000));
    /* The regular tetrahedron of edge 2: P4 = (1, 1/√3, √(8/3)). */
    swarm_vec3_t p3, p4;
    swarm_frame_p3(2, 2, 2, &p3);
    CHECK(swarm_frame_p4(2, &p3, 2, 2, 2, &p4) == 0 && fabsf(p4.x - 1) < 1e-5f &&
              fabsf(p4.y - 0.577350269f) < 1e-5f && fabsf(p4.z - 1.632993162f) < 1e-5f,
          "regular tetrahedron");
    /* Degenerate and inconsistent inputs. */
    CHECK(swarm_frame_p2(0, &p) == SWARM_COORDS_DEGENERATE, "coincident P1 P2");
    swarm_frame_p3(2, 1, 1, &p3); /* P3 on the X axis */
    CHECK(swarm_frame_p4(2, &p3, 1, 1, 1, &p4) == SWARM_COORDS_DEGENERATE, "collinear P1 P2 P3");
    CHECK(swarm_frame_p3(1, 1, 3, &p) == SWARM_COORDS_INCONSISTENT, "triangle inequality");
    swarm_vec3_t four[4] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}};
    float d4[4] = {1, 1, 1, 1};
    CHECK(swarm_trilaterate(four, d4, 4, 0, &p) == SWARM_COORDS_DEGENERATE, "coplanar references");

    /* Random tetrahedra (+ a fifth point) in a 10 m room, and triangles
     * on a table. */
    swarm_prng_t r;
    swarm_prng_seed(&r, 532);
    float worst3 = 0, worst2 = 0;
    int cases = 0;
    for (int c = 0; c < 200; c++) {
        int planar = c & 1;
        float pts[5][3];
        for (int i = 0; i < 5; i++)
            for (int k = 0; k < 3; k++)
                pts[i][k] = (planar && k == 2) ? 0.0f : (float)swarm_prng_below(&r, 10000) * 1e-3f;
        /* Skip nearly degenerate draws: the frame needs a real triangle
         * and (3D) a real tetrahedron. */
        float a[3], b[3], cr[3], v[3];
        vsub(a, pts[1], pts[0]);
        vsub(b, pts[2], pts[0]);
        cr[0] = a[1] * b[2] - a[2] * b[1];
        cr[1] = a[2] * b[0] - a[0] * b[2];
        cr[2] = a[0] * b[1] - a[1] * b[0];
        float area = sqrtf(vdot(cr, cr));
        vsub(v, pts[3], pts[0]);
        float vol = fabsf(vdot(cr, v));
        if (area < 4.0f || (!planar && vol < 8.0f))
            continue;
        float w = frame_case(pts, planar);
        if (planar)
            worst2 = w > worst2 ? w : worst2;
        else
            worst3 = w > worst3 ? w : worst3;
        cases++;
    }
    printf("coords: %d frames, worst error 3D %d um, planar %d um\n", cases,
           (int)(worst3 * 1e6f), (int)(worst2 * 1e6f));
    CHECK(cases > 100, "enough frames: %d", cases);
    CHECK(worst3 < 2e-3f && worst2 < 2e-3f, "frames within 2 mm");
}

/* ---- the Kalman filter -------------------------------------------------- */

static void kalman_converges(void)
{
    swarm_settings_t set;
    swarm_default_settings(&set);
    static const float anchor[4][3] = {{0, 0, 0}, {4, 0, 0}, {1, 3, 0}, {2, 1, 2.5f}};
    static const float truth[3] = {2.2f, 1.4f, 1.1f};
    swarm_kf_t kf;
    swarm_vec3_t zero = {0, 0, 0};
    /* §6.8.3: start at (0, 0, 0) with the maximum σ. */
    swarm_kf_init(&kf, &zero, set.init_std, set.init_std, 0);
    swarm_prng_t r;
    swarm_prng_seed(&r, 68);
    int stable_after = -1;
    for (int k = 0; k < 400; k++) {
        int a = k % 4;
        swarm_vec3_t from = {anchor[a][0], anchor[a][1], anchor[a][2]};
        float d = vdist(anchor[a], truth) + 0.05f * st_gauss(&r);
        swarm_kf_advance(&kf, (uint32_t)(k + 1) * 2500, &set.kf);
        swarm_kf_update_distance(&kf, &from, d, set.meas_std, &set.kf);
        if (stable_after < 0 && swarm_kf_is_stable(&kf, set.stable_std))
            stable_after = k + 1;
    }
    swarm_vec3_t p = swarm_kf_position(&kf);
    float e = err3(&p, truth);
    printf("kalman: from (0,0,0) σ=100 m: stable after %d distances, error %d mm\n", stable_after,
           (int)(e * 1000));
    CHECK(stable_after >= 4, "not stable before enough distances (%d)", stable_after);
    CHECK(stable_after > 0 && stable_after < 40, "stable after a few rounds (%d)", stable_after);
    CHECK(e < 0.05f, "converges within 5 cm (%d mm)", (int)(e * 1000));
}

/* §7.3: two drones in 1D, each placed from the other. */
typedef struct {
    float drift, spread, dist_err;
} mutual_t;

static mutual_t mutual_1d(float sigma, int prediction, uint64_t seed)
{
    swarm_settings_t set;
    swarm_default_settings(&set);
    set.meas_std = sigma;
    set.kf.prediction = (uint8_t)prediction;
    const float truth = 1.0f, noise = 0.03f;
    swarm_prng_t r;
    swarm_prng_seed(&r, seed);
    swarm_kf_t a, b;
    swarm_vec3_t zero = {0, 0, 0};
    swarm_kf_init(&a, &zero, set.init_std, set.init_std, 0);
    swarm_kf_init(&b, &zero, set.init_std, set.init_std, 0);
    uint32_t t = 0;
    /* Section A-B: A is the origin (arbitrary values) and B is placed from
     * it until both are stable. */
    for (int k = 0; k < 200; k++) {
        t += 10000;
        swarm_kf_advance(&a, t, &set.kf);
        for (int axis = 0; axis < 3; axis++)
            swarm_kf_update_axis(&a, axis, 0, set.pseudo_std, &set.kf);
        swarm_kf_advance(&b, t, &set.kf);
        swarm_vec3_t pa = swarm_kf_position(&a);
        swarm_kf_update_distance(&b, &pa, truth + noise * st_gauss(&r), sigma, &set.kf);
        swarm_kf_update_axis(&b, 1, 0, set.pseudo_std, &set.kf);
        swarm_kf_update_axis(&b, 2, 0, set.pseudo_std, &set.kf);
        if (b.x[0] < 0)
            swarm_kf_mirror(&b, 0);
    }
    /* Section C: 20 s at 100 packets/s, each placed from the other. */
    float m0 = 0.5f * (a.x[0] + b.x[0]);
    mutual_t out = {0, 0, 0};
    float sum = 0, sum2 = 0, derr = 0;
    int n = 0;
    for (int k = 0; k < 2000; k++) {
        t += 10000;
        swarm_kf_t *self = (k & 1) ? &a : &b, *other = (k & 1) ? &b : &a;
        swarm_kf_advance(self, t, &set.kf);
        swarm_vec3_t po = swarm_kf_position(other);
        swarm_kf_update_distance(self, &po, truth + noise * st_gauss(&r), sigma, &set.kf);
        swarm_kf_update_axis(self, 1, 0, set.pseudo_std, &set.kf);
        swarm_kf_update_axis(self, 2, 0, set.pseudo_std, &set.kf);
        float m = 0.5f * (a.x[0] + b.x[0]);
        if (fabsf(m - m0) > out.drift)
            out.drift = fabsf(m - m0);
        if (k >= 1000) {
            sum += a.x[0];
            sum2 += a.x[0] * a.x[0];
            derr += fabsf(b.x[0] - a.x[0]) - truth;
            n++;
        }
    }
    float mean = sum / (float)n;
    out.spread = sqrtf(fmaxf(sum2 / (float)n - mean * mean, 0.0f));
    out.dist_err = derr / (float)n;
    return out;
}

static void kalman_drift(void)
{
    mutual_t s25 = mutual_1d(0.25f, 0, 73), s0 = mutual_1d(0.0f, 0, 73),
             p25 = mutual_1d(0.25f, 1, 73);
    printf("§7.3 1D pair, 20 s, ranging noise 3 cm: drift of the pair / std of A / mean "
           "distance error (mm): σ=0.25 %d/%d/%d, σ=0 %d/%d/%d, σ=0.25 with prediction "
           "%d/%d/%d\n",
           (int)(s25.drift * 1000), (int)(s25.spread * 1000), (int)(s25.dist_err * 1000),
           (int)(s0.drift * 1000), (int)(s0.spread * 1000), (int)(s0.dist_err * 1000),
           (int)(p25.drift * 1000), (int)(p25.spread * 1000), (int)(p25.dist_err * 1000));
    CHECK(s25.drift < 0.1f, "σ=0.25: the pair stays put");
    CHECK(fabsf(s25.dist_err) < 0.01f, "σ=0.25: distance within 1 cm");
    CHECK(s0.drift > 5.0f * s25.drift, "σ=0: the pair drifts (§7.3, Figure 7.4)");
    CHECK(s0.spread > 3.0f * s25.spread, "σ=0: positions move up and down");
}

/* ---- costs -------------------------------------------------------------- */

#define COST_LOOP(name, n, body)                                                           \
    do {                                                                                   \
        uint64_t c0_ = st_cycles();                                                        \
        for (int i_ = 0; i_ < (n); i_++) {                                                 \
            body;                                                                          \
        }                                                                                  \
        uint64_t c1_ = st_cycles();                                                        \
        printf("cycles %s: mean %lu\n", name, (unsigned long)((c1_ - c0_) / (n)));         \
    } while (0)

static void costs(void)
{
    volatile float fa = 1.2345f, fb = 0.98765f, fr;
    volatile double da = 1.2345, db = 0.98765, dr;
    volatile int64_t ia = 1234567890123LL, ib = 987654321LL, ir;
    volatile int32_t xa = 123456, xb = 789, xr;
    COST_LOOP("empty loop + volatile loads/stores", 1000, xr = xa + xb);
    COST_LOOP("float add (soft)", 1000, fr = fa + fb);
    COST_LOOP("float mul (soft)", 1000, fr = fa * fb);
    COST_LOOP("float div (soft)", 1000, fr = fa / fb);
    COST_LOOP("sqrtf (soft)", 1000, fr = sqrtf(fa));
    COST_LOOP("double mul (soft)", 1000, dr = da * db);
    COST_LOOP("double div (soft)", 1000, dr = da / db);
    COST_LOOP("int64 mul", 1000, ir = ia * ib);
    COST_LOOP("int64 div", 1000, ir = ia / ib);
    (void)fr;
    (void)dr;
    (void)ir;
    (void)xr;

    volatile uint64_t lt = 123456789, lr = 123456789 + 20000000, rt;
    volatile uint32_t rrx = 5555, rtx = 5555 + 12000000;
    int32_t tof;
    volatile int64_t delta = 20 * (((int64_t)1 << 40) / 1000000);
    COST_LOOP("eq. 5.11 swarm_exchange_tof", 1000,
              swarm_exchange_tof(lt, rrx, rtx, lr, delta, 0, &tof));
    int64_t cand;
    COST_LOOP("swarm_clock_candidate", 1000, swarm_clock_candidate(lr, lr - 37, &cand));
    (void)rt;

    swarm_settings_t set;
    swarm_default_settings(&set);
    swarm_kf_t kf;
    swarm_vec3_t p0 = {0.1f, 0.2f, 0.3f}, from = {2, 1, 0.5f};
    swarm_kf_init(&kf, &p0, 1, 1, 0);
    uint32_t t = 0;
    COST_LOOP("kalman update (distance)", 200,
              swarm_kf_update_distance(&kf, &from, 2.0f, 0.25f, &set.kf));
    COST_LOOP("kalman update (axis)", 200, swarm_kf_update_axis(&kf, 2, 0.0f, 0.01f, &set.kf));
    COST_LOOP("kalman covariance correction", 200, swarm_kf_advance(&kf, t += 10000, &set.kf));
    set.kf.prediction = 1;
    COST_LOOP("kalman prediction + correction", 200, swarm_kf_advance(&kf, t += 10000, &set.kf));
    swarm_vec3_t p3, p4;
    COST_LOOP("frame P3 + P4", 200,
              (swarm_frame_p3(2, 2, 2, &p3), swarm_frame_p4(2, &p3, 2, 2, 2, &p4)));
    swarm_vec3_t refs[16];
    float dist[16];
    for (int i = 0; i < 16; i++) {
        refs[i] = (swarm_vec3_t){(float)(i % 4), (float)(i / 4), (float)((i * 7) % 5) * 0.5f};
        dist[i] = 2.0f + 0.1f * (float)i;
    }
    COST_LOOP("trilateration from 16 points", 100, swarm_trilaterate(refs, dist, 16, 0, &p4));
}

void coords_and_kalman_tests(void)
{
    coords();
    kalman_converges();
    kalman_drift();
    costs();
}
