"""What an odometry core is built from: one value, read by name by the C core and its twin."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["OdometrySettings"]


@dataclass(frozen=True)
class OdometrySettings:
    """Everything an odometry core is built from, the C core and this twin alike: the
    equivalent drive ``(r_left, r_right, track, axle_offset)`` (m), the method's index in
    ``METHODS``, ``rad_per_tick`` (0 when the counts per revolution are not known),
    ``max_wheel_speed`` (rad/s; inf for no limit), ``counter_bits`` (0: counters that never
    roll over), the wheel noise ``k`` ``(left, right)`` (m) and ``velocity_window`` (s)."""

    drive: tuple[float, float, float, float]
    method_code: int
    rad_per_tick: float
    max_wheel_speed: float
    counter_bits: int
    k: tuple[float, float]
    velocity_window: float
