/* step_cost: how many instructions one odometry update and one filter step take on the
 * Cortex-M4F, counted by QEMU. Under `-icount shift=0` QEMU's virtual clock advances exactly
 * 1 ns per instruction executed, and the MPS2 board's SysTick counts its 25 MHz system clock
 * from that clock: 40 instructions a tick. Each cost is the ticks over REPEATS calls less
 * those of the same loop around an empty call, times 40, over REPEATS. */
#include <stdint.h>
#include <stdio.h>

#include "diffdrive/filter.h"
#include "diffdrive/odometry.h"

#define REPEATS 2000
#define INSTRUCTIONS_PER_TICK 40

static volatile uint32_t *const SYST_CSR = (uint32_t *)0xE000E010;
static volatile uint32_t *const SYST_RVR = (uint32_t *)0xE000E014;
static volatile uint32_t *const SYST_CVR = (uint32_t *)0xE000E018;

static uint32_t now(void) { return *SYST_CVR; } /* counts down */

/* SysTick from its top, on the processor's clock, without its interrupt. */
static void start_clock(void) {
    *SYST_RVR = 0xFFFFFF;
    *SYST_CVR = 0;
    *SYST_CSR = 5;
}

static dd_odometry odometry, offset_odometry;
static dd_filter filter;
static dd_real x[DD_STATES], P[DD_STATES * DD_STATES];
static volatile int refused; /* readings the odometry refused: none, or the count is off */

__attribute__((noinline)) static void nothing(int k) { refused += k < 0; }

/* the readings, made before the count: a call costs the update and nothing else */
static double times[REPEATS + 1];
static int64_t lefts[REPEATS + 1], rights[REPEATS + 1];

__attribute__((noinline)) static void odometry_update(int k) {
    refused += dd_odometry_ticks(&odometry, &times[k], lefts[k], rights[k]) != DD_OK;
}

/* the same, with the reference point 5 cm ahead of the axle */
__attribute__((noinline)) static void offset_update(int k) {
    refused += dd_odometry_ticks(&offset_odometry, &times[k], lefts[k], rights[k]) != DD_OK;
}

__attribute__((noinline)) static void filter_step(int k) {
    /* 0.01 s of wheels (about 50 counts) and a gyro's turn, fused */
    dd_filter_predict(&filter, x, P, 0.08f + 0.0001f * (dd_real)(k & 7), 0.09f, 0.0052f, 0.0f,
                      0.01f, 0, 0);
}

/* Instructions per call of f, the loop's own cost taken off. */
static long cost(void (*f)(int)) {
    uint32_t begin = now();
    for (int k = 1; k <= REPEATS; ++k) f(k);
    uint32_t with = begin - now();
    begin = now();
    for (int k = 1; k <= REPEATS; ++k) nothing(k);
    uint32_t empty = begin - now();
    return ((long)with - (long)empty) * INSTRUCTIONS_PER_TICK / REPEATS;
}

int main(void) {
    start_clock();
    for (int k = 0; k <= REPEATS; ++k) { /* 100 Hz, 16-bit counters, about 8 rad/s */
        times[k] = 0.01 * k;
        lefts[k] = (52 * k) & 0xFFFF;
        rights[k] = (60 * k + (k & 3)) & 0xFFFF;
    }
    const dd_odometry_config config = {{0.033f, 0.033f, 0.16f, 0.0f}, DD_EXACT, 4096.0f, 16,
                                       1000.0f, 1e-4f, 1e-4f};
    dd_odometry_config ahead = config;
    ahead.drive.offset = 0.05f;
    dd_odometry_init(&odometry, &config);
    dd_odometry_init(&offset_odometry, &ahead);
    dd_odometry_ticks(&odometry, &times[0], lefts[0], rights[0]);
    dd_odometry_ticks(&offset_odometry, &times[0], lefts[0], rights[0]);
    dd_filter_config settings = {
        .drive = {0.033f, 0.033f, 0.16f, 0.0f},
        .method = DD_EXACT,
        .heading = DD_FROM_BOTH,
        .estimate_bias = 1,
        .estimate_scale = 1,
        .k_left = 1e-4f,
        .k_right = 1e-4f,
        .arw2 = 1e-6f,
        .rrw2 = 1e-10f,
        .slip_threshold = 13.8f,
        .slip_inflation = 100.0f,
        .gates = {9.0f, 13.8f, 16.3f},
    };
    dd_filter_init(&filter, &settings);
    x[DD_SCALE] = x[DD_DISTANCE] = 1.0f;
    for (int i = 0; i < 5; ++i) P[i * DD_STATES + i] = 1e-4f;
    long odometry_cost = cost(odometry_update);
    long offset_cost = cost(offset_update);
    long filter_cost = cost(filter_step);
    if (refused) {
        printf("step_cost: %d readings refused\n", refused);
        return 1;
    }
    printf("odometry_update %ld\nodometry_update_offset %ld\nfilter_step %ld\n", odometry_cost,
           offset_cost, filter_cost);
    return 0;
}
