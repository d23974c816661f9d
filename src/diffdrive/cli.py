"""The ``diffdrive`` command line. With no arguments it runs the main job on a built-in example."""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from diffdrive import se2
from diffdrive.calibration import METHODS as CALIBRATION_METHODS
from diffdrive.calibration import calibrate, odometry_of
from diffdrive.evaluation import ate, rpe, run_errors, worst
from diffdrive.examples import (
    EXAMPLE_DURATION,
    EXAMPLE_TICKS_PER_REVOLUTION,
    example_encoder_log,
    example_robot,
    example_wheel_velocities,
)
from diffdrive.files import (
    FORMATS,
    ROBOT_KEYS,
    TableError,
    atomic_output,
    read_header,
    read_robot,
    read_run,
    read_table,
    read_trajectory,
    write_robot,
    write_trajectory,
)
from diffdrive.integrate import METHODS
from diffdrive.model import DiffDrive
from diffdrive.odometry import Odometry
from diffdrive.simulation import simulate
from diffdrive.types import Pose, Twist, WheelVelocities

# (label, left, right) wheel velocities in rad/s that show the characteristic motions.
_EXAMPLE_WHEELS = (
    ("straight", 10.0, 10.0),
    ("gentle left", 8.0, 10.0),
    ("spin in place", -5.0, 5.0),
    ("pivot on right wheel", 6.0, 0.0),
)


def _matrix(m: np.ndarray) -> str:
    return "\n".join("    [" + "  ".join(f"{v:+10.5f}" for v in row) + " ]" for row in m)


def kinematics_report(robot: DiffDrive) -> str:
    """A text report of ``robot``'s kinematics: matrices and a few characteristic motions."""
    lines = [
        f"robot: {robot}",
        "",
        "seed 003: [vx, omega] = K @ [wl, wr]",
        _matrix(robot.to_twist_matrix()),
        "Modern Robotics: [wl, wr] = H @ (omega, vx, vy)",
        _matrix(robot.h_matrix()),
        "and back: (omega, vx, vy) = F @ [wl, wr]",
        _matrix(robot.f_matrix()),
        "",
        f"{'motion':22} {'wl':>7} {'wr':>7} {'vx m/s':>8} {'omega':>8} {'radius m':>9}"
        f"   pose after 1 s (x, y, theta deg)",
    ]
    for label, left, right in _EXAMPLE_WHEELS:
        wheels = WheelVelocities(left, right)
        twist = robot.to_twist(wheels)
        pose = se2.exp(twist, 1.0)
        lines.append(
            f"{label:22} {left:7.2f} {right:7.2f} {twist.vx:8.4f} {twist.omega:8.4f} "
            f"{robot.turning_radius(wheels):9.4f}   "
            f"({pose.x:+.4f}, {pose.y:+.4f}, {math.degrees(pose.theta):+.2f})"
        )
    return "\n".join(lines)


def simulation_report(robot: DiffDrive, steps: int = 2000) -> str:
    """Simulate the built-in driving history with each method; compare the final poses."""
    lines = [
        f"simulated {EXAMPLE_DURATION:g} s of the built-in driving history in {steps} steps:",
        f"{'method':8} {'x m':>9} {'y m':>9} {'theta deg':>10} {'distance m':>11}",
    ]
    for method in METHODS:
        trajectory = simulate(
            robot,
            example_wheel_velocities,
            dt=EXAMPLE_DURATION / steps,
            duration=EXAMPLE_DURATION,
            method=method,
        )
        x, y, theta = trajectory.final_pose
        lines.append(
            f"{method:8} {x:9.4f} {y:9.4f} {math.degrees(theta):10.2f} "
            f"{trajectory.distance[-1]:11.4f}"
        )
    return "\n".join(lines)


ROBOT_DEFAULTS = "the built-in example robot: 42 mm wheels, track 0.2 m"

EPILOGS = {
    "simulate": """examples:
  diffdrive simulate                       the built-in driving history -> trajectory.csv
  diffdrive simulate drive.csv -o out.tum --method rk2 --robot robot.toml

input columns: t (s), and either left_velocity, right_velocity (rad/s, held from this row's
time to the next; the last row's are not used) or left_angle, right_angle (rad, accumulated).""",
    "odometry": """examples:
  diffdrive odometry                      a built-in 20 Hz log of the example -> odometry.csv
  diffdrive odometry log.csv --ticks-per-revolution 2796.8 -o odometry.csv

input columns: t (s), and one of left_ticks, right_ticks (absolute counter readings);
left_angle, right_angle (rad, accumulated); left_velocity, right_velocity (rad/s over the
interval that ends at this row). With x, y, theta columns (ground truth) the odometry starts
from the first ground-truth pose and an error summary is printed.""",
    "plot": """examples:
  diffdrive plot                          the built-in example -> trajectory.png
  diffdrive plot odometry.csv --truth log.csv -o odometry.svg

input: a trajectory CSV with columns t, x, y, theta (what simulate and odometry write);
--truth: a CSV with columns t, x, y, theta, drawn underneath.""",
    "animate": """examples:
  diffdrive animate                       the built-in example -> trajectory.gif
  diffdrive animate trajectory.csv -o drive.mp4     (MP4 needs ffmpeg; else a GIF)""",
    "calibrate": """examples:
  diffdrive calibrate                      the built-in example runs -> robot.toml
  diffdrive calibrate runs/*_run-*.csv --method least_squares -o robot.toml

input: runs with ground truth, each the OptiOdom format (no header: t, x, y, theta,
ticks_right, ticks_left; 2796.8 counts a turn unless told) or a CSV with t, x, y, theta and
left_ticks, right_ticks (give --ticks-per-revolution) or left_angle, right_angle (rad).""",
    "evaluate": """examples:
  diffdrive evaluate                       the built-in example's odometry against its truth
  diffdrive evaluate odometry.csv --truth truth.csv --rpe 1.0 --json

input: two CSVs with t, x, y, theta sampled at the same times.""",
    "fk": """example:
  diffdrive fk 8 10 --json      wheel velocities (rad/s) -> body twist""",
    "ik": """example:
  diffdrive ik 0.5 1.0          forward speed (m/s) and turn rate (rad/s) -> wheel velocities""",
}

HISTORIES = {
    "left_velocity": ("left_velocity", "right_velocity"),
    "left_angle": ("left_angle", "right_angle"),
    "left_ticks": ("left_ticks", "right_ticks"),
}


def _robot_options() -> argparse.ArgumentParser:
    options = argparse.ArgumentParser(add_help=False)
    group = options.add_argument_group(f"robot (default: {ROBOT_DEFAULTS})")
    group.add_argument("--robot", type=Path, help="a robot file (TOML) with the settings below")
    for name in ROBOT_KEYS:
        unit = "counts" if name == "ticks_per_revolution" else "m"
        group.add_argument(f"--{name.replace('_', '-')}", type=float, help=f"{unit}")
    return options


def _output_options(default: str) -> argparse.ArgumentParser:
    options = argparse.ArgumentParser(add_help=False)
    options.add_argument("-o", "--output", type=Path, default=Path(default), help="file to write")
    options.add_argument("--format", choices=FORMATS, help="default: from the file's suffix")
    options.add_argument("--method", choices=METHODS, default="exact")
    options.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
    return options


def _robot(args: argparse.Namespace) -> tuple[DiffDrive, float | None]:
    """The robot of the command's options, and its ticks per revolution if known."""
    settings = read_robot(args.robot) if args.robot else {}
    for name in ROBOT_KEYS:
        value = getattr(args, name)
        if value is not None:
            settings[name] = value
    ticks = settings.pop("ticks_per_revolution", None)
    if not settings:
        return example_robot(), ticks
    return DiffDrive(**settings), ticks


def _format(args: argparse.Namespace) -> str:
    if args.format:
        return args.format
    suffix = args.output.suffix.lstrip(".").lower()
    return suffix if suffix in FORMATS else "csv"


def _history_columns(path: Path, kinds: tuple[str, ...]) -> tuple[str, str]:
    """Which pair of wheel columns the file has, from its header."""
    header = read_header(path)
    for kind in kinds:
        if kind in header:
            return HISTORIES[kind]
    wanted = " or ".join(", ".join(HISTORIES[kind]) for kind in kinds)
    raise TableError(f"{path}:1: missing columns {wanted} (the header has: {', '.join(header)})")


def _write(args: argparse.Namespace, times: np.ndarray, poses: np.ndarray, what: str) -> None:
    write_trajectory(args.output, times, poses, _format(args))
    if not args.quiet:
        print(f"{what}: wrote {len(times)} poses to {args.output} ({_format(args)})")


def run_simulate(args: argparse.Namespace) -> int:
    robot, _ = _robot(args)
    if args.input is None:
        trajectory = _example_trajectory(robot, args.dt, args.method)
        what = f"simulated the built-in {EXAMPLE_DURATION:g} s driving history"
    else:
        left, right = _history_columns(args.input, ("left_velocity", "left_angle"))
        table = read_table(args.input, ["t", left, right])
        wheels = np.column_stack([table[left], table[right]])
        if left == "left_velocity":
            trajectory = simulate(robot, wheels[:-1], times=table["t"], method=args.method)
        else:
            trajectory = simulate(
                robot, wheel_positions=wheels, times=table["t"], method=args.method
            )
        what = f"simulated {args.input}"
    _write(args, trajectory.times, trajectory.poses, what)
    return 0


def run_odometry(args: argparse.Namespace) -> int:
    robot, ticks = _robot(args)
    if args.input is None:
        table, what = example_encoder_log(), "the built-in encoder log"
        left, right = "left_ticks", "right_ticks"
        ticks = EXAMPLE_TICKS_PER_REVOLUTION if ticks is None else ticks
    else:
        what = str(args.input)
        left, right = _history_columns(args.input, ("left_ticks", "left_angle", "left_velocity"))
        integers = (left, right) if left == "left_ticks" else ()
        table = read_table(args.input, ["t", left, right], ["x", "y", "theta"], integers=integers)
    if left == "left_ticks" and ticks is None:
        raise TableError(
            f"{args.input}: ticks need --ticks-per-revolution (or ticks_per_revolution in "
            "the robot file)"
        )
    truth = None
    if {"x", "y", "theta"} <= table.keys():
        truth = np.column_stack([table["x"], table["y"], table["theta"]])
    start = Pose(*truth[0]) if truth is not None else Pose()
    odometry = Odometry(robot, args.method, start, ticks, args.counter_bits)
    times = table["t"]
    readings = np.column_stack([table[left], table[right]])
    poses = np.empty((len(times), 3))
    for k in _progress(range(len(times)), args.quiet, "odometry"):
        t = float(times[k])
        if left == "left_ticks":
            odometry.update_ticks(int(readings[k, 0]), int(readings[k, 1]), t)
        elif left == "left_angle":
            odometry.update_positions(float(readings[k, 0]), float(readings[k, 1]), t)
        elif k > 0:
            odometry.update_velocities(*readings[k].tolist(), t - float(times[k - 1]))
        poses[k] = odometry.pose.to_array()
    _write(args, times, poses, f"odometry of {what}")
    if truth is not None and not args.quiet:
        print(error_summary(poses, truth))
    return 0


def error_summary(poses: np.ndarray, truth: np.ndarray) -> str:
    """Maximum and final position (m) and heading (deg) errors of ``poses`` against ``truth``."""
    errors = run_errors(poses, truth)
    return (
        f"against the ground truth: position error max {errors.max_position:.4f} m, "
        f"final {errors.final_position:.4f} m; heading error max {errors.max_heading:.3f} deg, "
        f"final {errors.final_heading:.3f} deg"
    )


def _progress(steps: range, quiet: bool, label: str):
    """``steps``, with a progress bar (tqdm) on a terminal for long work."""
    if quiet or len(steps) < 10_000 or not sys.stderr.isatty():
        return steps
    from tqdm import tqdm

    return tqdm(steps, desc=label, unit="update", file=sys.stderr)


def _example_trajectory(robot: DiffDrive, dt: float = 0.01, method: str = "exact"):
    """The built-in driving history, simulated."""
    return simulate(
        robot, example_wheel_velocities, dt=dt, duration=EXAMPLE_DURATION, method=method
    )


def _trajectory_or_example(args: argparse.Namespace, robot: DiffDrive):
    """``(times, poses, what)`` from the input trajectory CSV, or the built-in example."""
    if args.input is None:
        example = _example_trajectory(robot)
        return example.times, example.poses, "the built-in example"
    return (*read_trajectory(args.input), str(args.input))


def run_plot(args: argparse.Namespace) -> int:
    from diffdrive.plot import plot_trajectory

    robot, _ = _robot(args)
    times, poses, what = _trajectory_or_example(args, robot)
    truth = None
    if args.truth is not None:
        truth = read_trajectory(args.truth)
    with atomic_output(args.output) as temporary:
        plot_trajectory(robot, times, poses, temporary, truth)
    if not args.quiet:
        print(f"plotted {what} to {args.output}")
    return 0


def run_animate(args: argparse.Namespace) -> int:
    from diffdrive.plot import animate, animation_writer

    robot, _ = _robot(args)
    times, poses, what = _trajectory_or_example(args, robot)
    writer, output = animation_writer(args.output)
    with atomic_output(output) as temporary:
        animate(robot, times, poses, temporary, writer, frames=args.frames, fps=args.fps)
    if not args.quiet:
        print(f"animated {what} to {output} ({writer})")
    return 0


def _mirrored_example(t: np.ndarray) -> np.ndarray:
    """The built-in history with the wheels swapped: the same path, turning the other way."""
    return example_wheel_velocities(t)[:, ::-1]


def _example_runs() -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Runs of the built-in history by a robot a little off the nominal one, with its truth."""
    true_robot = DiffDrive(
        left_wheel_radius=0.04166, right_wheel_radius=0.04163, track_width=0.2019
    )
    runs = []
    for history in (example_wheel_velocities, _mirrored_example):
        run = simulate(true_robot, history, dt=0.05, duration=EXAMPLE_DURATION)
        runs.append((run.times, np.diff(run.wheel_positions, axis=0), run.poses))
    return runs


def run_calibrate(args: argparse.Namespace) -> int:
    nominal, ticks = _robot(args)
    if args.runs:
        ticks = EXAMPLE_TICKS_PER_REVOLUTION if ticks is None else ticks
        runs = [read_run(path, ticks) for path in args.runs]
        what = f"{len(runs)} runs"
    else:
        runs, what = _example_runs(), "the built-in example runs"
    pairs = [(increments, truth) for _, increments, truth in runs]
    result = calibrate(nominal, pairs, args.method, integration=args.integration,
                       square_side=args.square_side)  # fmt: skip
    robot = result.robot
    settings = {
        "left_wheel_radius": robot.left_wheel_radius,
        "right_wheel_radius": robot.right_wheel_radius,
        "track_width": robot.track_width,
        "axle_offset": robot.axle_offset,
    }
    if ticks is not None:
        settings["ticks_per_revolution"] = ticks
    write_robot(args.output, settings, f"calibrated by diffdrive ({args.method}) on {what}")
    if not args.quiet:
        print(calibration_report(nominal, result, pairs, args.integration))
        print(f"calibrate: wrote the robot to {args.output}")
    return 0


def calibration_report(nominal: DiffDrive, result, runs, integration: str) -> str:
    """Parameters with their standard errors, and the largest errors before and after."""
    sigma = result.standard_errors
    lines = [f"{'parameter':20} {'nominal':>10} {'calibrated':>11} {'+-':>10}"]
    for k, name in enumerate(("left_wheel_radius", "right_wheel_radius", "track_width")):
        lines.append(
            f"{name:20} {getattr(nominal, name):10.6f} {getattr(result.robot, name):11.6f} "
            f"{sigma[k]:10.2g}"
        )
    before = worst([run_errors(odometry_of(nominal, i, t[0], integration), t) for i, t in runs])
    after = worst([run_errors(odometry_of(result.robot, i, t[0], integration), t) for i, t in runs])
    lines.append(f"condition number of the fit: {result.condition:.3g}")
    lines.append(
        f"largest position error over the runs: {before.max_position:.4f} m nominal, "
        f"{after.max_position:.4f} m calibrated"
    )
    return "\n".join(lines)


def run_evaluate(args: argparse.Namespace) -> int:
    if args.input is None:
        log = example_encoder_log()
        robot = example_robot()
        counts = np.column_stack([log["left_ticks"], log["right_ticks"]])
        increments = np.diff(counts, axis=0) * (2 * math.pi / EXAMPLE_TICKS_PER_REVOLUTION)
        truth = np.column_stack([log["x"], log["y"], log["theta"]])
        times, estimate = log["t"], odometry_of(robot, increments, truth[0])
    else:
        if args.truth is None:
            raise TableError("evaluate needs --truth with a trajectory file")
        times, estimate = read_trajectory(args.input)
        truth_times, truth = read_trajectory(args.truth)
        if truth_times.shape != times.shape or not np.allclose(truth_times, times, atol=1e-9):
            raise TableError(
                f"{args.truth}: its times must be those of {args.input} ({len(times)} samples)"
            )
    errors = run_errors(estimate, truth)
    metrics = {
        "max_position_error_m": errors.max_position,
        "final_position_error_m": errors.final_position,
        "max_heading_error_deg": errors.max_heading,
        "final_heading_error_deg": errors.final_heading,
        "ate_m": ate(estimate, truth),
        "ate_aligned_m": ate(estimate, truth, aligned=True),
    }
    translation, rotation = rpe(estimate, truth, args.rpe, unit=args.rpe_unit, times=times)
    metrics[f"rpe_{args.rpe:g}{args.rpe_unit}_m"] = translation
    metrics[f"rpe_{args.rpe:g}{args.rpe_unit}_deg"] = rotation
    if args.json:
        print(json.dumps(metrics))
    else:
        for name, value in metrics.items():
            print(f"{name:28} {value:12.6f}")
    return 0


def run_fk(args: argparse.Namespace) -> int:
    robot, _ = _robot(args)
    wheels = WheelVelocities(args.left, args.right)
    twist = robot.to_twist(wheels)
    values = {
        "vx": twist.vx, "vy": twist.vy, "omega": twist.omega,
        "turning_radius": robot.turning_radius(wheels),
    }  # fmt: skip
    units = {"vx": "m/s", "vy": "m/s", "omega": "rad/s", "turning_radius": "m"}
    _print_values(values, args.json, units)
    return 0


def run_ik(args: argparse.Namespace) -> int:
    robot, _ = _robot(args)
    wheels = robot.to_wheel_velocities(Twist(args.vx, 0.0, args.omega))
    values = {"left": wheels.left, "right": wheels.right}
    _print_values(values, args.json, {"left": "rad/s", "right": "rad/s"})
    return 0


def _print_values(values: dict[str, float], as_json: bool, units: dict[str, str]) -> None:
    if as_json:
        print(json.dumps({k: (v if math.isfinite(v) else str(v)) for k, v in values.items()}))
        return
    for name, value in values.items():
        print(f"{name:15} {value:12.6g} {units[name]}")


def _at_least(smallest: int):
    """An argparse type: a whole number >= ``smallest``."""

    def parse(text: str) -> int:
        value = int(text)
        if value < smallest:
            raise argparse.ArgumentTypeError(f"must be at least {smallest}, got {value}")
        return value

    parse.__name__ = "int"
    return parse


def example_outputs(robot: DiffDrive, folder: Path) -> str:
    """Write the built-in trajectory (CSV, and a picture if matplotlib is there) to ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    trajectory = _example_trajectory(robot)
    table = folder / "trajectory.csv"
    write_trajectory(table, trajectory.times, trajectory.poses)
    written = [str(table)]
    try:
        from diffdrive.plot import plot_trajectory

        picture = folder / "trajectory.png"
        with atomic_output(picture) as temporary:
            plot_trajectory(robot, trajectory.times, trajectory.poses, temporary)
        written.append(str(picture))
    except ImportError:
        written.append("(no picture: pip install 'diffdrive[plot]')")
    return "outputs: " + ", ".join(written)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="diffdrive",
        description="Kinematics of differential-drive robots. With no arguments: the "
        "kinematics of a built-in example robot, and a simulation of its built-in driving "
        "history with each integration method.",
    )
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")
    robot = _robot_options()
    formatter = argparse.RawDescriptionHelpFormatter

    def command(name: str, help: str, parents: list, run) -> argparse.ArgumentParser:
        sub = commands.add_parser(
            name, help=help, description=help, epilog=EPILOGS[name], parents=parents,
            formatter_class=formatter,
        )  # fmt: skip
        sub.set_defaults(run=run)
        return sub

    sim = command(
        "simulate", "integrate a driving history into a trajectory",
        [robot, _output_options("trajectory.csv")], run_simulate,
    )  # fmt: skip
    sim.add_argument("input", nargs="?", type=Path, help="driving history (CSV); none: built-in")
    sim.add_argument("--dt", type=float, default=0.01, help="step for the built-in history, s")
    odo = command(
        "odometry", "dead reckoning over an encoder log",
        [robot, _output_options("odometry.csv")], run_odometry,
    )  # fmt: skip
    odo.add_argument("input", nargs="?", type=Path, help="encoder log (CSV); none: built-in")
    odo.add_argument("--counter-bits", type=int, choices=[8, 16, 32, 64])
    pictures = argparse.ArgumentParser(add_help=False)
    pictures.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
    pictures.add_argument(
        "input", nargs="?", type=Path, help="trajectory (CSV t, x, y, theta); none: built-in"
    )
    plot = command("plot", "draw a trajectory", [robot, pictures], run_plot)
    plot.add_argument("-o", "--output", type=Path, default=Path("trajectory.png"))
    plot.add_argument("--truth", type=Path, help="ground truth (CSV t, x, y, theta)")
    movie = command("animate", "animate a trajectory", [robot, pictures], run_animate)
    movie.add_argument("-o", "--output", type=Path, default=Path("trajectory.gif"))
    movie.add_argument("--fps", type=_at_least(1), default=20)
    movie.add_argument("--frames", type=_at_least(2), default=120, help="frames to draw")
    cal = command("calibrate", "fit wheel radii and track width to ground truth",
                  [robot], run_calibrate)  # fmt: skip
    cal.add_argument("runs", nargs="*", type=Path, help="runs with ground truth; none: built-in")
    cal.add_argument("-o", "--output", type=Path, default=Path("robot.toml"))
    cal.add_argument("--method", choices=CALIBRATION_METHODS, default="least_squares")
    cal.add_argument("--integration", choices=METHODS, default="rk2")
    cal.add_argument("--square-side", type=float, help="UMBmark's square, m")
    cal.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
    ev = command("evaluate", "a trajectory against ground truth", [], run_evaluate)
    ev.add_argument("input", nargs="?", type=Path, help="trajectory CSV; none: built-in")
    ev.add_argument("--truth", type=Path, help="ground-truth CSV at the same times")
    ev.add_argument("--rpe", type=float, default=1.0, help="RPE window (default 1)")
    ev.add_argument("--rpe-unit", choices=["m", "s", "poses"], default="m")
    ev.add_argument("--json", action="store_true")
    fk = command("fk", "wheel velocities to the body twist", [robot], run_fk)
    fk.add_argument("left", type=float, help="rad/s")
    fk.add_argument("right", type=float, help="rad/s")
    fk.add_argument("--json", action="store_true")
    ik = command("ik", "a body twist to wheel velocities", [robot], run_ik)
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
    try:
        return args.run(args)
    except (ValueError, TypeError, OSError) as exc:
        print(f"diffdrive {args.command}: error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
