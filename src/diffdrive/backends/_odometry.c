/* diffdrive.Odometry's core for Python: the C library's odometry (c/src/odometry.c, the same
 * source the firmware builds) in a Python type, with what only Python needs around it: the
 * arguments parsed and refused by name, the library's status codes turned into messages that
 * give the values, and the velocity window (a growing buffer, so it stays out of the
 * allocation-free library).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "_odometry.h"
#include "diffdrive/odometry.h"

typedef struct {
    double t, left, right; /* time (s) and cumulative wheel arcs (m) */
} Sample;

typedef struct {
    PyObject_HEAD
    dd_odometry od;
    double window;   /* s, for the velocity estimate */
    Sample *samples; /* ring buffer of (t, arcs) inside the velocity window */
    Py_ssize_t first, count, capacity;
} Core;

/* A double as Python's repr writes it, for error messages. */
typedef struct {
    char text[40];
} Num;

static Num num(double v) {
    Num n;
    char *repr = PyOS_double_to_string(v, 'r', 0, Py_DTSF_ADD_DOT_0, NULL);
    if (repr == NULL) {
        PyErr_Clear();
        snprintf(n.text, sizeof n.text, "%.17g", v);
    } else {
        snprintf(n.text, sizeof n.text, "%s", repr);
        PyMem_Free(repr);
    }
    return n;
}

/* -- the velocity window ----------------------------------------------------------------- */

/* The window keeps samples at least window / WINDOW_SAMPLES apart (the newest one aside), so
 * its memory is bounded whatever the update rate; its span is the window to within that. */
#define WINDOW_SAMPLES 1024

/* Make room for n more samples; the only step of an update that can fail after its checks. */
static int ensure_room(Core *c, Py_ssize_t n) {
    if (c->count + n <= c->capacity) return 0;
    Py_ssize_t capacity = c->capacity ? 2 * c->capacity : 16;
    Sample *grown = PyMem_New(Sample, capacity);
    if (grown == NULL) {
        PyErr_NoMemory();
        return -1;
    }
    for (Py_ssize_t i = 0; i < c->count; ++i) grown[i] = c->samples[(c->first + i) % c->capacity];
    PyMem_Free(c->samples);
    c->samples = grown;
    c->first = 0;
    c->capacity = capacity;
    return 0;
}

/* Append (t, the wheels' arcs then); there must be room. Samples older than needed leave. */
static void push_sample(Core *c, double t, double left, double right) {
    Sample sample = {t, left, right};
    Py_ssize_t last = (c->first + c->count - 1) % c->capacity;
    Py_ssize_t before = (last - 1 + c->capacity) % c->capacity;
    if (c->count > 0 && c->samples[last].t == t) { /* the same instant: nothing moved */
        c->samples[last] = sample;
        return;
    }
    if (c->count >= 2 && t - c->samples[before].t < c->window / WINDOW_SAMPLES) {
        c->samples[last] = sample; /* too close to the one before the newest: replace it */
    } else {
        c->samples[(c->first + c->count) % c->capacity] = sample;
        c->count += 1;
    }
    /* Keep one sample at or before the start of the window, so that it spans the window. */
    while (c->count >= 2 && c->samples[(c->first + 1) % c->capacity].t <= t - c->window) {
        c->first = (c->first + 1) % c->capacity;
        c->count -= 1;
    }
}

/* -- one update: the library's, its refusal put in words ------------------------------------ */

/* The library refused a reading with status: raise the ValueError that names it and its
 * values (dl, dr: the increments, rad; t: the reading's time, has_t: whether it has one; dt:
 * the time since the last reading). */
static void refuse(const Core *c, const char *name, dd_status status, double dl, double dr,
                   int has_t, double t, double dt) {
    double before = c->od.time;
    double worst = fabs(dl) > fabs(dr) ? dl : dr;
    switch (status) {
    case DD_NOT_FINITE:
        if (!isfinite(dl) || !isfinite(dr))
            PyErr_Format(PyExc_ValueError, "%s: the wheel increments must be finite, got left "
                         "%s, right %s", name, num(dl).text, num(dr).text);
        else
            PyErr_Format(PyExc_ValueError, "%s: the clock would pass the largest finite time: "
                         "%s s after %s s", name, num(t).text, num(before).text);
        return;
    case DD_TIME_BACKWARDS:
        PyErr_Format(PyExc_ValueError, "%s: time went backwards: t = %s s after %s s", name,
                     num(t).text, num(before).text);
        return;
    case DD_TIME_STILL:
        PyErr_Format(PyExc_ValueError, "%s: time stands still at t = %s s while the wheels "
                     "moved: no velocity", name, num(t).text);
        return;
    case DD_TOO_FAST:
        if (!isfinite(fabs(worst) / dt))
            PyErr_Format(PyExc_ValueError, "%s: a wheel turned %s rad in %s s, a speed past "
                         "the largest float: a glitch, or a time stamp in the wrong unit", name,
                         num(worst).text, num(dt).text);
        else
            PyErr_Format(PyExc_ValueError, "%s: a wheel turned %s rad in %s s, %s rad/s, over "
                         "max_wheel_speed %s rad/s: a glitch, or a counter roll-over with the "
                         "wrong counter_bits", name, num(worst).text, num(dt).text,
                         num(fabs(worst) / dt).text, num(c->od.config.max_wheel_speed).text);
        return;
    case DD_OVERFLOW_POSE:
    case DD_OVERFLOW_COVARIANCE:
        PyErr_Format(PyExc_ValueError, "%s: increments of %s and %s rad would make the %s "
                     "overflow (not finite); refused, nothing changed", name, num(dl).text,
                     num(dr).text, status == DD_OVERFLOW_POSE ? "pose, distance or wheel travel"
                                                              : "covariance");
        return;
    default:
        PyErr_Format(PyExc_ValueError, "%s: %s", name, dd_status_text(status));
    }
}

/* After the library took a reading: the velocity window follows the clock (room ensured). */
static void follow_clock(Core *c, int has_t) {
    if (has_t)
        push_sample(c, c->od.time, c->od.arc_left, c->od.arc_right);
    else
        c->count = 0; /* the clock is lost until the next time stamp */
}

/* -- argument parsing --------------------------------------------------------------------- */

static int parse_double(PyObject *obj, const char *name, const char *field, double *out) {
    if (PyUnicode_Check(obj) || PyBytes_Check(obj) || PyBool_Check(obj)) {
        PyErr_Format(PyExc_TypeError, "%s: %s must be a number, got %R", name, field, obj);
        return -1;
    }
    double v = PyFloat_CheckExact(obj) ? PyFloat_AS_DOUBLE(obj) : PyFloat_AsDouble(obj);
    if (v == -1.0 && PyErr_Occurred()) {
        int overflow = PyErr_ExceptionMatches(PyExc_OverflowError);
        PyErr_Clear();
        if (overflow)
            PyErr_Format(PyExc_ValueError, "%s: %s must be finite, got an integer too large "
                         "for a float", name, field);
        else
            PyErr_Format(PyExc_TypeError, "%s: %s must be a number, got %R", name, field, obj);
        return -1;
    }
    if (!isfinite(v)) {
        /* The value as a float prints the same whatever its type (not np.float64(nan)). */
        PyErr_Format(PyExc_ValueError, "%s: %s must be finite, got %s", name, field, num(v).text);
        return -1;
    }
    *out = v;
    return 0;
}

/* (left, right[, t]) from fastcall arguments; t may be None or absent. */
static int parse_update(const char *name, const char *last, PyObject *const *args,
                        Py_ssize_t nargs, PyObject *kwnames, PyObject **left, PyObject **right,
                        PyObject **third) {
    PyObject *slots[3] = {NULL, NULL, NULL};
    const char *names[3] = {"left", "right", last};
    if (nargs > 3) {
        PyErr_Format(PyExc_TypeError, "%s takes at most 3 arguments (%zd given)", name, nargs);
        return -1;
    }
    for (Py_ssize_t i = 0; i < nargs; ++i) slots[i] = args[i];
    Py_ssize_t nkw = kwnames ? PyTuple_GET_SIZE(kwnames) : 0;
    for (Py_ssize_t k = 0; k < nkw; ++k) {
        const char *key = PyUnicode_AsUTF8(PyTuple_GET_ITEM(kwnames, k));
        if (key == NULL) return -1;
        int found = 0;
        for (int i = 0; i < 3; ++i) {
            if (strcmp(key, names[i]) == 0) {
                if (slots[i] != NULL) {
                    PyErr_Format(PyExc_TypeError, "%s got two values for %s", name, key);
                    return -1;
                }
                slots[i] = args[nargs + k];
                found = 1;
            }
        }
        if (!found) {
            PyErr_Format(PyExc_TypeError, "%s got an unexpected keyword argument %s", name, key);
            return -1;
        }
    }
    if (slots[0] == NULL || slots[1] == NULL) {
        PyErr_Format(PyExc_TypeError, "%s needs left and right", name);
        return -1;
    }
    *left = slots[0];
    *right = slots[1];
    *third = slots[2];
    return 0;
}

static int parse_time(const char *name, PyObject *obj, int *has_t, double *t) {
    *has_t = obj != NULL && obj != Py_None;
    return *has_t ? parse_double(obj, name, "t", t) : 0;
}

/* -- the update methods ---------------------------------------------------------------------- */

enum { TICKS = 0, POSITIONS = 1, INCREMENTS = 2, VELOCITIES = 3 }; /* as UPDATE_KINDS */
static const char *UPDATE_NAMES[4] = {"update_ticks", "update_positions", "update_increments",
                                      "update_velocities"};

/* Wheel angles (positions) or their increments, rad, with an optional time stamp to: checked,
 * then applied; a first positions reading only sets the reference. */
static PyObject *angles(Core *c, int kind, PyObject *lo, PyObject *ro, PyObject *to) {
    const char *name = UPDATE_NAMES[kind];
    double left, right, t = NAN;
    int has_t;
    if (parse_double(lo, name, "left", &left) < 0 ||
        parse_double(ro, name, "right", &right) < 0 || parse_time(name, to, &has_t, &t) < 0 ||
        (has_t && ensure_room(c, 1) < 0))
        return NULL;
    /* the increments the library takes, for a refusal's message (0 for the reference) */
    int reference = kind == POSITIONS && !c->od.have_positions;
    double dl = left, dr = right;
    if (kind == POSITIONS) {
        dl = reference ? 0.0 : left - c->od.position_left;
        dr = reference ? 0.0 : right - c->od.position_right;
    }
    const double *when = has_t ? &t : NULL;
    dd_status status = kind == POSITIONS ? dd_odometry_positions(&c->od, when, left, right)
                                         : dd_odometry_increments(&c->od, when, left, right);
    if (status != DD_OK) {
        refuse(c, name, status, dl, dr, has_t, t, t - c->od.time);
        return NULL;
    }
    if (has_t || !reference) follow_clock(c, has_t);
    Py_RETURN_NONE;
}

/* A counter reading as an int: a Python int, or a whole float (NumPy's loadtxt gives those). */
static PyObject *tick_index(PyObject *obj, const char *field) {
    static const char *name = "update_ticks";
    PyObject *index = PyBool_Check(obj) ? NULL : PyNumber_Index(obj);
    if (index != NULL) return index;
    PyErr_Clear();
    PyNumberMethods *number = Py_TYPE(obj)->tp_as_number;
    if (!PyBool_Check(obj) && number != NULL && number->nb_float != NULL) {
        double v = PyFloat_AsDouble(obj);
        if (v == -1.0 && PyErr_Occurred()) return NULL;
        if (isfinite(v) && v == floor(v)) return PyLong_FromDouble(v);
        PyErr_Format(PyExc_ValueError, "%s: %s must be a whole counter reading, got %R", name,
                     field, obj);
        return NULL;
    }
    PyErr_Format(PyExc_TypeError, "%s: %s must be an integer counter reading, got %R", name,
                 field, obj);
    return NULL;
}

/* A reading of a counter of `bits` bits (0: one that never rolls over), signed or unsigned;
 * 64-bit readings of 2^63 and more are kept as their two's-complement bit pattern. */
static int parse_ticks(PyObject *obj, const char *field, int bits, long long *out) {
    static const char *name = "update_ticks";
    PyObject *index = tick_index(obj, field);
    if (index == NULL) return -1;
    int overflow = 0;
    long long v = PyLong_AsLongLongAndOverflow(index, &overflow);
    if (overflow > 0 && bits == 64) {
        unsigned long long u = PyLong_AsUnsignedLongLong(index);
        if (u == (unsigned long long)-1 && PyErr_Occurred()) {
            PyErr_Clear();
        } else {
            overflow = 0;
            v = (long long)u;
        }
    }
    Py_DECREF(index);
    long long low = bits ? (bits == 64 ? LLONG_MIN : -(1LL << (bits - 1))) : LLONG_MIN;
    long long high = bits && bits < 64 ? (long long)((1ULL << bits) - 1) : LLONG_MAX;
    if (overflow || (bits != 64 && (v < low || v > high))) {
        if (bits)
            PyErr_Format(PyExc_ValueError, "%s: %s = %R does not fit a %d-bit counter (from "
                         "-2^%d to 2^%d - 1, signed or unsigned)", name, field, obj, bits,
                         bits - 1, bits);
        else
            PyErr_Format(PyExc_ValueError, "%s: %s = %R does not fit a 64-bit integer; give "
                         "counter_bits for a counter that rolls over", name, field, obj);
        return -1;
    }
    *out = v;
    return 0;
}

/* The library refused counter readings left, right (its state as it was): the message,
 * with the changes it read them as. */
static void ticks_refused(const Core *c, dd_status status, long long left, long long right,
                          int has_t, double t) {
    int64_t change[2] = {0, 0};
    if (c->od.have_ticks) {
        const long long readings[2][2] = {{c->od.ticks_left, left}, {c->od.ticks_right, right}};
        const char *sides[2] = {"left", "right"};
        for (int w = 0; w < 2; ++w)
            if (dd_tick_change(c->od.config.counter_bits, readings[w][0], readings[w][1],
                               &change[w]) != DD_OK) {
                PyErr_Format(PyExc_ValueError, "update_ticks: %s changed by more than 2^63 "
                             "counts", sides[w]);
                return;
            }
    }
    refuse(c, "update_ticks", status, (double)change[0] * c->od.rad_per_tick,
           (double)change[1] * c->od.rad_per_tick, has_t, t, t - c->od.time);
}

/* Absolute counter readings with an optional time stamp to; the first sets the reference. */
static PyObject *ticks(Core *c, PyObject *lo, PyObject *ro, PyObject *to) {
    static const char *name = "update_ticks";
    long long left, right;
    double t = NAN;
    int has_t, bits = c->od.config.counter_bits;
    if (c->od.config.ticks_per_revolution == 0.0) {
        PyErr_SetString(PyExc_ValueError, "update_ticks needs ticks_per_revolution, which this "
                        "Odometry was made without");
        return NULL;
    }
    if (parse_ticks(lo, "left", bits, &left) < 0 || parse_ticks(ro, "right", bits, &right) < 0 ||
        parse_time(name, to, &has_t, &t) < 0 || (has_t && ensure_room(c, 1) < 0))
        return NULL;
    int reference = !c->od.have_ticks;
    dd_status status = dd_odometry_ticks(&c->od, has_t ? &t : NULL, left, right);
    if (status != DD_OK) {
        ticks_refused(c, status, left, right, has_t, t);
        return NULL;
    }
    if (has_t || !reference) follow_clock(c, has_t);
    Py_RETURN_NONE;
}

/* Wheel velocities, rad/s, held over dto s. */
static PyObject *velocities(Core *c, PyObject *lo, PyObject *ro, PyObject *dto) {
    static const char *name = "update_velocities";
    double left, right, dt;
    if (dto == NULL) {
        PyErr_SetString(PyExc_TypeError, "update_velocities needs dt, s");
        return NULL;
    }
    if (parse_double(lo, name, "left", &left) < 0 ||
        parse_double(ro, name, "right", &right) < 0 || parse_double(dto, name, "dt", &dt) < 0)
        return NULL;
    if (dt <= 0.0) {
        PyErr_Format(PyExc_ValueError, "%s: dt must be > 0, got %R", name, dto);
        return NULL;
    }
    if (ensure_room(c, 2) < 0) return NULL;
    int started = !isnan(c->od.time);
    double start = started ? c->od.time : 0.0, arcs[2] = {c->od.arc_left, c->od.arc_right};
    dd_status status = dd_odometry_velocities(&c->od, left, right, dt);
    if (status != DD_OK) {
        Core clocked = *c; /* the message reads the clock the update would have started */
        clocked.od.time = start;
        refuse(&clocked, name, status, left * dt, right * dt, 1, start + dt, dt);
        return NULL;
    }
    if (!started) push_sample(c, 0.0, arcs[0], arcs[1]); /* without a clock, one starts at 0 s */
    follow_clock(c, 1);
    Py_RETURN_NONE;
}

/* One update of any kind (TICKS to VELOCITIES): (left, right[, t or dt]) parsed and refused
 * by name, then the library's update of that kind; the named methods wrap it. */
static PyObject *update(Core *c, int kind, PyObject *const *args, Py_ssize_t nargs,
                        PyObject *kwnames) {
    PyObject *lo, *ro, *third;
    const char *last = kind == VELOCITIES ? "dt" : "t";
    if (parse_update(UPDATE_NAMES[kind], last, args, nargs, kwnames, &lo, &ro, &third) < 0)
        return NULL;
    switch (kind) {
    case TICKS: return ticks(c, lo, ro, third);
    case VELOCITIES: return velocities(c, lo, ro, third);
    default: return angles(c, kind, lo, ro, third);
    }
}

#define UPDATE_METHOD(fn, kind)                                                              \
    static PyObject *fn(Core *c, PyObject *const *args, Py_ssize_t nargs, PyObject *kwnames) { \
        return update(c, kind, args, nargs, kwnames);                                        \
    }
UPDATE_METHOD(update_ticks, TICKS)
UPDATE_METHOD(update_positions, POSITIONS)
UPDATE_METHOD(update_increments, INCREMENTS)
UPDATE_METHOD(update_velocities, VELOCITIES)

/* -- what the Python class reads and sets --------------------------------------------------- */

static PyObject *get_state(Core *c, PyObject *unused) {
    double pose[3];
    dd_odometry_pose(&c->od, pose);
    return Py_BuildValue("(ddddd)", pose[0], pose[1], pose[2], dd_odometry_distance(&c->od),
                         c->od.time);
}

static PyObject *get_covariance(Core *c, PyObject *unused) {
    const double *P = c->od.cov;
    return Py_BuildValue("(ddddddddd)", P[0], P[1], P[2], P[3], P[4], P[5], P[6], P[7], P[8]);
}

/* Each wheel's travel (m) since the object was made: what an estimator built on this one takes
 * as the wheels' increments, every check of the update already passed. */
static PyObject *get_arcs(Core *c, PyObject *unused) {
    return Py_BuildValue("(dd)", c->od.arc_left, c->od.arc_right);
}

/* What one update can change, so that an estimator built on this core can take a reading
 * back when its own step refuses it: the library's state, and the velocity window's bounds
 * and newest sample (an update appends or replaces one sample and drops from the front, so
 * the samples it does not touch are still in place). */
typedef struct {
    dd_odometry od;
    Py_ssize_t first, count, capacity;
    Sample last;
} Snapshot;

static PyObject *snapshot(Core *c, PyObject *unused) {
    Snapshot s;
    memset(&s, 0, sizeof s);
    s.od = c->od;
    s.first = c->first;
    s.count = c->count;
    s.capacity = c->capacity;
    if (c->count > 0) s.last = c->samples[(c->first + c->count - 1) % c->capacity];
    return PyBytes_FromStringAndSize((const char *)&s, sizeof s);
}

static PyObject *restore(Core *c, PyObject *arg) {
    if (!PyBytes_Check(arg) || PyBytes_GET_SIZE(arg) != (Py_ssize_t)sizeof(Snapshot)) {
        PyErr_SetString(PyExc_TypeError, "_restore takes what _snapshot gave");
        return NULL;
    }
    Snapshot s;
    memcpy(&s, PyBytes_AS_STRING(arg), sizeof s);
    c->od = s.od;
    /* A grown buffer holds the samples in order from index 0. */
    c->first = s.capacity == c->capacity ? s.first : 0;
    c->count = s.count;
    if (s.count > 0) c->samples[(c->first + c->count - 1) % c->capacity] = s.last;
    Py_RETURN_NONE;
}

/* Mean wheel velocities (rad/s) over the window, or None with fewer than two samples. */
static PyObject *get_window_velocities(Core *c, PyObject *unused) {
    if (c->count < 2) Py_RETURN_NONE;
    Sample a = c->samples[c->first], b = c->samples[(c->first + c->count - 1) % c->capacity];
    double span = b.t - a.t;
    return Py_BuildValue("(ddd)", (b.left - a.left) / span / c->od.config.drive.r_left,
                         (b.right - a.right) / span / c->od.config.drive.r_right, span);
}

static PyObject *set_pose(Core *c, PyObject *args) {
    double pose[3], cov[9];
    if (!PyArg_ParseTuple(args, "ddd(ddddddddd)", &pose[0], &pose[1], &pose[2], &cov[0], &cov[1],
                          &cov[2], &cov[3], &cov[4], &cov[5], &cov[6], &cov[7], &cov[8]))
        return NULL;
    dd_odometry_set_pose(&c->od, pose, cov);
    Py_RETURN_NONE;
}

static PyObject *jacobians(Core *c, PyObject *args) {
    double dl, dr, p[9], w[6];
    if (!PyArg_ParseTuple(args, "dd", &dl, &dr)) return NULL;
    dd_odometry_jacobians(&c->od, dl, dr, p, w);
    return Py_BuildValue("((ddddddddd)(dddddd))", p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7],
                         p[8], w[0], w[1], w[2], w[3], w[4], w[5]);
}

/* Built from one settings object (backends.settings.OdometrySettings, which the twin takes
 * too), read by name; at the origin: Odometry's reset puts the core at its start. */
static int core_init(Core *c, PyObject *args, PyObject *kwargs) {
    PyObject *s;
    double drive[4], k[2], ticks_per_revolution, max_wheel_speed;
    int method, bits;
    if (!PyArg_ParseTuple(args, "O", &s)) return -1;
    if (attribute_into(s, "drive", drive, 4) < 0 || attribute_into(s, "k", k, 2) < 0 ||
        attribute_int(s, "method_code", &method) < 0 ||
        attribute_double(s, "ticks_per_revolution", &ticks_per_revolution) < 0 ||
        attribute_double(s, "max_wheel_speed", &max_wheel_speed) < 0 ||
        attribute_int(s, "counter_bits", &bits) < 0 ||
        attribute_double(s, "velocity_window", &c->window) < 0)
        return -1;
    const dd_odometry_config config = {{drive[0], drive[1], drive[2], drive[3]}, method,
                                       ticks_per_revolution, bits, max_wheel_speed, k[0], k[1]};
    dd_status status = dd_odometry_init(&c->od, &config);
    if (status != DD_OK) {
        PyErr_Format(PyExc_ValueError, "OdometryCore: %s", dd_status_text(status));
        return -1;
    }
    c->count = c->first = 0;
    return 0;
}

static void core_dealloc(Core *c) {
    PyMem_Free(c->samples);
    Py_TYPE(c)->tp_free((PyObject *)c);
}

/* The updates of a whole log: update_<kind>(lefts[k], rights[k], thirds[k]) for each k, the
 * same checked update as one call at a time, writing the pose after each into poses (a
 * C-contiguous float64 buffer of n x 3) and, unless None, the covariance into covariances
 * (n x 9). kind: 0 ticks, 1 positions, 2 increments, 3 velocities (thirds: dt). Returns None,
 * or (k, message) for the first refused update, after which the state is that of update k-1. */
static PyObject *run_log(Core *c, PyObject *args) {
    int kind;
    PyObject *lefts, *rights, *thirds, *poses_obj, *cov_obj;
    if (!PyArg_ParseTuple(args, "iO!O!O!OO", &kind, &PyList_Type, &lefts, &PyList_Type, &rights,
                          &PyList_Type, &thirds, &poses_obj, &cov_obj))
        return NULL;
    if (kind < 0 || kind > 3) {
        PyErr_SetString(PyExc_ValueError, "_run: kind must be 0 to 3");
        return NULL;
    }
    Py_ssize_t n = PyList_GET_SIZE(lefts);
    if (PyList_GET_SIZE(rights) != n || PyList_GET_SIZE(thirds) != n) {
        PyErr_SetString(PyExc_ValueError, "_run: lefts, rights and thirds differ in length");
        return NULL;
    }
    Py_buffer poses, cov = {0};
    if (PyObject_GetBuffer(poses_obj, &poses, PyBUF_C_CONTIGUOUS | PyBUF_WRITABLE) < 0)
        return NULL;
    int with_cov = cov_obj != Py_None;
    if (with_cov && PyObject_GetBuffer(cov_obj, &cov, PyBUF_C_CONTIGUOUS | PyBUF_WRITABLE) < 0) {
        PyBuffer_Release(&poses);
        return NULL;
    }
    PyObject *result = NULL;
    if (poses.len < (Py_ssize_t)(n * 3 * sizeof(double)) ||
        (with_cov && cov.len < (Py_ssize_t)(n * 9 * sizeof(double)))) {
        PyErr_SetString(PyExc_ValueError, "_run: the output buffers are too small");
        goto done;
    }
    double *out = poses.buf, *out_cov = with_cov ? cov.buf : NULL;
    for (Py_ssize_t k = 0; k < n; ++k) {
        PyObject *call[3] = {PyList_GET_ITEM(lefts, k), PyList_GET_ITEM(rights, k),
                             PyList_GET_ITEM(thirds, k)};
        PyObject *done = update(c, kind, call, 3, NULL);
        if (done == NULL) {
            if (!PyErr_ExceptionMatches(PyExc_ValueError) &&
                !PyErr_ExceptionMatches(PyExc_TypeError))
                goto done;
            PyObject *type, *value, *traceback;
            PyErr_Fetch(&type, &value, &traceback);
            PyObject *message = value ? PyObject_Str(value) : PyUnicode_FromString("refused");
            Py_XDECREF(type);
            Py_XDECREF(value);
            Py_XDECREF(traceback);
            if (message == NULL) goto done;
            result = Py_BuildValue("(nN)", k, message);
            goto done;
        }
        Py_DECREF(done);
        dd_odometry_pose(&c->od, out + 3 * k);
        if (out_cov) memcpy(out_cov + 9 * k, c->od.cov, sizeof c->od.cov);
    }
    result = Py_NewRef(Py_None);
done:
    PyBuffer_Release(&poses);
    if (with_cov) PyBuffer_Release(&cov);
    return result;
}

static PyMethodDef core_methods[] = {
    {"_run", (PyCFunction)run_log, METH_VARARGS, NULL},
    {"update_ticks", (PyCFunction)(void (*)(void))update_ticks, METH_FASTCALL | METH_KEYWORDS,
     "update_ticks(left, right, t=None): absolute encoder counter readings."},
    {"update_increments", (PyCFunction)(void (*)(void))update_increments,
     METH_FASTCALL | METH_KEYWORDS,
     "update_increments(left, right, t=None): wheel-angle increments since the last update, "
     "rad."},
    {"update_positions", (PyCFunction)(void (*)(void))update_positions,
     METH_FASTCALL | METH_KEYWORDS,
     "update_positions(left, right, t=None): accumulated wheel angles, rad."},
    {"update_velocities", (PyCFunction)(void (*)(void))update_velocities,
     METH_FASTCALL | METH_KEYWORDS,
     "update_velocities(left, right, dt): wheel velocities, rad/s, held over dt s."},
    {"_state", (PyCFunction)get_state, METH_NOARGS, NULL},
    {"_covariance", (PyCFunction)get_covariance, METH_NOARGS, NULL},
    {"_window_velocities", (PyCFunction)get_window_velocities, METH_NOARGS, NULL},
    {"_wheel_arcs", (PyCFunction)get_arcs, METH_NOARGS, NULL},
    {"_snapshot", (PyCFunction)snapshot, METH_NOARGS, NULL},
    {"_restore", (PyCFunction)restore, METH_O, NULL},
    {"_set_pose", (PyCFunction)set_pose, METH_VARARGS, NULL},
    {"_jacobians", (PyCFunction)jacobians, METH_VARARGS, NULL},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject CoreType = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "diffdrive.backends._odometry.OdometryCore",
    .tp_basicsize = sizeof(Core),
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_BASETYPE,
    .tp_doc = "The state and update of diffdrive.Odometry; use that class.",
    .tp_new = PyType_GenericNew,
    .tp_init = (initproc)core_init,
    .tp_dealloc = (destructor)core_dealloc,
    .tp_methods = core_methods,
};

/* -- what the estimator core (_estimator.c) takes from this one ---------------------------- */


int odometry_check(PyObject *obj) { return PyObject_TypeCheck(obj, &CoreType); }

PyObject *odometry_update(PyObject *core, int kind, PyObject *const *args, Py_ssize_t nargs) {
    return update((Core *)core, kind, args, nargs, NULL);
}

double odometry_time(PyObject *core) { return ((Core *)core)->od.time; }

void odometry_arcs(PyObject *core, double arcs[2]) {
    arcs[0] = ((Core *)core)->od.arc_left;
    arcs[1] = ((Core *)core)->od.arc_right;
}

PyObject *odometry_snapshot(PyObject *core) { return snapshot((Core *)core, NULL); }

int odometry_restore(PyObject *core, PyObject *saved) {
    PyObject *done = restore((Core *)core, saved);
    Py_XDECREF(done);
    return done == NULL ? -1 : 0;
}

int odometry_add_type(PyObject *module) {
    if (PyType_Ready(&CoreType) < 0) return -1;
    Py_INCREF(&CoreType);
    if (PyModule_AddObject(module, "OdometryCore", (PyObject *)&CoreType) < 0) {
        Py_DECREF(&CoreType);
        return -1;
    }
    return 0;
}
