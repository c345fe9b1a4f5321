"""What holds the simulator's time: lockstep's control instants, and the wait for
subscribers before t = 0. A mixin of the node (``simulator.py``), which owns the state
(``_held``, ``_instant``, ...)."""
import json
import time

from ..engine import NS

# wait_for_subscribers: the counts must hold this long, as the replies of the peers already
# running to a new participant's announcement arrive within a few milliseconds of each other
SUBSCRIBER_SETTLE_S = 0.2
# a recorder's report of the publishers it has matched (nodes/recorder.py: MATCHED_TOPIC)
MATCHED_SUFFIX = '/matched_publishers'


def _fqn(namespace: str, name: str) -> str:
    return f'/{namespace.strip("/")}/{name}'.replace('//', '/')




class Holds:
    """Lockstep (module docstring of ``simulator.py``) and ``wait_for_subscribers``."""

    def _hold(self):
        """The state of control instant ``_instant`` is out: hold until its command."""
        self._held, self._held_since = self._instant, time.monotonic()
        self._paused_reported = False
        self._round_trips.sent()

    def _check_held(self, now) -> float:
        """Held: after ``lockstep_timeout`` report the pause once (log and diagnostics);
        never guess a command. Returns the executor's wait."""
        late = now - self._held_since - self._p['lockstep_timeout']
        if late < 0:
            return -late
        if not self._paused_reported:
            self._paused_reported = True
            self._lockstep_pauses += 1
            self._log.warning(f'lockstep: paused at t = {self._held / NS:.9g} s: no command '
                              f'stamped {self._held_stamp()} for {self._p["lockstep_timeout"]:g}'
                              ' s (lockstep_timeout); waiting for it, nothing is extrapolated')
            self._publish_diagnostics()
        return 0.1

    @property
    def lockstep_held(self):
        """Lockstep holding a control instant for its command: why, in words; else None."""
        if not self._lockstep or self._held is None:
            return None
        return (f'lockstep holds t = {self._held / NS:.9g} s until the command stamped '
                f'{self._held_stamp()} arrives')

    def _held_stamp(self) -> str:
        sec, nsec = divmod(self.stamp_ns(self._held), NS)
        return f'{sec}.{nsec:09d}'

    def _on_lockstep_command(self, header, vector, source):
        """Apply the command for the held instant; any other is counted and rejected
        (stale: an instant already answered; unexpected: no instant held with that stamp)."""
        stamp = header.stamp.sec * NS + header.stamp.nanosec
        if self._held is not None and stamp == self.stamp_ns(self._held):
            self.engine.apply_command((vector.x, vector.y, vector.z))
            self._round_trips.applied()
            if self._paused_reported:
                self._log.info(f'lockstep: command for t = {self._held / NS:.9g} s arrived '
                               f'after {time.monotonic() - self._held_since:.3g} s; resuming')
                self._anchor()  # real time: pace on from here, not catching up on the pause
            self._held, self._instant = None, self._instant + self._lockstep
            return
        last = self.stamp_ns(self._instant - self._lockstep)
        reason = 'lockstep_stale' if stamp <= last else 'lockstep_unexpected'
        held = f'the held instant\'s stamp is {self._held_stamp()}' if self._held is not None \
            else 'no control instant is held'
        self.crafts[0].commands.reject(reason, source, f'stamp {header.stamp.sec}.'
                              f'{header.stamp.nanosec:09d}: {held}')

    def _lockstep_values(self) -> dict:
        held = self._held is not None
        return {'lockstep_paused': held and self._paused_reported,
                'lockstep_held_since_s': time.monotonic() - self._held_since if held else 0.0,
                'lockstep_pauses': self._lockstep_pauses, **self._round_trips.values()}

    def _controller_ready(self, pubs) -> bool:
        """A command topic has a matched publisher whose node this process has seen
        subscribe to a state topic: the controller is discovered, so the rule that every
        discovered subscription be matched now covers its state subscriptions too (the
        subscriber count alone is met by a recorder while the controller is still unknown,
        and the controller then misses the first samples under load)."""
        from rclpy._rclpy_pybind11 import RCLError
        from rclpy.node import NodeNameNonExistentError
        state = {p.topic_name for p in pubs}
        subs = self._command_subs + [s for c in self._crafts.values() for s in c.command_subs]
        for sub in subs:
            if not sub.get_publisher_count():
                continue
            for info in self.get_publishers_info_by_topic(sub.topic_name):
                ns = info.node_namespace  # may come without its leading '/'
                try:
                    topics = self.get_subscriber_names_and_types_by_node(
                        info.node_name, ns if ns.startswith('/') else '/' + ns)
                except (NodeNameNonExistentError, RCLError):  # gone, or not a ROS node
                    continue
                if any(name in state for name, _ in topics):
                    return True
        return False

    def _recorders_unmatched(self, reports) -> list:
        """Lockstep: the command topics a recorder subscribes to whose controllers (the
        publishers this node sees there) the recorder has not matched yet, by its report
        ``<recorder>/matched_publishers`` (``reports``: {report topic: its subscription and
        last report}, filled here). Without this wait a run as fast as possible could end,
        and its controller be stopped with its history, before the recorder and the
        controller discovered each other: the bag then held no command (1 run in ~10)."""
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from std_msgs.msg import String
        for topic, _ in self.get_topic_names_and_types():
            if topic.endswith(MATCHED_SUFFIX) and topic not in reports:
                entry = reports[topic] = {'report': None}
                entry['sub'] = self.create_subscription(
                    String, topic, lambda m, e=entry: e.update(report=json.loads(m.data)),
                    QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                               durability=DurabilityPolicy.TRANSIENT_LOCAL))
        from .recorder import hidden
        out = []
        for sub in self._lockstep_command_subs():
            name = sub.topic_name
            controllers = {_fqn(p.node_namespace, p.node_name)
                           for p in self.get_publishers_info_by_topic(name)}
            for topic, entry in reports.items():
                report = entry['report']
                if report is None:  # its report is on its way (transient local)
                    out.append(topic)
                    continue
                matched = report['matched']
                records = name in matched or (report['all'] and not hidden(name)
                                              and name not in report['exclude'])
                if records and not controllers <= set(matched.get(name, [])):
                    out.append(f'{name} (by {topic[:-len(MATCHED_SUFFIX)]})')
        return out

    def _lockstep_command_subs(self):
        """The command subscriptions whose commands lockstep waits for."""
        return [s for s in self._command_subs if s.topic_name.endswith('/torque_command')]

    def _wait_for_subscribers(self, executor):
        """Hold t = 0 until every state publisher has ``wait_for_subscribers`` matched
        subscriptions (a recorder subscribed at its start: the bag then holds every sample
        from the first), or ``wait_for_subscribers_timeout`` has passed: then start anyway,
        with a warning naming the topics still without them."""
        n = self._p['wait_for_subscribers']
        controller = self._lockstep or self._p['wait_for_controller']
        if n <= 0 and not controller:
            return
        pubs = list({id(p): p for c in self._crafts.values() for p in c.publishers()}.values())

        def missing():
            """Topics with fewer than n matched subscriptions, or with one discovered but
            not matched yet (discovery delivers a node's subscriptions one by one); with a
            controller awaited, also a command topic without one (_controller_ready)."""
            return [p.topic_name for p in pubs if p.get_subscription_count() < max(
                n, len(self.get_subscriptions_info_by_topic(p.topic_name)))] + (
                [self._command_subs[0].topic_name]
                if controller and not self._controller_ready(pubs) else []) + (
                self._recorders_unmatched(reports) if self._lockstep else [])
        reports = {}
        timeout = self._p['wait_for_subscribers_timeout']
        self._log.info(f'waiting up to {timeout:g} s for {n} matched subscription(s) on each '
                       f'of {len(pubs)} state topics before t = 0 (wait_for_subscribers)'
                       + (' and a controller on torque_command ('
                          + ('lockstep)' if self._lockstep else 'wait_for_controller)')
                          if controller else ''))
        now = time.monotonic()
        deadline, settled = now + timeout, now + SUBSCRIBER_SETTLE_S
        paused, self.paused = self.paused, True  # commands arriving meanwhile advance nothing
        while self.context.ok() and time.monotonic() < deadline and self._quit_at is None:
            if missing():
                settled = time.monotonic() + SUBSCRIBER_SETTLE_S
            elif time.monotonic() >= settled:
                break
            executor.spin_once(timeout_sec=0.02)
        self.paused = paused
        left = missing()
        for entry in reports.values():  # read before t = 0 only
            self.destroy_subscription(entry['sub'])
        if left:
            self._log.warning(f'starting at t = 0 without {n} subscription(s) on '
                              f'{", ".join(left)} after {timeout:g} s (wait_for_subscribers); '
                              'they miss the first samples')
        else:
            self._log.info('every state topic has its subscribers; starting at t = 0')
        self._refresh_subscribers()
        self._last_diag = (time.monotonic(), self.t_ns)  # the rate leaves the wait out
