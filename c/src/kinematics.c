/* The drive's kinematics (seeds 001 to 003) and the status texts. */
#include "real_math.h"

#include "diffdrive/kinematics.h"

const char *dd_status_text(dd_status status) {
    switch (status) {
    case DD_OK: return "ok";
    case DD_NULL: return "a required pointer is null";
    case DD_NOT_FINITE: return "a reading, time or setting is not finite";
    case DD_TIME_BACKWARDS: return "time went backwards";
    case DD_TIME_STILL: return "the wheels moved while the time stood still";
    case DD_TOO_FAST: return "a wheel turned faster than max_wheel_speed: a glitch, or a "
                             "counter roll-over read with the wrong counter_bits";
    case DD_COUNTER_RANGE: return "a tick reading does not fit the counter's width";
    case DD_NO_TICKS: return "ticks given to an odometry made without rad_per_tick";
    case DD_BAD_SETTING: return "a setting is out of range";
    case DD_BAD_DT: return "a time step must be > 0";
    case DD_OVERFLOW_POSE: return "the step would make the pose or distance overflow";
    case DD_OVERFLOW_COVARIANCE: return "the step would make the covariance overflow";
    case DD_NO_CLOCK: return "no reading has started the clock yet";
    case DD_FULL: return "the caller's buffer is full";
    case DD_TOO_OLD: return "a measurement older than the history";
    case DD_TOO_EARLY: return "a measurement too far ahead of the wheels";
    }
    return "unknown status";
}

dd_status dd_drive_check(const dd_drive *drive) {
    if (drive == 0) return DD_NULL;
    if (!(drive->r_left > 0.0 && drive->r_right > 0.0 && drive->track > 0.0) ||
        !isfinite(drive->r_left) || !isfinite(drive->r_right) || !isfinite(drive->track) ||
        !isfinite(drive->offset))
        return DD_BAD_SETTING;
    return DD_OK;
}

void dd_forward(const dd_drive *drive, dd_real left, dd_real right, dd_real *vx, dd_real *vy,
                dd_real *omega) {
    dd_real l = drive->r_left * left, r = drive->r_right * right;
    *omega = (r - l) / drive->track;
    *vx = 0.5 * (l + r);
    *vy = drive->offset * *omega;
}

void dd_inverse(const dd_drive *drive, dd_real v, dd_real omega, dd_real *left, dd_real *right) {
    dd_real half = 0.5 * drive->track;
    *left = (v - half * omega) / drive->r_left;
    *right = (v + half * omega) / drive->r_right;
}

dd_real dd_turning_radius(const dd_drive *drive, dd_real left, dd_real right) {
    dd_real vx, vy, omega;
    dd_forward(drive, left, right, &vx, &vy, &omega);
    return vx / omega; /* +-inf straight, 0 on the spot, NaN standing still */
}
