/* diffdrive.estimation.PoseEstimator's core for Python: the C library's filter step
 * (c/src/filter.c, the same source the firmware builds) with the history and the Python
 * objects around it, so that a wheel and gyro update costs about a microsecond and a late
 * measurement a few. The compiled twin of estimation/_estimator_python.py, which it mirrors
 * step for step (the tests hold the two together).
 *
 * The wheels are read by an OdometryCore kept alongside (_odometry.c): its checks refuse a
 * reading before anything changes, and its snapshot takes a reading back when the filter's
 * own step refuses it. The history keeps each wheel interval with the state at its start;
 * absolute measurements are kept in one array in the order of Measurement.order (stamp, kind,
 * values, covariance), and a measurement stamped in the past is applied at its stamp and the
 * intervals since replayed.
 *
 * A whole log (_run_log, estimate_trajectory's pass) runs without the history: forward
 * interval by interval, then, for the smoother, back, each interval run again from its
 * filtered start with the smoother's record of each step (the filter step's own, see
 * dd_filter_predict) and the Rauch-Tung-Striebel correction applied through it.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <string.h>

#include "_odometry.h"
#include "diffdrive/filter.h"

#define N DD_STATES
#define NN (DD_STATES * DD_STATES)
enum { WHEELS = DD_FROM_WHEELS, GYRO = DD_FROM_GYRO, FUSED = DD_FROM_BOTH };
enum { POSE = DD_POSE, POSITION = DD_POSITION, HEADING = DD_HEADING };
static const char *KIND_NAMES[3] = {"pose", "position", "heading"};
static const int KIND_RANK[3] = {1, 2, 0}; /* "heading" < "pose" < "position", as Python's */
static const char *UPDATES[4] = {"update_ticks", "update_positions", "update_increments",
                                 "update_velocities"};
#define SLIP_COMMAND_THRESHOLD 13.82

typedef dd_measurement Meas;

typedef dd_interval Interval;
typedef dd_filter_record Step;
/* _run_log copies Steps into a caller's rows of filter.RECORD_WIDTH float64 */
_Static_assert(sizeof(Step) == (2 * N + 3 * NN) * sizeof(double), "a Step is 208 doubles");

/* An interval's data, its state left unset (filled where it is kept in the history). */
static void interval_of(Interval *iv, double t0, double t1, double dl, double dr, double g,
                        int forced) {
    iv->t0 = t0, iv->t1 = t1, iv->dl = dl, iv->dr = dr, iv->g = g;
    iv->forced = forced, iv->slip = 0, iv->score = 0.0;
}

typedef struct {
    PyObject_HEAD
    PyObject *wheels;
    dd_filter f; /* the filter's settings, the C library's */
    double command_sigma, history, ahead, mount[3];
    /* state */
    double x[N], P[NN];
    Interval *iv;
    Py_ssize_t iv0, niv, civ;
    Meas *ms;
    Py_ssize_t ms0, nms, cms;
    Meas *pend;
    Py_ssize_t npend, cpend;
    long long settled_ok, settled_bad;
    double rate;
    int have_rate, slip;
    double slip_score, command_score;
} Est;

/* -- the history ------------------------------------------------------------------------ */

/* Measurement.order: -1, 0 or 1 as a sorts before, with or after b. */
static int order(const Meas *a, const Meas *b) {
    if (a->t != b->t) return a->t < b->t ? -1 : 1;
    if (a->kind != b->kind) return KIND_RANK[a->kind] < KIND_RANK[b->kind] ? -1 : 1;
    for (int i = 0; i < a->size; ++i)
        if (a->value[i] != b->value[i]) return a->value[i] < b->value[i] ? -1 : 1;
    for (int i = 0; i < a->size * a->size; ++i)
        if (a->cov[i] != b->cov[i]) return a->cov[i] < b->cov[i] ? -1 : 1;
    return 0;
}

/* The first measurement index (absolute, in ms) whose stamp is > t (or >= t if inclusive). */
static Py_ssize_t first_after(const Est *e, double t, int inclusive) {
    Py_ssize_t lo = e->ms0, hi = e->ms0 + e->nms;
    while (lo < hi) {
        Py_ssize_t mid = (lo + hi) / 2;
        int before = inclusive ? e->ms[mid].t < t : e->ms[mid].t <= t;
        if (before)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

/* The measurements of history interval i (absolute index): (t0, t1], or [t0, t1] for the first. */
static void slice_of(const Est *e, Py_ssize_t i, Py_ssize_t *lo, Py_ssize_t *hi) {
    *lo = first_after(e, e->iv[i].t0, i == e->iv0);
    *hi = first_after(e, e->iv[i].t1, 0);
}

/* P's block of the carried states, n x n row by row, into packed: what the history keeps. */
static void pack(const Est *e, double *packed, const double *P) {
    const int n = e->f.carried;
    for (int i = 0; i < n; ++i) /* element by element: memcpy's setup would cost more here */
        for (int j = 0; j < n; ++j) packed[i * n + j] = P[i * N + j];
}

/* P in full from its packed block, zero elsewhere (the states not carried). */
static void unpack(const Est *e, double *P, const double *packed) {
    const int n = e->f.carried;
    for (int i = 0; i < N; ++i)
        for (int j = 0; j < N; ++j) P[i * N + j] = i < n && j < n ? packed[i * n + j] : 0.0;
}

/* Replay history intervals from absolute index k on: x, P now. */
static void replay(Est *e, Py_ssize_t k, double *x, double *P) {
    memcpy(x, e->iv[k].x, sizeof e->iv[k].x);
    unpack(e, P, e->iv[k].P);
    Py_ssize_t lo, hi;
    slice_of(e, k, &lo, &hi);
    for (Py_ssize_t i = k; i < e->iv0 + e->niv; ++i) {
        memcpy(e->iv[i].x, x, sizeof e->iv[i].x);
        pack(e, e->iv[i].P, P);
        if (i > k) { /* the slices follow one another */
            lo = hi;
            while (hi < e->ms0 + e->nms && e->ms[hi].t <= e->iv[i].t1) ++hi;
        }
        dd_filter_interval(&e->f, &e->iv[i], e->ms + lo, hi - lo, 1, 0.0, x, P, NULL, NULL);
    }
}

static int grow(void **array, Py_ssize_t *first, Py_ssize_t count, Py_ssize_t *capacity,
                size_t size) {
    if (*first + count < *capacity) return 0;
    /* Move to the front, into the space the trimmed ones left, while they fill at most half:
     * then a move of count items comes at most once every count appends. */
    if (*first > 0 && 2 * count <= *capacity) {
        memmove(*array, (char *)*array + *first * size, count * size);
        *first = 0;
        return 0;
    }
    Py_ssize_t larger = *capacity ? 2 * *capacity : 64;
    void *bigger = PyMem_Realloc(*array, larger * size);
    if (bigger == NULL) {
        PyErr_NoMemory();
        return -1;
    }
    if (*first > 0) /* to the front of the larger array */
        memmove(bigger, (char *)bigger + *first * size, count * size);
    *array = bigger;
    *first = 0;
    *capacity = larger;
    return 0;
}

static void trim(Est *e) {
    double newest = e->iv[e->iv0 + e->niv - 1].t1;
    while (e->niv > 1 && e->iv[e->iv0 + 1].t0 < newest - e->history) {
        Py_ssize_t lo, hi;
        slice_of(e, e->iv0, &lo, &hi);
        for (Py_ssize_t j = e->ms0; j < hi; ++j) {
            if (e->ms[j].accepted)
                e->settled_ok++;
            else
                e->settled_bad++;
        }
        e->nms -= hi - e->ms0;
        e->ms0 = hi;
        e->iv0++;
        e->niv--;
    }
    if (e->nms == 0) e->ms0 = 0;
}

/* -- numbers from Python objects --------------------------------------------------------- */

/* A float from a real number (not text, not a bool-free check: as float() takes it); -1 with
 * nothing set when obj is not a plain number. */
static int plain_number(PyObject *obj, double *out) {
    if (PyFloat_Check(obj)) { /* a float, or NumPy's float64 (a subclass) */
        *out = PyFloat_AS_DOUBLE(obj);
        return 0;
    }
    if (PyLong_CheckExact(obj)) {
        *out = PyLong_AsDouble(obj);
        if (*out == -1.0 && PyErr_Occurred()) {
            PyErr_Clear();
            return -1;
        }
        return 0;
    }
    return -1;
}

/* _validate.finite's checks and words, for a plain number or anything float() takes. */
static int finite_number(PyObject *obj, const char *name, double *out) {
    if (PyUnicode_Check(obj) || PyBytes_Check(obj)) {
        PyErr_Format(PyExc_TypeError, "%s must be a real number, not text: got %R", name, obj);
        return -1;
    }
    if (plain_number(obj, out) < 0) {
        if (PyLong_Check(obj)) {
            PyErr_Format(PyExc_ValueError,
                         "%s must be finite, got an integer too large for a float", name);
            return -1;
        }
        *out = PyFloat_AsDouble(obj);
        if (*out == -1.0 && PyErr_Occurred()) {
            if (PyErr_ExceptionMatches(PyExc_OverflowError)) {
                PyErr_Clear();
                PyErr_Format(PyExc_ValueError,
                             "%s must be finite, got an integer too large for a float", name);
            } else {
                PyErr_Clear();
                PyErr_Format(PyExc_TypeError, "%s must be a real number, got %R", name, obj);
            }
            return -1;
        }
    }
    if (!isfinite(*out)) {
        PyObject *shown = PyFloat_FromDouble(*out);
        if (shown != NULL) {
            PyErr_Format(PyExc_ValueError, "%s must be finite, got %S", name, shown);
            Py_DECREF(shown);
        }
        return -1;
    }
    return 0;
}

/* n doubles from an object that exports them as a contiguous buffer (a NumPy float64 array of
 * n elements, whatever its shape); -1 for anything else. */
static int buffer_doubles(PyObject *obj, double *out, Py_ssize_t n) {
    if (!PyObject_CheckBuffer(obj)) return -1;
    Py_buffer view;
    if (PyObject_GetBuffer(obj, &view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0) {
        PyErr_Clear();
        return -1;
    }
    int ok = view.format != NULL && strcmp(view.format, "d") == 0 &&
             view.itemsize == (Py_ssize_t)sizeof(double) && view.len == n * (Py_ssize_t)sizeof(double);
    if (ok) memcpy(out, view.buf, n * sizeof(double));
    PyBuffer_Release(&view);
    return ok ? 0 : -1;
}

/* n plain numbers from a sequence (a list, tuple or array of floats); -1, nothing set, if not. */
static int plain_numbers(PyObject *obj, double *out, Py_ssize_t n) {
    if (!(PyList_Check(obj) || PyTuple_Check(obj))) return buffer_doubles(obj, out, n);
    if (PySequence_Fast_GET_SIZE(obj) != n) return -1;
    PyObject **items = PySequence_Fast_ITEMS(obj);
    for (Py_ssize_t i = 0; i < n; ++i)
        if (plain_number(items[i], &out[i]) < 0) return -1;
    return 0;
}

/* -- the wheel readings ------------------------------------------------------------------ */

static double gyro_rate_of(Est *e, PyObject *obj, int *failed) {
    double rate;
    *failed = 0;
    if (PyFloat_Check(obj) || PyLong_Check(obj)) {
        if (finite_number(obj, "gyro_rate", &rate) < 0) *failed = 1;
        return rate;
    }
    double three[3];
    PyObject *seq = PySequence_Check(obj) ? PySequence_Fast(obj, "") : NULL;
    if (seq != NULL && PySequence_Fast_GET_SIZE(seq) == 3) {
        PyObject **items = PySequence_Fast_ITEMS(seq);
        int good = 1;
        for (int i = 0; i < 3 && good; ++i) {
            three[i] = PyFloat_AsDouble(items[i]);
            if (three[i] == -1.0 && PyErr_Occurred()) {
                PyErr_Clear();
                good = 0;
            }
        }
        Py_DECREF(seq);
        if (good) {
            rate = e->mount[0] * three[0] + e->mount[1] * three[1] + e->mount[2] * three[2];
            if (isfinite(rate)) return rate;
        }
    } else {
        PyErr_Clear();
        Py_XDECREF(seq);
    }
    PyErr_Format(PyExc_ValueError, "gyro_rate must be a finite yaw rate or 3 IMU rates, got %R",
                 obj);
    *failed = 1;
    return 0.0;
}

/* WheelVelocities.coerce(obj, "commanded"), for its checks and words. */
static int commanded_of(PyObject *obj, double out[2]) {
    double pair[2];
    if (plain_numbers(obj, pair, 2) == 0 && isfinite(pair[0]) && isfinite(pair[1])) {
        out[0] = pair[0];
        out[1] = pair[1];
        return 0;
    }
    PyObject *types = PyImport_ImportModule("diffdrive.types");
    if (types == NULL) return -1;
    PyObject *cls = PyObject_GetAttrString(types, "WheelVelocities");
    Py_DECREF(types);
    if (cls == NULL) return -1;
    PyObject *made = PyObject_CallMethod(cls, "coerce", "Os", obj, "commanded");
    Py_DECREF(cls);
    if (made == NULL) return -1;
    const char *sides[2] = {"left", "right"};
    for (int i = 0; i < 2; ++i) {
        PyObject *side = PyObject_GetAttrString(made, sides[i]);
        out[i] = side == NULL ? -1.0 : PyFloat_AsDouble(side);
        Py_XDECREF(side);
    }
    Py_DECREF(made);
    return PyErr_Occurred() ? -1 : 0;
}

static PyObject *update(Est *e, int kind, PyObject *const *args, Py_ssize_t nargs,
                        PyObject *kwnames) {
    const char *name = UPDATES[kind], *third = kind == 3 ? "dt" : "t";
    PyObject *given[6] = {NULL}; /* left, right, t, gyro_angle, gyro_rate, commanded */
    static const char *names[6] = {"left", "right", NULL, "gyro_angle", "gyro_rate", "commanded"};
    if (nargs > 3) {
        PyErr_Format(PyExc_TypeError, "%s() takes 3 positional arguments but %zd were given",
                     name, nargs);
        return NULL;
    }
    for (Py_ssize_t i = 0; i < nargs; ++i) given[i] = args[i];
    Py_ssize_t nkw = kwnames ? PyTuple_GET_SIZE(kwnames) : 0;
    for (Py_ssize_t i = 0; i < nkw; ++i) {
        const char *key = PyUnicode_AsUTF8(PyTuple_GET_ITEM(kwnames, i));
        if (key == NULL) return NULL;
        int found = -1;
        for (int k = 0; k < 6; ++k)
            if (strcmp(key, k == 2 ? third : names[k]) == 0) found = k;
        if (found < 0 || given[found] != NULL) {
            PyErr_Format(PyExc_TypeError, "%s() got an unexpected or repeated argument '%s'",
                         name, key);
            return NULL;
        }
        given[found] = args[nargs + i];
    }
    if (given[0] == NULL || given[1] == NULL) {
        PyErr_Format(PyExc_TypeError, "%s() missing required arguments 'left' and 'right'", name);
        return NULL;
    }
    if (given[2] == NULL || given[2] == Py_None) {
        PyErr_Format(PyExc_ValueError,
                     "%s: PoseEstimator needs the time %s (s) of every reading: late "
                     "measurements are placed by time",
                     name, third);
        return NULL;
    }
    double previous = odometry_time(e->wheels);
    int have_previous = !isnan(previous);
    if (!have_previous && kind == 2) {
        PyErr_Format(PyExc_ValueError,
                     "%s: the estimator's clock has not started: give initial_time, or begin "
                     "with a ticks or positions reading",
                     name);
        return NULL;
    }
    if (!have_previous && kind == 3) {
        previous = 0.0; /* velocities start the clock at 0 s, as Odometry's do */
        have_previous = 1;
    }
    /* Everything about this reading is checked before anything changes: the gyro and the
     * commands here, the wheels by their own update, which is all or nothing. */
    int have_rate = given[4] != NULL && given[4] != Py_None, failed = 0;
    double rate = have_rate ? gyro_rate_of(e, given[4], &failed) : 0.0;
    if (failed) return NULL;
    int have_angle = given[3] != NULL && given[3] != Py_None;
    double angle = 0.0;
    if (have_angle && finite_number(given[3], "gyro_angle", &angle) < 0) return NULL;
    if (have_previous && !have_angle && !have_rate && e->f.config.heading != WHEELS) {
        PyErr_Format(PyExc_ValueError,
                     "%s: heading '%s' needs gyro_angle or gyro_rate with every wheel reading",
                     name, e->f.config.heading == GYRO ? "gyro" : "fused");
        return NULL;
    }
    int have_wanted = given[5] != NULL && given[5] != Py_None;
    double wanted[2] = {0.0, 0.0};
    if (have_wanted && commanded_of(given[5], wanted) < 0) return NULL;
    double before[2], after[2];
    odometry_arcs(e->wheels, before);
    PyObject *saved = odometry_snapshot(e->wheels);
    if (saved == NULL) return NULL;
    PyObject *reading[3] = {given[0], given[1], given[2]};
    PyObject *done = odometry_update(e->wheels, kind, reading, 3);
    if (done == NULL) {
        Py_DECREF(saved);
        return NULL;
    }
    Py_DECREF(done);
    double now = odometry_time(e->wheels);
    if (!have_previous) { /* a reference reading: the clock starts */
        Py_DECREF(saved);
        e->have_rate = have_rate;
        e->rate = rate;
        Py_RETURN_NONE;
    }
    double dt = now - previous;
    odometry_arcs(e->wheels, after);
    double dl = (after[0] - before[0]) / e->f.config.drive.r_left, dr = (after[1] - before[1]) / e->f.config.drive.r_right;
    double g = NAN;
    if (have_angle)
        g = angle;
    else if (have_rate)
        g = 0.5 * ((e->have_rate ? e->rate : rate) + rate) * dt;
    double command_score = 0.0;
    if (have_wanted && dt > 0.0) {
        double miss[2] = {dl / dt - wanted[0], dr / dt - wanted[1]};
        double sigma2 = e->command_sigma * e->command_sigma;
        command_score = (miss[0] * miss[0] + miss[1] * miss[1]) / sigma2;
    }
    /* The measurements that waited for the wheels and are due now, in order. */
    Py_ssize_t due = 0;
    for (Py_ssize_t i = 0; i < e->npend; ++i)
        if (e->pend[i].t <= now) ++due;
    if (grow((void **)&e->ms, &e->ms0, e->nms + due, &e->cms, sizeof(Meas)) < 0 ||
        grow((void **)&e->iv, &e->iv0, e->niv, &e->civ, sizeof(Interval)) < 0) {
        odometry_restore(e->wheels, saved);
        Py_DECREF(saved);
        return NULL;
    }
    Meas *tail = e->ms + e->ms0 + e->nms;
    Py_ssize_t n = 0;
    for (Py_ssize_t i = 0; i < e->npend; ++i)
        if (e->pend[i].t <= now) {
            Py_ssize_t at = n++;
            while (at > 0 && order(&tail[at - 1], &e->pend[i]) > 0) {
                tail[at] = tail[at - 1];
                --at;
            }
            tail[at] = e->pend[i];
        }
    /* The interval in its place in the history, kept only if its update succeeds. */
    Interval *iv = &e->iv[e->iv0 + e->niv];
    interval_of(iv, previous, now, dl, dr, g, command_score > SLIP_COMMAND_THRESHOLD);
    memcpy(iv->x, e->x, sizeof e->x);
    pack(e, iv->P, e->P);
    double x[N], P[NN];
    memcpy(x, e->x, sizeof x);
    memcpy(P, e->P, sizeof P);
    dd_filter_interval(&e->f, iv, tail, due, 1, 0.0, x, P, NULL, NULL);
    if (!dd_filter_finite(x, P)) {
        int restored = odometry_restore(e->wheels, saved);
        Py_DECREF(saved);
        if (restored < 0) return NULL;
        PyErr_Format(PyExc_ValueError,
                     "%s: the update would overflow the state; refused, nothing changed", name);
        return NULL;
    }
    Py_DECREF(saved);
    e->nms += due;
    Py_ssize_t kept = 0;
    for (Py_ssize_t i = 0; i < e->npend; ++i)
        if (e->pend[i].t > now) e->pend[kept++] = e->pend[i];
    e->npend = kept;
    if (have_rate) {
        e->rate = rate;
        e->have_rate = 1;
    }
    e->niv++;
    memcpy(e->x, x, sizeof x);
    memcpy(e->P, P, sizeof P);
    e->slip = iv->slip;
    e->slip_score = iv->score;
    e->command_score = command_score;
    trim(e);
    Py_RETURN_NONE;
}

#define UPDATE_METHOD(fn, kind)                                                              \
    static PyObject *fn(Est *e, PyObject *const *args, Py_ssize_t nargs, PyObject *kwnames) { \
        return update(e, kind, args, nargs, kwnames);                                        \
    }
UPDATE_METHOD(update_ticks, 0)
UPDATE_METHOD(update_positions, 1)
UPDATE_METHOD(update_increments, 2)
UPDATE_METHOD(update_velocities, 3)

/* -- absolute measurements ----------------------------------------------------------------- */

static PyObject *float_of(double v) { return PyFloat_FromDouble(v); }

static PyObject *add_measurement(Est *e, Meas *m) {
    PyObject *t = float_of(m->t);
    if (t == NULL) return NULL;
    double now = odometry_time(e->wheels);
    PyObject *result = NULL;
    if (isnan(now)) {
        PyErr_Format(PyExc_ValueError,
                     "%s measurement at t = %R s: no wheel reading yet, so no time to place it at",
                     KIND_NAMES[m->kind], t);
        goto done;
    }
    double start = e->niv ? e->iv[e->iv0].t0 : now;
    if (m->t > now + e->ahead) {
        PyObject *ahead = float_of(e->ahead), *newest = float_of(now);
        if (ahead && newest)
            PyErr_Format(PyExc_ValueError,
                         "%s measurement at t = %R s: more than ahead = %R s past the newest "
                         "wheel reading (%R s)",
                         KIND_NAMES[m->kind], t, ahead, newest);
        Py_XDECREF(ahead);
        Py_XDECREF(newest);
        goto done;
    }
    if (m->t > now) {
        Py_ssize_t zero = 0;
        if (grow((void **)&e->pend, &zero, e->npend, &e->cpend, sizeof(Meas)) < 0) goto done;
        e->pend[e->npend++] = *m;
        result = Py_NewRef(Py_False);
        goto done;
    }
    if (e->niv == 0 || m->t < start) {
        if (m->t == now && e->niv == 0) { /* at the start itself */
            double x[N], P[NN];
            memcpy(x, e->x, sizeof x);
            memcpy(P, e->P, sizeof P);
            dd_filter_correct(&e->f, x, P, m);
            int ok = m->accepted;
            if (!dd_filter_finite(x, P)) {
                PyErr_Format(PyExc_ValueError,
                             "%s measurement at t = %R s: it would overflow the state; refused",
                             KIND_NAMES[m->kind], t);
                goto done;
            }
            memcpy(e->x, x, sizeof x);
            memcpy(e->P, P, sizeof P);
            if (ok)
                e->settled_ok++;
            else
                e->settled_bad++;
            result = PyBool_FromLong(ok);
            goto done;
        }
        PyObject *first = float_of(start), *history = float_of(e->history);
        if (first && history)
            PyErr_Format(PyExc_ValueError,
                         "%s measurement at t = %R s: older than the history, which starts at "
                         "%R s (history = %R s)",
                         KIND_NAMES[m->kind], t, first, history);
        Py_XDECREF(first);
        Py_XDECREF(history);
        goto done;
    }
    /* The interval it falls in, and its place among the measurements. */
    Py_ssize_t lo = e->iv0, hi = e->iv0 + e->niv;
    while (lo < hi) {
        Py_ssize_t mid = (lo + hi) / 2;
        if (e->iv[mid].t1 < m->t)
            lo = mid + 1;
        else
            hi = mid;
    }
    Py_ssize_t k = lo;
    if (grow((void **)&e->ms, &e->ms0, e->nms + 1, &e->cms, sizeof(Meas)) < 0) goto done;
    Py_ssize_t at = e->ms0 + e->nms;
    while (at > e->ms0 && order(&e->ms[at - 1], m) > 0) --at;
    memmove(e->ms + at + 1, e->ms + at, (e->ms0 + e->nms - at) * sizeof(Meas));
    e->ms[at] = *m;
    e->nms++;
    double x[N], P[NN];
    replay(e, k, x, P);
    if (!dd_filter_finite(x, P)) {
        /* The history as it was: without the measurement, the same replay gives back, to the
         * bit, the states and outcomes it had (nothing else changed). */
        memmove(e->ms + at, e->ms + at + 1, (e->ms0 + e->nms - at - 1) * sizeof(Meas));
        e->nms--;
        replay(e, k, x, P);
        PyErr_Format(PyExc_ValueError,
                     "%s measurement at t = %R s: it would overflow the state; refused, "
                     "nothing changed",
                     KIND_NAMES[m->kind], t);
    } else {
        memcpy(e->x, x, sizeof x);
        memcpy(e->P, P, sizeof P);
        result = PyBool_FromLong(e->ms[at].accepted);
    }
done:
    Py_DECREF(t);
    return result;
}

/* _add_fast(kind, t, value, covariance, lever_arm): plain numbers, checked as
 * Measurement.make checks them, straight in; None for anything else, which the Python class
 * then makes (and names, if it is wrong). */
static PyObject *add_fast(Est *e, PyObject *const *args, Py_ssize_t nargs) {
    if (nargs != 5) {
        PyErr_SetString(PyExc_TypeError, "_add_fast takes 5 arguments");
        return NULL;
    }
    long kind = PyLong_AsLong(args[0]);
    if (kind < 0 || kind > 2) {
        if (!PyErr_Occurred()) PyErr_SetString(PyExc_ValueError, "_add_fast: no such kind");
        return NULL;
    }
    Meas m = {0};
    m.kind = (int)kind;
    m.size = kind == POSE ? 3 : kind == POSITION ? 2 : 1;
    int k = m.size;
    if (plain_number(args[1], &m.t) < 0 || !isfinite(m.t)) Py_RETURN_NONE;
    if (kind == HEADING) {
        if (plain_number(args[2], &m.value[0]) < 0) Py_RETURN_NONE;
    } else if (plain_numbers(args[2], m.value, k) < 0) {
        Py_RETURN_NONE;
    }
    for (int i = 0; i < k; ++i)
        if (!isfinite(m.value[i])) Py_RETURN_NONE;
    double sigma[3], row[3];
    int matrix = 0; /* a k x k matrix was given, not standard deviations */
    if (kind != POSE && plain_number(args[3], &sigma[0]) == 0) {
        for (int i = 1; i < k; ++i) sigma[i] = sigma[0];
    } else if (plain_numbers(args[3], sigma, k) < 0) {
        /* a k x k matrix: a NumPy array, or nested lists or tuples */
        if (buffer_doubles(args[3], m.cov, k * k) < 0) {
            if (!(PyList_Check(args[3]) || PyTuple_Check(args[3])) ||
                PySequence_Fast_GET_SIZE(args[3]) != k)
                Py_RETURN_NONE;
            PyObject **rows = PySequence_Fast_ITEMS(args[3]);
            for (int i = 0; i < k; ++i) {
                if (plain_numbers(rows[i], row, k) < 0) Py_RETURN_NONE;
                for (int j = 0; j < k; ++j) m.cov[i * k + j] = row[j];
            }
        }
        for (int i = 0; i < k * k; ++i)
            if (!isfinite(m.cov[i])) Py_RETURN_NONE;
        for (int i = 0; i < k; ++i)
            for (int j = 0; j < k; ++j) /* np.allclose(m, m.T, rtol=1e-9, atol=0) */
                if (fabs(m.cov[i * k + j] - m.cov[j * k + i]) > 1e-9 * fabs(m.cov[j * k + i]))
                    Py_RETURN_NONE;
        double L[9];
        if (dd_cholesky(m.cov, k, L) != DD_OK) Py_RETURN_NONE;
        /* measurements.SINGULAR: a pivot at rounding's size is a singular matrix. */
        for (int i = 0; i < k; ++i)
            if (!(L[i * k + i] * L[i * k + i] > 1e-12 * m.cov[i * k + i])) Py_RETURN_NONE;
        for (int i = 0; i < k; ++i)
            for (int j = 0; j < k; ++j) {
                double a = m.cov[i * k + j], b = m.cov[j * k + i];
                m.cov[i * k + j] = 0.5 * (a + b);
            }
        matrix = 1;
    }
    if (!matrix) { /* standard deviations; NaN among them is refused by name in Python */
        memset(m.cov, 0, sizeof m.cov);
        for (int i = 0; i < k; ++i) {
            double variance = sigma[i] * sigma[i];
            if (!(sigma[i] > 0.0 && isfinite(variance) && variance > 0.0)) Py_RETURN_NONE;
            m.cov[i * k + i] = variance;
        }
    }
    if (args[4] != Py_None && plain_numbers(args[4], m.lever, 2) < 0) Py_RETURN_NONE;
    if (!isfinite(m.lever[0]) || !isfinite(m.lever[1])) Py_RETURN_NONE;
    return add_measurement(e, &m);
}

/* _add(measurement): a Measurement made (and checked) in Python. */
static PyObject *add_made(Est *e, PyObject *made) {
    Meas m = {0};
    PyObject *kind = PyObject_GetAttrString(made, "kind");
    if (kind == NULL) return NULL;
    m.kind = -1;
    for (int i = 0; i < 3; ++i)
        if (PyUnicode_CompareWithASCIIString(kind, KIND_NAMES[i]) == 0) m.kind = i;
    Py_DECREF(kind);
    if (m.kind < 0) {
        PyErr_SetString(PyExc_ValueError, "_add: no such kind of measurement");
        return NULL;
    }
    m.size = m.kind == POSE ? 3 : m.kind == POSITION ? 2 : 1;
    PyObject *t = PyObject_GetAttrString(made, "t");
    if (t == NULL) return NULL;
    m.t = PyFloat_AsDouble(t);
    Py_DECREF(t);
    const char *fields[3] = {"value", "covariance", "lever_arm"};
    double *into[3] = {m.value, m.cov, m.lever};
    Py_ssize_t sizes[3] = {m.size, m.size * m.size, 2};
    for (int f = 0; f < 3; ++f) {
        PyObject *field = PyObject_GetAttrString(made, fields[f]);
        if (field == NULL) return NULL;
        PyObject *flat = f == 1 ? PyObject_CallMethod(field, "ravel", NULL) : Py_NewRef(field);
        Py_DECREF(field);
        if (flat == NULL) return NULL;
        PyObject *seq = PySequence_Fast(flat, "a measurement's field must be a sequence");
        Py_DECREF(flat);
        if (seq == NULL) return NULL;
        if (PySequence_Fast_GET_SIZE(seq) != sizes[f]) {
            Py_DECREF(seq);
            PyErr_Format(PyExc_ValueError, "_add: the measurement's %s has the wrong size",
                         fields[f]);
            return NULL;
        }
        for (Py_ssize_t i = 0; i < sizes[f]; ++i)
            into[f][i] = PyFloat_AsDouble(PySequence_Fast_GET_ITEM(seq, i));
        Py_DECREF(seq);
        if (PyErr_Occurred()) return NULL;
    }
    if (PyErr_Occurred()) return NULL;
    return add_measurement(e, &m);
}

/* -- what the Python class reads ------------------------------------------------------------- */

static PyObject *tuple_of(const double *v, int n) {
    PyObject *out = PyTuple_New(n);
    if (out == NULL) return NULL;
    for (int i = 0; i < n; ++i) {
        PyObject *item = PyFloat_FromDouble(v[i]);
        if (item == NULL) {
            Py_DECREF(out);
            return NULL;
        }
        PyTuple_SET_ITEM(out, i, item);
    }
    return out;
}

static PyObject *state_now(Est *e, PyObject *unused) { return tuple_of(e->x, N); }
static PyObject *covariance_now(Est *e, PyObject *unused) { return tuple_of(e->P, NN); }

static PyObject *counts(Est *e, PyObject *unused) {
    long long ok = e->settled_ok, bad = e->settled_bad;
    for (Py_ssize_t j = e->ms0; j < e->ms0 + e->nms; ++j) {
        if (e->ms[j].accepted)
            ++ok;
        else
            ++bad;
    }
    return Py_BuildValue("(LL)", ok, bad);
}

static PyObject *history_start(Est *e, PyObject *unused) {
    return PyFloat_FromDouble(e->niv ? e->iv[e->iv0].t0 : odometry_time(e->wheels));
}

static PyObject *slip_now(Est *e, PyObject *unused) {
    return Py_BuildValue("(Ndd)", PyBool_FromLong(e->slip), e->slip_score, e->command_score);
}

static PyObject *pose_at(Est *e, PyObject *arg) {
    double t = PyFloat_AsDouble(arg);
    if (t == -1.0 && PyErr_Occurred()) return NULL;
    Py_ssize_t lo = e->iv0, hi = e->iv0 + e->niv;
    while (lo < hi) {
        Py_ssize_t mid = (lo + hi) / 2;
        if (e->iv[mid].t1 < t)
            lo = mid + 1;
        else
            hi = mid;
    }
    double x[N], P[NN];
    if (lo == e->iv0 + e->niv) {
        memcpy(x, e->x, sizeof x);
        memcpy(P, e->P, sizeof P);
    } else {
        Py_ssize_t a, b;
        slice_of(e, lo, &a, &b);
        Interval copy = e->iv[lo];
        memcpy(x, copy.x, sizeof x);
        unpack(e, P, copy.P);
        dd_filter_interval(&e->f, &copy, e->ms + a, b - a, 0, t, x, P, NULL, NULL);
    }
    return Py_BuildValue("(NN)", tuple_of(x, N), tuple_of(P, NN));
}

/* -- the type -------------------------------------------------------------------------------- */

/* Built from one settings object (backends.settings.CoreSettings, which the twin takes too),
 * read by name: the drive, method and heading codes, noises, flags, gates and the start. */
static int est_init(Est *e, PyObject *args, PyObject *kwargs) {
    PyObject *wheels, *s;
    if (!PyArg_ParseTuple(args, "OO", &wheels, &s)) return -1;
    if (!odometry_check(wheels)) {
        PyErr_SetString(PyExc_TypeError, "EstimatorCore reads its wheels through an OdometryCore");
        return -1;
    }
    double drive[4], k[2];
    dd_filter_config c;
    if (attribute_into(s, "drive", drive, 4) < 0 || attribute_into(s, "k", k, 2) < 0 ||
        attribute_double(s, "arw2", &c.arw2) < 0 || attribute_double(s, "rrw2", &c.rrw2) < 0 ||
        attribute_double(s, "offset_rate2", &c.offset_rate2) < 0 ||
        attribute_double(s, "slip_threshold", &c.slip_threshold) < 0 ||
        attribute_double(s, "slip_inflation", &c.slip_inflation) < 0 ||
        attribute_double(s, "command_sigma", &e->command_sigma) < 0 ||
        attribute_into(s, "gates", c.gates, 3) < 0 ||
        attribute_double(s, "offset", &c.reference_offset) < 0 ||
        attribute_double(s, "history", &e->history) < 0 ||
        attribute_double(s, "ahead", &e->ahead) < 0 ||
        attribute_into(s, "mounting", e->mount, 3) < 0 ||
        attribute_into(s, "state", e->x, N) < 0 ||
        attribute_into(s, "covariance", e->P, NN) < 0 ||
        attribute_int(s, "method_code", &c.method) < 0 ||
        attribute_int(s, "heading_code", &c.heading) < 0 ||
        attribute_int(s, "estimate_bias", &c.estimate_bias) < 0 ||
        attribute_int(s, "estimate_scale", &c.estimate_scale) < 0 ||
        attribute_int(s, "estimate_distance", &c.estimate_distance) < 0 ||
        attribute_int(s, "estimate_offset", &c.estimate_offset) < 0 ||
        attribute_int(s, "inflate", &c.inflate) < 0)
        return -1;
    c.drive = (dd_drive){drive[0], drive[1], drive[2], drive[3]};
    c.k_left = k[0], c.k_right = k[1];
    dd_status status = dd_filter_init(&e->f, &c);
    if (status != DD_OK) {
        PyErr_Format(PyExc_ValueError, "EstimatorCore: %s", dd_status_text(status));
        return -1;
    }
    Py_XSETREF(e->wheels, Py_NewRef(wheels));
    e->iv0 = e->niv = e->ms0 = e->nms = e->npend = 0;
    e->settled_ok = e->settled_bad = 0;
    e->have_rate = e->slip = 0;
    e->rate = e->slip_score = e->command_score = 0.0;
    return 0;
}

static void est_dealloc(Est *e) {
    Py_XDECREF(e->wheels);
    PyMem_Free(e->iv);
    PyMem_Free(e->ms);
    PyMem_Free(e->pend);
    Py_TYPE(e)->tp_free((PyObject *)e);
}

/* -- a whole log ------------------------------------------------------------------------ */

/* A float64 buffer of exactly n numbers (writable if asked), or -1 with a ValueError naming it. */
static int doubles_view(PyObject *obj, Py_buffer *view, Py_ssize_t n, int writable,
                        const char *name) {
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, view, flags) < 0) return -1;
    if (view->format == NULL || strcmp(view->format, "d") != 0 ||
        view->len != n * (Py_ssize_t)sizeof(double)) {
        PyBuffer_Release(view);
        PyErr_Format(PyExc_ValueError, "_run_log: %s must be %zd contiguous float64", name, n);
        return -1;
    }
    return 0;
}

enum { LOG_TIMES, LOG_LEFT, LOG_RIGHT, LOG_GYRO, LOG_FORCED, LOG_MT, LOG_MKIND, LOG_MVALUE,
       LOG_MCOV, LOG_MLEVER, LOG_STATES, LOG_COVS, LOG_SLIPS, LOG_SCORES, LOG_OK, LOG_MSCORE,
       LOG_MLOGDET, LOG_VIEWS };

/* _run_log(times, left, right, gyro, forced, m_t, m_kind, m_value, m_cov, m_lever, smooth,
 *          states, covariances, slips, scores, accepted, distances, log_dets[, records]):
 * estimate_trajectory's pass over a whole log from the state now, in float64 arrays (see the
 * Python twin's docstring); records, unless None, takes the smoother's steps (a Step a row,
 * in time order). Returns -1, or the interval (-2: the start) whose state would overflow. */
static PyObject *run_whole_log(Est *e, PyObject *const *args, Py_ssize_t nargs) {
    if (nargs != 18 && nargs != 19) {
        PyErr_SetString(PyExc_TypeError, "_run_log takes 18 or 19 arguments");
        return NULL;
    }
    PyObject *records_obj = nargs == 19 ? args[18] : Py_None;
    Py_buffer records;
    int keep = 0;
    Py_ssize_t rows = 0, write = 0;
    static const char *names[LOG_VIEWS] = {
        "times", "left", "right", "gyro", "forced", "m_t", "m_kind", "m_value", "m_cov",
        "m_lever", "states", "covariances", "slips", "scores", "accepted", "distances",
        "log_dets"};
    PyObject *objs[LOG_VIEWS];
    for (int i = 0; i < LOG_VIEWS; ++i) objs[i] = args[i < 10 ? i : i + 1];
    int smooth = PyObject_IsTrue(args[10]);
    if (smooth < 0) return NULL;
    Py_buffer probe;
    Py_ssize_t n, nm;
    if (PyObject_GetBuffer(objs[LOG_TIMES], &probe, PyBUF_SIMPLE) < 0) return NULL;
    n = probe.len / (Py_ssize_t)sizeof(double);
    PyBuffer_Release(&probe);
    if (PyObject_GetBuffer(objs[LOG_MT], &probe, PyBUF_SIMPLE) < 0) return NULL;
    nm = probe.len / (Py_ssize_t)sizeof(double);
    PyBuffer_Release(&probe);
    if (n < 2) {
        PyErr_SetString(PyExc_ValueError, "_run_log: times must hold at least 2 stamps");
        return NULL;
    }
    const Py_ssize_t sizes[LOG_VIEWS] = {n, n - 1, n - 1, n - 1, n - 1, nm, nm, 3 * nm, 9 * nm,
                                         2 * nm, N * n, NN * n, n, n, nm, nm, nm};
    Py_buffer views[LOG_VIEWS];
    int got = 0;
    PyObject *result = NULL;
    Meas *ms = NULL;
    Step *steps = NULL;
    for (; got < LOG_VIEWS; ++got)
        if (doubles_view(objs[got], &views[got], sizes[got], got >= LOG_STATES, names[got]) < 0)
            goto done;
    if (records_obj != Py_None) {
        if (PyObject_GetBuffer(records_obj, &records,
                               PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_WRITABLE) < 0)
            goto done;
        keep = 1;
        if (records.format == NULL || strcmp(records.format, "d") != 0 ||
            records.len % (Py_ssize_t)sizeof(Step) != 0) {
            PyErr_SetString(PyExc_ValueError, "_run_log: records must be rows of 208 float64");
            goto done;
        }
        rows = write = records.len / (Py_ssize_t)sizeof(Step);
    }
    const double *t = views[LOG_TIMES].buf, *dl = views[LOG_LEFT].buf, *dr = views[LOG_RIGHT].buf;
    const double *g = views[LOG_GYRO].buf, *forced = views[LOG_FORCED].buf;
    const double *mt = views[LOG_MT].buf, *mkind = views[LOG_MKIND].buf;
    const double *mvalue = views[LOG_MVALUE].buf, *mcov = views[LOG_MCOV].buf;
    const double *mlever = views[LOG_MLEVER].buf;
    double *states = views[LOG_STATES].buf, *covs = views[LOG_COVS].buf;
    double *slips = views[LOG_SLIPS].buf, *scores = views[LOG_SCORES].buf;
    double *accepted = views[LOG_OK].buf, *distances = views[LOG_MSCORE].buf;
    double *log_dets = views[LOG_MLOGDET].buf;
    ms = PyMem_Calloc(nm ? nm : 1, sizeof(Meas));
    if (ms == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    for (Py_ssize_t j = 0; j < nm; ++j) {
        int kind = (int)mkind[j];
        if (kind < POSE || kind > HEADING || (j && mt[j] < mt[j - 1]) || !(mt[j] >= t[0]) ||
            !(mt[j] <= t[n - 1])) {
            PyErr_Format(PyExc_ValueError,
                         "_run_log: measurement %zd: a kind 0 to 2, stamps in order inside the "
                         "log",
                         j);
            goto done;
        }
        Meas *m = &ms[j];
        m->t = mt[j];
        m->kind = kind;
        m->size = kind == POSE ? 3 : kind == POSITION ? 2 : 1;
        memcpy(m->value, mvalue + 3 * j, 3 * sizeof(double));
        for (int a = 0; a < m->size * m->size; ++a) m->cov[a] = mcov[9 * j + a];
        memcpy(m->lever, mlever + 2 * j, 2 * sizeof(double));
    }
    if (smooth) { /* room for the steps of the interval with the most measurements */
        Py_ssize_t most = 0;
        for (Py_ssize_t k = 1, j = 0, lo; k < n; ++k) {
            for (lo = j; j < nm && ms[j].t <= t[k]; ++j) {}
            most = j - lo > most ? j - lo : most;
        }
        steps = PyMem_Malloc((most + 1) * sizeof(Step));
        if (steps == NULL) {
            PyErr_NoMemory();
            goto done;
        }
    }
    double x[N], P[NN];
    memcpy(x, e->x, sizeof x);
    memcpy(P, e->P, sizeof P);
    Py_ssize_t j = 0, failed = -1;
    Py_BEGIN_ALLOW_THREADS;
    for (; j < nm && ms[j].t == t[0]; ++j) /* at the start itself */
        dd_filter_correct(&e->f, x, P, &ms[j]);
    if (!dd_filter_finite(x, P)) failed = -2;
    memcpy(states, x, sizeof x);
    memcpy(covs, P, sizeof P);
    slips[0] = scores[0] = 0.0;
    for (Py_ssize_t k = 1; k < n && failed == -1; ++k) {
        Interval iv;
        interval_of(&iv, t[k - 1], t[k], dl[k - 1], dr[k - 1], g[k - 1], forced[k - 1] != 0.0);
        Py_ssize_t lo = j;
        while (j < nm && ms[j].t <= t[k]) ++j;
        dd_filter_interval(&e->f, &iv, ms + lo, j - lo, 1, 0.0, x, P, NULL, NULL);
        if (!dd_filter_finite(x, P)) failed = k - 1;
        memcpy(states + N * k, x, sizeof x);
        memcpy(covs + NN * k, P, sizeof P);
        slips[k] = iv.slip;
        scores[k] = iv.score;
    }
    for (Py_ssize_t q = 0; q < nm && failed == -1; ++q) {
        accepted[q] = ms[q].accepted;
        distances[q] = ms[q].score;
        log_dets[q] = ms[q].log_det;
    }
    if (smooth && failed == -1) {
        /* Backwards: each interval run again from its filtered start, its steps recorded,
         * and smoothed through them; its start's filtered state is then overwritten by the
         * smoothed one, which the interval before it reads next. */
        Py_ssize_t hi = nm;
        memcpy(x, states + N * (n - 1), sizeof x);
        memcpy(P, covs + NN * (n - 1), sizeof P);
        for (Py_ssize_t k = n - 1; k >= 1; --k) {
            Py_ssize_t lo = hi;
            while (lo > 0 && ms[lo - 1].t > t[k - 1]) --lo;
            Interval iv;
            interval_of(&iv, t[k - 1], t[k], dl[k - 1], dr[k - 1], g[k - 1], forced[k - 1] != 0.0);
            double fx[N], fP[NN];
            memcpy(fx, states + N * (k - 1), sizeof fx);
            memcpy(fP, covs + NN * (k - 1), sizeof fP);
            long count;
            dd_filter_interval(&e->f, &iv, ms + lo, hi - lo, 1, 0.0, fx, fP, steps, &count);
            if (keep) { /* backwards, so this interval's rows go before the later ones' */
                write -= count;
                if (write >= 0) memcpy((Step *)records.buf + write, steps, count * sizeof(Step));
            }
            for (long s = count - 1; s >= 0; --s) dd_filter_smooth(&steps[s], x, P);
            memcpy(states + N * (k - 1), x, sizeof x);
            memcpy(covs + NN * (k - 1), P, sizeof P);
            hi = lo;
        }
    }
    Py_END_ALLOW_THREADS;
    if (keep && smooth && failed == -1 && write != 0)
        PyErr_Format(PyExc_ValueError, "_run_log: records must have %zd rows, not %zd",
                     rows - write, rows);
    else
        result = PyLong_FromSsize_t(failed);
done:
    for (int i = 0; i < got; ++i) PyBuffer_Release(&views[i]);
    if (keep) PyBuffer_Release(&records);
    PyMem_Free(ms);
    PyMem_Free(steps);
    return result;
}

#define FASTCALL_KW (METH_FASTCALL | METH_KEYWORDS)
static PyMethodDef est_methods[] = {
    {"update_ticks", (PyCFunction)(void (*)(void))update_ticks, FASTCALL_KW,
     "update_ticks(left, right, t, *, gyro_angle=None, gyro_rate=None, commanded=None): "
     "absolute encoder counter readings at t s (the first sets the reference)."},
    {"update_positions", (PyCFunction)(void (*)(void))update_positions, FASTCALL_KW,
     "update_positions(left, right, t, *, ...): accumulated wheel angles (rad) at t s."},
    {"update_increments", (PyCFunction)(void (*)(void))update_increments, FASTCALL_KW,
     "update_increments(left, right, t, *, ...): wheel-angle increments (rad) at t s."},
    {"update_velocities", (PyCFunction)(void (*)(void))update_velocities, FASTCALL_KW,
     "update_velocities(left, right, dt, *, ...): wheel velocities (rad/s) held dt s."},
    {"_add_fast", (PyCFunction)(void (*)(void))add_fast, METH_FASTCALL, NULL},
    {"_add", (PyCFunction)add_made, METH_O, NULL},
    {"_state_now", (PyCFunction)state_now, METH_NOARGS, NULL},
    {"_covariance_now", (PyCFunction)covariance_now, METH_NOARGS, NULL},
    {"_counts", (PyCFunction)counts, METH_NOARGS, NULL},
    {"_history_start", (PyCFunction)history_start, METH_NOARGS, NULL},
    {"_slip", (PyCFunction)slip_now, METH_NOARGS, NULL},
    {"_pose_at", (PyCFunction)pose_at, METH_O, NULL},
    {"_run_log", (PyCFunction)(void (*)(void))run_whole_log, METH_FASTCALL, NULL},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject EstType = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "diffdrive.backends._odometry.EstimatorCore",
    .tp_basicsize = sizeof(Est),
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_BASETYPE,
    .tp_doc = "The state, history and updates of PoseEstimator; use that class.",
    .tp_new = PyType_GenericNew,
    .tp_init = (initproc)est_init,
    .tp_dealloc = (destructor)est_dealloc,
    .tp_methods = est_methods,
};

int estimator_add_type(PyObject *module) {
    if (PyType_Ready(&EstType) < 0) return -1;
    Py_INCREF(&EstType);
    if (PyModule_AddObject(module, "EstimatorCore", (PyObject *)&EstType) < 0) {
        Py_DECREF(&EstType);
        return -1;
    }
    return 0;
}
