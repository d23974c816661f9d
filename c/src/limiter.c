/* The command limiter (see diffdrive/limiter.h), as diffdrive.control.limiter without jerk. */
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

/* How far channel c can go from v toward goal in dt s under its acceleration limits. */
static dd_real reachable(const dd_limits *c, dd_real v, dd_real goal, dd_real dt) {
    dd_real gap = goal - v;
    int up = gap > 0.0;
    int forward = v != 0.0 ? v > 0.0 : up;
    dd_real rising = forward ? c->max_acceleration : c->max_reverse_deceleration;
    dd_real falling = forward ? c->max_deceleration : c->max_reverse_acceleration;
    dd_real bound = up ? rising : falling;
    dd_real other = up ? c->max_acceleration : c->max_reverse_acceleration;
    dd_real to_rest = dd_fabs(v) / bound;
    int crosses = ((v > 0.0 && !up) || (v < 0.0 && up)) && to_rest < dt;
    dd_real reach = crosses ? dd_fabs(v) + other * (dt - to_rest) : bound * dt;
    dd_real sign = gap > 0.0 ? 1.0 : gap < 0.0 ? -1.0 : 0.0;
    return v + sign * dd_fmin(reach, dd_fabs(gap));
}

dd_status dd_limiter_step(dd_limiter *l, const dd_real *target, dd_real dt, dd_real *out) {
    if (l == 0 || out == 0) return DD_NULL;
    if (!isfinite(dt) || !(dt > 0.0)) return DD_BAD_DT;
    const int n = l->channels;
    dd_real held[DD_LIMITER_CHANNELS], goal[DD_LIMITER_CHANNELS], next[DD_LIMITER_CHANNELS];
    for (int i = 0; i < n; ++i) {
        held[i] = target ? target[i] : l->target[i];
        if (!isfinite(held[i])) return DD_NOT_FINITE;
    }
    dd_real since = target ? 0.0 : l->since + dt, scale = 1.0;
    for (int i = 0; i < n; ++i) { /* one factor into every channel's velocity limit */
        dd_real limit = held[i] >= 0.0 ? l->limits[i].max_velocity
                                       : l->limits[i].max_reverse_velocity;
        if (dd_fabs(held[i]) > limit) scale = dd_fmin(scale, limit / dd_fabs(held[i]));
    }
    for (int i = 0; i < n; ++i) goal[i] = since >= l->timeout ? 0.0 : held[i] * scale;
    dd_real fraction = 1.0;
    for (int i = 0; i < n; ++i) {
        dd_real gap = goal[i] - l->value[i];
        next[i] = reachable(&l->limits[i], l->value[i], goal[i], dt);
        if (gap != 0.0) fraction = dd_fmin(fraction, (next[i] - l->value[i]) / gap);
    }
    fraction = dd_fmax(fraction, 0.0);
    for (int i = 0; i < n; ++i) {
        dd_real gap = goal[i] - l->value[i];
        dd_real v = gap != 0.0 ? l->value[i] + fraction * gap : goal[i];
        next[i] = dd_fmax(dd_fmin(v, l->limits[i].max_velocity), -l->limits[i].max_reverse_velocity);
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
