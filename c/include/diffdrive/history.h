/* diffdrive's C core: the estimator's history, in buffers the caller gives.
 *
 * The history keeps each interval of wheel readings with the filter's state at its start,
 * and the absolute measurements in the order of their stamps (then kind, values and
 * covariance, so the order never depends on arrival), for `span` seconds back. A measurement
 * stamped in the past is applied at its stamp and the intervals since replayed; one stamped
 * up to `ahead` seconds past the newest wheel reading waits until the wheels reach it.
 *
 * The caller owns the three buffers (dd_history_buffers) and may give larger ones whenever a
 * call returns DD_FULL (dd_history_rebuffer copies what they hold); nothing is allocated here.
 * A call that returns anything but DD_OK leaves the history as it was.
 */
#ifndef DIFFDRIVE_HISTORY_H
#define DIFFDRIVE_HISTORY_H

#include "diffdrive/filter.h"

typedef struct {
    dd_interval *intervals;
    long interval_room;
    dd_measurement *measurements; /* those applied, in order */
    long measurement_room;
    dd_measurement *pending; /* those ahead of the wheels */
    long pending_room;
} dd_history_buffers;

typedef struct {
    dd_history_buffers buffers;
    long first, count;                          /* intervals[first .. first + count) */
    long first_measurement, measurement_count;  /* measurements[first_measurement ..) */
    long pending_count;
    double span, ahead;                         /* s */
    long long settled_accepted, settled_refused; /* outcomes of measurements left behind */
    dd_real x[DD_STATES], P[DD_STATES * DD_STATES]; /* the state now */
    int slip;                                   /* the newest interval's slip test */
    dd_real slip_score;
} dd_history;

/* Empty, from state x, P; span and ahead >= 0 (s). DD_BAD_SETTING or DD_NULL otherwise. */
dd_status dd_history_init(dd_history *history, dd_history_buffers buffers, double span,
                          double ahead, const dd_real *x, const dd_real *P);

/* Move what the history holds into larger buffers (the old ones are the caller's again):
 * DD_FULL if any is smaller than what it must hold. */
dd_status dd_history_rebuffer(dd_history *history, dd_history_buffers larger);

/* The interval [t0, t1] of wheel increments dl, dr (rad) and gyro turn g (rad; NaN: none) of
 * variance gv beyond the angle random walk's (rad^2: how far the gyro's samples leave it
 * open; 0 for one angle), forced: declared slipping by the commands. The measurements waiting
 * for it are applied in it. DD_FULL (give larger buffers), DD_OVERFLOW_POSE (the state would
 * not be finite). */
dd_status dd_history_wheels(dd_history *history, const dd_filter *filter, double t0, double t1,
                            dd_real dl, dd_real dr, dd_real g, dd_real gv, int forced);

/* An absolute measurement, with the newest wheel reading at `now` (s; NaN: none yet).
 * *outcome: 1 accepted by the gate, 0 refused by it, -1 waiting for the wheels. Refused,
 * nothing changed: DD_NO_CLOCK, DD_TOO_EARLY (past now + ahead), DD_TOO_OLD (before the
 * history), DD_FULL, DD_OVERFLOW_POSE. */
dd_status dd_history_measure(dd_history *history, const dd_filter *filter, double now,
                             const dd_measurement *m, int *outcome);

/* The state at time t (s) into x, P: replayed from the interval t falls in, the newest
 * state past the last one. Nothing changes. */
void dd_history_state_at(const dd_history *history, const dd_filter *filter, double t,
                         dd_real *x, dd_real *P);

/* The measurements accepted and refused so far, kept and left behind. */
void dd_history_outcomes(const dd_history *history, long long *accepted, long long *refused);

/* Where the history starts (s): its first interval's start, else now. */
double dd_history_start(const dd_history *history, double now);

#endif
