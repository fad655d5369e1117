/*
 * Gate detector for the GAP8 firmware (DESIGN.md §10, docs/VISION.md):
 * finds the square gate frames of the world (DESIGN.md §5: centre, yaw,
 * inner size, bar width, one grey level) in the camera's 320x320 grey image
 * and locates the nearest one relative to the drone's body.
 *
 * Integer arithmetic only (the core is RV32IMC, no F): positions in the
 * image are fixed point with 8 fractional bits ("q8", 1/256 px), lengths in
 * the world are millimetres, angles milliradians.
 *
 * Image coordinates: x to the right, y down, (0, 0) the top-left corner of
 * the top-left pixel, so pixel (col, row) covers [col, col+1) x [row, row+1)
 * and the optical axis goes through (160, 160). This is the renderer's
 * convention (world-server/src/camera.rs samples each pixel at its centre).
 *
 * Not re-entrant: the work buffers are static (about 65 KiB of .bss).
 */
#ifndef GATE_DETECT_H
#define GATE_DETECT_H

#include <stdint.h>

#define GATE_IMAGE_WIDTH 320
#define GATE_IMAGE_HEIGHT 320

/* One pixel is 256 q8 units. */
#define GATE_Q8 256

/* What the firmware knows about the course (a setting, not measured). */
typedef struct {
    /* Grey level of the gate frames and the half-width of the band around
     * it that counts as "gate" (|pixel - grey| <= tolerance). Keep the
     * tolerance under 25 for the renderer's shading (camera.rs: faces
     * facing up are drawn x1.15, down x0.75; see docs/VISION.md); above
     * 63 the scan goes a pixel at a time. */
    uint8_t grey;
    uint8_t tolerance;
    /* Side of the square opening and width (= depth) of a bar (mm). */
    uint16_t inner_mm;
    uint16_t bar_mm;
    /* Smallest opening considered, in pixels of apparent height. */
    uint16_t min_size_px;
    /* Focal length (px, q8): 160 / tan(0.87 / 2) for the 0.87 rad
     * horizontal field of view of DESIGN.md §5. */
    int32_t focal_q8;
    /* Camera position in the body frame (mm; DESIGN.md §5: 30, 0, 10). */
    int16_t cam_x_mm, cam_y_mm, cam_z_mm;
} gate_config_t;

/* The thesis course (scenarios/worlds/thesis-course.toml): grey 170
 * (Webots's yellow gates), 0.8 m opening, 0.06 m bars. */
#define GATE_FOCAL_Q8 88145 /* 344.318 px x 256 */
#define GATE_CONFIG_DEFAULT                                              \
    {                                                                    \
        .grey = 170, .tolerance = 12, .inner_mm = 800, .bar_mm = 60,     \
        .min_size_px = 6, .focal_q8 = GATE_FOCAL_Q8, .cam_x_mm = 30,     \
        .cam_y_mm = 0, .cam_z_mm = 10,                                   \
    }

/* result.flags */
/* The opening reaches the image border on that side: that edge is not
 * seen and was estimated (see docs/VISION.md, "Partly out of view"). */
#define GATE_CUT_LEFT 0x01u
#define GATE_CUT_RIGHT 0x02u
#define GATE_CUT_TOP 0x04u
#define GATE_CUT_BOTTOM 0x08u
/* Too little of the opening is seen to estimate its size: centre is that
 * of the visible part, size and position are 0, only the bearing holds. */
#define GATE_NO_SIZE 0x10u
/* More runs in the image than the work buffers hold: the lowest rows were
 * not searched. */
#define GATE_OVERFLOW 0x20u

typedef struct {
    /* 1 if a gate was found; every other field is 0 when not. */
    int32_t found;
    uint32_t flags;
    /* Gate-like candidates seen (frames with an opening), chosen or not. */
    int32_t candidates;
    /* 0..100: how well the chosen opening matches a square frame. */
    int32_t confidence;
    /* Centre of the opening in the image (q8 px), at the intersection of
     * the diagonals of its four corners (the projection of its centre). */
    int32_t cx_q8, cy_q8;
    /* Apparent height of the opening at its centre (q8 px): the size that
     * gives the distance. Apparent width, between its side edges (q8 px). */
    int32_t size_q8, width_q8;
    /* Its side edges (image x, q8 px) and its height at each (q8 px); the
     * estimated ones when cut (flags). */
    int32_t left_q8, right_q8, height_left_q8, height_right_q8;
    /* Bearing of the centre from the optical axis: azimuth to the left and
     * elevation upwards (mrad). */
    int32_t azimuth_mrad, elevation_mrad;
    /* Gate centre in the camera frame: forward (depth), left, up (mm). */
    int32_t cam_fwd_mm, cam_left_mm, cam_up_mm;
    /* Gate centre in the body frame: x forward, y left, z up (mm), and its
     * distance from the body origin (mm). */
    int32_t body_x_mm, body_y_mm, body_z_mm;
    int32_t range_mm;
    /* Core cycles (mcycle) of the stages: the run scan, the components,
     * the openings and their geometry. For profiling. */
    uint32_t cycles_scan, cycles_components, cycles_openings;
} gate_result_t;

/* Finds the nearest gate in a row-major 320x320 grey image. Returns
 * out->found. */
int gate_detect(const uint8_t *image, const gate_config_t *cfg, gate_result_t *out);

/* The camera model (gate_geometry.c), exposed for tests and for the flight
 * code. atan2 for x > 0 in milliradians, by CORDIC. */
int32_t gate_atan2_mrad(int32_t y, int32_t x);
/* Integer square root (floor). */
uint32_t gate_isqrt64(uint64_t v);
/* For an opening facing the camera (gate plane across the optical axis):
 * the depth (mm) of its front plane given its two side edges (image x,
 * q8), and the image x (q8) of one side edge (side -1 left, +1 right)
 * given the other at x_q8 and the front depth. 0 when impossible. */
int32_t gate_depth_from_sides(const gate_config_t *cfg, int32_t left_q8, int32_t right_q8);
int32_t gate_other_side(const gate_config_t *cfg, int32_t x_q8, int32_t zf_mm, int32_t side);
/* Fills the bearing and position fields of `out` from its centre, side
 * edges and heights. */
void gate_locate(const gate_config_t *cfg, gate_result_t *out);

#endif
