/* The state, history and updates of diffdrive.estimation.PoseEstimator, in C so that a wheel
 * and gyro update costs about a microsecond and a late measurement a few: the compiled twin
 * of estimation/estimator_python.py, which it mirrors step for step (the tests hold the two
 * together), on the maths of diffdrive/estimation/filter.py.
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
 * filtered start with the smoother's record of each step (advance_record: filter.advance's
 * joint, in full) and the Rauch-Tung-Striebel correction applied through it.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <string.h>

#include "_odometry.h"

#define N 8
#define NN 64
enum { BIAS = 3, SCALE = 4, DISTANCE = 5, OFFSET = 6 };
enum { WHEELS = 0, GYRO = 1, FUSED = 2 };
enum { POSE = 0, POSITION = 1, HEADING = 2 };
static const char *KIND_NAMES[3] = {"pose", "position", "heading"};
static const int KIND_RANK[3] = {1, 2, 0}; /* "heading" < "pose" < "position", as Python's */
static const char *UPDATES[4] = {"update_ticks", "update_positions", "update_increments",
                                 "update_velocities"};
#define SLIP_COMMAND_THRESHOLD 13.82

typedef struct {
    double t;
    int kind, size;
    double value[3], cov[9], lever[2];
    int ok;
    double score, log_det; /* the squared Mahalanobis distance; log det of its covariance */
} Meas;

/* One wheel interval: its data and slip test, and in the history the state at its start: x in
 * full, P packed (the carried states' block, row by row, n x n: see pack). */
typedef struct {
    double t0, t1, dl, dr, g;
    int forced, slip;
    double score;
    double x[N], P[NN];
} Interval;

/* An interval's data, its state left unset (filled where it is kept in the history). */
static void interval_of(Interval *iv, double t0, double t1, double dl, double dr, double g,
                        int forced) {
    iv->t0 = t0, iv->t1 = t1, iv->dl = dl, iv->dr = dr, iv->g = g;
    iv->forced = forced, iv->slip = 0, iv->score = 0.0;
}

/* The smoother's record of one step (filter.Step): the state before it given the data to its
 * end, the state after it (before any absolute measurement), and the gain C. */
typedef struct {
    double before[N], before_cov[NN], after[N], after_cov[NN], gain[NN];
} Step;
/* _run_log copies Steps into a caller's rows of filter.RECORD_WIDTH float64 */
_Static_assert(sizeof(Step) == (2 * N + 3 * NN) * sizeof(double), "a Step is 208 doubles");

/* Where run_interval records the smoother's steps (NULL: it keeps none). */
typedef struct {
    Step *steps;
    Py_ssize_t count;
} Record;

typedef struct {
    PyObject_HEAD
    PyObject *wheels;
    /* configuration */
    double r_l, r_r, track, axle, weight;
    int chord, heading, est_bias, est_scale, est_distance, est_offset, inflate;
    double k_l, k_r, arw2, rrw2, offset_rate2, slip_thr, slip_infl, command_sigma;
    double k_per_r_l, k_per_r_r; /* k / r of each wheel: its angle noise's variance per rad */
    double gate[4], offset, history, ahead, mount[3];
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

/* Inlined wherever called: advance_n then has a constant n in each of its callers. */
#if defined(__GNUC__) || defined(__clang__)
#define ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define ALWAYS_INLINE inline
#endif

/* -- the maths of filter.py ------------------------------------------------------------- */

static double wrap(double a) {
    double w = remainder(a, 2.0 * M_PI);
    return w <= -M_PI ? w + 2.0 * M_PI : w;
}

static double slip_score(const Est *e, const double *x, const double *P, double dl, double dr,
                         double g, double dt) {
    double wheel_turn = (e->r_r * dr - e->r_l * dl) / e->track, scale = x[SCALE];
    double spread = e->k_l * fabs(e->r_l * dl) + e->k_r * fabs(e->r_r * dr);
    double innovation = scale * wheel_turn - (g - x[BIAS] * dt);
    double variance = scale * scale * spread / (e->track * e->track) + e->arw2 * dt +
                      dt * dt * P[BIAS * N + BIAS] + wheel_turn * wheel_turn * P[SCALE * N + SCALE] +
                      1e-18;
    return innovation * innovation / variance;
}

/* One step's move and its linearisation, as filter.advance builds them: the wheels' turn,
 * the turn, the move (dx, dy), the noises' variances (left, right wheel angle; gyro), and the
 * nonzero blocks of F - I (A: rows 0 to 2, columns 2 to 5: the heading, the bias, the turn
 * and the distance scale) and of G (rows 0 to 2). */
typedef struct {
    double wheel_turn, turn, dx, dy, noise[3], A[3][4], G[3][3];
} Move;

static ALWAYS_INLINE void
move_terms(const Est *e, const double *x, double dl, double dr, double g, double dt, int slip,
           Move *m) {
    double left = e->r_l * dl, right = e->r_r * dr;
    double travelled = 0.5 * (left + right), scale = x[SCALE], distance = x[DISTANCE];
    double forward = distance * travelled;
    double inflation = slip ? e->slip_infl : 1.0;
    m->wheel_turn = (right - left) / e->track;
    /* k |r dl| / r^2 = (k / r) |dl|: the radii are positive (checked in __init__) */
    m->noise[0] = inflation * e->k_per_r_l * fabs(dl);
    m->noise[1] = inflation * e->k_per_r_r * fabs(dr);
    m->noise[2] = e->heading != WHEELS ? e->arw2 * dt : 0.0;
    double bnf[3] = {0.5 * distance * e->r_l, 0.5 * distance * e->r_r, 0.0}, bnt[3],
           bst[N] = {0};
    if (e->heading == WHEELS) {
        m->turn = scale * m->wheel_turn;
        bnt[0] = -scale * e->r_l / e->track;
        bnt[1] = scale * e->r_r / e->track;
        bnt[2] = 0.0;
        bst[SCALE] = m->wheel_turn;
    } else {
        m->turn = g - x[BIAS] * dt;
        bnt[0] = bnt[1] = 0.0;
        bnt[2] = 1.0;
        bst[BIAS] = -dt;
    }
    double bf[2], bt[2];
    dd_move_jacobians(forward, e->axle, m->turn, e->weight, e->chord, x[2], &m->dx, &m->dy, bf,
                      bt);
    const double columns[3][4] = {
        {-m->dy, bt[0] * bst[BIAS], bt[0] * bst[SCALE], bf[0] * travelled},
        {m->dx, bt[1] * bst[BIAS], bt[1] * bst[SCALE], bf[1] * travelled},
        {0.0, bst[BIAS], bst[SCALE], 0.0}};
    memcpy(m->A, columns, sizeof columns);
    for (int i = 0; i < 3; ++i) {
        m->G[0][i] = bf[0] * bnf[i] + bt[0] * bnt[i];
        m->G[1][i] = bf[1] * bnf[i] + bt[1] * bnt[i];
        m->G[2][i] = bnt[i];
    }
}

/* filter.advance without the smoother's record, in place on x and P, for the first n states
 * (3: the pose; 4: and the bias; 5: and the turn scale; 6: and the distance scale; 8: and the
 * fixes' offset). The states that are not estimated have
 * zero rows and columns in P and keep them, untouched. Always inlined into advance with n a
 * constant, so every loop has fixed bounds the compiler unrolls. */
static ALWAYS_INLINE void
advance_n(const Est *e, double *x, double *P, double dl, double dr, double g, double dt, int slip,
          const int n) {
    Move mv;
    move_terms(e, x, dl, dr, g, dt, slip, &mv);
    const double wheel_turn = mv.wheel_turn, turn = mv.turn, dx = mv.dx, dy = mv.dy;
    const double *noise = mv.noise, scale = x[SCALE];
    /* A = F - I is zero but for columns 2 to 5 of rows 0 to 2, and G is zero below row 2:
     * FP = P + A P and moved = FP F^T + G Q G^T over those entries only (a column of A past n
     * meets a zero row of P: it adds an exact zero). */
    double (*A)[4] = mv.A, (*G)[3] = mv.G, GQ[3][3];
    for (int i = 0; i < 3; ++i)
        for (int k = 0; k < 3; ++k) GQ[i][k] = G[i][k] * noise[k];
    double after[N];
    memcpy(after, x, sizeof after);
    after[0] += dx;
    after[1] += dy;
    after[2] += turn;
    double FP[NN], moved[NN];
    /* the block the steps below read: the first n states, and the heading's to the distance
     * scale's columns and rows, which A and h4 multiply (zero when not carried); element by
     * element, n being a constant here */
    enum { READ = DISTANCE + 1 };
    for (int i = 0; i < (n > READ ? n : READ); ++i)
        for (int j = 0; j < (n > READ ? n : READ); ++j) FP[i * N + j] = P[i * N + j];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < n; ++j)
            FP[i * N + j] += A[i][0] * P[2 * N + j] + A[i][1] * P[3 * N + j] +
                             A[i][2] * P[4 * N + j] + A[i][3] * P[5 * N + j];
    /* moved is symmetric: its upper triangle, mirrored */
    for (int i = 0; i < n; ++i)
        for (int j = i; j < n; ++j) {
            double sum = FP[i * N + j];
            if (j < 3) {
                sum += FP[i * N + 2] * A[j][0] + FP[i * N + 3] * A[j][1] +
                       FP[i * N + 4] * A[j][2] + FP[i * N + 5] * A[j][3];
                if (i < 3) sum += GQ[i][0] * G[j][0] + GQ[i][1] * G[j][1] + GQ[i][2] * G[j][2];
            }
            moved[i * N + j] = moved[j * N + i] = sum;
        }
    if (e->est_bias && e->heading == FUSED) moved[BIAS * N + BIAS] += e->rrw2 * dt;
    if (n > OFFSET && e->est_offset) {
        moved[OFFSET * N + OFFSET] += e->offset_rate2 * dt;
        moved[(OFFSET + 1) * N + OFFSET + 1] += e->offset_rate2 * dt;
    }
    if (!(e->heading == FUSED && !slip)) {
        memcpy(x, after, sizeof after);
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j) P[i * N + j] = moved[i * N + j];
        return;
    }
    /* The wheels measure the turn over the scale, less their own noise. On the joint of
     * (state after, state before, noises), [[moved, FP, GQ], [FP^T, P, 0], [GQ^T, 0, Q]], with
     * H = (h_after, h_before, h_noise): its spread along H, block by block. h_after is zero
     * but at the heading and the scale, h_before but at the heading. */
    const double h2 = 1.0 / scale, h4 = e->est_scale ? -turn / (scale * scale) : 0.0;
    const double hn[3] = {e->r_l / e->track, -e->r_r / e->track, 0.0};
    double spread[N] = {0}, before[N] = {0}, s = 0.0;
    for (int i = 0; i < n; ++i) {
        double sum = moved[i * N + 2] * h2 - FP[i * N + 2] * h2;
        if (n >= 5) sum += moved[i * N + 4] * h4; /* moved is only filled up to n */
        if (i < 3) sum += GQ[i][0] * hn[0] + GQ[i][1] * hn[1];
        spread[i] = sum;
        before[i] = FP[2 * N + i] * h2 + FP[4 * N + i] * h4 - P[i * N + 2] * h2;
    }
    s = h2 * spread[2] + h4 * spread[4] - h2 * before[2];
    for (int k = 0; k < 2; ++k)
        s += hn[k] * (noise[k] * hn[k] + GQ[2][k] * h2);
    s += 1e-18;
    /* one division: the gains spread / s (moved is exactly symmetric, so Po is too) */
    double innovation = wheel_turn - turn * h2, inverse = 1.0 / s, gains[N];
    for (int i = 0; i < N; ++i) {
        gains[i] = spread[i] * inverse;
        x[i] = after[i] + gains[i] * innovation;
    }
    for (int i = 0; i < n; ++i)
        for (int j = i; j < n; ++j)
            P[i * N + j] = P[j * N + i] = moved[i * N + j] - gains[i] * spread[j];
}

/* How many leading states advance and advance_record carry: the ones past it are neither
 * estimated nor touched (zero rows and columns in P). */
static int carried(const Est *e) {
    return e->est_offset ? 8 : e->est_distance ? 6 : e->est_scale ? 5 : e->est_bias ? 4 : 3;
}

static void advance(const Est *e, double *x, double *P, double dl, double dr, double g, double dt,
                    int slip) {
    switch (carried(e)) { /* each with its own constant n */
    case 8: advance_n(e, x, P, dl, dr, g, dt, slip, 8); break;
    case 6: advance_n(e, x, P, dl, dr, g, dt, slip, 6); break;
    case 5: advance_n(e, x, P, dl, dr, g, dt, slip, 5); break;
    case 4: advance_n(e, x, P, dl, dr, g, dt, slip, 4); break;
    default: advance_n(e, x, P, dl, dr, g, dt, slip, 3);
    }
}

/* The eigenvalues w and eigenvectors V (columns, row-major) of a symmetric m x m matrix A
 * (m <= N), by cyclic Jacobi rotations: to rounding, as numpy.linalg.eigh. */
static void symmetric_eigen(const double *A, int m, double *w, double *V) {
    double a[NN];
    memcpy(a, A, sizeof(double) * m * m);
    for (int i = 0; i < m; ++i)
        for (int j = 0; j < m; ++j) V[i * m + j] = i == j ? 1.0 : 0.0;
    for (int sweep = 0; sweep < 60; ++sweep) {
        double off = 0.0, scale = 0.0;
        for (int i = 0; i < m; ++i)
            for (int j = 0; j < m; ++j) {
                if (i != j) off += a[i * m + j] * a[i * m + j];
                scale += a[i * m + j] * a[i * m + j];
            }
        if (off <= 1e-300 || off <= 1e-32 * scale) break;
        for (int p = 0; p < m - 1; ++p)
            for (int q = p + 1; q < m; ++q) {
                double apq = a[p * m + q];
                if (apq == 0.0) continue;
                double theta = 0.5 * (a[q * m + q] - a[p * m + p]) / apq;
                double t = (theta >= 0.0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
                double c = 1.0 / sqrt(t * t + 1.0), s = t * c;
                for (int k = 0; k < m; ++k) { /* columns p and q of a */
                    double akp = a[k * m + p], akq = a[k * m + q];
                    a[k * m + p] = c * akp - s * akq;
                    a[k * m + q] = s * akp + c * akq;
                }
                for (int k = 0; k < m; ++k) { /* rows p and q */
                    double apk = a[p * m + k], aqk = a[q * m + k];
                    a[p * m + k] = c * apk - s * aqk;
                    a[q * m + k] = s * apk + c * aqk;
                }
                for (int k = 0; k < m; ++k) {
                    double vkp = V[k * m + p], vkq = V[k * m + q];
                    V[k * m + p] = c * vkp - s * vkq;
                    V[k * m + q] = s * vkp + c * vkq;
                }
            }
    }
    for (int i = 0; i < m; ++i) w[i] = a[i * m + i];
}

/* The inverse of a symmetric m x m matrix A with a unit diagonal (m <= N) by Cholesky, when
 * every eigenvalue is surely above pinv's cut (1e-12 of the largest): the smallest is at
 * least 1 / trace(A^-1), the largest at most trace(A) = m. 0 (nothing promised) otherwise. */
static int well_conditioned_inverse(const double *A, int m, double *inverse) {
    double L[NN] = {0};
    for (int i = 0; i < m; ++i)
        for (int j = 0; j <= i; ++j) {
            double sum = A[i * m + j];
            for (int q = 0; q < j; ++q) sum -= L[i * m + q] * L[j * m + q];
            if (i == j) {
                if (!(sum > 0.0)) return 0;
                L[i * m + i] = sqrt(sum);
            } else {
                L[i * m + j] = sum / L[j * m + j];
            }
        }
    double Li[NN] = {0}; /* L^-1, lower */
    for (int i = 0; i < m; ++i) {
        Li[i * m + i] = 1.0 / L[i * m + i];
        for (int j = 0; j < i; ++j) {
            double sum = 0.0;
            for (int q = j; q < i; ++q) sum += L[i * m + q] * Li[q * m + j];
            Li[i * m + j] = -sum / L[i * m + i];
        }
    }
    double trace = 0.0;
    for (int i = 0; i < m; ++i)
        for (int j = i; j < m; ++j) {
            double sum = 0.0; /* (L^-T L^-1)_ij over the rows below both */
            for (int q = j; q < m; ++q) sum += Li[q * m + i] * Li[q * m + j];
            inverse[i * m + j] = inverse[j * m + i] = sum;
            if (i == j) trace += sum;
        }
    return isfinite(trace) && 1.0 / trace > 1e-9 * m;
}

/* filter._solve_right: cross @ pinv(covariance) over the estimated states, the covariance
 * scaled to unit variances first (pinv as numpy's, hermitian, rcond 1e-12). */
static void solve_right(const Est *e, const double *cross, const double *cov, double *gain) {
    int active[N], m = 0;
    active[m++] = 0;
    active[m++] = 1;
    active[m++] = 2;
    if (e->est_bias && e->heading == FUSED) active[m++] = BIAS;
    if (e->est_scale) active[m++] = SCALE;
    if (e->est_distance) active[m++] = DISTANCE;
    if (e->est_offset) {
        active[m++] = OFFSET;
        active[m++] = OFFSET + 1;
    }
    double block[NN], sigma[N], w[N], V[NN], inverse[NN];
    for (int i = 0; i < m; ++i) {
        double d = cov[active[i] * N + active[i]];
        sigma[i] = d > 0.0 ? sqrt(d) : 0.0;
        if (sigma[i] == 0.0) sigma[i] = 1.0;
    }
    for (int i = 0; i < m; ++i)
        for (int j = 0; j < m; ++j)
            block[i * m + j] = cov[active[i] * N + active[j]] / (sigma[i] * sigma[j]);
    if (well_conditioned_inverse(block, m, inverse)) { /* pinv is the inverse: by Cholesky */
        for (int i = 0; i < m; ++i)
            for (int j = 0; j < m; ++j) inverse[i * m + j] /= sigma[i] * sigma[j];
    } else {
        symmetric_eigen(block, m, w, V);
        double largest = 0.0;
        for (int i = 0; i < m; ++i) largest = fmax(largest, fabs(w[i]));
        for (int i = 0; i < m; ++i)
            for (int j = 0; j < m; ++j) {
                double sum = 0.0;
                for (int q = 0; q < m; ++q)
                    if (fabs(w[q]) > 1e-12 * largest) sum += V[i * m + q] * V[j * m + q] / w[q];
                inverse[i * m + j] = sum / (sigma[i] * sigma[j]);
            }
    }
    memset(gain, 0, sizeof(double) * NN);
    for (int i = 0; i < m; ++i)
        for (int j = 0; j < m; ++j) {
            double sum = 0.0;
            for (int q = 0; q < m; ++q) sum += cross[active[i] * N + active[q]] * inverse[q * m + j];
            gain[active[i] * N + active[j]] = sum;
        }
}

/* filter.advance's smoother record of one step from x, P (the joint of the state after, the
 * state before and the noises, the wheels' turn measured in it with a fused heading): the
 * same maths as advance_n, written out in full over the first n = carried(e) states (the
 * record's other entries: zero, and the state's own values before and after). */
static void advance_record(const Est *e, const double *x, const double *P, double dl, double dr,
                           double g, double dt, int slip, Step *out) {
    enum { JMAX = 2 * N + 3 };
    const int n = carried(e), J = 2 * n + 3;
    Move mv;
    move_terms(e, x, dl, dr, g, dt, slip, &mv);
    const double wheel_turn = mv.wheel_turn, turn = mv.turn, dx = mv.dx, dy = mv.dy;
    const double *noise = mv.noise, scale = x[SCALE];
    double F[NN] = {0}, G[N * 3] = {0}; /* in full: I + A, and G with its zero rows */
    for (int i = 0; i < n; ++i) F[i * N + i] = 1.0;
    for (int i = 0; i < 3; ++i) {
        for (int c = 0; c < 4 && 2 + c < n; ++c) F[i * N + 2 + c] += mv.A[i][c];
        for (int c = 0; c < 3; ++c) G[i * 3 + c] = mv.G[i][c];
    }
    double FP[NN], moved[NN], GQ[N * 3];
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            double sum = 0.0;
            for (int q = 0; q < n; ++q) sum += F[i * N + q] * P[q * N + j];
            FP[i * N + j] = sum;
        }
    for (int i = 0; i < n; ++i)
        for (int k = 0; k < 3; ++k) GQ[i * 3 + k] = G[i * 3 + k] * noise[k];
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            double sum = 0.0;
            for (int q = 0; q < n; ++q) sum += FP[i * N + q] * F[j * N + q];
            for (int k = 0; k < 3; ++k) sum += GQ[i * 3 + k] * G[j * 3 + k];
            moved[i * N + j] = sum;
        }
    if (e->est_bias && e->heading == FUSED) moved[BIAS * N + BIAS] += e->rrw2 * dt;
    if (e->est_offset) {
        moved[OFFSET * N + OFFSET] += e->offset_rate2 * dt;
        moved[(OFFSET + 1) * N + OFFSET + 1] += e->offset_rate2 * dt;
    }
    double joint[JMAX * JMAX];
    double mean[JMAX] = {0};
    memset(joint, 0, sizeof(double) * J * J);
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            joint[i * J + j] = moved[i * N + j];
            joint[i * J + n + j] = FP[i * N + j];
            joint[(n + j) * J + i] = FP[i * N + j];
            joint[(n + i) * J + n + j] = P[i * N + j];
        }
    for (int i = 0; i < n; ++i)
        for (int k = 0; k < 3; ++k) joint[i * J + 2 * n + k] = joint[(2 * n + k) * J + i] = GQ[i * 3 + k];
    for (int k = 0; k < 3; ++k) joint[(2 * n + k) * J + 2 * n + k] = noise[k];
    for (int i = 0; i < n; ++i) {
        mean[i] = x[i];
        mean[n + i] = x[i];
    }
    mean[0] += dx;
    mean[1] += dy;
    mean[2] += turn;
    if (e->heading == FUSED && !slip) {
        double H[JMAX] = {0}, spread[JMAX], s = 0.0;
        H[2] = 1.0 / scale;
        H[n + 2] = -1.0 / scale;
        if (n > SCALE) H[SCALE] = -turn / (scale * scale);
        H[2 * n] = e->r_l / e->track;
        H[2 * n + 1] = -e->r_r / e->track;
        for (int i = 0; i < J; ++i) {
            double sum = 0.0;
            for (int q = 0; q < J; ++q) sum += joint[i * J + q] * H[q];
            spread[i] = sum;
        }
        for (int i = 0; i < J; ++i) s += H[i] * spread[i];
        s += 1e-18;
        double innovation = wheel_turn - turn / scale;
        for (int i = 0; i < J; ++i) mean[i] += spread[i] / s * innovation;
        for (int i = 0; i < J; ++i)
            for (int j = 0; j < J; ++j) joint[i * J + j] -= spread[i] / s * spread[j];
    }
    double cross[NN];
    memset(out, 0, sizeof *out);
    memset(cross, 0, sizeof cross);
    for (int i = 0; i < N; ++i) /* the states not carried: where they are, before and after */
        out->before[i] = out->after[i] = x[i];
    for (int i = 0; i < n; ++i) {
        out->before[i] = mean[n + i];
        out->after[i] = mean[i];
        for (int j = 0; j < n; ++j) {
            out->before_cov[i * N + j] =
                0.5 * (joint[(n + i) * J + n + j] + joint[(n + j) * J + n + i]);
            out->after_cov[i * N + j] = 0.5 * (joint[i * J + j] + joint[j * J + i]);
            cross[i * N + j] = 0.5 * (joint[(n + i) * J + j] + joint[j * J + n + i]);
        }
    }
    solve_right(e, cross, out->after_cov, out->gain);
}

/* Cholesky of a k x k (k <= 3) matrix into L (lower); -1 unless positive definite. */
static int cholesky(const double *A, int k, double *L) {
    memset(L, 0, sizeof(double) * k * k);
    for (int i = 0; i < k; ++i)
        for (int j = 0; j <= i; ++j) {
            double sum = A[i * k + j];
            for (int m = 0; m < j; ++m) sum -= L[i * k + m] * L[j * k + m];
            if (i == j) {
                if (!(sum > 0.0)) return -1;
                L[i * k + i] = sqrt(sum);
            } else {
                L[i * k + j] = sum / L[j * k + j];
            }
        }
    return 0;
}

/* Solve L L^T y = b in place (b of k values). */
static void cholesky_solve(const double *L, int k, double *b) {
    for (int i = 0; i < k; ++i) {
        for (int m = 0; m < i; ++m) b[i] -= L[i * k + m] * b[m];
        b[i] /= L[i * k + i];
    }
    for (int i = k - 1; i >= 0; --i) {
        for (int m = i + 1; m < k; ++m) b[i] -= L[m * k + i] * b[m];
        b[i] /= L[i * k + i];
    }
}

/* filter.absolute_update: x, P (in and out, unchanged if the gate refuses); ok, score and the
 * log determinant of the innovation's covariance (NULL: not wanted). */
static void absolute_update(const Est *e, double *x, double *P, const Meas *m, int *ok,
                            double *score, double *log_det) {
    /* the states past carried(e) have zero rows and columns in P: left out */
    const int k = m->size, n = carried(e);
    double H[3 * N] = {0}, innovation[3];
    if (m->kind == HEADING) {
        H[2] = 1.0;
        innovation[0] = wrap(m->value[0] - x[2]);
    } else {
        double ax = m->lever[0], ay = m->lever[1] - e->offset, c = cos(x[2]), s = sin(x[2]);
        H[0 * N + 0] = H[1 * N + 1] = 1.0;
        H[0 * N + 2] = -s * ax - c * ay;
        H[1 * N + 2] = c * ax - s * ay;
        innovation[0] = m->value[0] - (x[0] + c * ax - s * ay);
        innovation[1] = m->value[1] - (x[1] + s * ax + c * ay);
        if (e->est_offset && m->kind == POSITION) { /* the fix carries the offset */
            H[0 * N + OFFSET] = H[1 * N + OFFSET + 1] = 1.0;
            innovation[0] -= x[OFFSET];
            innovation[1] -= x[OFFSET + 1];
        }
        if (k == 3) {
            H[2 * N + 2] = 1.0;
            innovation[2] = wrap(m->value[2] - x[2]);
        }
    }
    double HP[3 * N], S[9] = {0}, L[9];
    for (int i = 0; i < k; ++i)
        for (int j = 0; j < n; ++j) {
            double sum = 0.0;
            for (int q = 0; q < n; ++q) sum += H[i * N + q] * P[q * N + j];
            HP[i * N + j] = sum;
        }
    for (int i = 0; i < k; ++i)
        for (int j = 0; j < k; ++j) {
            double sum = 0.0;
            for (int q = 0; q < n; ++q) sum += HP[i * N + q] * H[j * N + q];
            S[i * k + j] = sum + m->cov[i * k + j];
        }
    *ok = 0;
    if (cholesky(S, k, L) < 0) {
        *score = INFINITY;
        if (log_det != NULL) *log_det = NAN;
        return;
    }
    if (log_det != NULL) {
        *log_det = 0.0;
        for (int i = 0; i < k; ++i) *log_det += 2.0 * log(L[i * k + i]);
    }
    double white[3];
    for (int i = 0; i < k; ++i) {
        double sum = innovation[i];
        for (int q = 0; q < i; ++q) sum -= L[i * k + q] * white[q];
        white[i] = sum / L[i * k + i];
    }
    double d2 = 0.0;
    for (int i = 0; i < k; ++i) d2 += white[i] * white[i];
    *score = d2;
    /* past the gate: refused, or (inflate) taken with its covariance R grown to R + (a - 1) S,
     * which makes S a S with a = d2 / gate: its score then lies on the gate */
    double grow = 1.0, R[9];
    if (d2 > e->gate[k]) {
        if (!e->inflate) return;
        grow = d2 / e->gate[k];
    }
    for (int i = 0; i < k * k; ++i) R[i] = m->cov[i] + (grow - 1.0) * S[i];
    /* gain = (S^-1 H P)^T / a, N x k */
    double gain[N * 3];
    for (int j = 0; j < n; ++j) {
        double column[3];
        for (int i = 0; i < k; ++i) column[i] = HP[i * N + j];
        cholesky_solve(L, k, column);
        for (int i = 0; i < k; ++i) gain[j * 3 + i] = column[i] / grow;
    }
    double keep[NN], KP[NN], out[NN];
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            double sum = i == j ? 1.0 : 0.0;
            for (int q = 0; q < k; ++q) sum -= gain[i * 3 + q] * H[q * N + j];
            keep[i * N + j] = sum;
        }
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            double sum = 0.0;
            for (int q = 0; q < n; ++q) sum += keep[i * N + q] * P[q * N + j];
            KP[i * N + j] = sum;
        }
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            double sum = 0.0;
            for (int q = 0; q < n; ++q) sum += KP[i * N + q] * keep[j * N + q];
            double noisy = 0.0;
            for (int a = 0; a < k; ++a)
                for (int b = 0; b < k; ++b)
                    noisy += gain[i * 3 + a] * R[a * k + b] * gain[j * 3 + b];
            out[i * N + j] = sum + noisy;
        }
    for (int i = 0; i < n; ++i) {
        double sum = 0.0;
        for (int q = 0; q < k; ++q) sum += gain[i * 3 + q] * innovation[q];
        x[i] += sum;
    }
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) P[i * N + j] = 0.5 * (out[i * N + j] + out[j * N + i]);
    *ok = 1;
}

/* -- the history ------------------------------------------------------------------------ */

static int finite_state(const double *x, const double *P) {
    for (int i = 0; i < N; ++i)
        if (!isfinite(x[i])) return 0;
    for (int i = 0; i < NN; ++i)
        if (!isfinite(P[i])) return 0;
    return 1;
}

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

/* Run interval iv over the measurements m[0..nm) (sorted), to its end (record: the slip test
 * and the outcomes kept) or to stop (recording nothing): x, P hold its start state (iv->x,
 * iv->P) on the way in, the state at the end on the way out. */
static void run_interval(const Est *e, Interval *iv, Meas *m, Py_ssize_t nm, int record,
                         double stop, double *x, double *P, Record *steps) {
    double duration = iv->t1 - iv->t0;
    if (record) {
        if (isnan(iv->g)) {
            iv->slip = iv->forced;
            iv->score = 0.0;
        } else {
            iv->score = slip_score(e, x, P, iv->dl, iv->dr, iv->g, duration);
            iv->slip = iv->score > e->slip_thr || iv->forced;
        }
    }
    double end = record ? iv->t1 : stop, done = 0.0, t = iv->t0;
    Py_ssize_t j = 0;
    for (;;) {
        double cut = (j < nm && m[j].t <= end) ? m[j].t : end;
        /* at the end, the share is 1 (what the division gives there too, exactly) */
        double share = cut == iv->t1 || !(duration > 0.0) ? 1.0 : (cut - iv->t0) / duration;
        double part = share - done;
        if (cut > t && steps != NULL) { /* the smoother's record: its state after is x's */
            Step *step = &steps->steps[steps->count++];
            advance_record(e, x, P, part * iv->dl, part * iv->dr, part * iv->g, cut - t,
                           iv->slip, step);
            memcpy(x, step->after, sizeof step->after);
            memcpy(P, step->after_cov, sizeof step->after_cov);
        } else if (cut > t) {
            advance(e, x, P, part * iv->dl, part * iv->dr, part * iv->g, cut - t, iv->slip);
        }
        done = share;
        t = cut;
        while (j < nm && m[j].t <= cut) {
            int ok;
            double score, log_det;
            absolute_update(e, x, P, &m[j], &ok, &score, &log_det);
            if (record) {
                m[j].ok = ok;
                m[j].score = score;
                m[j].log_det = log_det;
            }
            ++j;
        }
        if (cut >= end) break;
    }
}

/* P's block of the carried states, n x n row by row, into packed: what the history keeps. */
static void pack(const Est *e, double *packed, const double *P) {
    const int n = carried(e);
    for (int i = 0; i < n; ++i) /* element by element: memcpy's setup would cost more here */
        for (int j = 0; j < n; ++j) packed[i * n + j] = P[i * N + j];
}

/* P in full from its packed block, zero elsewhere (the states not carried). */
static void unpack(const Est *e, double *P, const double *packed) {
    const int n = carried(e);
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
        run_interval(e, &e->iv[i], e->ms + lo, hi - lo, 1, 0.0, x, P, NULL);
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
            if (e->ms[j].ok)
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
    if (have_previous && !have_angle && !have_rate && e->heading != WHEELS) {
        PyErr_Format(PyExc_ValueError,
                     "%s: heading '%s' needs gyro_angle or gyro_rate with every wheel reading",
                     name, e->heading == GYRO ? "gyro" : "fused");
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
    double dl = (after[0] - before[0]) / e->r_l, dr = (after[1] - before[1]) / e->r_r;
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
    run_interval(e, iv, tail, due, 1, 0.0, x, P, NULL);
    if (!finite_state(x, P)) {
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
            int ok;
            double score;
            memcpy(x, e->x, sizeof x);
            memcpy(P, e->P, sizeof P);
            absolute_update(e, x, P, m, &ok, &score, NULL);
            if (!finite_state(x, P)) {
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
    if (!finite_state(x, P)) {
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
        result = PyBool_FromLong(e->ms[at].ok);
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
        if (cholesky(m.cov, k, L) < 0) Py_RETURN_NONE;
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
        if (e->ms[j].ok)
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
        run_interval(e, &copy, e->ms + a, b - a, 0, t, x, P, NULL);
    }
    return Py_BuildValue("(NN)", tuple_of(x, N), tuple_of(P, NN));
}

/* -- the type -------------------------------------------------------------------------------- */

/* Built from one settings object (backends.settings.CoreSettings, which the twin takes too),
 * read by name: the drive, method and heading codes, noises, flags, gates and the start. */
static int est_init(Est *e, PyObject *args, PyObject *kwargs) {
    PyObject *wheels, *s;
    int method;
    if (!PyArg_ParseTuple(args, "OO", &wheels, &s)) return -1;
    if (!odometry_check(wheels)) {
        PyErr_SetString(PyExc_TypeError, "EstimatorCore reads its wheels through an OdometryCore");
        return -1;
    }
    double drive[4], k[2];
    if (attribute_into(s, "drive", drive, 4) < 0 || attribute_into(s, "k", k, 2) < 0 ||
        attribute_double(s, "arw2", &e->arw2) < 0 || attribute_double(s, "rrw2", &e->rrw2) < 0 ||
        attribute_double(s, "offset_rate2", &e->offset_rate2) < 0 ||
        attribute_double(s, "slip_threshold", &e->slip_thr) < 0 ||
        attribute_double(s, "slip_inflation", &e->slip_infl) < 0 ||
        attribute_double(s, "command_sigma", &e->command_sigma) < 0 ||
        attribute_into(s, "gates", e->gate + 1, 3) < 0 ||
        attribute_double(s, "offset", &e->offset) < 0 ||
        attribute_double(s, "history", &e->history) < 0 ||
        attribute_double(s, "ahead", &e->ahead) < 0 ||
        attribute_into(s, "mounting", e->mount, 3) < 0 ||
        attribute_into(s, "state", e->x, N) < 0 ||
        attribute_into(s, "covariance", e->P, NN) < 0 ||
        attribute_int(s, "method_code", &method) < 0 ||
        attribute_int(s, "heading_code", &e->heading) < 0 ||
        attribute_int(s, "estimate_bias", &e->est_bias) < 0 ||
        attribute_int(s, "estimate_scale", &e->est_scale) < 0 ||
        attribute_int(s, "estimate_distance", &e->est_distance) < 0 ||
        attribute_int(s, "estimate_offset", &e->est_offset) < 0 ||
        attribute_int(s, "inflate", &e->inflate) < 0)
        return -1;
    e->r_l = drive[0], e->r_r = drive[1], e->track = drive[2], e->axle = drive[3];
    e->k_l = k[0], e->k_r = k[1];
    /* METHODS: euler, rk2, exact (_step.METHOD_FLAGS) */
    e->k_per_r_l = e->k_l / e->r_l; /* the Python class has checked the radii are > 0 */
    e->k_per_r_r = e->k_r / e->r_r;
    e->weight = method == 0 ? 0.0 : 0.5;
    e->chord = method == 2;
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

/* The RTS step backwards through one record: x, P smoothed after it in, before it out. */
static void smooth_step(const Step *s, double *x, double *P) {
    double dx[N], G[NN], GD[NN];
    for (int i = 0; i < N; ++i) dx[i] = x[i] - s->after[i];
    for (int i = 0; i < N; ++i) {
        double sum = s->before[i];
        for (int q = 0; q < N; ++q) sum += s->gain[i * N + q] * dx[q];
        x[i] = sum;
    }
    for (int i = 0; i < NN; ++i) G[i] = P[i] - s->after_cov[i];
    for (int i = 0; i < N; ++i)
        for (int j = 0; j < N; ++j) {
            double sum = 0.0;
            for (int q = 0; q < N; ++q) sum += s->gain[i * N + q] * G[q * N + j];
            GD[i * N + j] = sum;
        }
    for (int i = 0; i < N; ++i)
        for (int j = i; j < N; ++j) {
            double a = 0.0, b = 0.0;
            for (int q = 0; q < N; ++q) {
                a += GD[i * N + q] * s->gain[j * N + q];
                b += GD[j * N + q] * s->gain[i * N + q];
            }
            P[i * N + j] = P[j * N + i] =
                0.5 * ((s->before_cov[i * N + j] + a) + (s->before_cov[j * N + i] + b));
        }
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
        absolute_update(e, x, P, &ms[j], &ms[j].ok, &ms[j].score, &ms[j].log_det);
    if (!finite_state(x, P)) failed = -2;
    memcpy(states, x, sizeof x);
    memcpy(covs, P, sizeof P);
    slips[0] = scores[0] = 0.0;
    for (Py_ssize_t k = 1; k < n && failed == -1; ++k) {
        Interval iv;
        interval_of(&iv, t[k - 1], t[k], dl[k - 1], dr[k - 1], g[k - 1], forced[k - 1] != 0.0);
        Py_ssize_t lo = j;
        while (j < nm && ms[j].t <= t[k]) ++j;
        run_interval(e, &iv, ms + lo, j - lo, 1, 0.0, x, P, NULL);
        if (!finite_state(x, P)) failed = k - 1;
        memcpy(states + N * k, x, sizeof x);
        memcpy(covs + NN * k, P, sizeof P);
        slips[k] = iv.slip;
        scores[k] = iv.score;
    }
    for (Py_ssize_t q = 0; q < nm && failed == -1; ++q) {
        accepted[q] = ms[q].ok;
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
            Record record = {steps, 0};
            run_interval(e, &iv, ms + lo, hi - lo, 1, 0.0, fx, fP, &record);
            if (keep) { /* backwards, so this interval's rows go before the later ones' */
                write -= record.count;
                if (write >= 0)
                    memcpy((Step *)records.buf + write, steps, record.count * sizeof(Step));
            }
            for (Py_ssize_t s = record.count - 1; s >= 0; --s) smooth_step(&steps[s], x, P);
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
