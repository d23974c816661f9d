"""``diffdrive learn``: the interactive page for learning the kinematics."""

from __future__ import annotations

import argparse
import sys


def run_learn(args: argparse.Namespace) -> int:
    from diffdrive import learn

    reason = learn.missing_extra()
    if reason is not None:
        print(f"diffdrive learn: error: {reason}", file=sys.stderr)
        return 1
    if args.export is not None:
        learn.export(args.export)
        print(f"wrote {args.export}: a static snapshot (it loads marimo's scripts from a CDN)")
        return 0
    return learn.serve(args.port, browser=not args.no_browser)
