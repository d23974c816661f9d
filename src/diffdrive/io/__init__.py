"""Files in and out: every format diffdrive reads or writes, and the one ``Run`` type.

- ``run``: ``Run``, a robot's wheels over time with ground truth where there is one;
  ``read``: ``read_run`` for any file that holds one (a table, an OptiOdom file, a bag), and
  ``read_commands``, the wheel velocities a robot was commanded (a bag's Twist topic, or a
  table's command columns);
  ``sniff``: which kind of file a path is;
- ``tables``: text tables of numbers as loggers and spreadsheets write them (the one parser
  the others share), with their time units;
- ``logs``: wheel-log tables; ``optiodom``: the OptiOdom run files (Sousa et al. 2022);
- ``trajectories``: ``t, x, y, theta`` as CSV, JSON lines or TUM, or a bag's topic;
- ``robots``: robot files (TOML); ``drives``: drive files (TOML, what ``identify`` found);
- ``stamps``: ``sample_times``, the sample times behind a fixed-rate publisher's stamps that
  are a clock tick early at times (a simulator's ``/joint_states``);
- ``ros``: ROS 1 bags, ROS 2 bags and MCAP files (the ``ros`` extra), loaded on first use;
- ``diffdrive.atomic`` (re-exported here): the atomic writes every writer goes through.

Every reader refuses a bad file with ``TableError`` (a ``ValueError``) naming the file, and
the line and column when known; every writer leaves the target as it was when it fails.
"""

from diffdrive.atomic import atomic_output, atomic_write
from diffdrive.io.drives import read_drive, write_drive
from diffdrive.io.logs import read_log
from diffdrive.io.optiodom import (
    OPTIODOM_TICKS_PER_REVOLUTION,
    optiodom_robot,
    optiodom_sessions,
    read_optiodom_run,
)
from diffdrive.io.read import read_commands, read_run
from diffdrive.io.robots import (
    NOISE_PARTS,
    ROBOT_KEYS,
    overridden,
    read_robot,
    read_robot_noise,
    robot_from_settings,
    write_robot,
)
from diffdrive.io.run import RIM_SPEED_LIMIT, WHEEL_COLUMNS, Run, WheelKind, narrower_counter
from diffdrive.io.sniff import is_bag
from diffdrive.io.stamps import SampleTimes, sample_times
from diffdrive.io.tables import TIME_UNITS, TableError, read_table
from diffdrive.io.trajectories import FORMATS, read_trajectory, write_trajectory

__all__ = [
    "FORMATS",
    "NOISE_PARTS",
    "OPTIODOM_TICKS_PER_REVOLUTION",
    "RIM_SPEED_LIMIT",
    "ROBOT_KEYS",
    "TIME_UNITS",
    "WHEEL_COLUMNS",
    "Run",
    "SampleTimes",
    "TableError",
    "WheelKind",
    "atomic_output",
    "atomic_write",
    "is_bag",
    "narrower_counter",
    "optiodom_robot",
    "optiodom_sessions",
    "overridden",
    "read_commands",
    "read_drive",
    "read_log",
    "read_optiodom_run",
    "read_robot",
    "read_robot_noise",
    "read_run",
    "read_table",
    "read_trajectory",
    "robot_from_settings",
    "sample_times",
    "write_drive",
    "write_robot",
    "write_trajectory",
]
