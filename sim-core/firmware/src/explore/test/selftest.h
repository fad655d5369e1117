/* The exploration self-test's harness: checks print a FAIL line; the exit
 * status is the number of failures (as selfcheck.h). */
#ifndef EXPLORE_SELFTEST_H
#define EXPLORE_SELFTEST_H

#include <stdio.h>

extern int st_checks, st_failures;

#define CHECK(cond, ...)                                                                           \
    do {                                                                                           \
        st_checks++;                                                                               \
        if (!(cond)) {                                                                             \
            st_failures++;                                                                         \
            printf("FAIL %s:%d: ", __FILE__, __LINE__);                                            \
            printf(__VA_ARGS__);                                                                   \
            printf("\n");                                                                          \
        }                                                                                          \
    } while (0)

#define CHECK_EQ(name, got, want)                                                                  \
    CHECK((long)(got) == (long)(want), "%s: got %ld, want %ld", name, (long)(got), (long)(want))

void test_fixmath(void);
void test_settings(void);
void test_sensor_model(void);
void test_export(void);
void test_frontiers(void);
void test_planner(void);
void test_follow(void);
void sim_run_all(void);
void bench_run(void);

#endif
