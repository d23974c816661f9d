/* odometry_stream FILE: the odometry of one robot over a file of encoder readings, the C
 * core's test harness and its example.
 *
 * FILE's first line: `robot r_left r_right track ticks_per_revolution counter_bits k_left
 * k_right [max_wheel_speed]` (m, m, m, counts, bits, m, m, rad/s; without the last, no speed
 * limit); then one line `t left_ticks right_ticks` a reading
 * (s, counts). For each reading after the first, standard output gets one line
 * `t x y theta P_xx P_xy P_xt P_yy P_yt P_tt` (s, m, m, rad, and the pose's covariance). A
 * reading the core refuses gets one line `refused line N: WHY` on standard error, and the
 * stream goes on from the reading before it.
 *
 * The same source runs on the host and, through semihosting, on a Cortex-M4F under QEMU:
 * standard I/O is the C library's (glibc, or newlib over semihosting). */
#include <stdint.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "diffdrive/odometry.h"

/* The pose's three values printed from their compensated sums in double, so a float build's
 * output keeps the digits its sums carry. */
static double exact(dd_sum s) { return (double)s.sum + (double)s.comp; }

int main(int argc, char **argv) {
    if (argc != 2) {
        fprintf(stderr, "usage: odometry_stream FILE\n");
        return 2;
    }
    FILE *in = fopen(argv[1], "r");
    if (in == NULL) {
        fprintf(stderr, "odometry_stream: cannot open %s\n", argv[1]);
        return 2;
    }
    char line[256];
    double r_left, r_right, track, ticks_per_revolution, k_left, k_right, fastest = INFINITY;
    int bits, fields = 0;
    if (fgets(line, sizeof line, in) != NULL)
        fields = sscanf(line, "robot %lf %lf %lf %lf %d %lf %lf %lf", &r_left, &r_right, &track,
                        &ticks_per_revolution, &bits, &k_left, &k_right, &fastest);
    if (fields != 7 && fields != 8) {
        fprintf(stderr, "odometry_stream: line 1 must be `robot r_left r_right track "
                        "ticks_per_revolution counter_bits k_left k_right [max_wheel_speed]`\n");
        return 2;
    }
    const dd_odometry_config config = {
        .drive = {(dd_real)r_left, (dd_real)r_right, (dd_real)track, 0.0},
        .method = DD_EXACT,
        .ticks_per_revolution = (dd_real)ticks_per_revolution,
        .counter_bits = bits,
        .max_wheel_speed = (dd_real)fastest,
        .k_left = (dd_real)k_left,
        .k_right = (dd_real)k_right,
    };
    dd_odometry odometry;
    dd_status status = dd_odometry_init(&odometry, &config);
    if (status != DD_OK) {
        fprintf(stderr, "odometry_stream: line 1: %s\n", dd_status_text(status));
        return 2;
    }
    long number = 1;
    int readings = 0;
    while (fgets(line, sizeof line, in) != NULL) {
        ++number;
        double t;
        long long left, right;
        if (sscanf(line, "%lf %lld %lld", &t, &left, &right) != 3) {
            fprintf(stderr, "refused line %ld: not `t left_ticks right_ticks`\n", number);
            continue;
        }
        status = dd_odometry_ticks(&odometry, &t, (int64_t)left, (int64_t)right);
        if (status != DD_OK) {
            fprintf(stderr, "refused line %ld (t = %.17g s, ticks %lld %lld): %s\n", number, t,
                    left, right, dd_status_text(status));
            continue;
        }
        if (readings++ == 0) continue; /* the first sets the reference */
        const dd_real *P = odometry.cov;
        printf("%.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n", t, exact(odometry.x),
               exact(odometry.y), exact(odometry.theta), (double)P[0], (double)P[1],
               (double)P[2], (double)P[4], (double)P[5], (double)P[8]);
    }
    fclose(in);
    return 0;
}
