"""Control: the commands a robot is given, within its limits.

- ``commands``: ``desaturate``, wheel commands within a wheel-speed limit;
- ``limiter``: ``Limits``, ``Limiter``: velocity, acceleration, jerk and a command timeout;
- ``open_loop``: ``OpenLoopOdometry``, ``drive_commands``: the path limited commands drive.
"""

from diffdrive.control.commands import KEEP, desaturate
from diffdrive.control.limiter import Limiter, Limits
from diffdrive.control.open_loop import OpenLoopOdometry, drive_commands

__all__ = ["KEEP", "Limiter", "Limits", "OpenLoopOdometry", "desaturate", "drive_commands"]
