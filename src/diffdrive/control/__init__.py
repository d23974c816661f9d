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
- ``follow``: ``follow``, closed-loop simulation of a batch of robots; ``delay_margin``;
- ``rollouts``: many candidate command sequences through a delay and acceleration limits.
"""

from diffdrive.control.commands import KEEP, desaturate
from diffdrive.control.follow import FollowResult, delay_margin, follow
from diffdrive.control.limiter import Limiter, Limits
from diffdrive.control.open_loop import OpenLoopOdometry, drive_commands
from diffdrive.control.path import from_segments, from_waypoints
from diffdrive.control.planning import PathLimits, Plan, limit_ratios, plan
from diffdrive.control.rollouts import rollouts
from diffdrive.control.tracking import LTVUnicycle, Predictive, PurePursuit, Ramsete, Tracker

__all__ = [
    "KEEP",
    "FollowResult",
    "LTVUnicycle",
    "Limiter",
    "Limits",
    "OpenLoopOdometry",
    "PathLimits",
    "Plan",
    "Predictive",
    "PurePursuit",
    "Ramsete",
    "Tracker",
    "delay_margin",
    "desaturate",
    "drive_commands",
    "follow",
    "from_segments",
    "from_waypoints",
    "limit_ratios",
    "plan",
    "rollouts",
]
