/* The estimator's history in the caller's buffers (see diffdrive/history.h). */
#include <string.h>

#include "diffdrive/history.h"

#define N DD_STATES
#define NN (DD_STATES * DD_STATES)

/* Measurement.order: -1, 0 or 1 as a sorts before, with or after b: by stamp, then kind
 * ("heading" < "pose" < "position", as Python compares the names), values, covariance. */
static int order(const dd_measurement *a, const dd_measurement *b) {
    static const int rank[3] = {1, 2, 0}; /* DD_POSE, DD_POSITION, DD_HEADING */
    if (a->t != b->t) return a->t < b->t ? -1 : 1;
    if (a->kind != b->kind) return rank[a->kind] < rank[b->kind] ? -1 : 1;
    for (int i = 0; i < a->size; ++i)
        if (a->value[i] != b->value[i]) return a->value[i] < b->value[i] ? -1 : 1;
    for (int i = 0; i < a->size * a->size; ++i)
        if (a->cov[i] != b->cov[i]) return a->cov[i] < b->cov[i] ? -1 : 1;
    return 0;
}

/* The first measurement index (absolute) whose stamp is > t (>= t if inclusive). */
static long first_after(const dd_history *h, double t, int inclusive) {
    const dd_measurement *ms = h->buffers.measurements;
    long lo = h->first_measurement, hi = h->first_measurement + h->measurement_count;
    while (lo < hi) {
        long mid = (lo + hi) / 2;
        int before = inclusive ? ms[mid].t < t : ms[mid].t <= t;
        if (before)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

/* The measurements of interval i (absolute index): (t0, t1], or [t0, t1] for the first. */
static void slice_of(const dd_history *h, long i, long *lo, long *hi) {
    const dd_interval *iv = &h->buffers.intervals[i];
    *lo = first_after(h, iv->t0, i == h->first);
    *hi = first_after(h, iv->t1, 0);
}

/* P's block of the carried states, n x n row by row: what an interval keeps. */
static void pack(const dd_filter *f, dd_real *packed, const dd_real *P) {
    const int n = f->carried;
    for (int i = 0; i < n; ++i) /* element by element: memcpy's setup would cost more here */
        for (int j = 0; j < n; ++j) packed[i * n + j] = P[i * N + j];
}

/* P in full from its packed block, zero elsewhere (the states not carried). */
static void unpack(const dd_filter *f, dd_real *P, const dd_real *packed) {
    const int n = f->carried;
    for (int i = 0; i < N; ++i)
        for (int j = 0; j < N; ++j) P[i * N + j] = i < n && j < n ? packed[i * n + j] : 0.0;
}

/* Replay intervals from absolute index k on: x, P the state after the newest. */
static void replay(dd_history *h, const dd_filter *f, long k, dd_real *x, dd_real *P) {
    dd_interval *iv = h->buffers.intervals;
    dd_measurement *ms = h->buffers.measurements;
    memcpy(x, iv[k].x, sizeof iv[k].x);
    unpack(f, P, iv[k].P);
    long lo, hi, end = h->first_measurement + h->measurement_count;
    slice_of(h, k, &lo, &hi);
    for (long i = k; i < h->first + h->count; ++i) {
        memcpy(iv[i].x, x, sizeof iv[i].x);
        pack(f, iv[i].P, P);
        if (i > k) { /* the slices follow one another */
            lo = hi;
            while (hi < end && ms[hi].t <= iv[i].t1) ++hi;
        }
        dd_filter_interval(f, &iv[i], ms + lo, hi - lo, 1, 0.0, x, P, 0, 0);
    }
}

/* Room for `wanted` items from *first in a buffer of `room` holding `live` of them: as it is,
 * or with them moved to the front while they fill at most half of it (a move of the live
 * items then comes at most once every so many appends); 0 if neither. */
static int make_room(void *array, long *first, long live, long wanted, long room, size_t size) {
    if (*first + wanted < room) return 1;
    if (*first > 0 && 2 * wanted <= room) {
        memmove(array, (char *)array + *first * size, live * size);
        *first = 0;
        return 1;
    }
    return 0;
}

/* Leave behind the intervals that start more than span before the newest one's end, and the
 * measurements in them, counting their outcomes. */
static void trim(dd_history *h) {
    const dd_interval *iv = h->buffers.intervals;
    double newest = iv[h->first + h->count - 1].t1;
    while (h->count > 1 && iv[h->first + 1].t0 < newest - h->span) {
        long lo, hi;
        slice_of(h, h->first, &lo, &hi);
        for (long j = h->first_measurement; j < hi; ++j) {
            if (h->buffers.measurements[j].accepted)
                h->settled_accepted++;
            else
                h->settled_refused++;
        }
        h->measurement_count -= hi - h->first_measurement;
        h->first_measurement = hi;
        h->first++;
        h->count--;
    }
    if (h->measurement_count == 0) h->first_measurement = 0;
}

dd_status dd_history_init(dd_history *h, dd_history_buffers buffers, double span, double ahead,
                          const dd_real *x, const dd_real *P) {
    if (h == 0 || x == 0 || P == 0) return DD_NULL;
    if (!(span >= 0) || !(ahead >= 0)) return DD_BAD_SETTING;
    memset(h, 0, sizeof *h);
    h->buffers = buffers;
    h->span = span;
    h->ahead = ahead;
    memcpy(h->x, x, sizeof h->x);
    memcpy(h->P, P, sizeof h->P);
    return DD_OK;
}

dd_status dd_history_rebuffer(dd_history *h, dd_history_buffers b) {
    if (h == 0) return DD_NULL;
    if (b.interval_room < h->count || b.measurement_room < h->measurement_count ||
        b.pending_room < h->pending_count)
        return DD_FULL;
    const dd_history_buffers *old = &h->buffers;
    memmove(b.intervals, old->intervals + h->first, h->count * sizeof *b.intervals);
    memmove(b.measurements, old->measurements + h->first_measurement,
            h->measurement_count * sizeof *b.measurements);
    memmove(b.pending, old->pending, h->pending_count * sizeof *b.pending);
    h->buffers = b;
    h->first = h->first_measurement = 0;
    return DD_OK;
}

dd_status dd_history_wheels(dd_history *h, const dd_filter *f, double t0, double t1,
                            dd_real dl, dd_real dr, dd_real g, dd_real gv, int forced) {
    if (h == 0 || f == 0) return DD_NULL;
    dd_history_buffers *b = &h->buffers;
    long due = 0; /* the measurements that waited for the wheels and are due now */
    for (long i = 0; i < h->pending_count; ++i)
        if (b->pending[i].t <= t1) ++due;
    if (!make_room(b->measurements, &h->first_measurement, h->measurement_count,
                   h->measurement_count + due, b->measurement_room, sizeof *b->measurements) ||
        !make_room(b->intervals, &h->first, h->count, h->count + 1, b->interval_room,
                   sizeof *b->intervals))
        return DD_FULL;
    /* the due ones after the kept ones, in order (not kept until the interval succeeds) */
    dd_measurement *tail = b->measurements + h->first_measurement + h->measurement_count;
    long n = 0;
    for (long i = 0; i < h->pending_count; ++i)
        if (b->pending[i].t <= t1) {
            long at = n++;
            while (at > 0 && order(&tail[at - 1], &b->pending[i]) > 0) {
                tail[at] = tail[at - 1];
                --at;
            }
            tail[at] = b->pending[i];
        }
    dd_interval *iv = &b->intervals[h->first + h->count];
    dd_interval_set(iv, t0, t1, dl, dr, g, gv, forced);
    memcpy(iv->x, h->x, sizeof h->x);
    pack(f, iv->P, h->P);
    dd_real x[N], P[NN];
    memcpy(x, h->x, sizeof x);
    memcpy(P, h->P, sizeof P);
    dd_filter_interval(f, iv, tail, due, 1, 0.0, x, P, 0, 0);
    if (!dd_filter_finite(x, P)) return DD_OVERFLOW_POSE;
    h->measurement_count += due;
    long kept = 0;
    for (long i = 0; i < h->pending_count; ++i)
        if (b->pending[i].t > t1) b->pending[kept++] = b->pending[i];
    h->pending_count = kept;
    h->count++;
    memcpy(h->x, x, sizeof x);
    memcpy(h->P, P, sizeof P);
    h->slip = iv->slip;
    h->slip_score = iv->score;
    trim(h);
    return DD_OK;
}

dd_status dd_history_measure(dd_history *h, const dd_filter *f, double now,
                             const dd_measurement *m, int *outcome) {
    if (h == 0 || f == 0 || m == 0 || outcome == 0) return DD_NULL;
    dd_history_buffers *b = &h->buffers;
    if (now != now) return DD_NO_CLOCK; /* NaN: no wheel reading yet */
    if (m->t > now + h->ahead) return DD_TOO_EARLY;
    if (m->t > now) { /* it waits for the wheels */
        long none = 0;
        if (!make_room(b->pending, &none, h->pending_count, h->pending_count + 1,
                       b->pending_room, sizeof *b->pending))
            return DD_FULL;
        b->pending[h->pending_count++] = *m;
        *outcome = -1;
        return DD_OK;
    }
    if (h->count == 0 || m->t < b->intervals[h->first].t0) {
        if (!(m->t == now && h->count == 0)) return DD_TOO_OLD;
        /* at the start itself */
        dd_real x[N], P[NN];
        dd_measurement applied = *m;
        memcpy(x, h->x, sizeof x);
        memcpy(P, h->P, sizeof P);
        dd_filter_correct(f, x, P, &applied);
        if (!dd_filter_finite(x, P)) return DD_OVERFLOW_POSE;
        memcpy(h->x, x, sizeof x);
        memcpy(h->P, P, sizeof P);
        if (applied.accepted)
            h->settled_accepted++;
        else
            h->settled_refused++;
        *outcome = applied.accepted;
        return DD_OK;
    }
    /* the interval it falls in, and its place among the measurements */
    long lo = h->first, hi = h->first + h->count;
    while (lo < hi) {
        long mid = (lo + hi) / 2;
        if (b->intervals[mid].t1 < m->t)
            lo = mid + 1;
        else
            hi = mid;
    }
    long k = lo;
    if (!make_room(b->measurements, &h->first_measurement, h->measurement_count,
                   h->measurement_count + 1, b->measurement_room, sizeof *b->measurements))
        return DD_FULL;
    long end = h->first_measurement + h->measurement_count, at = end;
    while (at > h->first_measurement && order(&b->measurements[at - 1], m) > 0) --at;
    memmove(b->measurements + at + 1, b->measurements + at, (end - at) * sizeof *m);
    b->measurements[at] = *m;
    h->measurement_count++;
    dd_real x[N], P[NN];
    replay(h, f, k, x, P);
    if (!dd_filter_finite(x, P)) {
        /* the history as it was: without the measurement, the same replay gives back, to the
         * bit, the states and outcomes it had (nothing else changed) */
        memmove(b->measurements + at, b->measurements + at + 1, (end - at) * sizeof *m);
        h->measurement_count--;
        replay(h, f, k, x, P);
        return DD_OVERFLOW_POSE;
    }
    memcpy(h->x, x, sizeof x);
    memcpy(h->P, P, sizeof P);
    *outcome = b->measurements[at].accepted;
    return DD_OK;
}

void dd_history_state_at(const dd_history *h, const dd_filter *f, double t, dd_real *x,
                         dd_real *P) {
    const dd_history_buffers *b = &h->buffers;
    long lo = h->first, hi = h->first + h->count;
    while (lo < hi) {
        long mid = (lo + hi) / 2;
        if (b->intervals[mid].t1 < t)
            lo = mid + 1;
        else
            hi = mid;
    }
    if (lo == h->first + h->count) {
        memcpy(x, h->x, sizeof h->x);
        memcpy(P, h->P, sizeof h->P);
        return;
    }
    long a, z;
    slice_of(h, lo, &a, &z);
    dd_interval copy = b->intervals[lo];
    memcpy(x, copy.x, sizeof copy.x);
    unpack(f, P, copy.P);
    dd_filter_interval(f, &copy, b->measurements + a, z - a, 0, t, x, P, 0, 0);
}

void dd_history_outcomes(const dd_history *h, long long *accepted, long long *refused) {
    *accepted = h->settled_accepted;
    *refused = h->settled_refused;
    for (long j = h->first_measurement; j < h->first_measurement + h->measurement_count; ++j) {
        if (h->buffers.measurements[j].accepted)
            ++*accepted;
        else
            ++*refused;
    }
}

double dd_history_start(const dd_history *h, double now) {
    return h->count ? h->buffers.intervals[h->first].t0 : now;
}
