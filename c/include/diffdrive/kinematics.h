/* diffdrive's C core: the drive's geometry and its kinematics.
 *
 * Body frame: x forward, y left, z up; angles counter-clockwise, rad. The reference point
 * lies `offset` m ahead of the midpoint of the axle. The seeds' notation: r is the wheel
 * radius (one per wheel here), d or L the half-track, so track = 2 d; phi_dot the wheel
 * angular velocities.
 */
#ifndef DIFFDRIVE_KINEMATICS_H
#define DIFFDRIVE_KINEMATICS_H

#include "diffdrive/real.h"

typedef struct {
    dd_real r_left, r_right; /* wheel radii, m, > 0 */
    dd_real track;           /* distance between the wheels' contact points, m, > 0 */
    dd_real offset;          /* the reference point ahead of the axle's midpoint, m */
} dd_drive;

/* DD_OK for finite radii and track > 0 and a finite offset, else DD_BAD_SETTING (or
 * DD_NULL). */
dd_status dd_drive_check(const dd_drive *drive);

/* Forward kinematics: wheel angular velocities (rad/s) to the body twist of the reference
 * point: vx, vy (m/s) and omega (rad/s). The same map takes wheel-angle increments (rad) to a
 * step's forward and sideways travel (m) and turn (rad). */
void dd_forward(const dd_drive *drive, dd_real left, dd_real right, dd_real *vx, dd_real *vy,
                dd_real *omega);

/* Inverse kinematics: the wheel angular velocities (rad/s) that give the forward speed v
 * (m/s) and turn rate omega (rad/s); the sideways speed follows, offset * omega. */
void dd_inverse(const dd_drive *drive, dd_real v, dd_real omega, dd_real *left, dd_real *right);

/* The turning radius (m, positive to the left) of the axle's midpoint for these wheel
 * velocities: infinite when they drive straight, 0 when it turns on the spot. */
dd_real dd_turning_radius(const dd_drive *drive, dd_real left, dd_real right);

#endif
