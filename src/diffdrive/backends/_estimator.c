/* diffdrive.estimation.PoseEstimator's core for Python: the C library's filter step
 * (c/src/filter.c, the same source the firmware builds) with the history and the Python
 * objects around it, so that a wheel and gyro update costs about a microsecond and a late
 * measurement a few. The compiled twin of estimation/_estimator_python.py, which it mirrors
 * step for step (the tests hold the two together).
 *
 * The wheels are read by an OdometryCore kept alongside (_odometry.c): its checks refuse a
 * reading before anything changes, and its snapshot takes a reading back when the filter's
 * own step refuses it. The history is the library's (c/src/history.c: a late measurement is
 * applied at its stamp and the intervals since replayed), in buffers this binding grows when
 * the library finds one full.
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
#include "diffdrive/history.h"

#define N DD_STATES
#define NN (DD_STATES * DD_STATES)
enum { WHEELS = DD_FROM_WHEELS, GYRO = DD_FROM_GYRO, FUSED = DD_FROM_BOTH };
enum { POSE = DD_POSE, POSITION = DD_POSITION, HEADING = DD_HEADING };
static const char *KIND_NAMES[3] = {"pose", "position", "heading"};
static const char *UPDATES[4] = {"update_ticks", "update_positions", "update_increments",
                                 "update_velocities"};
#define SLIP_COMMAND_THRESHOLD 13.82

typedef dd_measurement Meas;

typedef dd_interval Interval;
typedef dd_filter_record Step;
/* _run_log copies Steps into a caller's rows of filter.RECORD_WIDTH float64 */
_Static_assert(sizeof(Step) == (2 * N + 3 * NN) * sizeof(double), "a Step is 208 doubles");


typedef struct {
    PyObject_HEAD
    PyObject *wheels;
    dd_filter f;  /* the filter's settings, the C library's */
    dd_history h; /* its history and state, in the buffers below */
    double command_sigma, mount[3];
    double rate;
    int have_rate;
    double command_score;
} Est;

/* -- the history's buffers, grown here (the library allocates nothing) ---------------------- */

/* Double every buffer of the history (64 of each at first), what it holds moved over. */
static int enlarge(Est *e) {
    const dd_history_buffers *old = &e->h.buffers;
    dd_history_buffers larger = {
        PyMem_New(Interval, old->interval_room ? 2 * old->interval_room : 64),
        old->interval_room ? 2 * old->interval_room : 64,
        PyMem_New(Meas, old->measurement_room ? 2 * old->measurement_room : 64),
        old->measurement_room ? 2 * old->measurement_room : 64,
        PyMem_New(Meas, old->pending_room ? 2 * old->pending_room : 64),
        old->pending_room ? 2 * old->pending_room : 64,
    };
    if (larger.intervals == NULL || larger.measurements == NULL || larger.pending == NULL) {
        PyMem_Free(larger.intervals);
        PyMem_Free(larger.measurements);
        PyMem_Free(larger.pending);
        PyErr_NoMemory();
        return -1;
    }
    dd_history_buffers given = *old;
    dd_history_rebuffer(&e->h, larger); /* cannot fail: each is larger */
    PyMem_Free(given.intervals);
    PyMem_Free(given.measurements);
    PyMem_Free(given.pending);
    return 0;
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
    double g = NAN, gv = 0.0;
    if (have_angle) {
        g = angle;
    } else if (have_rate) { /* Gyro.interpolation_variances of the two rates */
        double held = e->have_rate ? e->rate : rate;
        g = 0.5 * (held + rate) * dt;
        gv = (dt * (rate - held)) * (dt * (rate - held)) / 12.0;
    }
    double command_score = 0.0;
    if (have_wanted && dt > 0.0) {
        double miss[2] = {dl / dt - wanted[0], dr / dt - wanted[1]};
        double sigma2 = e->command_sigma * e->command_sigma;
        command_score = (miss[0] * miss[0] + miss[1] * miss[1]) / sigma2;
    }
    dd_status status;
    while ((status = dd_history_wheels(&e->h, &e->f, previous, now, dl, dr, g, gv,
                                       command_score > SLIP_COMMAND_THRESHOLD)) == DD_FULL)
        if (enlarge(e) < 0) {
            odometry_restore(e->wheels, saved);
            Py_DECREF(saved);
            return NULL;
        }
    if (status != DD_OK) {
        int restored = odometry_restore(e->wheels, saved);
        Py_DECREF(saved);
        if (restored < 0) return NULL;
        PyErr_Format(PyExc_ValueError,
                     "%s: the update would overflow the state; refused, nothing changed", name);
        return NULL;
    }
    Py_DECREF(saved);
    if (have_rate) {
        e->rate = rate;
        e->have_rate = 1;
    }
    e->command_score = command_score;
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
    double now = odometry_time(e->wheels), start = dd_history_start(&e->h, now);
    int outcome, at_start = e->h.count == 0 && m->t == now;
    dd_status status;
    while ((status = dd_history_measure(&e->h, &e->f, now, m, &outcome)) == DD_FULL)
        if (enlarge(e) < 0) {
            Py_DECREF(t);
            return NULL;
        }
    PyObject *result = NULL, *first = NULL, *second = NULL;
    const char *kind = KIND_NAMES[m->kind];
    switch (status) {
    case DD_OK:
        result = outcome < 0 ? Py_NewRef(Py_False) : PyBool_FromLong(outcome);
        break;
    case DD_NO_CLOCK:
        PyErr_Format(PyExc_ValueError,
                     "%s measurement at t = %R s: no wheel reading yet, so no time to place it at",
                     kind, t);
        break;
    case DD_TOO_EARLY:
    case DD_TOO_OLD: {
        int early = status == DD_TOO_EARLY;
        first = float_of(early ? e->h.ahead : start);
        second = float_of(early ? now : e->h.span);
        if (first && second)
            PyErr_Format(PyExc_ValueError,
                         early ? "%s measurement at t = %R s: more than ahead = %R s past the "
                                 "newest wheel reading (%R s)"
                               : "%s measurement at t = %R s: older than the history, which "
                                 "starts at %R s (history = %R s)",
                         kind, t, first, second);
        break;
    }
    default:
        PyErr_Format(PyExc_ValueError, "%s measurement at t = %R s: it would overflow the state; "
                     "refused%s", kind, t, at_start ? "" : ", nothing changed");
    }
    Py_XDECREF(first);
    Py_XDECREF(second);
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

static PyObject *state_now(Est *e, PyObject *unused) { return tuple_of(e->h.x, N); }
static PyObject *covariance_now(Est *e, PyObject *unused) { return tuple_of(e->h.P, NN); }

static PyObject *counts(Est *e, PyObject *unused) {
    long long accepted, refused;
    dd_history_outcomes(&e->h, &accepted, &refused);
    return Py_BuildValue("(LL)", accepted, refused);
}

static PyObject *history_start(Est *e, PyObject *unused) {
    return PyFloat_FromDouble(dd_history_start(&e->h, odometry_time(e->wheels)));
}

static PyObject *slip_now(Est *e, PyObject *unused) {
    return Py_BuildValue("(Ndd)", PyBool_FromLong(e->h.slip), (double)e->h.slip_score,
                         e->command_score);
}

static PyObject *pose_at(Est *e, PyObject *arg) {
    double t = PyFloat_AsDouble(arg);
    if (t == -1.0 && PyErr_Occurred()) return NULL;
    double x[N], P[NN];
    dd_history_state_at(&e->h, &e->f, t, x, P);
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
    double drive[4], k[2], span, ahead, x[N], P[NN];
    dd_filter_config c;
    if (attribute_into(s, "drive", drive, 4) < 0 || attribute_into(s, "k", k, 2) < 0 ||
        attribute_double(s, "wheel_floor", &c.wheel_floor) < 0 ||
        attribute_double(s, "arw2", &c.arw2) < 0 || attribute_double(s, "rrw2", &c.rrw2) < 0 ||
        attribute_double(s, "offset_rate2", &c.offset_rate2) < 0 ||
        attribute_double(s, "slip_threshold", &c.slip_threshold) < 0 ||
        attribute_double(s, "slip_inflation", &c.slip_inflation) < 0 ||
        attribute_double(s, "command_sigma", &e->command_sigma) < 0 ||
        attribute_into(s, "gates", c.gates, 3) < 0 ||
        attribute_double(s, "offset", &c.reference_offset) < 0 ||
        attribute_double(s, "history", &span) < 0 ||
        attribute_double(s, "ahead", &ahead) < 0 ||
        attribute_into(s, "mounting", e->mount, 3) < 0 ||
        attribute_into(s, "state", x, N) < 0 ||
        attribute_into(s, "covariance", P, NN) < 0 ||
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
    /* empty, in the buffers a former __init__ left (tp_alloc zeroed them at first) */
    if (dd_history_init(&e->h, e->h.buffers, span, ahead, x, P) != DD_OK) {
        PyErr_SetString(PyExc_ValueError, "EstimatorCore: history and ahead must be >= 0");
        return -1;
    }
    e->have_rate = 0;
    e->rate = e->command_score = 0.0;
    return 0;
}

static void est_dealloc(Est *e) {
    Py_XDECREF(e->wheels);
    PyMem_Free(e->h.buffers.intervals);
    PyMem_Free(e->h.buffers.measurements);
    PyMem_Free(e->h.buffers.pending);
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

enum { LOG_TIMES, LOG_LEFT, LOG_RIGHT, LOG_GYRO, LOG_GYRO_VAR, LOG_FORCED, LOG_MT, LOG_MKIND, LOG_MVALUE,
       LOG_MCOV, LOG_MLEVER, LOG_STATES, LOG_COVS, LOG_SLIPS, LOG_SCORES, LOG_OK, LOG_MSCORE,
       LOG_MLOGDET, LOG_VIEWS };

/* The arrays of a whole log's pass, read by name from the log (backends.settings.LogArrays)
 * and the outputs (PassArrays), new references in objs (NULL where it failed; -1 then). */
static int pass_arrays(PyObject *log, PyObject *out, PyObject **objs, const char *const *names,
                       PyObject **records) {
    for (int i = 0; i < LOG_VIEWS; ++i)
        if ((objs[i] = PyObject_GetAttrString(i < LOG_STATES ? log : out, names[i])) == NULL)
            return -1;
    return (*records = PyObject_GetAttrString(out, "records")) == NULL ? -1 : 0;
}

/* _run_log(log, out, smooth): estimate_trajectory's pass over a whole log from the state
 * now, its float64 arrays read by name (see the Python twin's docstring); out.records, unless
 * None, takes the smoother's steps (a Step a row, in time order). Returns -1, or the
 * interval (-2: the start) whose state would overflow. */
static PyObject *run_whole_log(Est *e, PyObject *const *args, Py_ssize_t nargs) {
    if (nargs != 3) {
        PyErr_SetString(PyExc_TypeError, "_run_log takes the log, the outputs and smooth");
        return NULL;
    }
    static const char *names[LOG_VIEWS] = {
        "times", "left", "right", "gyro", "gyro_variance", "forced", "m_t", "m_kind", "m_value", "m_cov",
        "m_lever", "states", "covariances", "slips", "scores", "accepted", "distances",
        "log_dets"};
    PyObject *objs[LOG_VIEWS] = {NULL}, *records_obj = NULL, *result = NULL;
    Py_buffer records, views[LOG_VIEWS];
    int keep = 0, got = 0, smooth = PyObject_IsTrue(args[2]);
    Py_ssize_t rows = 0, write = 0, n = 0, nm = 0;
    Meas *ms = NULL;
    Step *steps = NULL;
    if (smooth < 0 || pass_arrays(args[0], args[1], objs, names, &records_obj) < 0) goto done;
    Py_buffer probe;
    if (PyObject_GetBuffer(objs[LOG_TIMES], &probe, PyBUF_SIMPLE) < 0) goto done;
    n = probe.len / (Py_ssize_t)sizeof(double);
    PyBuffer_Release(&probe);
    if (PyObject_GetBuffer(objs[LOG_MT], &probe, PyBUF_SIMPLE) < 0) goto done;
    nm = probe.len / (Py_ssize_t)sizeof(double);
    PyBuffer_Release(&probe);
    if (n < 2) {
        PyErr_SetString(PyExc_ValueError, "_run_log: times must hold at least 2 stamps");
        goto done;
    }
    const Py_ssize_t sizes[LOG_VIEWS] = {n, n - 1, n - 1, n - 1, n - 1, n - 1, nm, nm, 3 * nm, 9 * nm,
                                         2 * nm, N * n, NN * n, n, n, nm, nm, nm};
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
    const double *g = views[LOG_GYRO].buf, *gv = views[LOG_GYRO_VAR].buf;
    const double *forced = views[LOG_FORCED].buf;
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
    memcpy(x, e->h.x, sizeof x);
    memcpy(P, e->h.P, sizeof P);
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
        dd_interval_set(&iv, t[k - 1], t[k], dl[k - 1], dr[k - 1], g[k - 1], gv[k - 1],
                        forced[k - 1] != 0.0);
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
            dd_interval_set(&iv, t[k - 1], t[k], dl[k - 1], dr[k - 1], g[k - 1], gv[k - 1],
                        forced[k - 1] != 0.0);
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
    for (int i = 0; i < LOG_VIEWS; ++i) Py_XDECREF(objs[i]);
    Py_XDECREF(records_obj);
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
