"""The ``diffdrive`` command line: the parser and ``main``; a module per subcommand.

With no arguments it runs the main job on a built-in example (``report``)."""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from collections.abc import Sequence
from pathlib import Path

from diffdrive.calibration import EXTRAS, PARAMETERS
from diffdrive.calibration import METHODS as CALIBRATION_METHODS
from diffdrive.cli.calibrate import run_calibrate
from diffdrive.cli.evaluate import run_evaluate
from diffdrive.cli.info import run_info
from diffdrive.cli.kinematics import run_fk, run_ik
from diffdrive.cli.learn import run_learn
from diffdrive.cli.odometry import run_odometry
from diffdrive.cli.options import (
    COVARIANCE_COLUMNS,
    LOG_COLUMNS,
    NEGATIVE_NUMBER,
    RIM_SPEED_LIMIT,
    TRAJECTORY_FILES,
    at_least,
    between,
    log_options,
    output_options,
    robot_options,
)
from diffdrive.cli.plot import run_animate, run_plot
from diffdrive.cli.report import example_outputs, kinematics_report, simulation_report
from diffdrive.cli.simulate import run_simulate
from diffdrive.evaluation import RPE_PAIRS
from diffdrive.examples import example_robot
from diffdrive.files import TIME_UNITS
from diffdrive.integrate import METHODS

EPILOGS = {
    "simulate": f"""examples:
  diffdrive simulate                       the built-in driving history -> trajectory.csv
  diffdrive simulate drive.csv -o out.tum --method rk2 --robot robot.toml

{LOG_COLUMNS}""",
    "odometry": f"""examples:
  diffdrive odometry                      a built-in 20 Hz log of the example -> odometry.csv
  diffdrive odometry log.csv --ticks-per-revolution 4096 --counter-bits 12 -o odometry.csv
  diffdrive odometry log.csv --time-unit ns --max-wheel-speed 30 --twist --covariance

{LOG_COLUMNS}
With ground truth an error summary is printed. The largest wheel speed the log implies is
printed with its line: thousands of rad/s mean a wrong --counter-bits or ticks per revolution.""",
    "plot": f"""examples:
  diffdrive plot                          the built-in example -> trajectory.png
  diffdrive plot odometry.csv --truth log.csv -o odometry.svg

{TRAJECTORY_FILES} --truth is drawn underneath.""",
    "animate": """examples:
  diffdrive animate                       the built-in example -> trajectory.gif
  diffdrive animate trajectory.csv -o drive.mp4     (MP4 needs ffmpeg; else a GIF)""",
    "calibrate": f"""examples:
  diffdrive calibrate                      the built-in example runs -> robot.toml
  diffdrive calibrate runs/*_run-*.csv --method least_squares -o robot.toml

runs with ground truth, each as below (x, y, theta needed; OptiOdom files count 2796.8 a
turn unless told).
{LOG_COLUMNS}""",
    "evaluate": f"""examples:
  diffdrive evaluate                       the built-in example's odometry against its truth
  diffdrive evaluate odometry.tum --truth truth.csv --rpe 1.0 --json
  diffdrive evaluate est.tum --truth gt.tum --t-offset -0.003 --rpe 10 --rpe-unit poses

{TRAJECTORY_FILES} Poses are paired by time as evo pairs them: the nearest
stamp within --t-max-diff s, after adding --t-offset to the trajectory's times;
--interpolate instead samples the trajectory at every ground-truth time along its arcs.""",
    "info": """example:
  diffdrive info robot.bag      topics, types, counts, rates, and which diffdrive can use""",
    "learn": """examples:
  diffdrive learn                 serve the page on this machine and open it in the browser
  diffdrive learn --no-browser --port 2718     serve only; open http://127.0.0.1:2718
  diffdrive learn --export page.html           a static snapshot for a course website
needs the extra: pip install 'diffdrive[learn]'""",
    "fk": """example:
  diffdrive fk 8 10 --json      wheel velocities (rad/s) -> body twist
  diffdrive fk 1 -1e-3          (negative numbers are numbers, not options)""",
    "ik": """example:
  diffdrive ik 0.5 1.0          forward speed (m/s) and turn rate (rad/s) -> wheel velocities""",
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="diffdrive",
        description="Kinematics of differential-drive robots. With no arguments: the "
        "kinematics of a built-in example robot, and a simulation of its built-in driving "
        "history with each integration method.",
    )
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")
    robot = robot_options()
    formatter = argparse.RawDescriptionHelpFormatter

    def command(name: str, help: str, parents: list, run) -> argparse.ArgumentParser:
        sub = commands.add_parser(
            name, help=help, description=help, epilog=EPILOGS[name], parents=parents,
            formatter_class=formatter,
        )  # fmt: skip
        sub.set_defaults(run=run)
        return sub

    logs = log_options()
    sim = command(
        "simulate", "integrate a driving history into a trajectory",
        [robot, logs, output_options("trajectory.csv")], run_simulate,
    )  # fmt: skip
    sim.add_argument("input", nargs="?", type=Path, help="driving history or log; none: built-in")
    sim.add_argument("--dt", type=float, default=0.01, help="step for the built-in history, s")
    odo = command(
        "odometry", "dead reckoning over an encoder log",
        [robot, logs, output_options("odometry.csv")], run_odometry,
    )  # fmt: skip
    odo.add_argument("input", nargs="?", type=Path, help="encoder log; none: built-in")
    odo.add_argument(
        "--max-wheel-speed", type=float, metavar="RAD_S",
        help="refuse a row whose wheel turns faster (rad/s); default: a rim speed of "
        f"{RIM_SPEED_LIMIT:g} m/s",
    )  # fmt: skip
    odo.add_argument("--k-left", type=float, metavar="M",
                     help="left wheel-error constant of the covariance model, m (default 0; "
                     "1e-4 with a gyro)")  # fmt: skip
    odo.add_argument(
        "--k-right",
        type=float,
        metavar="M",
        help="right wheel-error constant, m (default 0; 1e-4 with a gyro)",
    )
    gyro = odo.add_argument_group("a gyro: a bag's IMU topic or a gyro_z column (rad/s)")
    gyro.add_argument("--gyro-topic", metavar="TOPIC", help="sensor_msgs/Imu topic of the bag")
    gyro.add_argument(
        "--imu-rpy",
        type=float,
        nargs=3,
        default=(0.0, 0.0, 0.0),
        metavar=("ROLL", "PITCH", "YAW"),
        help="the IMU's mounting in the body, degrees (default 0 0 0: z up)",
    )
    gyro.add_argument("--heading", choices=("wheels", "gyro", "fused"),
                      help="heading from the wheels, the gyro, or both (default: fused with a "
                      "gyro); writes slip, slip_score and gyro_bias columns")  # fmt: skip
    gyro.add_argument(
        "--gyro-bias",
        type=float,
        metavar="RAD_S",
        help="the gyro's bias (default: its mean while the wheels stand still)",
    )
    gyro.add_argument("--command-topic", metavar="TOPIC",
                      help="geometry_msgs/Twist commands of the bag, to flag wheels that spin "
                      "beyond them (or left_command, right_command columns)")  # fmt: skip
    odo.add_argument(
        "--twist",
        action="store_true",
        help="add columns vx, vy, omega: the twist over the interval ending at "
        "each row (nan on the first)",
    )
    odo.add_argument(
        "--covariance",
        action="store_true",
        help=f"add columns {', '.join(COVARIANCE_COLUMNS)} (m^2, m rad, rad^2)",
    )
    times = argparse.ArgumentParser(add_help=False)
    times.add_argument("--time-unit", choices=TIME_UNITS, help="unit of the t column (default s)")
    times.add_argument("--topic", metavar="TOPIC",
                       help="for a bag: the trajectory's topic (nav_msgs/Odometry, "
                       "sensor_msgs/NavSatFix) or tf:PARENT:CHILD")  # fmt: skip
    times.add_argument("--truth-topic", metavar="TOPIC", help="for a bag: the truth's topic")
    pictures = argparse.ArgumentParser(add_help=False, parents=[times])
    pictures.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
    pictures.add_argument(
        "input", nargs="?", type=Path, help="trajectory (CSV, JSON lines, TUM); none: built-in"
    )
    plot = command("plot", "draw a trajectory", [robot, pictures], run_plot)
    plot.add_argument("-o", "--output", type=Path, default=Path("trajectory.png"))
    plot.add_argument("--truth", type=Path, help="ground-truth trajectory, drawn underneath")
    movie = command("animate", "animate a trajectory", [robot, pictures], run_animate)
    movie.add_argument("-o", "--output", type=Path, default=Path("trajectory.gif"))
    movie.add_argument("--fps", type=at_least(1), default=20)
    movie.add_argument("--frames", type=at_least(2), default=120, help="frames to draw")
    cal = command("calibrate", "fit wheel radii and track width to ground truth",
                  [robot, logs], run_calibrate)  # fmt: skip
    cal.add_argument("runs", nargs="*", type=Path, help="runs with ground truth; none: built-in")
    cal.add_argument("-o", "--output", type=Path, default=Path("robot.toml"))
    cal.add_argument("--method", choices=CALIBRATION_METHODS, default="least_squares")
    cal.add_argument("--integration", choices=METHODS, default="exact",
                     help="the odometry's method (default exact)")  # fmt: skip
    cal.add_argument("--square-side", type=float, help="UMBmark's square, m")
    cal.add_argument("--cv", default="loo", metavar="loo|K|none",
                     help="held-out errors by cross-validation over the runs: leave one run "
                     "out (default), K folds, or none")  # fmt: skip
    cal.add_argument(
        "--fix",
        nargs="+",
        choices=PARAMETERS,
        metavar="PARAMETER",
        help="hold these at their nominal values (e.g. track_width)",
    )
    cal.add_argument(
        "--extra",
        nargs="+",
        choices=(*EXTRAS, "none"),
        metavar="PARAMETER",
        help="fit these too: axle_offset (the tracked point is not on the axle), "
        "heading_offset (the reference's heading is the robot's plus a constant); default "
        "both for least_squares and minimax, which predicted held-out runs best; none: neither",
    )
    cal.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
    ev = command("evaluate", "a trajectory against ground truth", [times], run_evaluate)
    ev.add_argument("input", nargs="?", type=Path, help="trajectory; none: built-in")
    ev.add_argument("--truth", type=Path, help="ground-truth trajectory")
    ev.add_argument(
        "--t-max-diff",
        type=float,
        default=0.01,
        metavar="S",
        help="largest time difference of a pair of poses, s (default 0.01, as evo)",
    )
    ev.add_argument(
        "--t-offset",
        type=float,
        default=0.0,
        metavar="S",
        help="added to the trajectory's times before pairing, s (default 0)",
    )
    ev.add_argument(
        "--interpolate",
        action="store_true",
        help="sample the trajectory at the truth's times along its arcs",
    )
    ev.add_argument("--rpe", type=float, default=1.0, help="RPE window (default 1)")
    ev.add_argument("--rpe-unit", choices=["m", "s", "poses"], default="m")
    ev.add_argument(
        "--rpe-pairs",
        choices=RPE_PAIRS,
        default="consecutive",
        help="consecutive (evo's default) or all (evo's --all_pairs)",
    )
    ev.add_argument("--json", action="store_true")
    info = command("info", "what a ROS bag or MCAP file holds, and what diffdrive can use",
                   [], run_info)  # fmt: skip
    info.add_argument("input", type=Path, help="a ROS 1 bag, ROS 2 bag folder or MCAP file")
    learn = command("learn", "an interactive page for learning the kinematics, in the browser",
                    [], run_learn)  # fmt: skip
    learn.add_argument("--port", type=between(1, 65535), help="port (default: a free one)")
    learn.add_argument("--no-browser", action="store_true", help="serve without opening it")
    learn.add_argument("--export", type=Path, metavar="HTML", help="write a static snapshot")
    fk = command("fk", "wheel velocities to the body twist", [robot], run_fk)
    fk._negative_number_matcher = NEGATIVE_NUMBER  # -1e-3 is a number, not an option
    fk.add_argument("left", type=float, help="rad/s")
    fk.add_argument("right", type=float, help="rad/s")
    fk.add_argument("--json", action="store_true")
    ik = command("ik", "a body twist to wheel velocities", [robot], run_ik)
    ik._negative_number_matcher = NEGATIVE_NUMBER
    ik.add_argument("vx", type=float, help="forward speed, m/s")
    ik.add_argument("omega", type=float, help="turn rate, rad/s")
    ik.add_argument("--json", action="store_true")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code (0 done, 1 failed, 2 misused)."""
    args = build_parser().parse_args(argv)
    if args.command is None:
        robot = example_robot()
        print(kinematics_report(robot))
        print()
        print(simulation_report(robot))
        print()
        print(example_outputs(robot, Path("out")))
        return 0
    previous = _exit_on_sigterm()
    try:
        return args.run(args)
    except (ValueError, TypeError, OSError) as exc:
        print(f"diffdrive {args.command}: error: {exc}", file=sys.stderr)
        return 1
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def _exit_on_sigterm():
    """Make SIGTERM unwind like Ctrl-C, so that a half-written output's temporary file goes;
    returns the handler it replaced (None where signals cannot be set: not the main thread)."""

    def terminate(signum, frame):
        raise SystemExit(128 + signum)

    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGTERM, terminate)


__all__ = ["build_parser", "kinematics_report", "main", "simulation_report"]
