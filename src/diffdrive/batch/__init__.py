"""The batch layer: the scalar operations over arrays, components on the last axis.

``diffdrive.batch.exp`` is to ``diffdrive.se2.exp`` what a NumPy ufunc is to ``math``:
the same formula, leading axes broadcast, the input's floating dtype kept.
"""

from diffdrive.batch.integrate import delta, step
from diffdrive.batch.integration import accumulate, rollout, twists
from diffdrive.batch.kinematics import (
    advance_wheel_positions,
    instantaneous_center,
    to_twist,
    to_wheel_velocities,
    turning_radius,
    wheel_velocities_from_positions,
)
from diffdrive.batch.se2 import (
    compose,
    exp,
    from_matrix,
    inverse,
    log,
    pose_derivative,
    relative_jacobians,
    relative_to,
    rotation_matrix,
    sinc,
    to_matrix,
    transform_points,
    wrap_angle,
)

__all__ = [
    "accumulate",
    "advance_wheel_positions",
    "compose",
    "delta",
    "exp",
    "from_matrix",
    "instantaneous_center",
    "inverse",
    "log",
    "pose_derivative",
    "relative_jacobians",
    "relative_to",
    "rollout",
    "rotation_matrix",
    "sinc",
    "step",
    "to_matrix",
    "to_twist",
    "to_wheel_velocities",
    "transform_points",
    "turning_radius",
    "twists",
    "wheel_velocities_from_positions",
    "wrap_angle",
]
