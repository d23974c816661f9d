"""The body twist a robot had over each interval of a log, and its covariance from the noise
model: what a ``nav_msgs/Odometry`` message's twist and twist covariance carry.

An interval's twist is its motion over its duration ``dt``: the forward travel of the
equivalent drive's wheels ``f = (r_l dl + r_r dr) / 2`` and the turn of the heading source,
either the wheels' ``w = (r_r dr - r_l dl) / track`` times the turn scale (heading
``"wheels"``) or a turn given from elsewhere (the gyro's less its bias, ``"gyro"`` and
``"fused"``). At the equivalent drive's reference point that is ``(f, axle_offset turn,
turn) / dt``; at the body origin, ``reference_offset`` to the right of it, ``vx`` gains
``reference_offset * omega`` (``SkidSteer.to_twist``'s rigid shift).

Covariance, from the same noise model the estimators propagate: each wheel's travel ``s`` in
the interval has variance ``k |s|`` (plus the filter's ``wheel_floor`` times ``r^2``, and
times a slipping interval's inflation), so ``var f =
(k_l |s_l| + k_r |s_r|) / 4``, ``var w = (k_l |s_l| + k_r |s_r|) / track^2`` and ``cov(f, w)
= (k_r |s_r| - k_l |s_l|) / (2 track)``; a turn scale adds ``w^2 var(scale)``; a turn given
from elsewhere comes with its own variance and no covariance with the wheels (another sensor).
Row ``k`` of the result is the interval that ends at row ``k``; row 0, which ends none, takes
the first interval's (the velocity the log starts with).
"""

from __future__ import annotations

import numpy as np

from diffdrive.model import Robot, geometry_of
from diffdrive.sensor_noise import WheelNoise, WheelNoiseLike

__all__ = ["TWIST_AXES", "interval_twists"]

TWIST_AXES = ("vx", "vy", "omega")


def interval_twists(
    robot: Robot,
    times: object,
    increments: object,
    wheel_noise: WheelNoiseLike,
    *,
    turns: object = None,
    turn_variances: object = None,
    turn_scale: object = None,
    turn_scale_variances: object = None,
    noise_scale: object = None,
    wheel_floor: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """The body twist ``(N, 3)`` ``[vx, vy, omega]`` (m/s, m/s, rad/s) over the intervals of
    wheel-angle ``increments`` ``(N-1, 2)`` rad between ``times`` ``(N,)`` s, and its
    covariance ``(N, 3, 3)`` (see the module).

    ``turns`` ``(N-1,)`` rad: the heading source's turn over each interval, with
    ``turn_variances`` (rad^2); None: the wheels' turn, times ``turn_scale`` (default 1) of
    variance ``turn_scale_variances`` (default 0). ``noise_scale`` ``(N-1,)``: a factor on
    each interval's wheel noise (default 1; a slipping interval's inflation);
    ``wheel_floor`` (rad^2): each wheel angle increment's least variance, as the filter's."""
    times = np.asarray(times, dtype=float)
    increments = np.asarray(increments, dtype=float)
    if times.ndim != 1 or len(times) < 2 or increments.shape != (len(times) - 1, 2):
        raise ValueError(
            f"times (N,) with N >= 2 and increments (N-1, 2) must match, got {times.shape} "
            f"and {increments.shape}"
        )
    count = len(times) - 1
    dt = np.diff(times)
    r_l, r_r, track, sideways = geometry_of(robot)
    left, right = r_l * increments[:, 0], r_r * increments[:, 1]
    forward, wheel_turn = 0.5 * (left + right), (right - left) / track
    inflation = _per_interval(noise_scale, 1.0, count, "noise_scale")
    noise = WheelNoise.coerce(wheel_noise)
    var_left = inflation * (noise.left * np.abs(left) + wheel_floor * r_l * r_l)
    var_right = inflation * (noise.right * np.abs(right) + wheel_floor * r_r * r_r)
    var_forward = 0.25 * (var_left + var_right)
    if turns is None:
        scale = _per_interval(turn_scale, 1.0, count, "turn_scale")
        scale_var = _per_interval(turn_scale_variances, 0.0, count, "turn_scale_variances")
        turn = scale * wheel_turn
        # as a square of the product: no 0 * inf where the scale is known and the turn huge
        with np.errstate(over="ignore"):
            by_scale = (wheel_turn * np.sqrt(scale_var)) ** 2
        var_turn = scale * scale * (var_left + var_right) / track**2 + by_scale
        cov_forward_turn = scale * 0.5 * (var_right - var_left) / track
    else:
        turn = _per_interval(turns, 0.0, count, "turns")
        var_turn = _per_interval(turn_variances, 0.0, count, "turn_variances")
        cov_forward_turn = np.zeros(count)
    # (forward, turn) -> (vx, vy, omega) at the body origin: linear, M / dt.
    shift = robot.reference_offset
    mixing = np.array([[1.0, shift], [0.0, sideways], [0.0, 1.0]])
    moves = np.column_stack([forward, turn])
    twists = moves @ mixing.T / dt[:, None]
    # mixing @ [[var f, cov], [cov, var w]] @ mixing.T, term by term (over dt^2)
    along_f, along_w = mixing[:, 0], mixing[:, 1]
    per_dt2 = 1.0 / (dt * dt)
    covariances = (
        (var_forward * per_dt2)[:, None, None] * np.outer(along_f, along_f)
        + (cov_forward_turn * per_dt2)[:, None, None]
        * (np.outer(along_f, along_w) + np.outer(along_w, along_f))
        + (var_turn * per_dt2)[:, None, None] * np.outer(along_w, along_w)
    )
    return np.concatenate([twists[:1], twists]), np.concatenate([covariances[:1], covariances])


def _per_interval(values: object, default: float, count: int, name: str) -> np.ndarray:
    """``values`` as ``(count,)`` floats (one value broadcasts), or ``default`` for None."""
    if values is None:
        return np.full(count, default)
    array = np.asarray(values, dtype=float)
    if array.shape not in ((), (count,)):
        raise ValueError(
            f"{name} must be one value or one per interval ({count},), got {array.shape}"
        )
    array = np.broadcast_to(array, (count,))
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be finite")
    return array
