"""replay: publish a recorded bag again (``replay PATH [options]``; ``replay --help``).

Each message goes out on its topic with its recorded type and offered QoS, as the stored
serialized bytes (no deserialize/re-serialize), spaced by log time. ``--clock`` publishes
``/clock`` from the log time so ``use_sim_time`` nodes follow the recording.
"""
from __future__ import annotations

import argparse
import sys
import time
from typing import Any

# imported here, not in main: a Ctrl-C while they load lands in nodes.entry's quiet exit
import rclpy
import rclpy.logging
from rclpy.executors import ExternalShutdownException

from rigid_body_sim.bag.errors import BagError

from .process import signals_ignored, start_ros
from .replay_args import parse_args, split_ros_args  # noqa: F401 (tests use them from here)

NODE_NAME = 'mcap_replay'


def _absolute(topic: str) -> str:
    return topic if topic.startswith('/') else '/' + topic


class Player:
    """Publishers for the playable topics of one bag, and the timed playback loop."""

    def __init__(self, node: Any, args: argparse.Namespace) -> None:
        from rigid_body_sim.bag.reader import read_info
        from rigid_body_sim.bag.schema import (TypeNotFound, message_class, parse_qos_yaml,
                                               qos_from_dict)
        self.node, self.args = node, args
        self.info = read_info(args.path)
        remap = dict(item.split(':=', 1) for item in args.remap)
        remap = {_absolute(k): _absolute(v) for k, v in remap.items()}
        wanted = {_absolute(t) for t in args.topics} if args.topics else None
        if wanted:
            for topic in sorted(wanted - set(self.info.topics)):
                node.get_logger().warning(f'topic {topic} is not in the bag')
        self.publishers: dict[str, Any] = {}
        for name, topic in sorted(self.info.topics.items()):
            if (wanted is not None and name not in wanted) or (args.clock and name == '/clock'):
                continue
            try:
                msg_type = message_class(topic.type)
            except TypeNotFound as exc:
                node.get_logger().warning(f'skipping {name}: {exc}')
                continue
            offered = parse_qos_yaml(topic.offered_qos_profiles)
            qos = qos_from_dict(offered[0] if offered else {})
            self.publishers[name] = node.create_publisher(msg_type, remap.get(name, name), qos)
        if not self.publishers:
            raise BagError(f'{args.path}: no playable topics')
        self.clock_pub = None
        if args.clock:
            from rclpy.qos import QoSProfile
            from rosgraph_msgs.msg import Clock
            self.clock_pub = node.create_publisher(Clock, '/clock', QoSProfile(depth=1))
            self._clock_msg = Clock()
        self.published = 0

    def message_count(self) -> int:
        """The messages of the replayed topics (not the whole bag's)."""
        return sum(self.info.topics[name].count for name in self.publishers)

    def sleep(self, seconds: float) -> None:
        """Sleep, in slices: a Ctrl-C shuts the context down and ends the wait."""
        deadline = time.monotonic() + seconds
        while self.node.context.ok() and time.monotonic() < deadline:
            time.sleep(min(0.05, max(0.0, deadline - time.monotonic())))

    def wait_for_subscribers(self, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        waiting = dict(self.publishers)
        while waiting and time.monotonic() < deadline and self.node.context.ok():
            waiting = {t: p for t, p in waiting.items() if p.get_subscription_count() == 0}
            time.sleep(0.02)
        if waiting and timeout > 0:
            self.node.get_logger().warning(f'no subscriber yet on {sorted(waiting)}; playing')
        elif timeout > 0:
            time.sleep(0.2)  # the subscriber side may still be matching our writers

    def wait_for_acks(self, timeout: float) -> None:
        """Before exiting: let reliable subscribers get (or re-request) the last messages."""
        from rclpy.duration import Duration
        deadline = time.monotonic() + timeout
        for pub in self.publishers.values():
            left = deadline - time.monotonic()
            if left <= 0 or not self.node.context.ok():
                return
            pub.wait_for_all_acked(Duration(nanoseconds=int(left * 1e9)))

    def _publish_clock(self, stamp_ns: int) -> None:
        self._clock_msg.clock.sec, self._clock_msg.clock.nanosec = divmod(stamp_ns, 10**9)
        self.clock_pub.publish(self._clock_msg)

    def _wait_until(self, wall_ns: int, bag_origin: int, wall_origin: int) -> None:
        """Sleep until ``wall_ns`` (monotonic), ticking /clock meanwhile when enabled."""
        tick = int(1e9 / self.args.clock) if self.clock_pub else 100_000_000
        while self.node.context.ok():
            now = time.monotonic_ns()
            if now >= wall_ns:
                return
            if self.clock_pub:
                self._publish_clock(bag_origin + int((now - wall_origin) * self.args.rate))
            time.sleep(min(wall_ns - now, tick) / 1e9)

    def play_once(self) -> None:
        from rigid_body_sim.bag.reader import iter_messages
        start = self.info.start_ns + int(self.args.start_offset * 1e9)
        bag_origin = wall_origin = None
        for msg in iter_messages(self.args.path, topics=list(self.publishers), start_ns=start):
            if not self.node.context.ok():
                return
            if bag_origin is None:
                bag_origin, wall_origin = msg.log_time_ns, time.monotonic_ns()
            target = wall_origin + int((msg.log_time_ns - bag_origin) / self.args.rate)
            self._wait_until(target, bag_origin, wall_origin)
            if self.clock_pub:
                self._publish_clock(msg.log_time_ns)
            self.publishers[msg.topic].publish(msg.data)
            self.published += 1


def main(argv: list[str] | None = None) -> int:
    ours, ros_args = split_ros_args(sys.argv if argv is None else argv)
    args = parse_args(ours)
    code = start_ros(NODE_NAME, ros_args)  # Ctrl-C from here on: a quiet stop
    if code is not None:
        return code
    node = None
    code = 0
    try:
        node = rclpy.create_node(NODE_NAME)
        player = Player(node, args)
        node.get_logger().info(f'playing {args.path}: {len(player.publishers)} topics, '
                               f'{player.message_count()} messages, rate {args.rate}')
        player.sleep(args.delay)
        player.wait_for_subscribers(args.wait_for_subscribers)
        while node.context.ok():
            player.play_once()
            if not args.loop:
                break
        player.wait_for_acks(2.0)
        rclpy.logging.get_logger('rigid_body_sim.replay').info(
            f'published {player.published} messages')
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except BagError as exc:
        print(f'error: {exc}', file=sys.stderr)
        code = 1
    except Exception as exc:  # shutdown mid-publish and the like: no traceback
        if rclpy.ok():
            print(f'error: {type(exc).__name__}: {exc}', file=sys.stderr)
            code = 1
    finally:
        with signals_ignored():
            if node is not None:
                node.destroy_node()
            rclpy.try_shutdown()
    return code


if __name__ == '__main__':
    sys.exit(main())
