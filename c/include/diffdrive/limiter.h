/* diffdrive's C core: a command limiter (velocity, acceleration and jerk limits, a command
 * timeout), the rules of diffdrive.control.Limiter for one robot.
 *
 * Each step toward a target: (1) with no new target for `timeout` s, the target becomes 0;
 * (2) all channels are scaled by one factor into their velocity limits (forward, reverse), so
 * the target's curvature is kept; (3) each channel moves toward its target within its
 * acceleration limits (speeding up and slowing down, forward and reverse; through zero it
 * slows to rest, then speeds up the other way); (4) every channel moves the same fraction of
 * its way, the smallest any allows, so the output keeps the target's curvature. With jerk
 * limits, each step's acceleration changes by at most jerk dt and ramps down to land on the
 * target; with them on every channel, and the acceleration pointing along the way to the
 * target, the fraction itself follows one jerk-limited profile in the tightest channel's
 * limits, so the curvature is kept through it.
 */
#ifndef DIFFDRIVE_LIMITER_H
#define DIFFDRIVE_LIMITER_H

#include "diffdrive/real.h"

#define DD_LIMITER_CHANNELS 4

/* One channel's limits, in its units (m/s or rad/s, and per s); INFINITY for none. */
typedef struct {
    dd_real max_velocity, max_reverse_velocity; /* > 0; reverse 0 forbids reversing */
    dd_real max_acceleration, max_deceleration; /* moving forward, > 0 */
    dd_real max_reverse_acceleration, max_reverse_deceleration; /* moving backward, > 0 */
    dd_real max_jerk;                                           /* > 0 */
} dd_limits;

typedef struct {
    int channels; /* 1 to DD_LIMITER_CHANNELS */
    dd_limits limits[DD_LIMITER_CHANNELS];
    dd_real timeout; /* s, > 0; INFINITY for none */
    dd_real value[DD_LIMITER_CHANNELS], acceleration[DD_LIMITER_CHANNELS];
    dd_real target[DD_LIMITER_CHANNELS];
    dd_real since; /* s since the last target */
} dd_limiter;

/* At rest: DD_OK, or DD_BAD_SETTING for a channel count or limit out of range. */
dd_status dd_limiter_init(dd_limiter *limiter, int channels, const dd_limits *limits,
                          dd_real timeout);

/* The limited command after dt s (> 0) toward target (channels values; NULL: no new target
 * this cycle), into out and the limiter's state. Refused, nothing changed: DD_BAD_DT,
 * DD_NOT_FINITE (a target or an output that would not be finite). */
dd_status dd_limiter_step(dd_limiter *limiter, const dd_real *target, dd_real dt, dd_real *out);

#endif
