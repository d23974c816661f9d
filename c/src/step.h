/* The step's maths, shared by odometry.c and filter.c (private to the library): the same
 * operations, in the same order, as diffdrive/_step.py, which the Python twins use. */
#ifndef DIFFDRIVE_STEP_H
#define DIFFDRIVE_STEP_H

#include "real_math.h"

#include "diffdrive/real.h"

/* dd_sin(u)/u: its Taylor form to u^8 below 1/16 (where dd_sin(u)/u loses digits), libm above. */
static inline dd_real dd_sinc(dd_real u) {
    if (dd_fabs(u) >= 1.0 / 16.0) return dd_sin(u) / u;
    dd_real u2 = u * u;
    return 1.0 - u2 * (1.0 / 6) *
                     (1.0 - u2 * (1.0 / 20) * (1.0 - u2 * (1.0 / 42) * (1.0 - u2 * (1.0 / 72))));
}

/* d/du of dd_sin(u)/u: (u cos u - sin u)/u^2, with its Taylor form near 0 where that cancels. */
static inline dd_real dd_sinc_derivative(dd_real u) {
    if (dd_fabs(u) < 0.05) {
        dd_real u2 = u * u;
        return -u / 3.0 * (1.0 - u2 / 10.0 * (1.0 - u2 / 28.0 * (1.0 - u2 / 54.0)));
    }
    return (u * dd_cos(u) - dd_sin(u)) / (u * u);
}

/* The world move (dx, dy) of a step that goes `forward` and turns `turn` (the reference point
 * `offset` ahead of the axle moves sideways by offset * turn), from `heading`: its direction
 * at heading + weight * turn (0: Euler, 1/2: the mid-step heading), its length times
 * sinc(turn / 2) if `chord` (the exact arc). bf and bt: its derivatives in forward and turn. */
static inline void dd_move_jacobians(dd_real forward, dd_real offset, dd_real turn, dd_real weight,
                                     int chord, dd_real heading, dd_real *dx, dd_real *dy,
                                     dd_real bf[2], dd_real bt[2]) {
    dd_real angle = heading + weight * turn, ca = dd_cos(angle), sa = dd_sin(angle);
    dd_real sideways = offset * turn;
    dd_real gx = ca * forward - sa * sideways, gy = sa * forward + ca * sideways;
    dd_real scale = 1.0, slope = 0.0;
    if (chord) {
        scale = dd_sinc(0.5 * turn);
        slope = 0.5 * dd_sinc_derivative(0.5 * turn);
    }
    bt[0] = slope * gx + scale * (-sa * offset - gy * weight);
    bt[1] = slope * gy + scale * (ca * offset + gx * weight);
    *dx = scale * gx;
    *dy = scale * gy;
    bf[0] = scale * ca;
    bf[1] = scale * sa;
}

#endif
