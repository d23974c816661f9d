/* The state and the update of diffdrive.Odometry, in C so that one update costs well under a
 * microsecond (the Python class diffdrive.odometry.Odometry derives from OdometryCore).
 *
 * One update is the step of diffdrive/_step.py, mirrored here: wheel-angle increments (rad)
 * -> wheel arcs (m) -> forward travel, sideways travel (axle offset) and turn -> the pose moved
 * along the start heading (euler) or the mid-step heading (rk2, exact; exact scales by the
 * chord factor sinc(turn/2)), and the covariance moved with the same step's Jacobians. Every check runs before any state changes,
 * so a refused update leaves the object exactly as it was.
 *
 * Uncertainty (Siegwart, Nourbakhsh and Scaramuzza, "Introduction to Autonomous Mobile
 * Robots", 2nd ed., 2011, sec. 5.2.4, eq. 5.9): the travel of each wheel in one update has a
 * variance proportional to its absolute value, var(ds_l) = k_left |ds_l|, var(ds_r) =
 * k_right |ds_r|, independent. k scales the variance, not the standard deviation, so the
 * covariance after a path does not depend on how finely the updates slice it.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "_odometry.h"

enum { EULER = 0, RK2 = 1, EXACT = 2 };

typedef struct {
    double t, left, right; /* time (s) and cumulative wheel arcs (m) */
} Sample;

typedef struct {
    PyObject_HEAD
    /* configuration */
    double r_left, r_right, track, offset; /* m */
    int method;
    double rad_per_tick;    /* 0: no ticks_per_revolution given */
    int counter_bits;       /* 0: counters that do not roll over */
    double max_wheel_speed; /* rad/s; infinity: no limit */
    double k_left, k_right; /* m: wheel-travel variance per metre travelled */
    double window;          /* s, for the velocity estimate */
    /* state: each of x, y, theta, distance is sum + compensation (Neumaier), so that a long
     * run of small updates does not drift from a compensated batch sum */
    double x, y, theta, distance;
    double x_comp, y_comp, theta_comp, distance_comp;
    double cov[9];
    double time; /* s of the last update; NaN when unknown */
    int have_ticks;
    long long ticks_left, ticks_right;
    int have_positions;
    double position_left, position_right;
    double arc_left, arc_right; /* m travelled by each wheel, for the velocity window */
    Sample *samples;            /* ring buffer of (t, arcs) inside the velocity window */
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

/* -- the maths of one step ------------------------------------------------------------- */

typedef struct {
    double dx, dy, dtheta; /* world-frame move of the pose */
    double travel;         /* how far the reference point moved, m */
    double jac_pose[9];    /* d(new pose)/d(pose), row-major 3x3 */
    double jac_wheels[6];  /* d(new pose)/d(wheel-angle increments [left, right]), 3x2 */
} Step;

/* One step from wheel-angle increments (rad) at heading theta, with its Jacobians: the move's
 * (the header's dd_move_jacobians, the estimator's too) taken through each wheel's arc
 * (d forward = 1/2, d turn = -+1/track per metre), as odometry_python's step. */
static void step(const Core *c, double theta, double dphi_left, double dphi_right, Step *s) {
    double left = c->r_left * dphi_left, right = c->r_right * dphi_right;
    double turn = (right - left) / c->track, forward = 0.5 * (left + right);
    double weight = c->method == EULER ? 0.0 : 0.5; /* direction: theta + weight * turn */
    double bf[2], bt[2];
    dd_move_jacobians(forward, c->offset, turn, weight, c->method == EXACT, theta, &s->dx, &s->dy,
                      bf, bt);
    s->dtheta = turn;
    s->travel = hypot(forward, c->offset * turn);
    double jp[9] = {1.0, 0.0, -s->dy, 0.0, 1.0, s->dx, 0.0, 0.0, 1.0};
    memcpy(s->jac_pose, jp, sizeof jp);
    double dturn[2] = {-1.0 / c->track, 1.0 / c->track};
    double radius[2] = {c->r_left, c->r_right};
    for (int w = 0; w < 2; ++w) {
        s->jac_wheels[w] = radius[w] * (0.5 * bf[0] + dturn[w] * bt[0]);
        s->jac_wheels[2 + w] = radius[w] * (0.5 * bf[1] + dturn[w] * bt[1]);
        s->jac_wheels[4 + w] = radius[w] * dturn[w];
    }
}

/* cov <- J cov J^T + W diag(q) W^T, with J 3x3 and W 3x2. */
static void propagate(double cov[9], const double J[9], const double W[6], const double q[2]) {
    double JC[9], out[9];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            JC[3 * i + j] = J[3 * i] * cov[j] + J[3 * i + 1] * cov[3 + j] + J[3 * i + 2] * cov[6 + j];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            out[3 * i + j] = JC[3 * i] * J[3 * j] + JC[3 * i + 1] * J[3 * j + 1] +
                             JC[3 * i + 2] * J[3 * j + 2] + W[2 * i] * q[0] * W[2 * j] +
                             W[2 * i + 1] * q[1] * W[2 * j + 1];
    memcpy(cov, out, sizeof out);
}

/* -- compensated sums -------------------------------------------------------------------- */

/* Add term to the sum, carrying the rounding error in comp (Neumaier's variant of Kahan's). */
static void add(double *sum, double *comp, double term) {
    double t = *sum + term;
    *comp += fabs(*sum) >= fabs(term) ? (*sum - t) + term : (term - t) + *sum;
    *sum = t;
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

/* Append (t, arcs now); there must be room. Samples older than needed leave. */
static void push_sample(Core *c, double t) {
    Sample sample = {t, c->arc_left, c->arc_right};
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

/* -- one update, checked first ------------------------------------------------------------ */

/* Refuse an update that cannot be right; dt is the time since the last update, NaN if unknown. */
static int check_update(const Core *c, const char *name, double dl, double dr, int has_t, double t,
                        double dt) {
    if (!isfinite(dl) || !isfinite(dr)) {
        PyErr_Format(PyExc_ValueError, "%s: the wheel increments must be finite, got left %s, "
                     "right %s", name, num(dl).text, num(dr).text);
        return -1;
    }
    if (has_t && !isfinite(t)) {
        PyErr_Format(PyExc_ValueError, "%s: the clock would pass the largest finite time: "
                     "%s s after %s s", name, num(t).text, num(c->time).text);
        return -1;
    }
    if (has_t && dt < 0.0) {
        PyErr_Format(PyExc_ValueError, "%s: time went backwards: t = %s s after %s s", name,
                     num(t).text, num(c->time).text);
        return -1;
    }
    if (has_t && dt == 0.0 && (dl != 0.0 || dr != 0.0)) {
        PyErr_Format(PyExc_ValueError, "%s: time stands still at t = %s s while the wheels "
                     "moved: no velocity", name, num(t).text);
        return -1;
    }
    if (dt > 0.0 && !isfinite(fmax(fabs(dl), fabs(dr)) / dt)) {
        double worst = fabs(dl) > fabs(dr) ? dl : dr;
        PyErr_Format(PyExc_ValueError, "%s: a wheel turned %s rad in %s s, a speed past the "
                     "largest float: a glitch, or a time stamp in the wrong unit", name,
                     num(worst).text, num(dt).text);
        return -1;
    }
    if (dt > 0.0 && fmax(fabs(dl), fabs(dr)) > c->max_wheel_speed * dt) {
        double worst = fabs(dl) > fabs(dr) ? dl : dr;
        PyErr_Format(PyExc_ValueError, "%s: a wheel turned %s rad in %s s, %s rad/s, over "
                     "max_wheel_speed %s rad/s: a glitch, or a counter roll-over with the wrong "
                     "counter_bits", name, num(worst).text, num(dt).text,
                     num(fabs(worst) / dt).text, num(c->max_wheel_speed).text);
        return -1;
    }
    return 0;
}

/* The state an update leads to, computed before anything changes. */
typedef struct {
    double x, y, theta, distance, x_comp, y_comp, theta_comp, distance_comp;
    double cov[9], arc_left, arc_right;
} Next;

/* Compute the next state; refuse one that is not finite (an overflow of huge increments), so
 * that an accepted update never leaves a pose, covariance or distance that cannot be read. */
static int next_state(const Core *c, const char *name, double dl, double dr, Next *n) {
    Step s;
    step(c, c->theta + c->theta_comp, dl, dr, &s);
    double q[2] = {c->k_left * fabs(c->r_left * dl) / (c->r_left * c->r_left),
                   c->k_right * fabs(c->r_right * dr) / (c->r_right * c->r_right)};
    memcpy(n->cov, c->cov, sizeof n->cov);
    propagate(n->cov, s.jac_pose, s.jac_wheels, q);
    double left = c->r_left * dl, right = c->r_right * dr;
    n->x = c->x, n->x_comp = c->x_comp;
    n->y = c->y, n->y_comp = c->y_comp;
    n->theta = c->theta, n->theta_comp = c->theta_comp;
    n->distance = c->distance, n->distance_comp = c->distance_comp;
    add(&n->x, &n->x_comp, s.dx);
    add(&n->y, &n->y_comp, s.dy);
    add(&n->theta, &n->theta_comp, s.dtheta);
    add(&n->distance, &n->distance_comp, s.travel);
    n->arc_left = c->arc_left + left;
    n->arc_right = c->arc_right + right;
    int finite = isfinite(n->x + n->x_comp) && isfinite(n->y + n->y_comp) &&
                 isfinite(n->theta + n->theta_comp) && isfinite(n->distance + n->distance_comp) &&
                 isfinite(n->arc_left) && isfinite(n->arc_right);
    const char *what = "pose, distance or wheel travel";
    for (int i = 0; finite && i < 9; ++i) {
        finite = isfinite(n->cov[i]);
        what = "covariance";
    }
    if (!finite) {
        PyErr_Format(PyExc_ValueError, "%s: increments of %s and %s rad would make the %s "
                     "overflow (not finite); refused, nothing changed", name, num(dl).text,
                     num(dr).text, what);
        return -1;
    }
    return 0;
}

/* Move to the next state and the velocity window; cannot fail (room is ensured). */
static void commit(Core *c, const Next *n, int has_t, double t) {
    c->x = n->x, c->x_comp = n->x_comp;
    c->y = n->y, c->y_comp = n->y_comp;
    c->theta = n->theta, c->theta_comp = n->theta_comp;
    c->distance = n->distance, c->distance_comp = n->distance_comp;
    memcpy(c->cov, n->cov, sizeof c->cov);
    c->arc_left = n->arc_left;
    c->arc_right = n->arc_right;
    if (has_t) {
        c->time = t;
        push_sample(c, t);
    } else {
        c->time = NAN; /* the clock is lost until the next time stamp */
        c->count = 0;
    }
}

/* An update from increments with an optional time stamp: checked, then applied. */
static int update(Core *c, const char *name, double dl, double dr, int has_t, double t) {
    double dt = has_t ? t - c->time : NAN; /* NaN too while the clock is unknown */
    Next n;
    if (check_update(c, name, dl, dr, has_t, t, dt) < 0 || next_state(c, name, dl, dr, &n) < 0 ||
        (has_t && ensure_room(c, 1) < 0))
        return -1;
    commit(c, &n, has_t, t);
    return 0;
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

static PyObject *update_increments(Core *c, PyObject *const *args, Py_ssize_t nargs,
                                   PyObject *kwnames) {
    static const char *name = "update_increments";
    PyObject *lo, *ro, *to;
    double dl, dr, t = NAN;
    int has_t;
    if (parse_update(name, "t", args, nargs, kwnames, &lo, &ro, &to) < 0 ||
        parse_double(lo, name, "left", &dl) < 0 || parse_double(ro, name, "right", &dr) < 0 ||
        parse_time(name, to, &has_t, &t) < 0 || update(c, name, dl, dr, has_t, t) < 0)
        return NULL;
    Py_RETURN_NONE;
}

/* A first reading only sets the reference: its time starts the clock and the window. */
static PyObject *start_reference(Core *c, const char *name, int has_t, double t) {
    if (has_t) {
        if (check_update(c, name, 0.0, 0.0, 1, t, t - c->time) < 0 || ensure_room(c, 1) < 0)
            return NULL;
        c->time = t;
        push_sample(c, t);
    }
    Py_RETURN_NONE;
}

static PyObject *update_positions(Core *c, PyObject *const *args, Py_ssize_t nargs,
                                  PyObject *kwnames) {
    static const char *name = "update_positions";
    PyObject *lo, *ro, *to;
    double left, right, t = NAN;
    int has_t;
    if (parse_update(name, "t", args, nargs, kwnames, &lo, &ro, &to) < 0 ||
        parse_double(lo, name, "left", &left) < 0 ||
        parse_double(ro, name, "right", &right) < 0 || parse_time(name, to, &has_t, &t) < 0)
        return NULL;
    if (!c->have_positions) {
        PyObject *done = start_reference(c, name, has_t, t);
        if (done != NULL) {
            c->have_positions = 1;
            c->position_left = left;
            c->position_right = right;
        }
        return done;
    }
    double dl = left - c->position_left, dr = right - c->position_right;
    if (update(c, name, dl, dr, has_t, t) < 0) return NULL;
    c->position_left = left;
    c->position_right = right;
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

/* The change from an old to a new counter reading, through at most one roll-over. */
static int tick_change(const Core *c, long long before, long long after, const char *field,
                       long long *out) {
    if (c->counter_bits == 0) {
        if (__builtin_sub_overflow(after, before, out)) {
            PyErr_Format(PyExc_ValueError, "update_ticks: %s changed by more than 2^63 counts",
                         field);
            return -1;
        }
        return 0;
    }
    uint64_t change = (uint64_t)after - (uint64_t)before;
    if (c->counter_bits < 64) {
        uint64_t modulus = 1ULL << c->counter_bits;
        change &= modulus - 1;
        *out = change >= modulus / 2 ? (long long)change - (long long)modulus : (long long)change;
    } else {
        *out = (long long)change;
    }
    return 0;
}

static PyObject *update_ticks(Core *c, PyObject *const *args, Py_ssize_t nargs,
                              PyObject *kwnames) {
    static const char *name = "update_ticks";
    PyObject *lo, *ro, *to;
    long long left, right, change_left, change_right;
    double t = NAN;
    int has_t;
    if (c->rad_per_tick == 0.0) {
        PyErr_SetString(PyExc_ValueError, "update_ticks needs ticks_per_revolution, which this "
                        "Odometry was made without");
        return NULL;
    }
    if (parse_update(name, "t", args, nargs, kwnames, &lo, &ro, &to) < 0 ||
        parse_ticks(lo, "left", c->counter_bits, &left) < 0 ||
        parse_ticks(ro, "right", c->counter_bits, &right) < 0 ||
        parse_time(name, to, &has_t, &t) < 0)
        return NULL;
    if (!c->have_ticks) {
        PyObject *done = start_reference(c, name, has_t, t);
        if (done != NULL) {
            c->have_ticks = 1;
            c->ticks_left = left;
            c->ticks_right = right;
        }
        return done;
    }
    if (tick_change(c, c->ticks_left, left, "left", &change_left) < 0 ||
        tick_change(c, c->ticks_right, right, "right", &change_right) < 0)
        return NULL;
    double dl = (double)change_left * c->rad_per_tick;
    double dr = (double)change_right * c->rad_per_tick;
    if (update(c, name, dl, dr, has_t, t) < 0) return NULL;
    c->ticks_left = left;
    c->ticks_right = right;
    Py_RETURN_NONE;
}

static PyObject *update_velocities(Core *c, PyObject *const *args, Py_ssize_t nargs,
                                   PyObject *kwnames) {
    static const char *name = "update_velocities";
    PyObject *lo, *ro, *dto;
    double left, right, dt;
    if (parse_update(name, "dt", args, nargs, kwnames, &lo, &ro, &dto) < 0) return NULL;
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
    /* Without a clock, one starts at 0 s with these velocities. */
    double start = isnan(c->time) ? 0.0 : c->time, dl = left * dt, dr = right * dt;
    Next n;
    if (check_update(c, name, dl, dr, 1, start + dt, dt) < 0 ||
        next_state(c, name, dl, dr, &n) < 0 || ensure_room(c, 2) < 0)
        return NULL;
    if (isnan(c->time)) {
        c->time = 0.0;
        push_sample(c, 0.0);
    }
    commit(c, &n, 1, start + dt);
    Py_RETURN_NONE;
}

/* -- what the Python class reads and sets --------------------------------------------------- */

static PyObject *get_state(Core *c, PyObject *unused) {
    return Py_BuildValue("(ddddd)", c->x + c->x_comp, c->y + c->y_comp, c->theta + c->theta_comp,
                         c->distance + c->distance_comp, c->time);
}

static PyObject *get_covariance(Core *c, PyObject *unused) {
    return Py_BuildValue("(ddddddddd)", c->cov[0], c->cov[1], c->cov[2], c->cov[3], c->cov[4],
                         c->cov[5], c->cov[6], c->cov[7], c->cov[8]);
}

/* Each wheel's travel (m) since the object was made: what an estimator built on this one takes
 * as the wheels' increments, every check of the update already passed. */
static PyObject *get_arcs(Core *c, PyObject *unused) {
    return Py_BuildValue("(dd)", c->arc_left, c->arc_right);
}

/* What one update can change, so that an estimator built on this core can take a reading
 * back when its own step refuses it: the state, the references, and the velocity window's
 * bounds and newest sample (an update appends or replaces one sample and drops from the
 * front, so the samples it does not touch are still in place). */
typedef struct {
    double x, y, theta, distance, x_comp, y_comp, theta_comp, distance_comp;
    double cov[9];
    double time;
    int have_ticks, have_positions;
    long long ticks_left, ticks_right;
    double position_left, position_right, arc_left, arc_right;
    Py_ssize_t first, count, capacity;
    Sample last;
} Snapshot;

static PyObject *snapshot(Core *c, PyObject *unused) {
    Snapshot s = {c->x, c->y, c->theta, c->distance, c->x_comp, c->y_comp, c->theta_comp,
                  c->distance_comp};
    memcpy(s.cov, c->cov, sizeof s.cov);
    s.time = c->time;
    s.have_ticks = c->have_ticks;
    s.have_positions = c->have_positions;
    s.ticks_left = c->ticks_left;
    s.ticks_right = c->ticks_right;
    s.position_left = c->position_left;
    s.position_right = c->position_right;
    s.arc_left = c->arc_left;
    s.arc_right = c->arc_right;
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
    c->x = s.x, c->y = s.y, c->theta = s.theta, c->distance = s.distance;
    c->x_comp = s.x_comp, c->y_comp = s.y_comp, c->theta_comp = s.theta_comp;
    c->distance_comp = s.distance_comp;
    memcpy(c->cov, s.cov, sizeof s.cov);
    c->time = s.time;
    c->have_ticks = s.have_ticks, c->have_positions = s.have_positions;
    c->ticks_left = s.ticks_left, c->ticks_right = s.ticks_right;
    c->position_left = s.position_left, c->position_right = s.position_right;
    c->arc_left = s.arc_left, c->arc_right = s.arc_right;
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
    return Py_BuildValue("(ddd)", (b.left - a.left) / span / c->r_left,
                         (b.right - a.right) / span / c->r_right, span);
}

static PyObject *set_pose(Core *c, PyObject *args) {
    double cov[9];
    if (!PyArg_ParseTuple(args, "ddd(ddddddddd)", &c->x, &c->y, &c->theta, &cov[0], &cov[1],
                          &cov[2], &cov[3], &cov[4], &cov[5], &cov[6], &cov[7], &cov[8]))
        return NULL;
    memcpy(c->cov, cov, sizeof cov);
    c->distance = 0.0;
    c->x_comp = c->y_comp = c->theta_comp = c->distance_comp = 0.0;
    Py_RETURN_NONE;
}

static PyObject *jacobians(Core *c, PyObject *args) {
    double dl, dr;
    if (!PyArg_ParseTuple(args, "dd", &dl, &dr)) return NULL;
    Step s;
    step(c, c->theta + c->theta_comp, dl, dr, &s);
    double *p = s.jac_pose, *w = s.jac_wheels;
    return Py_BuildValue("((ddddddddd)(dddddd))", p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7],
                         p[8], w[0], w[1], w[2], w[3], w[4], w[5]);
}

/* Built from one settings object (backends.settings.OdometrySettings, which the twin takes
 * too), read by name; at the origin: Odometry's reset puts the core at its start. */
static int core_init(Core *c, PyObject *args, PyObject *kwargs) {
    PyObject *s;
    double drive[4], k[2];
    if (!PyArg_ParseTuple(args, "O", &s)) return -1;
    if (attribute_into(s, "drive", drive, 4) < 0 || attribute_into(s, "k", k, 2) < 0 ||
        attribute_int(s, "method_code", &c->method) < 0 ||
        attribute_double(s, "rad_per_tick", &c->rad_per_tick) < 0 ||
        attribute_double(s, "max_wheel_speed", &c->max_wheel_speed) < 0 ||
        attribute_int(s, "counter_bits", &c->counter_bits) < 0 ||
        attribute_double(s, "velocity_window", &c->window) < 0)
        return -1;
    c->r_left = drive[0], c->r_right = drive[1], c->track = drive[2], c->offset = drive[3];
    c->k_left = k[0], c->k_right = k[1];
    c->x = c->y = c->theta = 0.0;
    c->distance = 0.0;
    c->x_comp = c->y_comp = c->theta_comp = c->distance_comp = 0.0;
    memset(c->cov, 0, sizeof c->cov);
    c->time = NAN;
    c->have_ticks = c->have_positions = 0;
    c->arc_left = c->arc_right = 0.0;
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
    typedef PyObject *(*Update)(Core *, PyObject *const *, Py_ssize_t, PyObject *);
    Update updates[4] = {update_ticks, update_positions, update_increments, update_velocities};
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
        PyObject *done = updates[kind](c, call, 3, NULL);
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
        out[3 * k] = c->x + c->x_comp;
        out[3 * k + 1] = c->y + c->y_comp;
        out[3 * k + 2] = c->theta + c->theta_comp;
        if (out_cov) memcpy(out_cov + 9 * k, c->cov, sizeof c->cov);
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
    Core *c = (Core *)core;
    switch (kind) {
    case 0: return update_ticks(c, args, nargs, NULL);
    case 1: return update_positions(c, args, nargs, NULL);
    case 2: return update_increments(c, args, nargs, NULL);
    default: return update_velocities(c, args, nargs, NULL);
    }
}

double odometry_time(PyObject *core) { return ((Core *)core)->time; }

void odometry_arcs(PyObject *core, double arcs[2]) {
    arcs[0] = ((Core *)core)->arc_left;
    arcs[1] = ((Core *)core)->arc_right;
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
