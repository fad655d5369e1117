/*
 * Indoor mapping and frontier exploration for the AI-deck core (seed 004,
 * DESIGN.md §9): an occupancy grid built from the Multi-ranger's ranges
 * (§2.4.2, §4.2.1.A), frontier-based exploration (§2.5.1, Yamauchi 1997;
 * Algorithm 2 of §4.2.1.B), a grid planner, a path follower with reactive
 * avoidance, and the seed's two flights: explore with a 360° scan at each
 * goal (§5.2), and "go around the room" (§5.1, Table 6) as the wall follower
 * of §4.2.1.B.
 *
 * The boundary with the platform is one call per control period:
 * explore_step(input) -> output. The input is what the STM32 gives the AI
 * deck (state estimate and the six ranges), the output a MotionCommander-like
 * command (take-off, body-frame velocity set-point with height and yaw rate,
 * land). Everything is integer: millimetres, milliradians, milliseconds.
 *
 * Memory is static (no malloc): the grid and the planner's work arrays are
 * sized for EXPLORE_MAX_CELLS cells; a grid that does not fit is refused by
 * explore_init with a message. One explorer (and one grid) at a time.
 */
#ifndef EXPLORE_H
#define EXPLORE_H

#include <stdint.h>

/* The memory budget: 8 x 8 m at 5 cm, the seed's explored cell size (§5.2).
 * 8 bytes per cell in all (grid 1, planner 7): 200 KiB of the 256 KiB data
 * region of gap8.ld. Cell indices are uint16_t, so at most 65535. */
#ifndef EXPLORE_MAX_CELLS
#define EXPLORE_MAX_CELLS 25600
#endif

/* The six ranges, in the order of the input array. */
enum explore_range {
    EXPLORE_FRONT,
    EXPLORE_BACK,
    EXPLORE_LEFT,
    EXPLORE_RIGHT,
    EXPLORE_UP,
    EXPLORE_DOWN,
    EXPLORE_RANGES
};

/* One sample of the state estimate and the ranges. World frame: x, y on
 * the floor, z up, yaw counter-clockwise from +x seen from above. A range of
 * 0 means "no reading" (cflib's None: sensor fault); a range >= max_range_mm
 * means nothing within the maximum range. */
typedef struct {
    uint32_t t_ms; /* simulated time of the sample */
    int32_t x_mm, y_mm, z_mm;
    int32_t yaw_mrad;
    uint16_t range_mm[EXPLORE_RANGES];
    uint16_t max_range_mm;
} explore_input;

typedef enum {
    EXPLORE_CMD_NONE = 0, /* on the ground, nothing to do */
    EXPLORE_CMD_TAKEOFF,  /* take off to z_mm and hover */
    EXPLORE_CMD_VELOCITY, /* hold z_mm; body-frame vx, vy; yaw rate */
    EXPLORE_CMD_LAND,     /* land where the drone is */
    EXPLORE_CMD_DONE      /* landed: the run is over */
} explore_cmd;

typedef enum {
    EXPLORE_ST_GROUND = 0,
    EXPLORE_ST_TAKEOFF,
    EXPLORE_ST_SCAN,   /* 360° turn at a goal (§5.2 b) */
    EXPLORE_ST_FOLLOW, /* flying the planned path to a goal */
    EXPLORE_ST_ROUND,  /* wall following around the room (Table 6) */
    EXPLORE_ST_HOME,   /* flying back to the take-off point */
    EXPLORE_ST_LAND,
    EXPLORE_ST_DONE,
    EXPLORE_ST_ERROR /* explore_init failed; explore_step only lands */
} explore_state;

typedef struct {
    explore_cmd cmd;
    int32_t vx_mm_s, vy_mm_s; /* body frame: x forward, y left */
    int32_t z_mm;             /* height set-point */
    int32_t yaw_rate_mrad_s;  /* counter-clockwise positive */
    explore_state state;
    uint8_t new_goal; /* 1 on the step a goal was chosen */
    int32_t goal_x_mm, goal_y_mm;
} explore_output;

typedef enum {
    EXPLORE_MODE_FRONTIER = 0, /* §5.2: scan, frontier goal, fly, repeat */
    EXPLORE_MODE_ROUND = 1     /* §5.1: go around the room, land at start */
} explore_mode;

/* Run settings (runtime, not compile-time). explore_default_settings gives
 * the seed's values where it has them. */
typedef struct {
    explore_mode mode;
    /* Map (§4.2.1.A, Table 6): the explorable area's bounds, the cell size
     * and the sensor cone's full angle in centidegrees. */
    int32_t x_min_mm, y_min_mm, x_max_mm, y_max_mm;
    uint16_t cell_mm;
    uint16_t fov_cdeg;
    /* Log-odds per observation and clamps, in 1/16 nat (EXPLORE_LO_PER_NAT). */
    int8_t l_occ, l_free, l_min, l_max;
    /* Drone and motion. */
    uint16_t drone_radius_mm;  /* half the span, propellers included */
    uint16_t margin_mm;        /* kept between the drone and known obstacles */
    uint16_t min_frontier_mm;  /* frontier regions shorter than this are ignored */
    uint16_t speed_mm_s;       /* cruise speed (§5.1: 0.2 m/s) */
    uint16_t height_mm;        /* flight height */
    uint16_t scan_rate_mrad_s; /* yaw rate of the 360° scan */
    uint16_t avoid_mm;         /* reactive avoidance below this range */
    uint16_t goal_tol_mm;      /* a goal within this distance is reached */
    uint16_t wall_mm;          /* wall distance of the round flight */
    uint16_t visited_mm;       /* frontier cells this close to a visited goal are skipped */
    uint32_t time_budget_ms;   /* land when spent (from the first step) */
    uint32_t stuck_ms;         /* no progress for this long: goal unreachable */
    uint32_t replan_ms;        /* re-plan the path this often while following */
} explore_settings;

#define EXPLORE_LO_PER_NAT 16

/* Error codes of explore_init. */
enum {
    EXPLORE_OK = 0,
    EXPLORE_E_CELL = 1,    /* cell size outside 10..1000 mm */
    EXPLORE_E_BOUNDS = 2,  /* empty area, or wider than 20 m */
    EXPLORE_E_BUDGET = 3,  /* more cells than EXPLORE_MAX_CELLS */
    EXPLORE_E_FOV = 4,     /* FOV outside 0..90 degrees */
    EXPLORE_E_LOGODDS = 5, /* l_occ <= 0, l_free >= 0, or clamps not around 0 */
    EXPLORE_E_MOTION = 6   /* a zero speed, height, tolerance or scan rate */
};

void explore_default_settings(explore_settings *s);

/* Checks the settings, clears the map, and arms the state machine. Returns
 * EXPLORE_OK or an error code; explore_last_error() then says why in one
 * line (for example the requested and the available cells). */
int explore_init(const explore_settings *s);
const char *explore_last_error(void);

/* One control period. */
void explore_step(const explore_input *in, explore_output *out);

/* Counters for the platform's summary (DESIGN.md §9: map_cycles). Cycles
 * are the core's mcycle CSR. */
typedef struct {
    uint32_t steps;
    uint32_t map_updates;
    uint64_t map_cycles;
    uint32_t plans;
    uint64_t plan_cycles;
    uint32_t goals;               /* goals chosen */
    uint32_t goals_reached;       /* goals reached and scanned */
    uint32_t goals_failed;        /* goals abandoned: unreachable, no progress, or no longer a
                                     valid goal after the map changed */
    uint32_t avoid_steps;         /* steps where the reactive avoidance acted */
    uint32_t map_avoid_steps;     /* steps where the map-based avoidance acted */
    uint32_t regions_unreachable; /* frontier regions skipped for want of a reachable cell */
    uint32_t start_ms, end_ms;
} explore_stats;

const explore_stats *explore_get_stats(void);

/* The map export, written into the grid's own storage (no copy): returns
 * the image and its length in bytes. Format (little-endian, see
 * docs/EXPLORE.md): a 32-byte header "CFOG", version, header length, width,
 * height, cell_mm, fov_cdeg, origin x/y (mm), log-odds scale and clamps,
 * CRC-32 of the cells; then width*height int8 log-odds, row-major from the
 * cell at the origin, x fastest. The image is also reachable through the
 * symbols explore_map_image and explore_map_image_len. */
const uint8_t *explore_map_export(uint32_t *len);

/* The core's cycle counter (mcycle/mcycleh). */
uint64_t explore_cycles(void);

#endif
