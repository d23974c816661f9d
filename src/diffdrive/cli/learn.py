"""``diffdrive learn``: the interactive page for learning the kinematics."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from diffdrive.cli.options import (
    Command,
    Parents,
    between,
)


def run_learn(args: argparse.Namespace) -> int:
    from diffdrive import learn

    reason = learn.missing_extra()
    if reason is not None:
        print(f"diffdrive learn: error: {reason}", file=sys.stderr)
        return 1
    if args.export is not None:
        learn.export_page(args.export)
        print(f"wrote {args.export}: a static snapshot (it loads marimo's scripts from a CDN)")
        return 0
    return learn.serve(args.port, browser=not args.no_browser)


EPILOGS = {
    "learn": """examples:
  diffdrive learn                 serve the page on this machine and open it in the browser
  diffdrive learn --no-browser --port 2718     serve only; open http://127.0.0.1:2718
  diffdrive learn --export page.html           a static snapshot for a course website
needs the extra: pip install 'diffdrive[learn]'""",
}


def add_to(command: Command, parents: Parents) -> None:
    """The options of ``diffdrive learn``."""
    learn = command(
        "learn",
        "an interactive page for learning the kinematics, in the browser",
        [],
        run_learn,
        EPILOGS["learn"],
    )
    learn.add_argument("--port", type=between(1, 65535), help="port (default: a free one)")
    learn.add_argument("--no-browser", action="store_true", help="serve without opening it")
    learn.add_argument("--export", type=Path, metavar="HTML", help="write a static snapshot")
