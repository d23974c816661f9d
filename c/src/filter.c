/* The pose estimator's filter step (see diffdrive/filter.h): the maths of
 * diffdrive/estimation/filter.py, which the Python twin runs; the tests hold the two together.
 */
#include <string.h>

#include "diffdrive/filter.h"
#include "diffdrive/odometry.h"
#include "real_math.h"
#include "step.h"

#define N DD_STATES
#define NN (DD_STATES * DD_STATES)
enum { BIAS = DD_BIAS, SCALE = DD_SCALE, DISTANCE = DD_DISTANCE, OFFSET = DD_OFFSET };
enum { WHEELS = DD_FROM_WHEELS, GYRO = DD_FROM_GYRO, FUSED = DD_FROM_BOTH };
enum { POSE = DD_POSE, POSITION = DD_POSITION, HEADING = DD_HEADING };
typedef dd_measurement Meas;
typedef dd_filter_record Step;
static const dd_real PI = 3.14159265358979323846;

/* For speed, advance_n is inlined into each of dd_filter_predict's cases, with n a constant
 * there (its loops unrolled: a third faster on the host). Built for size (-Os, as for a
 * microcontroller) it is one function, a fifth of the code. */
/* The smoother's record of a step, unless the build leaves the smoother out (DD_NO_SMOOTHER:
 * a robot does not smooth its own past on line; 2.6 KiB less on a Cortex-M4F). */
#ifdef DD_NO_SMOOTHER
#define RECORD(call) (void)record
#else
#define RECORD(call) \
    if (record) call
#endif

#if (defined(__GNUC__) || defined(__clang__)) && !defined(__OPTIMIZE_SIZE__)
#define ALWAYS_INLINE inline __attribute__((always_inline))
#define SPECIALISED 1
#else
#define ALWAYS_INLINE
#define SPECIALISED 0
#endif

static dd_real wrap(dd_real a) {
    dd_real w = dd_remainder(a, 2.0 * PI);
    return w <= -PI ? w + 2.0 * PI : w;
}

dd_real dd_filter_slip_score(const dd_filter *f, const dd_real *x, const dd_real *P, dd_real dl, dd_real dr,
                         dd_real g, dd_real gv, dd_real dt) {
    dd_real wheel_turn = (f->config.drive.r_right * dr - f->config.drive.r_left * dl) / f->config.drive.track, scale = x[SCALE];
    const dd_drive *d = &f->config.drive;
    dd_real spread = f->config.k_left * dd_fabs(d->r_left * dl) + f->config.k_right * dd_fabs(d->r_right * dr) +
                     f->config.wheel_floor * (d->r_left * d->r_left + d->r_right * d->r_right);
    dd_real innovation = scale * wheel_turn - (g - x[BIAS] * dt);
    dd_real variance = scale * scale * spread / (f->config.drive.track * f->config.drive.track) + f->config.arw2 * dt + gv +
                      dt * dt * P[BIAS * N + BIAS] + wheel_turn * wheel_turn * P[SCALE * N + SCALE] +
                      1e-18;
    return innovation * innovation / variance;
}

/* One step's move and its linearisation, as filter.advance builds them: the wheels' turn,
 * the turn, the move (dx, dy), the noises' variances (left, right wheel angle; gyro), and the
 * nonzero blocks of F - I (A: rows 0 to 2, columns 2 to 5: the heading, the bias, the turn
 * and the distance scale) and of G (rows 0 to 2). */
typedef struct {
    dd_real wheel_turn, turn, dx, dy, noise[3], A[3][4], G[3][3];
} Move;

static ALWAYS_INLINE void
move_terms(const dd_filter *f, const dd_real *x, dd_real dl, dd_real dr, dd_real g, dd_real gv, dd_real dt, int slip,
           Move *m) {
    dd_real left = f->config.drive.r_left * dl, right = f->config.drive.r_right * dr;
    dd_real travelled = 0.5 * (left + right), scale = x[SCALE], distance = x[DISTANCE];
    dd_real forward = distance * travelled;
    dd_real inflation = slip ? f->config.slip_inflation : 1.0;
    m->wheel_turn = (right - left) / f->config.drive.track;
    /* k |r dl| / r^2 = (k / r) |dl|: the radii are positive (checked in __init__); the floor
     * keeps an interval in which a counter did not move from reading as no turn, exactly */
    m->noise[0] = inflation * (f->k_per_r_left * dd_fabs(dl) + f->config.wheel_floor);
    m->noise[1] = inflation * (f->k_per_r_right * dd_fabs(dr) + f->config.wheel_floor);
    m->noise[2] = f->config.heading != WHEELS ? f->config.arw2 * dt + gv : 0.0;
    dd_real bnf[3] = {0.5 * distance * f->config.drive.r_left, 0.5 * distance * f->config.drive.r_right, 0.0}, bnt[3],
           bst[N] = {0};
    if (f->config.heading == WHEELS) {
        m->turn = scale * m->wheel_turn;
        bnt[0] = -scale * f->config.drive.r_left / f->config.drive.track;
        bnt[1] = scale * f->config.drive.r_right / f->config.drive.track;
        bnt[2] = 0.0;
        bst[SCALE] = m->wheel_turn;
    } else {
        m->turn = g - x[BIAS] * dt;
        bnt[0] = bnt[1] = 0.0;
        bnt[2] = 1.0;
        bst[BIAS] = -dt;
    }
    dd_real bf[2], bt[2];
    dd_move_jacobians(forward, f->config.drive.offset, m->turn, f->weight, f->chord, x[2], &m->dx, &m->dy, bf,
                      bt);
    const dd_real columns[3][4] = {
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

#ifndef DD_NO_SMOOTHER
static void solve_right(const dd_filter *f, const dd_real *cross, const dd_real *cov,
                        dd_real *gain);

/* The smoother's record of a step from x, P (filter.advance's joint of the state after, the
 * state before and the noises), from what advance_n computed on its way: the state after it
 * (after) with its covariance (moved) and its cross-covariance with the state before (FP =
 * F P); with a fused heading, the wheels' turn measured in that joint: the covariances of the
 * state after and before with the innovation (spread, before), 1 / its variance (inverse)
 * and the innovation. spread NULL: nothing measured. The states past n keep their values,
 * with zero covariances and gain. */
static void record_of(const dd_filter *f, Step *r, const dd_real *x, const dd_real *P,
                      const dd_real *after, const dd_real *moved, const dd_real *FP,
                      const dd_real *spread, const dd_real *before, dd_real inverse,
                      dd_real innovation, int n) {
    dd_real cross[NN], gains[N] = {0}, back[N] = {0};
    memset(r, 0, sizeof *r);
    memset(cross, 0, sizeof cross);
    for (int i = 0; i < N; ++i) {
        if (spread != 0 && i < n) {
            gains[i] = spread[i] * inverse;
            back[i] = before[i] * inverse;
        }
        r->before[i] = x[i] + back[i] * innovation;
        r->after[i] = after[i] + gains[i] * innovation;
    }
    /* each covariance's upper triangle, mirrored: exactly symmetric, as the filter's P */
    for (int i = 0; i < n; ++i)
        for (int j = i; j < n; ++j) {
            r->before_cov[i * N + j] = r->before_cov[j * N + i] =
                P[i * N + j] - back[i] * (spread ? before[j] : 0.0);
            r->after_cov[i * N + j] = r->after_cov[j * N + i] =
                moved[i * N + j] - gains[i] * (spread ? spread[j] : 0.0);
        }
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j)
            cross[i * N + j] = FP[j * N + i] - back[i] * (spread ? spread[j] : 0.0);
    solve_right(f, cross, r->after_cov, r->gain);
}

#endif

/* filter.advance in place on x and P, for the first n states (3: the pose; 4: and the bias;
 * 5: and the turn scale; 6: and the distance scale; 8: and the fixes' offset), and, unless
 * record is NULL, the smoother's record of the step. The states that are not estimated have
 * zero rows and columns in P and keep them, untouched. Always inlined into dd_filter_predict
 * with n a constant, so every loop has fixed bounds the compiler unrolls. */
static ALWAYS_INLINE void advance_n(const dd_filter *f, dd_real *x, dd_real *P, dd_real dl,
                                    dd_real dr, dd_real g, dd_real gv, dd_real dt, int slip,
                                    Step *record, const int n) {
    Move mv;
    move_terms(f, x, dl, dr, g, gv, dt, slip, &mv);
    const dd_real wheel_turn = mv.wheel_turn, turn = mv.turn, dx = mv.dx, dy = mv.dy;
    const dd_real *noise = mv.noise, scale = x[SCALE];
    /* A = F - I is zero but for columns 2 to 5 of rows 0 to 2, and G is zero below row 2:
     * FP = P + A P and moved = FP F^T + G Q G^T over those entries only (a column of A past n
     * meets a zero row of P: it adds an exact zero). */
    dd_real (*A)[4] = mv.A, (*G)[3] = mv.G, GQ[3][3];
    for (int i = 0; i < 3; ++i)
        for (int k = 0; k < 3; ++k) GQ[i][k] = G[i][k] * noise[k];
    dd_real after[N];
    memcpy(after, x, sizeof after);
    after[0] += dx;
    after[1] += dy;
    after[2] += turn;
    dd_real FP[NN], moved[NN];
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
            dd_real sum = FP[i * N + j];
            if (j < 3) {
                sum += FP[i * N + 2] * A[j][0] + FP[i * N + 3] * A[j][1] +
                       FP[i * N + 4] * A[j][2] + FP[i * N + 5] * A[j][3];
                if (i < 3) sum += GQ[i][0] * G[j][0] + GQ[i][1] * G[j][1] + GQ[i][2] * G[j][2];
            }
            moved[i * N + j] = moved[j * N + i] = sum;
        }
    if (f->config.estimate_bias && f->config.heading == FUSED) moved[BIAS * N + BIAS] += f->config.rrw2 * dt;
    if (n > OFFSET && f->config.estimate_offset) {
        moved[OFFSET * N + OFFSET] += f->config.offset_rate2 * dt;
        moved[(OFFSET + 1) * N + OFFSET + 1] += f->config.offset_rate2 * dt;
    }
    if (!(f->config.heading == FUSED && !slip)) {
        RECORD(record_of(f, record, x, P, after, moved, FP, 0, 0, 0.0, 0.0, n));
        memcpy(x, after, sizeof after);
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j) P[i * N + j] = moved[i * N + j];
        return;
    }
    /* The wheels measure the turn over the scale, less their own noise. On the joint of
     * (state after, state before, noises), [[moved, FP, GQ], [FP^T, P, 0], [GQ^T, 0, Q]], with
     * H = (h_after, h_before, h_noise): its spread along H, block by block. h_after is zero
     * but at the heading and the scale, h_before but at the heading. */
    const dd_real h2 = 1.0 / scale, h4 = f->config.estimate_scale ? -turn / (scale * scale) : 0.0;
    const dd_real hn[3] = {f->config.drive.r_left / f->config.drive.track, -f->config.drive.r_right / f->config.drive.track, 0.0};
    dd_real spread[N] = {0}, before[N] = {0}, s = 0.0;
    for (int i = 0; i < n; ++i) {
        dd_real sum = moved[i * N + 2] * h2 - FP[i * N + 2] * h2;
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
    dd_real innovation = wheel_turn - turn * h2, inverse = 1.0 / s, gains[N];
    RECORD(record_of(f, record, x, P, after, moved, FP, spread, before, inverse, innovation, n));
    for (int i = 0; i < N; ++i) {
        gains[i] = spread[i] * inverse;
        x[i] = after[i] + gains[i] * innovation;
    }
    for (int i = 0; i < n; ++i)
        for (int j = i; j < n; ++j)
            P[i * N + j] = P[j * N + i] = moved[i * N + j] - gains[i] * spread[j];
}


void dd_filter_predict(const dd_filter *f, dd_real *x, dd_real *P, dd_real dl, dd_real dr,
                       dd_real g, dd_real gv, dd_real dt, int slip, dd_filter_record *record) {
    if (!SPECIALISED) {
        advance_n(f, x, P, dl, dr, g, gv, dt, slip, record, f->carried);
        return;
    }
    switch (f->carried) { /* each with its own constant n */
    case 8: advance_n(f, x, P, dl, dr, g, gv, dt, slip, record, 8); break;
    case 6: advance_n(f, x, P, dl, dr, g, gv, dt, slip, record, 6); break;
    case 5: advance_n(f, x, P, dl, dr, g, gv, dt, slip, record, 5); break;
    case 4: advance_n(f, x, P, dl, dr, g, gv, dt, slip, record, 4); break;
    default: advance_n(f, x, P, dl, dr, g, gv, dt, slip, record, 3);
    }
}

#ifndef DD_NO_SMOOTHER
/* The eigenvalues w and eigenvectors V (columns, row-major) of a symmetric m x m matrix A
 * (m <= N), by cyclic Jacobi rotations: to rounding, as numpy.linalg.eigh. */
static void symmetric_eigen(const dd_real *A, int m, dd_real *w, dd_real *V) {
    dd_real a[NN];
    memcpy(a, A, sizeof(dd_real) * m * m);
    for (int i = 0; i < m; ++i)
        for (int j = 0; j < m; ++j) V[i * m + j] = i == j ? 1.0 : 0.0;
    for (int sweep = 0; sweep < 60; ++sweep) {
        dd_real off = 0.0, scale = 0.0;
        for (int i = 0; i < m; ++i)
            for (int j = 0; j < m; ++j) {
                if (i != j) off += a[i * m + j] * a[i * m + j];
                scale += a[i * m + j] * a[i * m + j];
            }
        if (off <= DD_TINY || off <= DD_ROUNDING2 * scale) break;
        for (int p = 0; p < m - 1; ++p)
            for (int q = p + 1; q < m; ++q) {
                dd_real apq = a[p * m + q];
                if (apq == 0.0) continue;
                dd_real theta = 0.5 * (a[q * m + q] - a[p * m + p]) / apq;
                dd_real t = (theta >= 0.0 ? 1.0 : -1.0) / (dd_fabs(theta) + dd_sqrt(theta * theta + 1.0));
                dd_real c = 1.0 / dd_sqrt(t * t + 1.0), s = t * c;
                for (int k = 0; k < m; ++k) { /* columns p and q of a */
                    dd_real akp = a[k * m + p], akq = a[k * m + q];
                    a[k * m + p] = c * akp - s * akq;
                    a[k * m + q] = s * akp + c * akq;
                }
                for (int k = 0; k < m; ++k) { /* rows p and q */
                    dd_real apk = a[p * m + k], aqk = a[q * m + k];
                    a[p * m + k] = c * apk - s * aqk;
                    a[q * m + k] = s * apk + c * aqk;
                }
                for (int k = 0; k < m; ++k) {
                    dd_real vkp = V[k * m + p], vkq = V[k * m + q];
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
static int well_conditioned_inverse(const dd_real *A, int m, dd_real *inverse) {
    dd_real L[NN] = {0};
    for (int i = 0; i < m; ++i)
        for (int j = 0; j <= i; ++j) {
            dd_real sum = A[i * m + j];
            for (int q = 0; q < j; ++q) sum -= L[i * m + q] * L[j * m + q];
            if (i == j) {
                if (!(sum > 0.0)) return 0;
                L[i * m + i] = dd_sqrt(sum);
            } else {
                L[i * m + j] = sum / L[j * m + j];
            }
        }
    dd_real Li[NN] = {0}; /* L^-1, lower */
    for (int i = 0; i < m; ++i) {
        Li[i * m + i] = 1.0 / L[i * m + i];
        for (int j = 0; j < i; ++j) {
            dd_real sum = 0.0;
            for (int q = j; q < i; ++q) sum += L[i * m + q] * Li[q * m + j];
            Li[i * m + j] = -sum / L[i * m + i];
        }
    }
    dd_real trace = 0.0;
    for (int i = 0; i < m; ++i)
        for (int j = i; j < m; ++j) {
            dd_real sum = 0.0; /* (L^-T L^-1)_ij over the rows below both */
            for (int q = j; q < m; ++q) sum += Li[q * m + i] * Li[q * m + j];
            inverse[i * m + j] = inverse[j * m + i] = sum;
            if (i == j) trace += sum;
        }
    return isfinite(trace) && 1.0 / trace > 1e-9 * m;
}

/* filter._solve_right: cross @ pinv(covariance) over the estimated states, the covariance
 * scaled to unit variances first (pinv as numpy's, hermitian, rcond 1e-12). */
static void solve_right(const dd_filter *f, const dd_real *cross, const dd_real *cov, dd_real *gain) {
    int active[N], m = 0;
    active[m++] = 0;
    active[m++] = 1;
    active[m++] = 2;
    if (f->config.estimate_bias && f->config.heading == FUSED) active[m++] = BIAS;
    if (f->config.estimate_scale) active[m++] = SCALE;
    if (f->config.estimate_distance) active[m++] = DISTANCE;
    if (f->config.estimate_offset) {
        active[m++] = OFFSET;
        active[m++] = OFFSET + 1;
    }
    dd_real block[NN], sigma[N], w[N], V[NN], inverse[NN];
    for (int i = 0; i < m; ++i) {
        dd_real d = cov[active[i] * N + active[i]];
        sigma[i] = d > 0.0 ? dd_sqrt(d) : 0.0;
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
        dd_real largest = 0.0;
        for (int i = 0; i < m; ++i) largest = dd_fmax(largest, dd_fabs(w[i]));
        for (int i = 0; i < m; ++i)
            for (int j = 0; j < m; ++j) {
                dd_real sum = 0.0;
                for (int q = 0; q < m; ++q)
                    if (dd_fabs(w[q]) > 1e-12 * largest) sum += V[i * m + q] * V[j * m + q] / w[q];
                inverse[i * m + j] = sum / (sigma[i] * sigma[j]);
            }
    }
    memset(gain, 0, sizeof(dd_real) * NN);
    for (int i = 0; i < m; ++i)
        for (int j = 0; j < m; ++j) {
            dd_real sum = 0.0;
            for (int q = 0; q < m; ++q) sum += cross[active[i] * N + active[q]] * inverse[q * m + j];
            gain[active[i] * N + active[j]] = sum;
        }
}


#endif

dd_status dd_cholesky(const dd_real *A, int k, dd_real *L) {
    memset(L, 0, sizeof(dd_real) * k * k);
    for (int i = 0; i < k; ++i)
        for (int j = 0; j <= i; ++j) {
            dd_real sum = A[i * k + j];
            for (int m = 0; m < j; ++m) sum -= L[i * k + m] * L[j * k + m];
            if (i == j) {
                if (!(sum > 0.0)) return DD_BAD_SETTING;
                L[i * k + i] = dd_sqrt(sum);
            } else {
                L[i * k + j] = sum / L[j * k + j];
            }
        }
    return DD_OK;
}

/* Solve L L^T y = b in place (b of k values). */
static void cholesky_solve(const dd_real *L, int k, dd_real *b) {
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
static void absolute_update(const dd_filter *f, dd_real *x, dd_real *P, const Meas *m, int *ok,
                            dd_real *score, dd_real *log_det) {
    /* the states past f->carried have zero rows and columns in P: left out */
    const int k = m->size, n = f->carried;
    dd_real H[3 * N] = {0}, innovation[3];
    if (m->kind == HEADING) {
        H[2] = 1.0;
        innovation[0] = wrap(m->value[0] - x[2]);
    } else {
        dd_real ax = m->lever[0], ay = m->lever[1] - f->config.reference_offset, c = dd_cos(x[2]), s = dd_sin(x[2]);
        H[0 * N + 0] = H[1 * N + 1] = 1.0;
        H[0 * N + 2] = -s * ax - c * ay;
        H[1 * N + 2] = c * ax - s * ay;
        innovation[0] = m->value[0] - (x[0] + c * ax - s * ay);
        innovation[1] = m->value[1] - (x[1] + s * ax + c * ay);
        if (f->config.estimate_offset && m->kind == POSITION) { /* the fix carries the offset */
            H[0 * N + OFFSET] = H[1 * N + OFFSET + 1] = 1.0;
            innovation[0] -= x[OFFSET];
            innovation[1] -= x[OFFSET + 1];
        }
        if (k == 3) {
            H[2 * N + 2] = 1.0;
            innovation[2] = wrap(m->value[2] - x[2]);
        }
    }
    dd_real HP[3 * N], S[9] = {0}, L[9];
    for (int i = 0; i < k; ++i)
        for (int j = 0; j < n; ++j) {
            dd_real sum = 0.0;
            for (int q = 0; q < n; ++q) sum += H[i * N + q] * P[q * N + j];
            HP[i * N + j] = sum;
        }
    for (int i = 0; i < k; ++i)
        for (int j = 0; j < k; ++j) {
            dd_real sum = 0.0;
            for (int q = 0; q < n; ++q) sum += HP[i * N + q] * H[j * N + q];
            S[i * k + j] = sum + m->cov[i * k + j];
        }
    *ok = 0;
    if (dd_cholesky(S, k, L) != DD_OK) {
        *score = INFINITY;
        if (log_det != NULL) *log_det = NAN;
        return;
    }
    if (log_det != NULL) {
        *log_det = 0.0;
        for (int i = 0; i < k; ++i) *log_det += 2.0 * dd_log(L[i * k + i]);
    }
    dd_real white[3];
    for (int i = 0; i < k; ++i) {
        dd_real sum = innovation[i];
        for (int q = 0; q < i; ++q) sum -= L[i * k + q] * white[q];
        white[i] = sum / L[i * k + i];
    }
    dd_real d2 = 0.0;
    for (int i = 0; i < k; ++i) d2 += white[i] * white[i];
    *score = d2;
    /* past the gate: refused, or (inflate) taken with its covariance R grown to R + (a - 1) S,
     * which makes S a S with a = d2 / gate: its score then lies on the gate */
    dd_real grow = 1.0, R[9];
    if (d2 > f->config.gates[k - 1]) {
        if (!f->config.inflate) return;
        grow = d2 / f->config.gates[k - 1];
    }
    for (int i = 0; i < k * k; ++i) R[i] = m->cov[i] + (grow - 1.0) * S[i];
    /* gain = (S^-1 H P)^T / a, N x k */
    dd_real gain[N * 3];
    for (int j = 0; j < n; ++j) {
        dd_real column[3];
        for (int i = 0; i < k; ++i) column[i] = HP[i * N + j];
        cholesky_solve(L, k, column);
        for (int i = 0; i < k; ++i) gain[j * 3 + i] = column[i] / grow;
    }
    dd_real keep[NN], KP[NN], out[NN];
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            dd_real sum = i == j ? 1.0 : 0.0;
            for (int q = 0; q < k; ++q) sum -= gain[i * 3 + q] * H[q * N + j];
            keep[i * N + j] = sum;
        }
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            dd_real sum = 0.0;
            for (int q = 0; q < n; ++q) sum += keep[i * N + q] * P[q * N + j];
            KP[i * N + j] = sum;
        }
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            dd_real sum = 0.0;
            for (int q = 0; q < n; ++q) sum += KP[i * N + q] * keep[j * N + q];
            dd_real noisy = 0.0;
            for (int a = 0; a < k; ++a)
                for (int b = 0; b < k; ++b)
                    noisy += gain[i * 3 + a] * R[a * k + b] * gain[j * 3 + b];
            out[i * N + j] = sum + noisy;
        }
    for (int i = 0; i < n; ++i) {
        dd_real sum = 0.0;
        for (int q = 0; q < k; ++q) sum += gain[i * 3 + q] * innovation[q];
        x[i] += sum;
    }
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) P[i * N + j] = 0.5 * (out[i * N + j] + out[j * N + i]);
    *ok = 1;
}


int dd_filter_finite(const dd_real *x, const dd_real *P) {
    for (int i = 0; i < N; ++i)
        if (!isfinite(x[i])) return 0;
    for (int i = 0; i < NN; ++i)
        if (!isfinite(P[i])) return 0;
    return 1;
}


void dd_filter_interval(const dd_filter *f, dd_interval *iv, dd_measurement *m, long count,
                        int record_outcomes, double stop, dd_real *x, dd_real *P,
                        dd_filter_record *steps, long *nsteps) {
    double duration = iv->t1 - iv->t0;
    if (record_outcomes) {
        if (isnan(iv->g)) {
            iv->slip = iv->forced;
            iv->score = 0.0;
        } else {
            iv->score = dd_filter_slip_score(f, x, P, iv->dl, iv->dr, iv->g, iv->gv, (dd_real)duration);
            iv->slip = iv->score > f->config.slip_threshold || iv->forced;
        }
    }
    double end = record_outcomes ? iv->t1 : stop, t = iv->t0;
    dd_real done = 0.0;
    long j = 0;
    if (nsteps) *nsteps = 0;
    for (;;) {
        double cut = (j < count && m[j].t <= end) ? m[j].t : end;
        /* at the end, the share is 1 (what the division gives there too, exactly) */
        dd_real share = cut == iv->t1 || !(duration > 0) ? 1.0 : (dd_real)((cut - iv->t0) / duration);
        dd_real part = share - done;
        if (cut > t)
            dd_filter_predict(f, x, P, part * iv->dl, part * iv->dr, part * iv->g, part * iv->gv,
                              (dd_real)(cut - t), iv->slip, steps ? &steps[(*nsteps)++] : 0);
        done = share;
        t = cut;
        for (; j < count && m[j].t <= cut; ++j) {
            if (record_outcomes) {
                dd_filter_correct(f, x, P, &m[j]);
            } else { /* the measurement's outcome as it was */
                int accepted;
                dd_real score, log_det;
                absolute_update(f, x, P, &m[j], &accepted, &score, &log_det);
            }
        }
        if (cut >= end) break;
    }
}

void dd_interval_set(dd_interval *iv, double t0, double t1, dd_real dl, dd_real dr, dd_real g,
                     dd_real gv, int forced) {
    iv->t0 = t0, iv->t1 = t1, iv->dl = dl, iv->dr = dr, iv->g = g, iv->gv = gv;
    iv->forced = forced, iv->slip = 0, iv->score = 0.0;
}

void dd_filter_correct(const dd_filter *f, dd_real *x, dd_real *P, dd_measurement *m) {
    absolute_update(f, x, P, m, &m->accepted, &m->score, &m->log_det);
}



#ifndef DD_NO_SMOOTHER
void dd_filter_smooth(const dd_filter_record *s, dd_real *x, dd_real *P) {
    dd_real dx[N], G[NN], GD[NN];
    for (int i = 0; i < N; ++i) dx[i] = x[i] - s->after[i];
    for (int i = 0; i < N; ++i) {
        dd_real sum = s->before[i];
        for (int q = 0; q < N; ++q) sum += s->gain[i * N + q] * dx[q];
        x[i] = sum;
    }
    for (int i = 0; i < NN; ++i) G[i] = P[i] - s->after_cov[i];
    for (int i = 0; i < N; ++i)
        for (int j = 0; j < N; ++j) {
            dd_real sum = 0.0;
            for (int q = 0; q < N; ++q) sum += s->gain[i * N + q] * G[q * N + j];
            GD[i * N + j] = sum;
        }
    for (int i = 0; i < N; ++i)
        for (int j = i; j < N; ++j) {
            dd_real a = 0.0, b = 0.0;
            for (int q = 0; q < N; ++q) {
                a += GD[i * N + q] * s->gain[j * N + q];
                b += GD[j * N + q] * s->gain[i * N + q];
            }
            P[i * N + j] = P[j * N + i] =
                0.5 * ((s->before_cov[i * N + j] + a) + (s->before_cov[j * N + i] + b));
        }
}
#endif


dd_status dd_filter_init(dd_filter *f, const dd_filter_config *config) {
    if (f == 0 || config == 0) return DD_NULL;
    const dd_filter_config *c = config;
    if (dd_drive_check(&c->drive) != DD_OK || c->method < DD_EULER || c->method > DD_EXACT ||
        c->heading < WHEELS || c->heading > FUSED || !(c->k_left >= 0.0) ||
        !(c->k_right >= 0.0) || !(c->wheel_floor >= 0.0) || !(c->arw2 >= 0.0) || !(c->rrw2 >= 0.0) ||
        !(c->offset_rate2 >= 0.0) || !(c->slip_threshold > 0.0) || !(c->slip_inflation >= 1.0) ||
        !(c->gates[0] > 0.0) || !(c->gates[1] > 0.0) || !(c->gates[2] > 0.0) ||
        !isfinite(c->reference_offset))
        return DD_BAD_SETTING;
    f->config = *config;
    f->k_per_r_left = c->k_left / c->drive.r_left;
    f->k_per_r_right = c->k_right / c->drive.r_right;
    f->weight = c->method == DD_EULER ? 0.0 : 0.5;
    f->chord = c->method == DD_EXACT;
    f->carried = c->estimate_offset     ? 8
                 : c->estimate_distance ? 6
                 : c->estimate_scale    ? 5
                 : c->estimate_bias     ? 4
                                        : 3;
    return DD_OK;
}
