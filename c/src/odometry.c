/* Odometry from wheel readings (see diffdrive/odometry.h): check, step, covariance. */
#include <string.h>
#include "real_math.h"

#include "diffdrive/odometry.h"
#include "step.h"

static dd_real value(dd_sum s) { return s.sum + s.comp; }

/* The heading the step's sines and cosines take. In double, sum + comp: libm reduces a large
 * angle exactly. In float, sum + comp rounds to float before libm sees it, and an hour of
 * turning puts theta at hundreds of rad where a float's step is 1e-5 rad: the sum is reduced
 * by whole turns first (Cody and Waite's three-part 2 pi, each k * part exact for |k| < 2^12),
 * so the angle keeps a float's precision near 0 whatever the turns before. */
static dd_real heading(dd_sum theta) {
#ifdef DD_SINGLE
    /* A and B have 12 significant bits each, C is 2 pi - A - B to a float's precision */
    const float A = 6.28125f, B = 1.9354820251464844e-3f, C = -1.7484555314695172e-7f;
    /* the nearest whole number of turns: adding and taking off 1.5 * 2^23 rounds to it
     * (exactly, below 2^22 turns), without libm's nearbyintf */
    float k = (theta.sum * 0.159154943f + 12582912.0f) - 12582912.0f;
    return ((theta.sum - k * A) - k * B) - k * C + theta.comp;
#else
    return value(theta);
#endif
}

/* The low parts of a step's travel and turn. A float build's readings take few values (a
 * tick count changes by a few dozen counts a reading), so the rounding of r * dl, of the
 * wheels' sum and difference and of the turn's division repeats the same way reading after
 * reading: a bias, not noise, which the compensated sums alone cannot remove (2 mm an hour at
 * 100 Hz in a float build). So a float build carries each of these as a value and its
 * rounding error, found exactly by the FPU's fused multiply-add (the Cortex-M4F has one) and
 * Knuth's TwoSum, and adds the errors' effect on the move to the sums' compensation. A
 * double's rounding is 2^29 times smaller: the double build leaves them out (they are 0 and
 * the compiler drops them). */
#ifdef DD_SINGLE
#define LOW_PARTS 1
#else
#define LOW_PARTS 0
#endif

/* The rounding error of p = a * b, exactly. */
DD_INLINE dd_real product_error(dd_real a, dd_real b, dd_real p) {
    return LOW_PARTS ? dd_fma(a, b, -p) : 0;
}

/* The rounding error of s = a + b, exactly (Knuth's TwoSum). */
DD_INLINE dd_real sum_error(dd_real a, dd_real b, dd_real s) {
    if (!LOW_PARTS) return 0;
    dd_real bb = s - a;
    return (a - (s - bb)) + (b - bb);
}

/* Add term to the sum, carrying the rounding error in comp (Neumaier's variant of Kahan's).
 * A float build then renormalises, so that comp stays below half a unit of sum: the pair is a
 * "double-float" of 48 bits. Without that, comp itself grows (a heading of 3,000 rad after an
 * hour of circling keeps only 5 bits of a 0.008 rad step in sum, the rest in comp) and its
 * own rounding drifts the heading by 4e-4 rad an hour. */
DD_INLINE void add(dd_sum *s, dd_real term) {
    dd_real t = s->sum + term;
    s->comp += dd_fabs(s->sum) >= dd_fabs(term) ? (s->sum - t) + term : (term - t) + s->sum;
    s->sum = t;
    if (LOW_PARTS) { /* Fast2Sum: |sum| >= |comp| */
        t = s->sum + s->comp;
        s->comp -= t - s->sum;
        s->sum = t;
    }
}

typedef struct {
    dd_real dx, dy, dtheta; /* the pose's world-frame move */
    dd_real dx_low, dy_low, dtheta_low; /* the move's low parts (float builds) */
    dd_real travel;         /* how far the reference point moved, m */
    dd_real jac_wheels[6];  /* d(new pose)/d(wheel-angle increments), 3x2 (and d(new pose)/
                               d(pose) is the identity but for its last column, -dy, dx, 1) */
} Step;

/* One step from wheel-angle increments (rad) at heading theta, with its Jacobians: the move's
 * taken through each wheel's arc (d forward = 1/2, d turn = -+1/track per metre). */
static void step(const dd_odometry_config *c, dd_real theta, dd_real dl, dd_real dr,
                 dd_real dl_low, dd_real dr_low, Step *s) {
    const dd_drive *d = &c->drive;
    dd_real left = d->r_left * dl, right = d->r_right * dr;
    dd_real turn = (right - left) / d->track, forward = 0.5 * (left + right);
    dd_real forward_low = 0, turn_low = 0;
    if (LOW_PARTS) {
        dd_real left_low = product_error(d->r_left, dl, left) + d->r_left * dl_low;
        dd_real right_low = product_error(d->r_right, dr, right) + d->r_right * dr_low;
        dd_real sum = left + right, difference = right - left;
        forward_low = 0.5 * (sum_error(left, right, sum) + left_low + right_low);
        dd_real difference_low = sum_error(right, -left, difference) + right_low - left_low;
        turn_low = (dd_fma(-turn, d->track, difference) + difference_low) / d->track;
    }
    dd_real weight = c->method == DD_EULER ? 0.0 : 0.5;
    dd_real bf[2], bt[2];
    dd_move_jacobians(forward, d->offset, turn, weight, c->method == DD_EXACT, theta, &s->dx,
                      &s->dy, bf, bt);
    s->dtheta = turn;
    s->dx_low = bf[0] * forward_low + bt[0] * turn_low; /* the move's first order in them */
    s->dy_low = bf[1] * forward_low + bt[1] * turn_low;
    s->dtheta_low = turn_low;
    /* hypot(forward, 0) is |forward|, exactly: the common case without libm's call */
    s->travel = d->offset == 0.0 ? dd_fabs(forward) : dd_hypot(forward, d->offset * turn);
    const dd_real dturn[2] = {-1.0 / d->track, 1.0 / d->track};
    const dd_real radius[2] = {d->r_left, d->r_right};
    for (int w = 0; w < 2; ++w) {
        s->jac_wheels[w] = radius[w] * (0.5 * bf[0] + dturn[w] * bt[0]);
        s->jac_wheels[2 + w] = radius[w] * (0.5 * bf[1] + dturn[w] * bt[1]);
        s->jac_wheels[4 + w] = radius[w] * dturn[w];
    }
}

/* out <- J cov J^T + W diag(q) W^T, with W 3x2 and J = d(pose after)/d(pose), the identity
 * but for its last column (a, b, 1) = (-dy, dx, 1): written out, without J's zeros and ones,
 * whose terms are exact, so each entry is what the full product gives, to the bit (the
 * Python twin's), in a third of the operations. */
static void propagate(const dd_real c[9], dd_real dx, dd_real dy, const dd_real W[6],
                      const dd_real q[2], dd_real out[9]) {
    const dd_real a = -dy, b = dx;
    /* J c: rows 0 and 1 plus a and b times row 2 */
    const dd_real r0[3] = {c[0] + a * c[6], c[1] + a * c[7], c[2] + a * c[8]};
    const dd_real r1[3] = {c[3] + b * c[6], c[4] + b * c[7], c[5] + b * c[8]};
    const dd_real *r2 = c + 6;
    /* W diag(q), row by row */
    const dd_real n[6] = {W[0] * q[0], W[1] * q[1], W[2] * q[0], W[3] * q[1], W[4] * q[0],
                          W[5] * q[1]};
#define NOISE(i, j) + n[2 * (i)] * W[2 * (j)] + n[2 * (i) + 1] * W[2 * (j) + 1]
    /* (J c) J^T: columns 0 and 1 plus a and b times column 2 */
    out[0] = r0[0] + r0[2] * a NOISE(0, 0);
    out[1] = r0[1] + r0[2] * b NOISE(0, 1);
    out[2] = r0[2] NOISE(0, 2);
    out[3] = r1[0] + r1[2] * a NOISE(1, 0);
    out[4] = r1[1] + r1[2] * b NOISE(1, 1);
    out[5] = r1[2] NOISE(1, 2);
    out[6] = r2[0] + r2[2] * a NOISE(2, 0);
    out[7] = r2[1] + r2[2] * b NOISE(2, 1);
    out[8] = r2[2] NOISE(2, 2);
#undef NOISE
}

/* A time's sign and size by its bits, which a float build reads without a double unit (the
 * comparisons of doubles are library calls there). */
DD_INLINE uint64_t bits_of(double t) {
    uint64_t bits;
    memcpy(&bits, &t, sizeof bits);
    return bits;
}
#define MAGNITUDE(bits) ((bits) & ~((uint64_t)1 << 63)) /* |t|'s bits */
#define INFINITE ((uint64_t)0x7FF << 52)                /* +inf's bits; past them: NaN */

/* 1 unless all nine are finite: v - v is 0 for a finite v and NaN otherwise, so one test
 * covers them (a loop would cost a microcontroller more than the test). */
DD_INLINE int not_finite(dd_real a, dd_real b, dd_real c, dd_real d, dd_real e, dd_real f,
                         dd_real g, dd_real h, dd_real i) {
    return ((a - a) + (b - b) + (c - c)) + ((d - d) + (e - e) + (f - f)) +
               ((g - g) + (h - h) + (i - i)) !=
           0.0;
}

/* Refuse a reading that cannot be right; dt is the time since the last one, NaN if unknown. */
static dd_status check(const dd_odometry *o, dd_real dl, dd_real dr, const double *t, double dt) {
    if (not_finite(dl, dr, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)) return DD_NOT_FINITE;
    if (t == 0) return DD_OK;
    if (MAGNITUDE(bits_of(*t)) >= INFINITE) return DD_NOT_FINITE;
    const uint64_t since = bits_of(dt), size = MAGNITUDE(since);
    if (size > INFINITE) return DD_OK; /* NaN: the time since the last reading is not known */
    if (size == 0) return dl != 0.0 || dr != 0.0 ? DD_TIME_STILL : DD_OK;
    if (since >> 63) return DD_TIME_BACKWARDS;
    /* a float build's speed check in float: 1e-7 of a limit does not matter */
    dd_real fastest = dd_fabs(dl) > dd_fabs(dr) ? dd_fabs(dl) : dd_fabs(dr), step = (dd_real)dt;
    if (!isfinite(fastest / step) || fastest > o->config.max_wheel_speed * step)
        return DD_TOO_FAST;
    return DD_OK;
}

/* Checked, then applied: the next state is made whole before any of it is kept. dt: the time
 * since the last reading (NaN: unknown). */
static dd_status update(dd_odometry *o, dd_real dl, dd_real dr, dd_real dl_low, dd_real dr_low,
                        const double *t, double dt) {
    dd_status status = check(o, dl, dr, t, dt);
    if (status != DD_OK) return status;
    const dd_drive *d = &o->config.drive;
    Step s;
    step(&o->config, heading(o->theta), dl, dr, dl_low, dr_low, &s);
    const dd_real q[2] = {o->config.k_left * dd_fabs(d->r_left * dl) / (d->r_left * d->r_left),
                          o->config.k_right * dd_fabs(d->r_right * dr) / (d->r_right * d->r_right)};
    dd_real cov[9];
    propagate(o->cov, s.dx, s.dy, s.jac_wheels, q, cov);
    dd_sum x = o->x, y = o->y, theta = o->theta, distance = o->distance;
    add(&x, s.dx);
    add(&y, s.dy);
    add(&theta, s.dtheta);
    if (LOW_PARTS) {
        x.comp += s.dx_low;
        y.comp += s.dy_low;
        theta.comp += s.dtheta_low;
    }
    add(&distance, s.travel);
    dd_real arc_left = o->arc_left + d->r_left * dl, arc_right = o->arc_right + d->r_right * dr;
    if (not_finite(value(x), value(y), value(theta), value(distance), arc_left, arc_right, 0.0,
                   0.0, 0.0))
        return DD_OVERFLOW_POSE;
    if (not_finite(cov[0], cov[1], cov[2], cov[3], cov[4], cov[5], cov[6], cov[7], cov[8]))
        return DD_OVERFLOW_COVARIANCE;
    o->x = x, o->y = y, o->theta = theta, o->distance = distance;
    for (int i = 0; i < 9; ++i) o->cov[i] = cov[i];
    o->arc_left = arc_left, o->arc_right = arc_right;
    o->time = t ? *t : (double)NAN; /* without a stamp the clock is lost until the next one */
    return DD_OK;
}

/* The time since the last reading, NaN while unknown or without a stamp. */
static double since(const dd_odometry *o, const double *t) { return t ? *t - o->time : (double)NAN; }

/* A first reading only sets the reference: its time starts the clock. */
static dd_status start(dd_odometry *o, const double *t) {
    if (t == 0) return DD_OK;
    dd_status status = check(o, 0.0, 0.0, t, *t - o->time);
    if (status == DD_OK) o->time = *t;
    return status;
}

dd_status dd_odometry_init(dd_odometry *o, const dd_odometry_config *config) {
    if (o == 0 || config == 0) return DD_NULL;
    const dd_odometry_config *c = config;
    if (dd_drive_check(&c->drive) != DD_OK || c->method < DD_EULER || c->method > DD_EXACT ||
        !(c->ticks_per_revolution >= 0.0) || !isfinite(c->ticks_per_revolution) ||
        c->counter_bits < 0 ||
        c->counter_bits > 64 || !(c->max_wheel_speed > 0.0) || !(c->k_left >= 0.0) ||
        !(c->k_right >= 0.0) || !isfinite(c->k_left) || !isfinite(c->k_right))
        return DD_BAD_SETTING;
    memset(o, 0, sizeof *o);
    o->config = *config;
    o->time = (double)NAN;
    if (c->ticks_per_revolution > 0.0) {
        /* 2 pi as a float and its rounding error: a float build's rad_per_tick to 48 bits */
        const dd_real pi2 = 6.283185307179586, pi2_low = LOW_PARTS ? -1.7484555314695172e-7 : 0;
        o->rad_per_tick = pi2 / c->ticks_per_revolution;
        if (!isfinite(o->rad_per_tick)) return DD_BAD_SETTING;
        if (LOW_PARTS)
            o->rad_per_tick_low = (dd_fma(-o->rad_per_tick, c->ticks_per_revolution, pi2) + pi2_low) /
                                  c->ticks_per_revolution;
    }
    return DD_OK;
}

dd_status dd_tick_change(int bits, int64_t before, int64_t after, int64_t *change) {
    if (bits == 0) {
        if ((after >= 0 && before < 0 && after > INT64_MAX + before) ||
            (after < 0 && before > 0 && after < INT64_MIN + before))
            return DD_COUNTER_RANGE;
        *change = after - before;
    } else if (bits <= 32) { /* in 32 bits, where a microcontroller's counters are */
        uint32_t step = (uint32_t)after - (uint32_t)before;
        if (bits < 32) {
            uint32_t modulus = (uint32_t)1 << bits;
            step &= modulus - 1;
            *change = step >= modulus / 2 ? (int64_t)step - (int64_t)modulus : (int64_t)step;
        } else {
            *change = (int32_t)step;
        }
    } else {
        uint64_t step = (uint64_t)after - (uint64_t)before;
        if (bits < 64) {
            uint64_t modulus = (uint64_t)1 << bits;
            step &= modulus - 1;
            *change = step >= modulus / 2 ? (int64_t)step - (int64_t)modulus : (int64_t)step;
        } else {
            *change = (int64_t)step;
        }
    }
    return DD_OK;
}

/* A reading fits a counter of `bits` bits read signed or unsigned: -2^(bits-1) to 2^bits - 1
 * (64 bits: any int64_t, an unsigned reading past 2^63 kept as its bit pattern). */
static int fits(int bits, int64_t reading) {
    if (bits == 0 || bits == 64) return 1;
    return reading >= -((int64_t)1 << (bits - 1)) && reading <= (int64_t)(((uint64_t)1 << bits) - 1);
}

/* A counter change as a dd_real: through 32 bits where it fits, which a single-precision FPU
 * converts in one instruction (64 bits take a library call). */
static dd_real counts(int64_t change) {
    return change >= INT32_MIN && change <= INT32_MAX ? (dd_real)(int32_t)change : (dd_real)change;
}

dd_status dd_odometry_ticks(dd_odometry *o, const double *t, int64_t left, int64_t right) {
    if (o == 0) return DD_NULL;
    if (o->config.ticks_per_revolution == 0.0) return DD_NO_TICKS;
    int bits = o->config.counter_bits;
    if (!fits(bits, left) || !fits(bits, right)) return DD_COUNTER_RANGE;
    dd_status status;
    if (!o->have_ticks) {
        status = start(o, t);
    } else {
        int64_t change_left, change_right;
        status = dd_tick_change(bits, o->ticks_left, left, &change_left);
        if (status == DD_OK) status = dd_tick_change(bits, o->ticks_right, right, &change_right);
        if (status == DD_OK) {
            const dd_real rad = o->rad_per_tick, low = o->rad_per_tick_low;
            dd_real counts_left = counts(change_left), counts_right = counts(change_right);
            dd_real dl = counts_left * rad, dr = counts_right * rad;
            status = update(o, dl, dr, product_error(counts_left, rad, dl) + counts_left * low,
                            product_error(counts_right, rad, dr) + counts_right * low, t,
                            since(o, t));
        }
    }
    if (status == DD_OK) {
        o->have_ticks = 1;
        o->ticks_left = left;
        o->ticks_right = right;
    }
    return status;
}

dd_status dd_odometry_positions(dd_odometry *o, const double *t, dd_real left, dd_real right) {
    if (o == 0) return DD_NULL;
    if (!isfinite(left) || !isfinite(right)) return DD_NOT_FINITE;
    dd_status status = o->have_positions
                           ? update(o, left - o->position_left, right - o->position_right, 0,
                                    0, t, since(o, t))
                           : start(o, t);
    if (status == DD_OK) {
        o->have_positions = 1;
        o->position_left = left;
        o->position_right = right;
    }
    return status;
}

dd_status dd_odometry_increments(dd_odometry *o, const double *t, dd_real left, dd_real right) {
    if (o == 0) return DD_NULL;
    return update(o, left, right, 0, 0, t, since(o, t));
}

dd_status dd_odometry_velocities(dd_odometry *o, dd_real left, dd_real right, double dt) {
    if (o == 0) return DD_NULL;
    if (!isfinite(left) || !isfinite(right) || !isfinite(dt)) return DD_NOT_FINITE;
    if (!(dt > 0)) return DD_BAD_DT;
    double end = (isnan(o->time) ? 0 : o->time) + dt; /* without a clock, one starts at 0 s */
    return update(o, left * (dd_real)dt, right * (dd_real)dt, 0, 0, &end, dt);
}

void dd_odometry_pose(const dd_odometry *o, dd_real pose[3]) {
    pose[0] = value(o->x);
    pose[1] = value(o->y);
    pose[2] = value(o->theta);
}

dd_real dd_odometry_distance(const dd_odometry *o) { return value(o->distance); }

void dd_odometry_set_pose(dd_odometry *o, const dd_real pose[3], const dd_real cov[9]) {
    const dd_sum zero = {0.0, 0.0};
    o->x = o->y = o->theta = o->distance = zero;
    o->x.sum = pose[0], o->y.sum = pose[1], o->theta.sum = pose[2];
    memcpy(o->cov, cov, sizeof o->cov);
}

void dd_odometry_jacobians(const dd_odometry *o, dd_real left, dd_real right, dd_real jac_pose[9],
                           dd_real jac_wheels[6]) {
    Step s;
    step(&o->config, heading(o->theta), left, right, 0, 0, &s);
    const dd_real pose[9] = {1.0, 0.0, -s.dy, 0.0, 1.0, s.dx, 0.0, 0.0, 1.0};
    memcpy(jac_pose, pose, sizeof pose);
    memcpy(jac_wheels, s.jac_wheels, sizeof s.jac_wheels);
}
