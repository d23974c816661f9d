/* diffdrive's C core: odometry from wheel readings, with its covariance.
 *
 * One update is the step of diffdrive/_step.py: wheel-angle increments (rad) -> wheel arcs
 * (m) -> forward travel, sideways travel (offset * turn) and turn -> the pose moved along the
 * start heading (DD_EULER), the mid-step heading (DD_RK2) or the exact arc (DD_EXACT: the
 * mid-step heading and the chord factor sinc(turn / 2), the SE(2) exponential of the step's
 * twist). The covariance moves with the same step's Jacobians: each wheel's travel in one
 * update has a variance k |travel| (Siegwart, Nourbakhsh and Scaramuzza, "Introduction to
 * Autonomous Mobile Robots", 2nd ed., 2011, sec. 5.2.4), so the covariance after a path does
 * not depend on how finely the updates slice it.
 *
 * The pose and distance are compensated sums (Neumaier's variant of Kahan's): a long run of
 * small updates does not drift from the exact sum of its steps, in float as in double.
 *
 * No allocation, no global state, no I/O: a dd_odometry is a plain struct the caller owns.
 * Every update checks its reading first and, when it refuses it, leaves the state as it was.
 */
#ifndef DIFFDRIVE_ODOMETRY_H
#define DIFFDRIVE_ODOMETRY_H

#include <stdint.h>

#include "diffdrive/kinematics.h"

enum { DD_EULER = 0, DD_RK2 = 1, DD_EXACT = 2 };

typedef struct {
    dd_drive drive;
    int method;              /* DD_EULER, DD_RK2 or DD_EXACT */
    dd_real ticks_per_revolution; /* counts per wheel revolution; 0: not known (no ticks) */
    int counter_bits;        /* 1 to 64 for counters that roll over; 0: counters that do not */
    dd_real max_wheel_speed; /* rad/s, > 0; INFINITY for no limit */
    dd_real k_left, k_right; /* m: each wheel's travel variance per metre travelled, >= 0 */
} dd_odometry_config;

/* A compensated sum: its value is sum + comp. */
typedef struct {
    dd_real sum, comp;
} dd_sum;

typedef struct {
    dd_odometry_config config;
    dd_real rad_per_tick, rad_per_tick_low; /* 2 pi / ticks_per_revolution, and (float
                                               builds) its rounding error */
    dd_sum x, y, theta, distance; /* m, m, rad (not wrapped), m along the path */
    dd_real cov[9];               /* of (x, y, theta), row-major */
    double time;                  /* s of the last reading; NaN while unknown */
    int have_ticks, have_positions;
    int64_t ticks_left, ticks_right;       /* the last counter readings */
    dd_real position_left, position_right; /* the last wheel angles, rad */
    dd_real arc_left, arc_right;           /* m each wheel travelled since init */
} dd_odometry;

/* At the origin with a zero covariance and no reading yet: DD_OK, or DD_BAD_SETTING for a
 * drive or setting out of range, DD_NULL for a null pointer. */
dd_status dd_odometry_init(dd_odometry *odometry, const dd_odometry_config *config);

/* Readings, each at time *t (s; t NULL: no time stamp, which stops the clock until the next
 * stamped reading). The first ticks or positions reading only sets the reference.
 * Refused, with nothing changed: DD_NOT_FINITE, DD_TIME_BACKWARDS, DD_TIME_STILL,
 * DD_TOO_FAST, DD_OVERFLOW_POSE, DD_OVERFLOW_COVARIANCE; for ticks also DD_NO_TICKS (no
 * ticks_per_revolution) and
 * DD_COUNTER_RANGE (a reading outside -2^(bits-1) .. 2^bits - 1). A counter of `bits` bits
 * changes by at most 2^(bits-1) counts between readings: more is read as a roll-over the
 * other way, which the speed limit then catches. */
dd_status dd_odometry_ticks(dd_odometry *odometry, const double *t, int64_t left, int64_t right);
dd_status dd_odometry_positions(dd_odometry *odometry, const double *t, dd_real left,
                                dd_real right);
dd_status dd_odometry_increments(dd_odometry *odometry, const double *t, dd_real left,
                                 dd_real right);
/* Wheel velocities (rad/s) held for dt s (> 0, else DD_BAD_DT); without a clock, one starts
 * at 0 s. */
dd_status dd_odometry_velocities(dd_odometry *odometry, dd_real left, dd_real right, double dt);

/* The counter change from `before` to `after` through at most one roll-over of a counter of
 * `bits` bits (0: none; DD_COUNTER_RANGE when the change passes 2^63). */
dd_status dd_tick_change(int bits, int64_t before, int64_t after, int64_t *change);

/* The pose (x, y, theta) and the distance now. */
void dd_odometry_pose(const dd_odometry *odometry, dd_real pose[3]);
dd_real dd_odometry_distance(const dd_odometry *odometry);

/* Put the robot at pose (x, y, theta) with covariance cov (row-major 3x3); the distance
 * restarts at 0. */
void dd_odometry_set_pose(dd_odometry *odometry, const dd_real pose[3], const dd_real cov[9]);

/* The Jacobians of one step from the pose now by wheel-angle increments (rad):
 * d(pose after)/d(pose before), row-major 3x3, and d(pose after)/d(increments), 3x2. */
void dd_odometry_jacobians(const dd_odometry *odometry, dd_real left, dd_real right,
                           dd_real jac_pose[9], dd_real jac_wheels[6]);

#endif
