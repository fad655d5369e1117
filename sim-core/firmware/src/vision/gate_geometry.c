/*
 * The camera model of the gate detector (docs/VISION.md, "Camera model"):
 * pixel -> bearing, apparent size -> distance, camera frame -> body frame.
 * Integer arithmetic only (RV32IMC has no FPU).
 *
 * The pinhole of world-server/src/camera.rs (DESIGN.md §5): focal length
 * f = 160 / tan(0.87 / 2) = 344.318 px for the 320-pixel width; the camera
 * sits at (0.03, 0, 0.01) m in the body and looks along body +x; image x
 * grows to the body's right (-y), image y downwards (-z).
 */
#include "gate_detect.h"

/* atan(2^-i) in microradians, i = 0..19, for CORDIC. */
static const int32_t atan_table_urad[20] = {
    785398, 463648, 244979, 124355, 62419, 31240, 15624, 7812, 3906, 1953,
    977,    488,    244,    122,    61,    31,    15,    8,    4,    2,
};

int32_t gate_atan2_mrad(int32_t y, int32_t x)
{
    /* CORDIC in vectoring mode: rotate (x, y) onto the x axis by +-atan(2^-i)
     * steps and add up the angles. The vector grows by 1.647 (the CORDIC
     * gain), so it is first scaled to 2^24 at most: room for the gain, and
     * enough bits that y >> 19 still carries information. */
    if (x <= 0)
        return 0; /* only used in front of the camera */
    int32_t neg = y < 0;
    uint32_t ux = (uint32_t)x, uy = neg ? -(uint32_t)y : (uint32_t)y;
    while ((ux | uy) >= (1u << 24)) {
        ux >>= 1;
        uy >>= 1;
    }
    while ((ux | uy) < (1u << 23)) {
        ux <<= 1;
        uy <<= 1;
    }
    int32_t cx = (int32_t)ux, cy = (int32_t)uy, z = 0;
    for (int i = 0; i < 20; i++) {
        int32_t dx = cx >> i, dy = cy >> i;
        if (cy > 0) {
            cx += dy;
            cy -= dx;
            z += atan_table_urad[i];
        } else {
            cx -= dy;
            cy += dx;
            z -= atan_table_urad[i];
        }
    }
    int32_t mrad = (z + 500) / 1000;
    return neg ? -mrad : mrad;
}

uint32_t gate_isqrt64(uint64_t v)
{
    /* Bit by bit, high to low: 32 steps, no division. */
    uint64_t res = 0, bit = (uint64_t)1 << 62;
    while (bit > v)
        bit >>= 2;
    while (bit) {
        if (v >= res + bit) {
            v -= res + bit;
            res = (res >> 1) + bit;
        } else {
            res >>= 1;
        }
        bit >>= 2;
    }
    return (uint32_t)res;
}

/* a / b rounded to nearest, b > 0. */
static int32_t div_round(int64_t a, int64_t b)
{
    return (int32_t)(a >= 0 ? (a + b / 2) / b : -((-a + b / 2) / b));
}

/* Depth of a side edge behind the opening's front plane (mm). A side bar's
 * inner face has the gate's grey; the camera sees it, and the edge between
 * bar and opening is then the bar's back edge (a bar's depth behind the
 * front), when the camera is on the opening's side of that face: right of
 * the left bar's (the edge left of the optical axis, u < 0), left of the
 * right bar's (u > 0). Otherwise the front edge bounds the opening. */
static int32_t edge_behind(const gate_config_t *cfg, int32_t u_q8, int32_t side)
{
    return (side < 0 ? u_q8 < 0 : u_q8 > 0) ? cfg->bar_mm : 0;
}

#define CENTRE_Q8 (GATE_IMAGE_WIDTH / 2 * GATE_Q8)

int32_t gate_depth_from_sides(const gate_config_t *cfg, int32_t left_q8, int32_t right_q8)
{
    /* The edges' lateral positions differ by s: with x_i = u_i (Z + d_i) / f,
     * u_r (Z + d_r) - u_l (Z + d_l) = f s. */
    int32_t ul = left_q8 - CENTRE_Q8, ur = right_q8 - CENTRE_Q8;
    if (ur <= ul)
        return 0;
    int64_t num = (int64_t)cfg->focal_q8 * cfg->inner_mm - (int64_t)ur * edge_behind(cfg, ur, 1) +
                  (int64_t)ul * edge_behind(cfg, ul, -1);
    return num > 0 ? div_round(num, ur - ul) : 0;
}

int32_t gate_other_side(const gate_config_t *cfg, int32_t x_q8, int32_t zf_mm, int32_t side)
{
    /* Lateral position of the seen edge (q8 px x mm, i.e. f times metres),
     * moved by the opening's side s, projected back at its own depth. */
    int32_t u = x_q8 - CENTRE_Q8;
    int64_t f_lat = (int64_t)u * (zf_mm + edge_behind(cfg, u, -side));
    f_lat += (int64_t)side * cfg->focal_q8 * cfg->inner_mm;
    int32_t behind = (side < 0 ? f_lat < 0 : f_lat > 0) ? cfg->bar_mm : 0;
    if (zf_mm + behind <= 0)
        return 0;
    return CENTRE_Q8 + div_round(f_lat, zf_mm + behind);
}

void gate_locate(const gate_config_t *cfg, gate_result_t *r)
{
    /* Offsets from the optical axis (q8 px): right and up. */
    int32_t u = r->cx_q8 - GATE_IMAGE_WIDTH / 2 * GATE_Q8;
    int32_t v = GATE_IMAGE_HEIGHT / 2 * GATE_Q8 - r->cy_q8;
    int32_t f = cfg->focal_q8;

    /* Bearing: the ray through the centre makes tan(az) = -u / f with the
     * optical axis in the horizontal plane of the camera, tan(el) = v / f
     * in its vertical plane. */
    r->azimuth_mrad = gate_atan2_mrad(-u, f);
    r->elevation_mrad = gate_atan2_mrad(v, f);

    r->cam_fwd_mm = r->cam_left_mm = r->cam_up_mm = 0;
    r->body_x_mm = r->body_y_mm = r->body_z_mm = r->range_mm = 0;
    if ((r->flags & GATE_NO_SIZE) || r->size_q8 <= 0)
        return;

    /* Depth from apparent size: an opening of side s at depth Z is
     * f * s / Z pixels high (pinhole). Its top and bottom edges, as the
     * detector sees them, are the front edges of the horizontal bars (their
     * inner faces are shaded out of the grey band), b/2 in front of the
     * gate's centre plane: Z = f * s / h + b / 2, with the front depths
     * f * s / h at the centre and at either side edge. */
    int64_t fs = (int64_t)f * cfg->inner_mm;
    int32_t b = cfg->bar_mm;
    int32_t zf = div_round(fs, r->size_q8);
    int32_t z = zf + b / 2;
    /* The centre's height: the midline between the front edges, at the
     * front depth. */
    int32_t up = div_round((int64_t)v * zf, f);
    /* Its side: the mean of the side edges' lateral positions, each
     * back-projected at its own depth (front depth from the height there,
     * plus edge_behind). */
    int32_t right = 0;
    if (r->height_left_q8 > 0 && r->height_right_q8 > 0) {
        int32_t ul = r->left_q8 - CENTRE_Q8, ur = r->right_q8 - CENTRE_Q8;
        int32_t zl = div_round(fs, r->height_left_q8) + edge_behind(cfg, ul, -1);
        int32_t zr = div_round(fs, r->height_right_q8) + edge_behind(cfg, ur, 1);
        right = div_round((int64_t)ul * zl + (int64_t)ur * zr, 2 * (int64_t)f);
    } else {
        right = div_round((int64_t)u * z, f);
    }
    r->cam_fwd_mm = z;
    r->cam_left_mm = -right;
    r->cam_up_mm = up;
    /* The camera's axes are the body's (forward = +x, left = +y, up = +z),
     * offset by its mounting position. */
    r->body_x_mm = z + cfg->cam_x_mm;
    r->body_y_mm = -right + cfg->cam_y_mm;
    r->body_z_mm = up + cfg->cam_z_mm;
    int64_t bx = r->body_x_mm, by = r->body_y_mm, bz = r->body_z_mm;
    r->range_mm = (int32_t)gate_isqrt64((uint64_t)(bx * bx + by * by + bz * bz));
}
