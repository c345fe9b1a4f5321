"""mcap_recorder: record topics into a rosbag2-compatible MCAP bag (see rigid_body_sim.bag).

Subscriptions are raw (the CDR bytes go to disk untouched) and the node runs in a
SingleThreadedExecutor ``spin()`` with minimal callbacks: that is what lets Python keep
up with several kHz.

Subscriptions. The package's own topics (``KNOWN_TYPES``) are subscribed at start, reliable,
before any publisher exists: a simulator started with ``wait_for_subscribers`` then sees
this recorder matched before its t = 0, and the bag holds every sample from the first.
Any other topic is subscribed once a publisher is seen, with a QoS compatible with all its
publishers (like rosbag2); a topic subscribed early whose publishers turn out to offer
best effort, or another type, is subscribed again to match them. So is one whose
publishers all keep a transient-local history (the controller's commands in lockstep),
to get that history: its messages are not recorded from the early subscription, so the
bag gets every one, once and in order, even from a publisher discovered late. A topic is
added to the bag at its first message, with the QoS its publishers offer (stored like
rosbag2).

Matched publishers. ``~/matched_publishers`` says what it records and which publishers it
has matched (``matches.py``): a simulator in lockstep waits for it before t = 0.
"""
from __future__ import annotations

import datetime
import os
import sys
import time
from typing import Any, Callable

import rclpy
import rclpy.logging
from rclpy.clock import Clock, ClockType
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from rigid_body_sim.bag.errors import BagError
from rigid_body_sim.bag.recover import recovered_copy, unfinished_files
from rigid_body_sim.bag.reader import recover_hint
from rigid_body_sim.bag.schema import (DEFAULT_QOS_YAML, TypeNotFound, message_class,
                                       qos_to_dict, qos_yaml)
from rigid_body_sim.bag.writer import BagWriter
from rigid_body_sim.node_interfaces import (DEFAULT_OUTPUT_DIR, RECORDED_BY_DEFAULT,
                                            RECORDED_TYPES, RECORDER_PARAMETERS)
from rigid_body_sim.nodes import matches
from rigid_body_sim.nodes.matches import hidden, latched as _latched
from rigid_body_sim.nodes.process import signals_ignored, start_ros
from rigid_body_sim.nodes.recorder_config import fetch_simulator_parameters

# The default topics, their types (subscribed at start, before their publishers exist) and
# the parameters are data, shared with the docs' reference.
DEFAULT_TOPICS = RECORDED_BY_DEFAULT
KNOWN_TYPES = RECORDED_TYPES
# Messages taken per callback beyond the one the executor delivered (see _callback).
DRAIN_LIMIT = 200


class Recorder(Node):
    """Node ``mcap_recorder``; parameters: ``node_interfaces.RECORDER_PARAMETERS``."""

    def __init__(self) -> None:
        super().__init__('mcap_recorder')
        for spec in RECORDER_PARAMETERS:  # the specs recorder --help prints (nodes/usage.py)
            self.declare_parameter(spec.name, spec.default)
        get = self.get_parameter

        self._all = bool(get('all').value)
        self._wanted = {self.resolve_topic_name(t) for t in get('topics').value if t}
        self._exclude = {self.resolve_topic_name(t) for t in get('exclude').value if t}
        self._depth = int(get('qos_depth').value)
        self._sim_time = bool(get('use_sim_time').value)
        output = get('output').value or os.path.join(
            DEFAULT_OUTPUT_DIR, f'rigid_body_sim_{datetime.datetime.now():%Y_%m_%d-%H_%M_%S}')
        self._warn_unfinished(os.path.abspath(output))
        self.writer = BagWriter(output, name=get('name').value or None,
                                max_bag_duration=float(get('max_bag_duration').value),
                                max_bag_size=int(get('max_bag_size').value),
                                flush_period=float(get('flush_period').value),
                                compression=get('compression').value)
        try:
            self._start(get)
        except BaseException:
            # Ctrl-C during start-up (rclpy shuts the context down under a call, which then
            # raises) must still leave a finished bag, not an MCAP without its summary
            with signals_ignored():
                self.writer.close()
            raise

    def _start(self, get) -> None:
        self.get_logger().info(f'recording to {self.writer.directory} '
                               f'({"all topics" if self._all else sorted(self._wanted)})')
        self._subs: dict[str, Any] = {}
        self._record: dict[str, Callable[[bytes, dict], None]] = {}
        self._skipped: set[str] = set()
        self._early: set[str] = set()  # subscribed before any publisher was seen
        self._replayed: set[str] = set()  # early, its publishers' history to be asked for
        self._added: set[str] = set()  # in the bag
        self._before_clock: list[tuple[str, bytes, dict]] = []  # use_sim_time, no /clock yet
        # Same keys as the offline run's bag (rigid_body_sim.offline) where they overlap.
        self._config: dict[str, Any] = {'mode': 'live', 'scene': get('scene').value or None,
                                        'recorder': self._own_parameters()}
        self.writer.add_run_configuration(self._config)

        # Wall-clock timers: under use_sim_time a stalled /clock must not stop flushing.
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        # the report before the subscriptions: a simulator that sees them sees it too
        self._report = matches.Report(self)
        self._report_changed = time.monotonic()  # the report's last change (its pace)
        flush_period = float(get('flush_period').value)
        self.create_timer(max(0.01, flush_period / 4), self.writer.flush_if_due, clock=steady)
        self._subscribe_known()
        self._discovery = self.create_timer(float(get('discovery_period').value),
                                            self._discover, clock=steady)
        self._discover()
        self._report_timer = self.create_timer(matches.PERIOD_S, self._report_matches,
                                               clock=steady)
        self._report_matches()
        fetch_simulator_parameters(self, get('simulator_node').value,
                                   float(get('config_timeout').value), steady, self._config,
                                   self.writer)

    # --- topics --------------------------------------------------------------------

    def _subscribe_known(self) -> None:
        """Subscribe now to the wanted topics whose type we know (the nodes' own), so that
        a publisher waiting for subscribers finds this recorder matched before it starts."""
        for name, type_name in KNOWN_TYPES.items():
            topic = self.resolve_topic_name(name)
            if topic not in self._wanted or topic in self._exclude:
                continue
            try:
                message_class(type_name)
            except TypeNotFound:  # e.g. /tf without tf2_msgs: left to discovery
                continue
            self._subscribe(topic, type_name, [])
            self._early.add(topic)

    def _discover(self) -> None:
        for topic, types in self.get_topic_names_and_types():
            if topic in self._skipped or topic in self._exclude or \
                    topic == self._report.pub.topic_name:
                continue
            if topic in self._subs and topic not in self._early:
                continue
            if not (topic in self._wanted or (self._all and not hidden(topic))):
                continue
            publishers = self.get_publishers_info_by_topic(topic)
            if not publishers:  # QoS and type come from the publishers
                continue
            if topic in self._early:
                self._early.discard(topic)
                try:
                    same = self._subs[topic].msg_type is message_class(publishers[0].topic_type)
                except TypeNotFound:
                    same = False
                if same and all(p.qos_profile.reliability == ReliabilityPolicy.RELIABLE
                            for p in publishers) and (topic in self._added or not _latched(
                                publishers)):
                    continue  # the early subscription matches them
                self.get_logger().info(f'{topic}: its publishers offer another type, best '
                                       'effort or a history; subscribing again to match them')
                self.destroy_subscription(self._subs.pop(topic))
                self._replayed.discard(topic)
            self._subscribe(topic, publishers[0].topic_type, publishers)
        if not self._all and self._wanted <= (set(self._subs) - self._early) | self._skipped:
            self._discovery.cancel()

    def _report_matches(self) -> None:
        """Publish ``~/matched_publishers`` when it changed (matches.py); look again at
        matches.PERIOD_S after a change, at QUIET_PERIOD_S once they are settled."""
        changed = self._report.update(self._subs, self._wanted - self._exclude - self._skipped,
                                      self._early, self._all, self._exclude)
        now = time.monotonic()
        if changed:
            self._report_pace(True)
        elif now - self._report_changed > matches.SETTLE_S:
            self._report_pace(False)

    def _report_pace(self, fast: bool) -> None:
        """Look at the matches every PERIOD_S (``fast``) or QUIET_PERIOD_S from now on."""
        if fast:
            self._report_changed = time.monotonic()
        period = matches.PERIOD_S if fast else matches.QUIET_PERIOD_S
        timer = getattr(self, '_report_timer', None)
        if timer is None or timer.timer_period_ns == int(period * 1e9):
            return
        timer.timer_period_ns = int(period * 1e9)
        timer.reset()  # the next look one new period from now, not at the old schedule's
        self.get_logger().debug(f'looking at the matched publishers every {period:g} s')

    def _subscribe(self, topic: str, type_name: str, publishers: list[Any]) -> None:
        """Subscribe ``topic``; with ``publishers`` (discovered) the QoS is chosen to match
        them, without (subscribed early) it is reliable, volatile, ``qos_depth`` deep."""
        try:
            msg_type = message_class(type_name)
        except TypeNotFound as exc:
            self.get_logger().warning(f'not recording {topic}: {exc}')
            self._skipped.add(topic)
            return
        offered = [p.qos_profile for p in publishers]
        # Like rosbag2: request the strongest policy every publisher offers.
        reliable = all(q.reliability == ReliabilityPolicy.RELIABLE for q in offered)
        latched = bool(offered) and _latched(publishers)
        # Subscribed early (the nodes' own, reliable topics): keep all, so that a burst (a
        # run as fast as possible) waits in the publisher until this node has taken it,
        # instead of overwriting what it has not taken yet.
        qos = QoSProfile(
            history=HistoryPolicy.KEEP_LAST if offered else HistoryPolicy.KEEP_ALL,
            depth=max([self._depth] + [q.depth for q in offered]),
            reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
            durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)
        subscription = self.create_subscription(msg_type, topic, lambda *_: None, qos, raw=True)
        self._report_pace(True)  # its publishers are matched within moments: look often
        self._record[topic] = self._recorder(topic, type_name)
        subscription.callback = self._callback(topic, subscription)
        self._subs[topic] = subscription
        self.get_logger().info(f'subscribed to {topic} [{type_name}]')

    def _add_to_bag(self, topic: str, type_name: str) -> bool:
        """Add ``topic`` to the bag (at its first message), with the QoS its publishers
        offer; False, with a warning, if it cannot be recorded."""
        publishers = self.get_publishers_info_by_topic(topic)
        try:
            self.writer.add_topic(topic, type_name, qos_yaml(
                qos_to_dict(p.qos_profile) for p in publishers) if publishers
                else DEFAULT_QOS_YAML)
        except (TypeNotFound, BagError) as exc:
            self.get_logger().warning(f'not recording {topic}: {exc}')
            self._skipped.add(topic)
            return False
        self._added.add(topic)
        return True

    def _replay_instead(self, topic: str) -> bool:
        """At the first message of an early subscription: True if its publishers all keep
        a transient-local history, which the subscription that replaces it will get
        (_discover), so that nothing is recorded here (it would come twice, out of order)."""
        if topic in self._replayed:
            return True
        if topic in self._early and _latched(self.get_publishers_info_by_topic(topic)):
            self._replayed.add(topic)
            return True
        return False

    def _callback(self, topic: str, subscription: Any) -> Callable[[bytes, dict], None]:
        """The per-message path: stamp and append the raw bytes, nothing else.

        The executor costs far more per wake-up than the write, so each callback also
        drains what is already queued on the subscription (bounded, to stay fair).
        """
        handle, msg_type = subscription.handle, subscription.msg_type
        record = self._record[topic]

        def on_message(data: bytes, info: dict) -> None:
            record(data, info)
            with handle:
                for _ in range(DRAIN_LIMIT):
                    taken = handle.take_message(msg_type, True)
                    if taken is None:
                        return
                    record(*taken)
        return on_message

    def _recorder(self, topic: str, type_name: str) -> Callable[[bytes, dict], None]:
        write = self.writer.write
        clock = self.get_clock()
        sim_time = self._sim_time
        before_clock = self._before_clock
        state = {'added': None}  # None until the first message: then True, or False (refused)

        def record(data: bytes, info: dict) -> None:
            if not state['added']:
                if state['added'] is False or self._replay_instead(topic):
                    return
                state['added'] = self._add_to_bag(topic, type_name)
                if not state['added']:
                    return
            if sim_time:
                stamp = clock.now().nanoseconds
                if stamp == 0:  # no /clock yet: held until it comes (topics subscribed at
                    before_clock.append((topic, data, info))  # start can beat it)
                    return
                if before_clock:
                    self._write_before_clock(stamp)
            else:
                stamp = info.get('received_timestamp') or time.time_ns()
            write(topic, data, stamp, info.get('source_timestamp'))
        return record

    def _write_before_clock(self, stamp: int) -> None:
        """Messages that arrived before the first /clock, logged at the first sim time
        (with no clock at all, at 0 when the bag closes): none is lost, and none is logged
        before the replayed timeline starts."""
        held, self._before_clock[:] = list(self._before_clock), []
        for topic, data, info in held:
            self.writer.write(topic, data, stamp, info.get('source_timestamp'))

    # --- run configuration ---------------------------------------------------------

    def _own_parameters(self) -> dict[str, Any]:
        names = self.list_parameters([], 0).names
        return {p.name: p.value for p in self.get_parameters(names)}

    # --- lifecycle -----------------------------------------------------------------

    def _warn_unfinished(self, output: str) -> None:
        """Unfinished files (a killed recorder) in the output or sibling bags: say how to
        recover them; they are never touched."""
        parent = os.path.dirname(output)
        found = sorted(set(unfinished_files(output)) | set(unfinished_files(parent)))
        for path in found:
            copy = recovered_copy(path)
            if copy:  # bag recover made it: no need to say it again at every start
                self.get_logger().info(f'unfinished bag file {path} was recovered into {copy}')
                continue
            # A file inside a bag directory: recover the whole bag (gets a metadata.yaml).
            target = path if os.path.dirname(path) == parent else os.path.dirname(path)
            self.get_logger().warning(f'unfinished bag file {path} (recorder killed?); '
                                      f'recover it with: {recover_hint(target)}')

    def drain(self) -> None:
        """Write what is still queued in the subscriptions (a backlog at shutdown)."""
        for topic, sub in self._subs.items():
            try:
                with sub.handle:
                    while (taken := sub.handle.take_message(sub.msg_type, True)) is not None:
                        self._record[topic](*taken)
            except Exception:  # handle already gone: nothing left to save
                pass

    def close(self) -> None:
        self.drain()
        if self._before_clock:
            self._write_before_clock(self.get_clock().now().nanoseconds)
        self.writer.close()
        counts = self.writer.topic_counts()
        # After SIGINT the context is gone: log without the /rosout publisher.
        rclpy.logging.get_logger('rigid_body_sim.recorder').info(
            f'wrote {sum(counts.values())} messages to {self.writer.directory}: {counts}')


def main(argv: list[str] | None = None) -> int:
    code = start_ros('mcap_recorder', argv)  # stops between callbacks: never inside a write
    if code is not None:
        return code
    node = executor = None
    code = 0
    try:
        node = Recorder()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except BagError as exc:
        print(f'error: {exc}', file=sys.stderr)
        code = 1
    except Exception:
        if rclpy.ok():  # not a shutdown by SIGINT/SIGTERM in the middle of a call
            raise
    finally:
        with signals_ignored():  # the bag is finished even if Ctrl-C comes again
            if node is not None:
                try:
                    node.close()
                except BagError as exc:
                    print(f'error: {exc}', file=sys.stderr)
                    code = 1
                node.destroy_node()
            if executor is not None:
                # before the context goes: collected after it, the executor's __del__
                # destroys a guard condition the shutdown already took and prints an
                # "Exception ignored ... InvalidHandle" traceback (a launch group's
                # double Ctrl-C, 1 in 2 runs of test_signals in one suite)
                executor.shutdown(timeout_sec=0)
            rclpy.try_shutdown()
    return code


if __name__ == '__main__':
    sys.exit(main())
