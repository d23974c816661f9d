/* diffdrive's C core: the real type and the status codes every function returns.
 *
 * The real type is double unless DD_SINGLE is defined, for a microcontroller whose FPU does
 * single precision only (a Cortex-M4F, where it is chosen by itself): build every source of
 * the library and its callers with the same choice, and there add -fsingle-precision-constant
 * (GCC, Clang), or the constants in the sources stay double and cost a library call each. Times stay double in both builds: a float clock an hour in has a
 * resolution of 0.24 ms, a tenth of a 100 Hz reading's interval, so a float build would
 * misjudge speeds; a double subtraction per reading costs little on a single-precision FPU.
 */
#ifndef DIFFDRIVE_REAL_H
#define DIFFDRIVE_REAL_H

/* An ARM core whose FPU has no double precision (a Cortex-M4F: __ARM_FP without bit 3) gets
 * the float build by itself; DD_DOUBLE keeps double there (slow: a library call a step). */
#if !defined(DD_SINGLE) && !defined(DD_DOUBLE) && defined(__ARM_FP) && !(__ARM_FP & 8)
#define DD_SINGLE
#endif

#ifdef DD_SINGLE
typedef float dd_real;
#else
typedef double dd_real;
#endif

/* What a call did. Every function that can refuse its input returns one of these and, on
 * anything but DD_OK, leaves the state it was given exactly as it was. */
typedef enum {
    DD_OK = 0,
    DD_NULL = 1,            /* a required pointer is null */
    DD_NOT_FINITE = 2,      /* a reading, time or setting is NaN or infinite */
    DD_TIME_BACKWARDS = 3,  /* a reading's time is before the last one's */
    DD_TIME_STILL = 4,      /* the wheels moved while the time stood still: no velocity */
    DD_TOO_FAST = 5,        /* a wheel turned faster than the robot's max_wheel_speed: a
                               glitch, or a counter roll-over read with the wrong width */
    DD_COUNTER_RANGE = 6,   /* a tick reading does not fit the counter's width */
    DD_NO_TICKS = 7,        /* ticks given to an odometry made without rad_per_tick */
    DD_BAD_SETTING = 8,     /* a setting out of range (a radius <= 0, counter_bits > 64...) */
    DD_BAD_DT = 9,          /* a time step <= 0 where one is needed */
    DD_OVERFLOW_POSE = 10,  /* the step would make the pose or distance overflow */
    DD_OVERFLOW_COVARIANCE = 11, /* the step would make the covariance overflow */
    DD_NO_CLOCK = 12,       /* a step that needs the time since the last reading, before any */
    DD_FULL = 13,           /* the caller's buffer has no room left: give a larger one */
    DD_TOO_OLD = 14,        /* a measurement older than the history the caller's buffer holds */
    DD_TOO_EARLY = 15       /* a measurement further ahead of the wheels than allowed */
} dd_status;

/* A short English sentence for a status, for logs. */
const char *dd_status_text(dd_status status);

#endif
