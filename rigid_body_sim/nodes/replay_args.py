"""replay's command line, free of ROS: ``replay --help`` is answered from here before
rclpy is imported (``nodes.usage``), and ``nodes.replay`` parses with the same parser."""
from __future__ import annotations

import argparse

from .. import command
from ..cli import ArgumentParser, number

DESCRIPTION = ('Publish a recorded bag again: each message on its topic with its recorded '
               'type and offered QoS, as the stored bytes, spaced by log time. Node name: '
               'mcap_replay. Topics: the bag\'s (or --topics), remappable with --remap; '
               '/clock from log time with --clock. ROS arguments go after --ros-args.')


def parser() -> argparse.ArgumentParser:
    exe = command('replay')
    p = ArgumentParser(prog=exe, description=DESCRIPTION,
                       epilog=f'Example: {exe} out/my_run --rate 2 --clock')
    p.add_argument('path', help='bag directory or .mcap file')
    p.add_argument('--rate', type=number(0.0, 1e6, low_open=True), default=1.0,
                   help='playback speed factor (default 1)')
    p.add_argument('--loop', action='store_true', help='play again when the bag ends')
    p.add_argument('--start-offset', type=number(0.0), default=0.0, metavar='S',
                   help='skip the first S seconds of the bag (default 0)')
    p.add_argument('--topics', nargs='+', metavar='TOPIC', help='only these topics')
    p.add_argument('--remap', action='append', default=[], metavar='OLD:=NEW',
                   help='publish topic OLD as NEW (repeatable)')
    p.add_argument('--clock', nargs='?', type=number(0.0, 1e6), const=100.0, default=0.0,
                   metavar='HZ', help='publish /clock from log time (default 100 Hz)')
    p.add_argument('--delay', type=number(0.0, 3600.0), default=0.5, metavar='S',
                   help='wait S seconds after creating publishers so subscribers match '
                        '(default 0.5)')
    p.add_argument('--wait-for-subscribers', type=number(0.0, 1e6), default=0.0,
                   metavar='S',
                   help='wait up to S seconds until every replayed topic has a subscriber')
    return p


def parse_args(argv: list[str]) -> argparse.Namespace:
    p = parser()
    args = p.parse_args(argv)
    for item in args.remap:
        if ':=' not in item:
            p.error(f'--remap expects OLD:=NEW, got {item!r}')
    return args


def split_ros_args(argv: list[str]) -> tuple[list[str], list[str]]:
    """(our arguments, ROS arguments). Done by hand: rcl would swallow ``--remap a:=b``
    values as deprecated bare remap rules."""
    ours, ros, in_ros = [], [], False
    for arg in argv[1:]:
        if arg == '--ros-args':
            in_ros = True
        elif arg == '--' and in_ros:
            in_ros = False
            continue
        (ros if in_ros else ours).append(arg)
    return ours, argv[:1] + ros
