/*
 * Seed 004's mapping and exploration on the AI deck (docs/EXPLORE.md,
 * "Glue to the platform"): every control period the firmware reads the
 * STM32's state estimate and six ranges (cosim_regs.h, "STM32 extension"),
 * calls explore_step, and turns its output into MotionCommander-like
 * commands (take-off, body-frame velocity set-point, land), then lets the
 * simulations advance one period. The map stays in explore_map_image, which
 * the platform copies out at the end of the run (map.cfog).
 *
 * Run parameters are the explore_param_* globals below: the platform may
 * overwrite them before the core starts (sim-core's `firmware.NAME` run
 * keys, e.g. `--set firmware.explore_param_cell_mm=80`). Their defaults are
 * the seed's exploration of §5.2 (5 cm, FOV 4°, 0.2 m/s, rangers capped at
 * 3 m).
 *
 * Console (parsed by `cosim`, scenarios/src/mapping): one line each
 *   EXPLORE settings mode= cell_mm= fov_cdeg= height_mm= max_range_mm= ...
 *   EXPLORE start x_mm= y_mm=              the estimate at take-off
 *   EXPLORE goal t_ms= x_mm= y_mm=         each frontier goal, in order
 *   EXPLORE error <message>                settings refused (then it lands)
 *   EXPLORE end t_ms= ... map_cycles= ...  the counters of explore_stats
 */
#include <math.h>
#include <stdio.h>

#include "../cosim_regs.h"
#include "../stm32.h"
#include "explore.h"

/* Run parameters (the platform may patch them; volatile so the compiler
 * reads what is in memory). Area bounds are relative to the take-off
 * estimate, so a room can be explored without knowing where it is. */
/* In .data, not .bss (zeroed at start): the platform patches the load image. */
__attribute__((section(".data"))) volatile int32_t explore_param_mode = EXPLORE_MODE_FRONTIER;
volatile int32_t explore_param_cell_mm = 50;    /* §5.2: 5 cm */
volatile int32_t explore_param_fov_cdeg = 400;  /* §5.2: 4.0° */
volatile int32_t explore_param_height_mm = 300; /* cflib's default height */
volatile int32_t explore_param_speed_mm_s = 200; /* §5.1: 0.2 m/s */
/* §5.2: "the sensor maximum range is capped at 3 m (for more accuracy)". */
volatile int32_t explore_param_max_range_mm = 3000;
volatile int32_t explore_param_x_min_mm = -4000; /* 8 x 8 m around take-off */
volatile int32_t explore_param_x_max_mm = 4000;
volatile int32_t explore_param_y_min_mm = -4000;
volatile int32_t explore_param_y_max_mm = 4000;
volatile int32_t explore_param_time_budget_ms = 300000;
/* The seed logs poses and ranges every 100 ms (§4.2.1.A): here three PID
 * iterations of 32 ms, 96 ms. */
volatile int32_t explore_param_period_ms = 100;
/* The core's clock (Hz), for the firmware's time: platform time in lockstep
 * with the world's (ITER_ADVANCE moves both). GAP8 fabric controller. */
volatile int32_t explore_param_core_hz = 250000000;
/* Samples taken at a larger roll or pitch are dropped from the map
 * (§4.2.1.A); 0 disables the filter. */
volatile int32_t explore_param_max_tilt_mrad = 0;
/* Steps without an answer from the firmware's state machine to land after
 * (a guard against a machine that never ends: the run ends anyway by the
 * scenario's max_time_s). */
volatile int32_t explore_param_max_steps = 20000;

/* An extension command (stm32_ext), refused ones reported. Returns 0 on
 * success. */
static int ext_perform(uint32_t cmd)
{
    uint32_t st = stm32_ext(cmd);
    if (st != cmd) {
        printf("EXPLORE error the STM32 refused extension command %lu (status %lu)\n",
               (unsigned long)cmd, (unsigned long)st);
        return -1;
    }
    return 0;
}

static int low_battery = 0;

/* One PID iteration of the STM32 flying the current set-point: the
 * simulations advance ITER_MS - PID_MS, then RUN_SINGLE_STEP_PID (the
 * STM32's PID takes PID_MS, the world steps once at a 32 ms basicTimeStep).
 * The sequence of stm32.h's stm32_iteration, written out: calling that
 * helper here moves functions within explore_app.elf, whose committed
 * build `make check` compares byte for byte. */
#define ITER_MS 32
#define PID_MS 7
static void iteration(void)
{
    uint8_t st;
    stm32_control = (uint8_t)(ITER_ADVANCE + ITER_MS - PID_MS);
    while (stm32_status != ITER_ADVANCE)
        ;
    stm32_status = 0;
    stm32_control = RUN_SINGLE_STEP_PID;
    while ((st = stm32_status) == 0)
        ;
    stm32_status = 0;
    stm32_control = 0;
    if (st == BATTERY_LOW)
        low_battery = 1;
}

/* One control period: whole PID iterations (96 ms for the seed's 100 ms at
 * a 32 ms basicTimeStep). */
static void advance(uint32_t ms)
{
    for (uint32_t t = 0; t + ITER_MS / 2 < ms || t == 0; t += ITER_MS)
        iteration();
}

static int32_t mm(double m) { return (int32_t)lround(m * 1000.0); }

/* A range register (m; negative: nothing within the sensor's range) in mm
 * for explore_step: capped at the maximum, which means "nothing within". */
static uint16_t range_mm(double m, uint16_t max_mm)
{
    if (!(m >= 0.0)) /* negative or NaN */
        return max_mm;
    int32_t v = mm(m);
    return v >= max_mm ? max_mm : (uint16_t)v;
}

static void read_input(explore_input *in, uint16_t max_mm)
{
    uint64_t cycles = explore_cycles();
    in->t_ms = (uint32_t)(cycles / (uint64_t)(explore_param_core_hz / 1000));
    in->x_mm = mm(REGF64(STM32_EST_X_OFFSET));
    in->y_mm = mm(REGF64(STM32_EST_Y_OFFSET));
    in->z_mm = mm(REGF64(STM32_EST_Z_OFFSET));
    in->yaw_mrad = mm(REGF64(STM32_EST_YAW_OFFSET));
    in->range_mm[EXPLORE_FRONT] = range_mm(REGF64(STM32_RANGE_FRONT_OFFSET), max_mm);
    in->range_mm[EXPLORE_BACK] = range_mm(REGF64(STM32_RANGE_BACK_OFFSET), max_mm);
    in->range_mm[EXPLORE_LEFT] = range_mm(REGF64(STM32_RANGE_LEFT_OFFSET), max_mm);
    in->range_mm[EXPLORE_RIGHT] = range_mm(REGF64(STM32_RANGE_RIGHT_OFFSET), max_mm);
    in->range_mm[EXPLORE_UP] = range_mm(REGF64(STM32_RANGE_UP_OFFSET), max_mm);
    in->range_mm[EXPLORE_DOWN] = range_mm(REGF64(STM32_RANGE_DOWN_OFFSET), max_mm);
    in->max_range_mm = max_mm;
}

static void print_end(uint32_t t_ms)
{
    const explore_stats *st = explore_get_stats();
    printf("EXPLORE end t_ms=%lu steps=%lu map_updates=%lu map_cycles=%llu plans=%lu "
           "plan_cycles=%llu goals=%lu reached=%lu failed=%lu avoid=%lu map_avoid=%lu "
           "unreachable=%lu start_ms=%lu end_ms=%lu\n",
           (unsigned long)t_ms, (unsigned long)st->steps, (unsigned long)st->map_updates,
           (unsigned long long)st->map_cycles, (unsigned long)st->plans,
           (unsigned long long)st->plan_cycles, (unsigned long)st->goals,
           (unsigned long)st->goals_reached, (unsigned long)st->goals_failed,
           (unsigned long)st->avoid_steps, (unsigned long)st->map_avoid_steps,
           (unsigned long)st->regions_unreachable, (unsigned long)st->start_ms,
           (unsigned long)st->end_ms);
}

int main(void)
{
    uint16_t max_mm = (uint16_t)explore_param_max_range_mm;
    uint32_t period = (uint32_t)explore_param_period_ms;
    stm32_perform(INIT_PID);
    explore_input in;
    read_input(&in, max_mm);

    explore_settings s;
    explore_default_settings(&s);
    s.mode = (explore_mode)explore_param_mode;
    s.cell_mm = (uint16_t)explore_param_cell_mm;
    s.fov_cdeg = (uint16_t)explore_param_fov_cdeg;
    s.height_mm = (uint16_t)explore_param_height_mm;
    s.speed_mm_s = (uint16_t)explore_param_speed_mm_s;
    s.time_budget_ms = (uint32_t)explore_param_time_budget_ms;
    s.x_min_mm = in.x_mm + explore_param_x_min_mm;
    s.x_max_mm = in.x_mm + explore_param_x_max_mm;
    s.y_min_mm = in.y_mm + explore_param_y_min_mm;
    s.y_max_mm = in.y_mm + explore_param_y_max_mm;
    printf("EXPLORE settings mode=%d cell_mm=%u fov_cdeg=%u height_mm=%u max_range_mm=%u "
           "speed_mm_s=%u period_ms=%lu x_min_mm=%ld x_max_mm=%ld y_min_mm=%ld y_max_mm=%ld\n",
           (int)s.mode, s.cell_mm, s.fov_cdeg, s.height_mm, max_mm, s.speed_mm_s,
           (unsigned long)period, (long)s.x_min_mm, (long)s.x_max_mm, (long)s.y_min_mm,
           (long)s.y_max_mm);
    printf("EXPLORE start x_mm=%ld y_mm=%ld\n", (long)in.x_mm, (long)in.y_mm);
    int rc = explore_init(&s);
    if (rc != EXPLORE_OK) {
        /* Nothing flies: the drone is still on the ground. The map image
         * stays empty (length 0), and the run ends here. */
        printf("EXPLORE error %s\n", explore_last_error());
        print_end(in.t_ms);
        return 2;
    }
    REGF64(STM32_CMD_SPEED_LIMIT_OFFSET) = s.speed_mm_s / 1000.0;
    if (ext_perform(EXT_SET_SPEED_LIMIT) != 0)
        return 3;

    int took_off = 0, landing = 0;
    explore_output out;
    for (int32_t step = 0;; step++) {
        read_input(&in, max_mm);
        explore_step(&in, &out);
        /* Keep the exported image current (about once a second, ~0.5 M
         * cycles at 10 000 cells), so a run cut short by the scenario's
         * max_time_s or a flat battery still leaves its map. */
        if (step % 10 == 0) {
            uint32_t len;
            explore_map_export(&len);
        }
        if (out.new_goal)
            printf("EXPLORE goal t_ms=%lu x_mm=%ld y_mm=%ld\n", (unsigned long)in.t_ms,
                   (long)out.goal_x_mm, (long)out.goal_y_mm);
        if (step >= explore_param_max_steps && out.cmd != EXPLORE_CMD_DONE) {
            printf("EXPLORE error no end after %ld steps: landing\n", (long)step);
            out.cmd = EXPLORE_CMD_LAND;
        }
        if (low_battery && out.cmd != EXPLORE_CMD_DONE) {
            printf("EXPLORE low battery: landing\n");
            out.cmd = EXPLORE_CMD_LAND;
        }
        switch (out.cmd) {
        case EXPLORE_CMD_TAKEOFF:
            if (!took_off) {
                REGF64(STM32_CMD_HEIGHT_OFFSET) = out.z_mm / 1000.0;
                if (ext_perform(EXT_TAKEOFF) != 0)
                    return 3;
                took_off = 1;
            } else {
                advance(period);
            }
            break;
        case EXPLORE_CMD_VELOCITY:
            REGF64(STM32_CMD_VX_OFFSET) = out.vx_mm_s / 1000.0;
            REGF64(STM32_CMD_VY_OFFSET) = out.vy_mm_s / 1000.0;
            REGF64(STM32_CMD_HEIGHT_OFFSET) = out.z_mm / 1000.0;
            REGF64(STM32_CMD_YAW_RATE_OFFSET) = out.yaw_rate_mrad_s / 1000.0;
            if (ext_perform(EXT_SET_VELOCITY) != 0)
                return 3;
            advance(period);
            break;
        case EXPLORE_CMD_LAND:
        case EXPLORE_CMD_DONE:
            if (!landing) {
                landing = 1;
                uint32_t len;
                explore_map_export(&len); /* header and CRC, for map.cfog */
                read_input(&in, max_mm);
                print_end(in.t_ms);
                /* EXT_LAND descends, stops the motors and STOPs the drone. */
                if (ext_perform(EXT_LAND) != 0)
                    return 3;
            }
            return 0;
        case EXPLORE_CMD_NONE:
        default:
            advance(period);
            break;
        }
    }
}
