/* The command limiter (see diffdrive/limiter.h), as diffdrive.control.limiter. */
#include <string.h>
#include "real_math.h"

#include "diffdrive/limiter.h"

static int positive_or_none(dd_real v, int zero_allowed) {
    return zero_allowed ? v >= 0.0 : v > 0.0; /* INFINITY passes, NaN does not */
}

dd_status dd_limiter_init(dd_limiter *l, int channels, const dd_limits *limits, dd_real timeout) {
    if (l == 0 || limits == 0) return DD_NULL;
    if (channels < 1 || channels > DD_LIMITER_CHANNELS || !positive_or_none(timeout, 0))
        return DD_BAD_SETTING;
    for (int i = 0; i < channels; ++i) {
        const dd_limits *c = &limits[i];
        if (!positive_or_none(c->max_velocity, 0) || !positive_or_none(c->max_reverse_velocity, 1) ||
            !positive_or_none(c->max_jerk, 0) ||
            !positive_or_none(c->max_acceleration, 0) ||
            !positive_or_none(c->max_deceleration, 0) ||
            !positive_or_none(c->max_reverse_acceleration, 0) ||
            !positive_or_none(c->max_reverse_deceleration, 0))
            return DD_BAD_SETTING;
    }
    memset(l, 0, sizeof *l);
    l->channels = channels;
    memcpy(l->limits, limits, channels * sizeof *limits);
    l->timeout = timeout;
    return DD_OK;
}

static dd_real sign_of(dd_real x) { return x > 0.0 ? 1.0 : x < 0.0 ? -1.0 : 0.0; }

static dd_real clip(dd_real x, dd_real low, dd_real high) {
    return dd_fmin(dd_fmax(x, low), high);
}

/* A channel's bounds toward goal from v: the acceleration up and down as the motion's
 * direction makes them (speeding up or slowing down, forward or reverse), and the one the gap
 * asks for. */
typedef struct {
    dd_real gap, rising, falling, bound;
} Toward;

static Toward toward(const dd_limits *c, dd_real v, dd_real goal) {
    Toward w;
    w.gap = goal - v;
    int up = w.gap > 0.0, forward = v != 0.0 ? v > 0.0 : up;
    w.rising = forward ? c->max_acceleration : c->max_reverse_deceleration;
    w.falling = forward ? c->max_deceleration : c->max_reverse_acceleration;
    w.bound = up ? w.rising : w.falling;
    return w;
}

/* How far channel c can go from v toward goal in dt s under its acceleration limits; through
 * zero it slows to rest, then speeds up the other way. */
static dd_real reachable(const dd_limits *c, dd_real v, dd_real goal, dd_real dt) {
    Toward w = toward(c, v, goal);
    int up = w.gap > 0.0;
    dd_real other = up ? c->max_acceleration : c->max_reverse_acceleration;
    dd_real to_rest = dd_fabs(v) / w.bound;
    int crosses = ((v > 0.0 && !up) || (v < 0.0 && up)) && to_rest < dt;
    dd_real reach = crosses ? dd_fabs(v) + other * (dt - to_rest) : w.bound * dt;
    return v + sign_of(w.gap) * dd_fmin(reach, dd_fabs(w.gap));
}

/* The next acceleration toward gap: at most bound toward it, within falling and rising,
 * changed by at most jerk dt, and no more than the one from which ramping down by jerk dt a
 * step still ends at rest on the goal: a dt + a (a - j dt) / (2 j) <= |gap|. */
static dd_real jerk_limited(dd_real gap, dd_real a, dd_real bound, dd_real falling,
                            dd_real rising, dd_real jerk, dd_real dt) {
    dd_real j_dt = jerk * dt;
    dd_real approach = 0.5 * (dd_sqrt(j_dt * j_dt + 8.0 * jerk * dd_fabs(gap)) - j_dt);
    dd_real wanted = sign_of(gap) * dd_fmin(dd_fmin(bound, approach), dd_fabs(gap) / dt);
    return clip(clip(wanted, a - j_dt, a + j_dt), -falling, rising);
}

/* A jerk-limited step v -> next held to the hard limits at rest: it stops there rather than
 * go on past it away from the goal, and past rest toward the goal it speeds up the other way
 * within that direction's acceleration limit, over the part of the step after rest. */
static dd_real through_rest(const dd_limits *c, dd_real v, dd_real next, dd_real goal,
                            dd_real dt) {
    int into_reverse = next < 0.0 && v >= 0.0, into_forward = next > 0.0 && v <= 0.0;
    if ((into_reverse && goal > 0.0) || (into_forward && goal < 0.0)) return 0.0;
    if (!into_reverse && !into_forward) return next;
    dd_real to_rest = v != 0.0 ? dd_fabs(v) * dt / dd_fabs(next - v) : 0.0;
    dd_real limit = into_reverse ? c->max_reverse_acceleration : c->max_acceleration;
    return sign_of(next) * dd_fmin(dd_fabs(next), limit * dd_fmax(dt - to_rest, 0.0));
}

/* The acceleration a as a rate of fractions of gap per s^2 (into *rate), if it points along
 * the gap or is zero, so that moving all channels by one fraction keeps the jerk limits. */
static int rate_along(const dd_real *a, const dd_real *gap, int n, dd_real *rate) {
    dd_real length = 0.0, along = 0.0, off = 0.0, size = 0.0;
    for (int i = 0; i < n; ++i) {
        length += gap[i] * gap[i];
        along += a[i] * gap[i];
    }
    if (length < DD_SQUARE_FLOOR) return 0; /* no gap, or one too small to divide by */
    *rate = along / length;
    for (int i = 0; i < n; ++i) {
        dd_real rest = a[i] - *rate * gap[i];
        off += rest * rest;
        size += a[i] * a[i];
    }
    return dd_sqrt(off) <= 1e-9 * dd_sqrt(size);
}

/* Each channel's next value toward goal under jerk limits (some channel has one): every
 * channel the same fraction of its gap, by one jerk-limited profile of that fraction in the
 * tightest channel's limits, when all have a jerk limit and the acceleration points along the
 * gap; else each channel its own profile (and one without a jerk limit its plain reach). */
static void jerk_step(const dd_limiter *l, const dd_real *goal, dd_real dt, dd_real *next) {
    const int n = l->channels;
    dd_real gap[DD_LIMITER_CHANNELS], rate, largest = 0.0;
    int all = 1;
    for (int i = 0; i < n; ++i) {
        gap[i] = goal[i] - l->value[i];
        largest = dd_fmax(largest, dd_fabs(gap[i]));
        all = all && isfinite(l->limits[i].max_jerk);
    }
    if (all && rate_along(l->acceleration, gap, n, &rate)) {
        dd_real near = (dd_real)INFINITY, far = (dd_real)INFINITY, jerk = (dd_real)INFINITY;
        for (int i = 0; i < n; ++i) {
            if (!(dd_fabs(gap[i]) > 1e-9 * largest)) continue; /* the others move a hair too */
            Toward w = toward(&l->limits[i], l->value[i], goal[i]);
            dd_real size = dd_fabs(gap[i]);
            near = dd_fmin(near, (gap[i] > 0.0 ? w.rising : w.falling) / size);
            far = dd_fmin(far, (gap[i] > 0.0 ? w.falling : w.rising) / size);
            jerk = dd_fmin(jerk, l->limits[i].max_jerk / size);
        }
        dd_real fraction = jerk_limited(1.0, rate, near, far, near, jerk, dt) * dt;
        for (int i = 0; i < n; ++i)
            next[i] = dd_fabs(1.0 - fraction) <= 1e-12
                          ? goal[i]
                          : through_rest(&l->limits[i], l->value[i],
                                         l->value[i] + fraction * gap[i], goal[i], dt);
        return;
    }
    for (int i = 0; i < n; ++i) {
        const dd_limits *c = &l->limits[i];
        if (!isfinite(c->max_jerk)) {
            next[i] = reachable(c, l->value[i], goal[i], dt);
            continue;
        }
        Toward w = toward(c, l->value[i], goal[i]);
        dd_real a = jerk_limited(w.gap, l->acceleration[i], w.bound, w.falling, w.rising,
                                 c->max_jerk, dt);
        /* the acceleration decides the step, even past the goal (stopping short of it would
         * make the acceleration jump); it lands on the goal when it can */
        int lands = dd_fabs(w.gap - a * dt) <= 1e-12 * dd_fmax(1.0, dd_fabs(goal[i]));
        next[i] = lands ? goal[i] : through_rest(c, l->value[i], l->value[i] + a * dt, goal[i], dt);
    }
}

dd_status dd_limiter_step(dd_limiter *l, const dd_real *target, dd_real dt, dd_real *out) {
    if (l == 0 || out == 0) return DD_NULL;
    if (!isfinite(dt) || !(dt > 0.0)) return DD_BAD_DT;
    const int n = l->channels;
    dd_real held[DD_LIMITER_CHANNELS], goal[DD_LIMITER_CHANNELS], next[DD_LIMITER_CHANNELS];
    int jerks = 0;
    for (int i = 0; i < n; ++i) {
        held[i] = target ? target[i] : l->target[i];
        if (!isfinite(held[i])) return DD_NOT_FINITE;
        jerks += isfinite(l->limits[i].max_jerk) != 0;
    }
    dd_real since = target ? 0.0 : l->since + dt, scale = 1.0;
    for (int i = 0; i < n; ++i) { /* one factor into every channel's velocity limit */
        dd_real limit = held[i] >= 0.0 ? l->limits[i].max_velocity
                                       : l->limits[i].max_reverse_velocity;
        if (dd_fabs(held[i]) > limit) scale = dd_fmin(scale, limit / dd_fabs(held[i]));
    }
    for (int i = 0; i < n; ++i) goal[i] = since >= l->timeout ? 0.0 : held[i] * scale;
    if (jerks) {
        jerk_step(l, goal, dt, next);
    } else { /* every channel the same fraction of its way, the smallest any allows */
        dd_real fraction = 1.0;
        for (int i = 0; i < n; ++i) {
            dd_real gap = goal[i] - l->value[i];
            next[i] = reachable(&l->limits[i], l->value[i], goal[i], dt);
            if (gap != 0.0) fraction = dd_fmin(fraction, (next[i] - l->value[i]) / gap);
        }
        fraction = dd_fmax(fraction, 0.0);
        for (int i = 0; i < n; ++i) {
            dd_real gap = goal[i] - l->value[i];
            next[i] = gap != 0.0 ? l->value[i] + fraction * gap : goal[i];
        }
    }
    for (int i = 0; i < n; ++i) { /* a jerk profile may run past the goal; never past a limit */
        next[i] = clip(next[i], -l->limits[i].max_reverse_velocity, l->limits[i].max_velocity);
        if (!isfinite(next[i]) || !isfinite((next[i] - l->value[i]) / dt)) return DD_NOT_FINITE;
    }
    for (int i = 0; i < n; ++i) {
        l->acceleration[i] = (next[i] - l->value[i]) / dt;
        l->value[i] = out[i] = next[i];
        l->target[i] = held[i];
    }
    l->since = since;
    return DD_OK;
}
