"""Control: the commands a robot is given, within its limits, and the paths it is asked to follow.

- ``commands``: ``desaturate``, wheel commands within a wheel-speed limit;
- ``limiter``: ``Limits``, ``Limiter``: velocity, acceleration, jerk and a command timeout;
- ``open_loop``: ``OpenLoopOdometry``, ``drive_commands``: the path limited commands drive;
- ``path``: ``from_waypoints``, ``from_segments``: the geometry of a path (G2 quintic splines
  through waypoints, lines, arcs, turns in place);
- ``planning``: ``plan``, ``PathLimits``, ``Plan``: the fastest timing within every wheel's
  limits; ``limit_ratios`` judges any timed path against them;
- ``tracking``: ``Ramsete``, ``LTVUnicycle``, ``PurePursuit``, and ``Predictive`` for a known
  delay and lag;
- ``closed_loop``: ``follow``, closed-loop simulation of a batch of robots; ``delay_margin``;
- ``candidates``: ``rollouts``, many candidate command sequences through a delay and
  acceleration limits;
- ``mppi``: ``MPPI``, a tracker that samples them (model predictive path integral control),
  with its ``MPPICosts``, ``MPPISampling``, ``WheelLimits``, ``Avoidance`` and ``Arrival``
  (a ``Stall`` each time a robot stops short of the goal);
  ``_mppi_arrays`` runs its cycle in an array library;
- ``obstacles``: ``Obstacles``, a clearance field from circles, an occupancy grid or a ROS map
  (``read_map``); ``clearance``: ``guide``, a plan made to clear them; ``courses``:
  ``cluttered_corridor``, a random course to test a controller on.
"""

from typing import TYPE_CHECKING

from diffdrive._lazy import attach

# Each name loads its module on first use.
_NAMES = {
    **dict.fromkeys(["KEEP", "desaturate"], "commands"),
    **dict.fromkeys(["FollowResult", "FollowSettings", "delay_margin", "follow"], "closed_loop"),
    **dict.fromkeys(["Limiter", "Limits"], "limiter"),
    **dict.fromkeys(["OpenLoopOdometry", "drive_commands"], "open_loop"),
    **dict.fromkeys(["from_segments", "from_waypoints"], "path"),
    **dict.fromkeys(["PathLimits", "Plan", "limit_ratios", "plan"], "planning"),
    "rollouts": "candidates",
    **dict.fromkeys(
        ["MPPI", "Arrival", "Avoidance", "MPPICosts", "MPPISampling", "Stall", "WheelLimits"],
        "mppi",
    ),
    **dict.fromkeys(["Obstacles", "read_map"], "obstacles"),
    "guide": "clearance",
    **dict.fromkeys(["Course", "cluttered_corridor"], "courses"),
    **dict.fromkeys(["LTVUnicycle", "Predictive", "PurePursuit", "Ramsete", "Tracker"], "tracking"),
}
__getattr__, __dir__ = attach(__name__, _NAMES)
__all__ = [
    "KEEP",
    "MPPI",
    "Arrival",
    "Avoidance",
    "Course",
    "FollowResult",
    "FollowSettings",
    "LTVUnicycle",
    "Limiter",
    "Limits",
    "MPPICosts",
    "MPPISampling",
    "Obstacles",
    "OpenLoopOdometry",
    "PathLimits",
    "Plan",
    "Predictive",
    "PurePursuit",
    "Ramsete",
    "Stall",
    "Tracker",
    "WheelLimits",
    "cluttered_corridor",
    "delay_margin",
    "desaturate",
    "drive_commands",
    "follow",
    "from_segments",
    "from_waypoints",
    "guide",
    "limit_ratios",
    "plan",
    "read_map",
    "rollouts",
]

if TYPE_CHECKING:  # what the names are, for type checkers
    from diffdrive.control.candidates import rollouts
    from diffdrive.control.clearance import guide
    from diffdrive.control.closed_loop import FollowResult, FollowSettings, delay_margin, follow
    from diffdrive.control.commands import KEEP, desaturate
    from diffdrive.control.courses import Course, cluttered_corridor
    from diffdrive.control.limiter import Limiter, Limits
    from diffdrive.control.mppi import (
        MPPI,
        Arrival,
        Avoidance,
        MPPICosts,
        MPPISampling,
        Stall,
        WheelLimits,
    )
    from diffdrive.control.obstacles import Obstacles, read_map
    from diffdrive.control.open_loop import OpenLoopOdometry, drive_commands
    from diffdrive.control.path import from_segments, from_waypoints
    from diffdrive.control.planning import PathLimits, Plan, limit_ratios, plan
    from diffdrive.control.tracking import LTVUnicycle, Predictive, PurePursuit, Ramsete, Tracker
