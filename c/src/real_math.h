/* libm's functions for dd_real, private to the library: the float ones in a single-precision
 * build (newlib has no complex long double functions, so <tgmath.h> is not an option). */
#ifndef DIFFDRIVE_REAL_MATH_H
#define DIFFDRIVE_REAL_MATH_H

#include <math.h>

#include "diffdrive/real.h" /* which may choose DD_SINGLE */

/* Inlined even where the compiler optimises for size: small helpers on the hot path. */
#if defined(__GNUC__) || defined(__clang__)
#define DD_INLINE static inline __attribute__((always_inline))
#else
#define DD_INLINE static inline
#endif

/* DD_TINY: a positive number near the smallest normal one; DD_ROUNDING2: the square of a few
 * units of rounding, for convergence tests on squared sums; DD_SQUARE_FLOOR: a squared length
 * too small to divide by (diffdrive.control.Limiter's 1e-200; a float's smallest normal). */
#ifdef DD_SINGLE
#define DD_TINY 1e-37f
#define DD_ROUNDING2 1e-13f
#define DD_SQUARE_FLOOR DD_TINY
#define dd_fma fmaf
#define dd_sin sinf
#define dd_cos cosf
#define dd_fabs fabsf
/* newlib's hypotf guards against overflow at 700 instructions a call; a float build's steps
 * are far below 1e19 m, where a*a would overflow, and the FPU has a square root */
#define dd_hypot(a, b) sqrtf((a) * (a) + (b) * (b))
#define dd_fmax fmaxf
#define dd_fmin fminf
#define dd_sqrt sqrtf
#define dd_log logf
#define dd_remainder remainderf
#else
#define DD_TINY 1e-300
#define DD_ROUNDING2 1e-32
#define DD_SQUARE_FLOOR 1e-200
#define dd_fma fma
#define dd_sin sin
#define dd_cos cos
#define dd_fabs fabs
#define dd_hypot hypot
#define dd_fmax fmax
#define dd_fmin fmin
#define dd_sqrt sqrt
#define dd_log log
#define dd_remainder remainder
#endif

#endif
