/*
 * Unit checks of the fixed-point helpers, the settings, the inverse sensor
 * model and the map export. The sensor-model cases are worked out by hand
 * in the comments (cell 50 mm, the drone at a cell centre).
 */
#include <string.h>

#include "../explore.h"
#include "../fixmath.h"
#include "../grid.h"
#include "selftest.h"

static og_grid g;

/* A grid of w x h cells of cell_mm from (0, 0). */
static void grid(int32_t w, int32_t h, uint16_t cell_mm, uint16_t fov_cdeg)
{
    explore_settings s;
    explore_default_settings(&s);
    s.x_min_mm = 0;
    s.y_min_mm = 0;
    s.x_max_mm = w * cell_mm;
    s.y_max_mm = h * cell_mm;
    s.cell_mm = cell_mm;
    s.fov_cdeg = fov_cdeg;
    char msg[160];
    int rc = og_init(&g, &s, msg, sizeof msg);
    CHECK(rc == EXPLORE_OK && g.w == w && g.h == h, "grid %ldx%ld: %s", (long)w, (long)h, msg);
}

/* Compares the grid's classes with a picture: rows from the top (largest
 * y) down, '.' unknown, 'f' free, 'X' occupied. */
static void expect_picture(const char *name, const char *const *rows)
{
    int bad = 0;
    for (int32_t r = 0; r < g.h; r++) {
        int32_t iy = g.h - 1 - r;
        for (int32_t ix = 0; ix < g.w; ix++) {
            char want = rows[r][ix];
            int c = og_class(og_get(&g, ix, iy));
            char got = c == OG_FREE ? 'f' : c == OG_OCC ? 'X' : '.';
            if (got != want && bad++ < 8)
                printf("  %s: cell (%ld, %ld) is '%c', want '%c'\n", name, (long)ix, (long)iy, got,
                       want);
        }
    }
    CHECK(bad == 0, "%s: %d cells differ from the picture", name, bad);
}

void test_fixmath(void)
{
    CHECK_EQ("sin 0", fx_sin(0), 0);
    CHECK_EQ("sin 90", fx_sin(16384), 16384);
    CHECK_EQ("sin 45", fx_sin(8192), 11585); /* 16384 / sqrt 2 = 11585.2 */
    CHECK_EQ("sin 180", fx_sin(32768), 0);
    CHECK_EQ("sin 270", fx_sin(49152), -16384);
    CHECK_EQ("cos 0", fx_cos(0), 16384);
    CHECK_EQ("cos 180", fx_cos(32768), -16384);
    /* sin 30° = 8192 exactly; the interpolation error stays below 2/16384. */
    CHECK(fx_abs(fx_sin(5461) - 8192) <= 2, "sin 30: %ld", (long)fx_sin(5461));
    /* 1571 mrad * 65536 / (2 pi 1000) = 16386.2 */
    CHECK_EQ("mrad 1571 -> bam", fx_mrad_to_bam(1571), 16386);
    CHECK_EQ("mrad -1571 -> bam", fx_mrad_to_bam(-1571), 65536 - 16386);
    CHECK_EQ("bam 16384 -> mrad", fx_bam_to_mrad(16384), 1571);
    CHECK_EQ("bam 49152 -> mrad", fx_bam_to_mrad(49152), -1571);
    CHECK_EQ("cdeg 9000 -> bam", fx_cdeg_to_bam(9000), 16384);
    CHECK_EQ("isqrt 0", fx_isqrt(0), 0);
    CHECK_EQ("isqrt 15", fx_isqrt(15), 3);
    CHECK_EQ("isqrt 16", fx_isqrt(16), 4);
    CHECK_EQ("isqrt max", fx_isqrt(0xffffffffu), 65535);
    CHECK_EQ("mrad diff across pi", fx_mrad_diff(3100, -3100), -83);
    CHECK_EQ("mrad diff small", fx_mrad_diff(-100, 100), -200);
}

void test_settings(void)
{
    explore_settings s;
    explore_default_settings(&s);
    CHECK_EQ("default settings", explore_init(&s), EXPLORE_OK);
    /* 8 x 8 m at 2 cm: 400 x 400 cells, beyond the 160 x 160 budget. */
    s.cell_mm = 20;
    CHECK_EQ("8 m at 2 cm", explore_init(&s), EXPLORE_E_BUDGET);
    CHECK(strstr(explore_last_error(), "400 x 400 = 160000 cells exceeds the budget of 25600") !=
              NULL,
          "budget message: %s", explore_last_error());
    s.cell_mm = 5;
    CHECK_EQ("cell 5 mm", explore_init(&s), EXPLORE_E_CELL);
    explore_default_settings(&s);
    s.x_max_mm = s.x_min_mm;
    CHECK_EQ("empty area", explore_init(&s), EXPLORE_E_BOUNDS);
    explore_default_settings(&s);
    s.fov_cdeg = 9100;
    CHECK_EQ("FOV 91 deg", explore_init(&s), EXPLORE_E_FOV);
    explore_default_settings(&s);
    s.l_free = 3;
    CHECK_EQ("positive l_free", explore_init(&s), EXPLORE_E_LOGODDS);
    explore_default_settings(&s);
    s.speed_mm_s = 0;
    CHECK_EQ("zero speed", explore_init(&s), EXPLORE_E_MOTION);
    /* A failed init lands whatever comes in. */
    explore_input in = {0};
    explore_output out;
    explore_step(&in, &out);
    CHECK(out.cmd == EXPLORE_CMD_LAND && out.state == EXPLORE_ST_ERROR, "failed init: cmd %d",
          out.cmd);
}

void test_sensor_model(void)
{
    /* 4°: the drone at the centre of cell (2, 5) = (125, 275) mm, looking
     * along +x, hit at 400 mm. On its row (across 0) the cell k to the
     * right is at r = 50k: free while r <= 400 - 25 (k = 1..7), occupied
     * for 375 < r <= 425 (k = 8), unknown beyond. The next rows (across
     * 50 mm) would need along * tan 2° + 25 >= 50, along >= 716 mm: none. */
    /* clang-format off: one row of the picture per line */
    static const char *const beam4[10] = {
        "....................", "....................", "....................",
        "....................", "...fffffffX.........", "....................",
        "....................", "....................", "....................",
        "....................",
    };
    /* clang-format on */
    grid(20, 10, 50, 400);
    int n = og_update_beam(&g, 125, 275, 0, 400, 3000);
    CHECK_EQ("4 deg beam: cells updated", n, 8);
    expect_picture("4 deg beam", beam4);
    CHECK_EQ("4 deg beam: free log-odds", og_get(&g, 3, 5), -10);
    CHECK_EQ("4 deg beam: hit log-odds", og_get(&g, 10, 5), 10);

    /* 20°: tan 10° = 0.176. The rows at across 50 mm join when
     * along * 0.176 + 25 >= 50, along >= 142 mm: k = 3 on; r = 50
     * sqrt(k^2 + 1) is free up to k = 7 (354 mm), occupied at k = 8
     * (403 mm). Rows at 100 mm would need along >= 425 mm: beyond reach. */
    /* clang-format off: one row of the picture per line */
    static const char *const beam20[10] = {
        "....................", "....................", "....................",
        ".....fffffX.........", "...fffffffX.........", ".....fffffX.........",
        "....................", "....................", "....................",
        "....................",
    };
    /* clang-format on */
    grid(20, 10, 50, 2000);
    n = og_update_beam(&g, 125, 275, 0, 400, 3000);
    CHECK_EQ("20 deg beam: cells updated", n, 8 + 2 * 6);
    expect_picture("20 deg beam", beam20);

    /* No hit (range >= max 300 mm): free up to r <= 300 (k = 1..6), no
     * obstacle anywhere. */
    /* clang-format off: one row of the picture per line */
    static const char *const maxr[10] = {
        "....................", "....................", "....................",
        "....................", "...ffffff...........", "....................",
        "....................", "....................", "....................",
        "....................",
    };
    /* clang-format on */
    grid(20, 10, 50, 400);
    n = og_update_beam(&g, 125, 275, 0, 65535, 300);
    CHECK_EQ("max-range beam: cells updated", n, 6);
    expect_picture("max-range beam", maxr);

    /* No reading (0): nothing changes. */
    CHECK_EQ("range 0", og_update_beam(&g, 125, 275, 0, 0, 300), 0);

    /* 45°, 4°, from the centre of cell (1, 1), hit at 500 mm. Diagonal cell
     * (1+k, 1+k) is at r = 70.7k: free for k <= 6, occupied at k = 7
     * (495 mm). Its neighbours (2+k, 1+k) and (1+k, 2+k) are 35.4 mm
     * across at along 35.4 (2k + 1): inside once along * tan 2° + 25 >=
     * 35.4, along >= 297 mm, k >= 4; free up to k = 6 (461 mm); k = 7 is
     * at 531 mm, past the band's 525 mm. */
    /* clang-format off: one row of the picture per line */
    static const char *const diag[12] = {
        "............", "............", "............", ".......fX...",
        "......fff...", ".....fff....", ".....ff.....", "....f.......",
        "...f........", "..f.........", "............", "............",
    };
    /* clang-format on */
    grid(12, 12, 50, 400);
    n = og_update_beam(&g, 75, 75, 8192, 500, 3000);
    CHECK_EQ("diagonal beam: cells updated", n, 13);
    expect_picture("diagonal beam", diag);

    /* A whole sample: yaw 90° (front looks +y, left looks -x), front hit at
     * 200 mm (3 free, 1 occupied), left hit at 240 mm (4 free, then the hit
     * in (5, 10)), back no reading, right nothing within the max 250 mm (5
     * free), from the centre of cell (10, 10). Plus the drone's own cell,
     * free. */
    grid(21, 21, 50, 400);
    explore_input in = {.t_ms = 0, .x_mm = 525, .y_mm = 525, .z_mm = 300, .yaw_mrad = 1571};
    in.range_mm[EXPLORE_FRONT] = 200;
    in.range_mm[EXPLORE_LEFT] = 240;
    in.range_mm[EXPLORE_BACK] = 0;
    in.range_mm[EXPLORE_RIGHT] = 4000;
    in.max_range_mm = 250;
    n = og_update(&g, &in);
    CHECK_EQ("sample: cells updated", n, 4 + 5 + 5 + 1);
    CHECK(og_class(og_get(&g, 10, 14)) == OG_OCC && og_class(og_get(&g, 10, 13)) == OG_FREE,
          "sample: front hit at (10, 14)");
    CHECK(og_class(og_get(&g, 5, 10)) == OG_OCC && og_class(og_get(&g, 6, 10)) == OG_FREE,
          "sample: left hit at (5, 10)");
    CHECK(og_class(og_get(&g, 15, 10)) == OG_FREE && og_class(og_get(&g, 16, 10)) == OG_UNKNOWN,
          "sample: right free to 250 mm");
    CHECK(og_class(og_get(&g, 10, 9)) == OG_UNKNOWN, "sample: no reading behind");
    CHECK_EQ("sample: own cell", og_get(&g, 10, 10), -10);

    /* Accumulation and clamping: 15 observations stop at the clamps. */
    for (int i = 0; i < 14; i++)
        og_update(&g, &in);
    CHECK_EQ("clamped at l_min", og_get(&g, 10, 10), -32);
    CHECK_EQ("hit accumulates, clamped at l_max", og_get(&g, 10, 14), 56);
}

void test_export(void)
{
    const uint8_t check[] = "123456789";
    CHECK_EQ("crc32 check value", og_crc32(check, 9), 0xcbf43926u);
    grid(4, 3, 80, 500);
    g.x0_mm = -160; /* as a run with the origin off the corner would have */
    g.y0_mm = 40;
    og_set(&g, 0, 0, -7);
    og_set(&g, 3, 2, 100);
    uint32_t len;
    const uint8_t *p = og_export(&g, &len);
    CHECK_EQ("export length", len, 32 + 12);
    CHECK(memcmp(p, "CFOG", 4) == 0, "export magic");
    CHECK_EQ("export version", p[4] | p[5] << 8, 1);
    CHECK_EQ("export header length", p[6] | p[7] << 8, 32);
    CHECK_EQ("export width", p[8] | p[9] << 8, 4);
    CHECK_EQ("export height", p[10] | p[11] << 8, 3);
    CHECK_EQ("export cell", p[12] | p[13] << 8, 80);
    CHECK_EQ("export fov", p[14] | p[15] << 8, 500);
    CHECK_EQ("export origin x", (int32_t)(p[16] | p[17] << 8 | p[18] << 16 | (uint32_t)p[19] << 24),
             -160);
    CHECK_EQ("export origin y", (int32_t)(p[20] | p[21] << 8 | p[22] << 16 | (uint32_t)p[23] << 24),
             40);
    CHECK_EQ("export scale", p[24], 16);
    CHECK_EQ("export l_min", (int8_t)p[25], -32);
    CHECK_EQ("export l_max", (int8_t)p[26], 56);
    CHECK_EQ("export cell (0,0)", (int8_t)p[32], -7);
    CHECK_EQ("export cell (3,2)", (int8_t)p[32 + 11], 100);
    uint32_t crc = p[28] | p[29] << 8 | p[30] << 16 | (uint32_t)p[31] << 24;
    CHECK_EQ("export crc", crc, og_crc32(p + 32, 12));
}
