"""An ``MPPI``'s settings as Nav2's MPPI controller reads them (``nav2_mppi_controller``, a
ROS 2 parameter file for ``controller_server``), where the two correspond.

Carried over:

- the sampling: ``batch_size`` (samples), ``time_steps`` (the horizon plus the steps in
  flight: Nav2 rolls out from the robot's state now, with no delay), ``model_dt``,
  ``vx_std`` and ``wz_std`` (the sigmas), one iteration, ``gamma`` 0 (diffdrive's update has
  no control-cost term);
- the limits, from the wheels' (the controller's, else the plan's): ``vx_max`` the speed with
  both wheels at their limit (at most the plan's ``max_velocity``), ``vx_min`` its negative
  (the controller may back up), ``wz_max`` the turn in place at the wheels' limit (at most the
  plan's ``max_angular_velocity``); with a wheel acceleration limit, ``ax_max``, ``ax_min``
  and ``az_max`` (read by Nav2 Jazzy and later);
- with obstacles: the ``ObstaclesCritic``'s ``collision_cost`` and ``inflation_radius``
  (footprint plus inflation band), and the footprint as the costmap's ``robot_radius`` to
  give the local costmap (stated in a comment: it is another node's parameter).

Not carried over, and said so in the file: the temperature and the cost weights (Nav2's critics
score other quantities, to the first power, so no number maps onto another), the drive's delay
and lag (Nav2 has no model of them, navigation2#5214), the smoothing, the guide around
obstacles (Nav2's planner server makes the path), and the arrival tolerance and the way made
for a stalled robot (``controller_server``'s goal and progress checkers are other plugins).
"""

from __future__ import annotations

import math
from pathlib import Path

from diffdrive.control.mppi import MPPI
from diffdrive.control.planning import PathLimits
from diffdrive.export.files import write, yaml_value
from diffdrive.model import Robot

__all__ = ["nav2_mppi_parameters", "render_nav2_mppi", "write_nav2_mppi"]

_NOT_CARRIED = [
    "not carried over: temperature and cost weights (Nav2's critics score other quantities, to "
    "the first power: keep Nav2's defaults and tune there)",
    "not carried over: the drive's delay and lag (Nav2 does not roll them out), the smoothing, "
    "and the guide around obstacles (Nav2's planner server makes the path)",
    "not carried over: the arrival tolerance and the way made for a stalled robot (the "
    "controller server's goal checker and progress checker are plugins of their own)",
]


def nav2_mppi_parameters(mppi: MPPI, robot: Robot, limits: PathLimits | None = None) -> dict:
    """The ``FollowPath`` parameters (nested: critics are sub-dictionaries) of ``mppi`` on
    ``robot`` with the plan's ``limits`` (see the module)."""
    if not isinstance(mppi, MPPI):
        raise TypeError(f"mppi must be an MPPI, got {type(mppi).__name__}")
    drive = robot.equivalent
    radius = 0.5 * (drive.left_wheel_radius + drive.right_wheel_radius)
    wheel = _first(mppi.max_wheel_velocity, _of(limits, "max_wheel_velocity"))
    if wheel is None:
        raise ValueError(
            "Nav2's vx_max and wz_max need a wheel limit: give the controller's "
            "max_wheel_velocity or the plan's"
        )
    vx = min(radius * wheel, _of(limits, "max_velocity") or math.inf)
    turn = _of(limits, "max_angular_velocity") or math.inf
    wz = min(2.0 * radius * wheel / drive.track_width, turn)
    figures: dict = {
        "plugin": "nav2_mppi_controller::MPPIController",
        "motion_model": "DiffDrive",
        "batch_size": mppi.samples,
        "time_steps": mppi.delay_steps + mppi.horizon,
        "model_dt": mppi.dt,
        "iteration_count": 1,
        "vx_std": float(mppi.sigma[0]),
        "wz_std": float(mppi.sigma[1]),
        "gamma": 0.0,
        "vx_max": vx,
        "vx_min": -vx,
        "wz_max": wz,
    }
    acceleration = _first(mppi.max_wheel_acceleration, _of(limits, "max_wheel_acceleration"))
    if acceleration is not None:
        figures["ax_max"] = radius * acceleration
        figures["ax_min"] = -radius * acceleration
        figures["az_max"] = 2.0 * radius * acceleration / drive.track_width
    critics = [
        "ConstraintCritic",
        "GoalCritic",
        "GoalAngleCritic",
        "PathAlignCritic",
        "PathFollowCritic",
        "PathAngleCritic",
    ]
    if mppi.obstacles is not None:
        critics.insert(1, "ObstaclesCritic")
        figures["ObstaclesCritic"] = {
            "enabled": True,
            "collision_cost": mppi.costs.collision,
            "inflation_radius": mppi.footprint + mppi.inflation,
            "consider_footprint": False,
        }
    figures["critics"] = critics
    return figures


def render_nav2_mppi(mppi: MPPI, robot: Robot, limits: PathLimits | None = None) -> str:
    """The parameter file's text (``controller_server: ros__parameters: FollowPath: ...``)."""
    figures = nav2_mppi_parameters(mppi, robot, limits)
    lines = [
        "# Nav2 MPPI controller parameters from diffdrive's MPPI (diffdrive.export."
        "nav2_mppi says how each is derived)"
    ]
    lines += [f"# {note}" for note in _NOT_CARRIED]
    if mppi.obstacles is not None:
        lines.append(f"# give the local costmap robot_radius: {yaml_value(mppi.footprint)} (m)")
    lines += ["controller_server:", "  ros__parameters:", "    FollowPath:"]
    for name, value in figures.items():
        if isinstance(value, dict):
            lines.append(f"      {name}:")
            lines += [f"        {key}: {yaml_value(item)}" for key, item in value.items()]
        else:
            lines.append(f"      {name}: {yaml_value(value)}")
    return "\n".join(lines) + "\n"


def write_nav2_mppi(
    path: str | Path, mppi: MPPI, robot: Robot, limits: PathLimits | None = None
) -> None:
    """The parameter file, written whole or not at all."""
    write(path, render_nav2_mppi(mppi, robot, limits))


def _of(limits: PathLimits | None, name: str) -> float | None:
    """The plan's limit ``name``, None without one."""
    return None if limits is None else getattr(limits, name)


def _first(*values: float | None) -> float | None:
    return next((value for value in values if value is not None), None)
