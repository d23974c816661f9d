"""The ``diffdrive`` command line: the parser and ``main``; a module per subcommand.

With no arguments it runs the main job on a built-in example (``report``)."""

from __future__ import annotations

import argparse
import contextlib
import signal
import sys
import threading
from collections.abc import Sequence
from pathlib import Path

from diffdrive import __version__
from diffdrive.cli import (
    calibrate,
    calibrate_driving,
    calibrate_gyro,
    estimate,
    evaluate,
    export,
    identify,
    info,
    kinematics,
    learn,
    odometry,
    plan,
    plot,
    renamed,
    simulate,
    synth,
)
from diffdrive.cli.options import (
    Parents,
    log_options,
    robot_options,
)
from diffdrive.cli.report import example_outputs, kinematics_report, simulation_report
from diffdrive.demo import example_robot
from diffdrive.io import TIME_UNITS


def build_parser() -> argparse.ArgumentParser:
    """The `diffdrive` command line's parser: every subcommand, its options and its help."""
    parser = argparse.ArgumentParser(
        prog="diffdrive",
        description="Kinematics of differential-drive robots. With no arguments: the "
        "kinematics of a built-in example robot, and a simulation of its built-in driving "
        "history with each integration method.",
    )
    parser.add_argument("--version", action="version", version=f"diffdrive {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")
    formatter = argparse.RawDescriptionHelpFormatter

    def command(name: str, help: str, parents: list, run, epilog: str) -> argparse.ArgumentParser:
        sub = commands.add_parser(
            name,
            help=help,
            description=help,
            epilog=epilog,
            parents=parents,
            formatter_class=formatter,
        )
        sub.set_defaults(run=run)
        return sub

    times = argparse.ArgumentParser(add_help=False)
    times.add_argument("--time-unit", choices=TIME_UNITS, help="unit of the t column (default s)")
    times.add_argument(
        "--topic",
        metavar="TOPIC",
        help="for a bag: the trajectory's topic (nav_msgs/Odometry, "
        "sensor_msgs/NavSatFix) or tf:PARENT:CHILD",
    )
    times.add_argument("--truth-topic", metavar="TOPIC", help="for a bag: the truth's topic")
    pictures = argparse.ArgumentParser(add_help=False, parents=[times])
    pictures.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
    pictures.add_argument(
        "input", nargs="?", type=Path, help="trajectory (CSV, JSON lines, TUM); none: built-in"
    )
    parents = Parents(
        robot=robot_options(),
        logs=log_options(),
        times=times,
        pictures=pictures,
        robot_required=robot_options(required=True),
    )
    modules = (
        simulate,
        odometry,
        estimate,
        plot,
        calibrate,
        calibrate_gyro,
        calibrate_driving,
        evaluate,
        export,
        identify,
        info,
        learn,
        kinematics,
        synth,
        plan,
    )
    for module in modules:
        module.add_to(command, parents)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code (0 done, 1 failed, 2 misused)."""
    parser = build_parser()
    given = list(sys.argv[1:] if argv is None else argv)
    try:
        rewritten = renamed.today(given, lambda name: _options_of(parser, name))
    except renamed.MisspelledError as exc:
        parser.error(str(exc))
    for note in rewritten.notes:
        print(f"diffdrive: note: {note}", file=sys.stderr)
    args = parser.parse_args(rewritten.argv)
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
        code = args.run(args)
        sys.stdout.flush()  # here, not at exit: a closed pipe is then this handler's
        return code
    except BrokenPipeError:
        # The reader went away (``diffdrive info BAG | head -1``): nothing more to say to it.
        _quiet_stdout()
        return 141  # 128 + SIGPIPE, as a program the pipe killed
    except KeyboardInterrupt:
        print(f"diffdrive {args.command}: interrupted; no file was half-written", file=sys.stderr)
        return 130  # 128 + SIGINT
    except ImportError as exc:  # an optional part missing: its message names the extra
        print(f"diffdrive {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except (ValueError, TypeError, OSError) as exc:
        print(f"diffdrive {args.command}: error: {exc}", file=sys.stderr)
        return 1
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def _options_of(parser: argparse.ArgumentParser, command: str) -> dict[str, object]:
    """Each option string of ``parser``'s subcommand ``command`` (``"export amcl"``: a
    subcommand's own) with its ``nargs``; none for an unknown one."""
    for name in command.split():
        found = [
            action.choices[name]
            for action in parser._actions
            if isinstance(action, argparse._SubParsersAction) and name in action.choices
        ]
        if not found:
            return {}
        parser = found[0]
    return {option: known.nargs for known in parser._actions for option in known.option_strings}


def _quiet_stdout() -> None:
    """Point standard output at /dev/null: Python's flush at exit would fail on the closed
    pipe again and print a traceback."""
    import os

    with contextlib.suppress(OSError, ValueError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())


def _exit_on_sigterm():
    """Make SIGTERM unwind like Ctrl-C, so that a half-written output's temporary file goes;
    returns the handler it replaced (None where signals cannot be set: not the main thread)."""

    def terminate(signum, frame):
        raise SystemExit(128 + signum)

    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGTERM, terminate)


__all__ = ["build_parser", "kinematics_report", "main", "simulation_report"]
