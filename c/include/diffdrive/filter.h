/* diffdrive's C core: the pose estimator's filter step, the maths of
 * diffdrive/estimation/filter.py.
 *
 * The state (DD_STATES = 8): x, y, theta (m, m, rad), the gyro's bias (rad/s), the turn
 * scale, the distance scale, and the position fixes' offset x, y (m). The states not
 * estimated keep their values and zero rows and columns in P (8 x 8, row-major).
 *
 * One interval of wheel readings is predicted with the wheels and the gyro (dd_filter_predict):
 * the heading from the wheels (DD_FROM_WHEELS), the gyro (DD_FROM_GYRO) or both, the wheels'
 * turn then a measurement of the gyro's (DD_FROM_BOTH). An absolute measurement (a pose, a
 * position or a heading) corrects it (dd_filter_correct), gated by its Mahalanobis distance.
 * dd_filter_interval runs an interval with the measurements that fall in it; a history of
 * intervals, which lets a late measurement be applied at its stamp and the intervals since
 * replayed, lives in buffers the caller gives (dd_history, history.h).
 *
 * No allocation, no global state, no I/O.
 */
#ifndef DIFFDRIVE_FILTER_H
#define DIFFDRIVE_FILTER_H

#include "diffdrive/kinematics.h"

#define DD_STATES 8
enum { DD_BIAS = 3, DD_SCALE = 4, DD_DISTANCE = 5, DD_OFFSET = 6 };
enum { DD_FROM_WHEELS = 0, DD_FROM_GYRO = 1, DD_FROM_BOTH = 2 }; /* the heading's source */
enum { DD_POSE = 0, DD_POSITION = 1, DD_HEADING = 2 };           /* a measurement's kind */

typedef struct {
    dd_drive drive;
    int method;  /* DD_EULER, DD_RK2 or DD_EXACT (odometry.h) */
    int heading; /* DD_FROM_WHEELS, DD_FROM_GYRO or DD_FROM_BOTH */
    int estimate_bias, estimate_scale, estimate_distance, estimate_offset; /* 0 or 1 */
    dd_real k_left, k_right;  /* m: each wheel's travel variance per metre */
    dd_real wheel_floor;      /* rad^2: each wheel angle increment's least variance (its
                                 counter's rounding, (2 pi / counts)^2 / 6); 0: none */
    dd_real arw2;             /* the gyro's angle random walk, rad^2/s */
    dd_real rrw2;             /* its bias's random walk, (rad/s)^2/s */
    dd_real offset_rate2;     /* the fixes' offset's random walk, m^2/s */
    dd_real slip_threshold;   /* the slip test's chi-square threshold (1 dof) */
    dd_real slip_inflation;   /* how much a slipping interval's wheel noise grows */
    dd_real gates[3];         /* chi-square gates for measurements of 1, 2 and 3 values */
    int inflate;              /* past the gate: 1 takes it with its covariance grown, 0 refuses */
    dd_real reference_offset; /* m: the state's reference point left of the body origin */
} dd_filter_config;

typedef struct {
    dd_filter_config config;
    /* derived from it by dd_filter_init */
    dd_real weight, k_per_r_left, k_per_r_right;
    int chord, carried; /* carried: how many leading states move (3, 4, 5, 6 or 8) */
} dd_filter;

/* An absolute measurement: its stamp (s), kind, size (3, 2 or 1 values), values, covariance
 * (size x size, row-major), the antenna's or marker's lever arm (m, body frame), and, once
 * applied, whether the gate accepted it, its squared Mahalanobis distance and the log
 * determinant of its innovation's covariance. */
typedef struct {
    double t;
    int kind, size;
    dd_real value[3], cov[9], lever[2];
    int accepted;
    dd_real score, log_det;
} dd_measurement;

/* The smoother's record of one step: the state before it given the data to its end, the
 * state after it (before any absolute measurement), and the Rauch-Tung-Striebel gain. */
typedef struct {
    dd_real before[DD_STATES], before_cov[DD_STATES * DD_STATES];
    dd_real after[DD_STATES], after_cov[DD_STATES * DD_STATES];
    dd_real gain[DD_STATES * DD_STATES];
} dd_filter_record;

/* One interval of wheel data: [t0, t1] s, the wheels' angle increments (rad), the gyro's
 * turn (rad; NaN: none) and its variance beyond the angle random walk's (gv, rad^2: how far
 * its samples leave the turn between them open; 0 where unknown), whether the commands declared it slipping (forced), and, once run,
 * the slip test's outcome and score. x and P: the state at its start, where a history keeps
 * it (P packed: the carried block, n x n). */
typedef struct {
    double t0, t1;
    dd_real dl, dr, g, gv;
    int forced, slip;
    dd_real score;
    dd_real x[DD_STATES], P[DD_STATES * DD_STATES];
} dd_interval;

/* An interval's data, its state and outcomes left unset (a history fills them). */
void dd_interval_set(dd_interval *iv, double t0, double t1, dd_real dl, dd_real dr, dd_real g,
                     dd_real gv, int forced);

/* DD_OK, DD_NULL, or DD_BAD_SETTING (a radius, gate or noise out of range). */
dd_status dd_filter_init(dd_filter *filter, const dd_filter_config *config);

/* The slip test's score: the squared, normalised gap between the wheels' turn (scaled) and
 * the gyro's over an interval (gv: the gyro turn's variance beyond its random walk's). */
dd_real dd_filter_slip_score(const dd_filter *filter, const dd_real *x, const dd_real *P,
                             dd_real dl, dd_real dr, dd_real g, dd_real gv, dd_real dt);

/* One step of dt s by wheel increments dl, dr (rad) and gyro turn g (rad; of variance gv
 * beyond its random walk's, rad^2), in place on x and P; slip: the interval slips (its wheels' noise inflated, their turn not fused). record:
 * NULL, or where the smoother's record of the step goes. */
void dd_filter_predict(const dd_filter *filter, dd_real *x, dd_real *P, dd_real dl, dd_real dr,
                       dd_real g, dd_real gv, dd_real dt, int slip, dd_filter_record *record);

/* Apply an absolute measurement to x, P (unchanged when the gate refuses it); sets its
 * accepted, score and log_det. */
void dd_filter_correct(const dd_filter *filter, dd_real *x, dd_real *P, dd_measurement *m);

#ifndef DD_NO_SMOOTHER
/* The Rauch-Tung-Striebel step backwards through a record: x, P smoothed after it in,
 * smoothed before it out. A build with DD_NO_SMOOTHER leaves the smoother out (a robot does
 * not smooth its own past on line; the host does it over whole logs): it has no
 * dd_filter_smooth, and the record pointers below must be NULL there. */
void dd_filter_smooth(const dd_filter_record *record, dd_real *x, dd_real *P);
#endif

/* Run interval iv over the measurements m[0..count) (sorted by stamp; those in it): from its
 * start state in x, P to its end (record_outcomes: the slip test and the measurements'
 * outcomes kept) or to `stop` s (nothing kept). steps: NULL, or room for one record per step
 * (count + 1), their number into *nsteps. */
void dd_filter_interval(const dd_filter *filter, dd_interval *iv, dd_measurement *m, long count,
                        int record_outcomes, double stop, dd_real *x, dd_real *P,
                        dd_filter_record *steps, long *nsteps);

/* The Cholesky factor L (lower, k x k row-major) of a k x k matrix A (k <= 3): DD_OK, or
 * DD_BAD_SETTING unless A is positive definite. */
dd_status dd_cholesky(const dd_real *A, int k, dd_real *L);

/* 1 if every value of x (8) and P (64) is finite. */
int dd_filter_finite(const dd_real *x, const dd_real *P);

#endif
