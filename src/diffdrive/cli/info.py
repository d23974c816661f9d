"""``diffdrive info``: what a ROS bag or MCAP file holds."""

from __future__ import annotations

import argparse


def run_info(args: argparse.Namespace) -> int:
    from diffdrive import ros

    found = ros.topics(args.input)
    print(f"{args.input}: {len(found)} topics")
    print(f"{'topic':32} {'type':32} {'messages':>8} {'Hz':>7}  use")
    for topic in found:
        print(f"{topic.name:32} {topic.msgtype:32} {topic.count:8} {topic.rate:7.2f}  {topic.use}")
    return 0
