"""``diffdrive info``: what a ROS bag or MCAP file holds."""

from __future__ import annotations

import argparse
from pathlib import Path

from diffdrive.cli.options import (
    Command,
    Parents,
)


def run_info(args: argparse.Namespace) -> int:
    from diffdrive.io import ros

    found = ros.topics(args.input)
    print(f"{args.input}: {len(found)} topics")
    print(f"{'topic':32} {'type':32} {'messages':>8} {'Hz':>7}  use")
    for topic in found:
        use = topic.use
        if topic.msgtype == "sensor_msgs/msg/JointState" and topic.count:
            use += f" (joints: {', '.join(ros.joint_names(args.input, topic.name))})"
        print(f"{topic.name:32} {topic.msgtype:32} {topic.count:8} {topic.rate:7.2f}  {use}")
    return 0


EPILOGS = {
    "info": """example:
  diffdrive info robot.bag      topics, types, counts, rates, and which diffdrive can use""",
}


def add_to(command: Command, parents: Parents) -> None:
    """The options of ``diffdrive info``."""
    info = command(
        "info",
        "what a ROS bag or MCAP file holds, and what diffdrive can use",
        [],
        run_info,
        EPILOGS["info"],
    )
    info.add_argument("input", type=Path, help="a ROS 1 bag, ROS 2 bag folder or MCAP file")
