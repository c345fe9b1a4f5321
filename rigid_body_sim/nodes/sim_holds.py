"""What holds the simulator's time: lockstep's control instants, and the wait for
subscribers before t = 0. A mixin of the node (``simulator.py``), which owns the state
(``_held``, ``_instant``, ...)."""
import time

from ..engine import NS
from . import matches

# wait_for_subscribers: the counts must hold this long, as the replies of the peers already
# running to a new participant's announcement arrive within a few milliseconds of each other
SUBSCRIBER_SETTLE_S = 0.2


class Holds:
    """Lockstep (module docstring of ``simulator.py``) and ``wait_for_subscribers``."""

    def _hold(self, awaiting=None) -> bool:
        """The state of control instant ``_instant`` is out: hold until every command
        for it (``_awaiting``: (spacecraft name, 'torque' | 'dipole') of each spacecraft in
        the loop, or ``awaiting``, a new set of them known already); False, and on to the
        next instant, if no spacecraft is in the loop."""
        self._awaiting = awaiting if awaiting is not None else {
            (c.name, kind) for c in self._crafts.values() for kind in c.awaited}
        if not self._awaiting:
            self._instant += self._lockstep
            return False
        self._held, self._held_since = self._instant, time.monotonic()
        self._held_fields = divmod(self.stamp_ns(self._held), NS)  # sim_lockstep: why
        self._paused_reported = False
        self._round_trips.sent()
        return True

    def _release(self):
        """Every command of the held instant is applied: on to the next."""
        self._round_trips.applied()
        if self._paused_reported:
            self._log.info(f'lockstep: commands for t = {self._held / NS:.9g} s arrived '
                           f'after {time.monotonic() - self._held_since:.3g} s; resuming')
            self._anchor()  # real time: pace on from here, not catching up on the pause
        self._held, self._instant = None, self._instant + self._lockstep
        self._held_fields = None

    def _forget_lockstep(self, name):
        """Spacecraft ``name`` leaves: the held instant no longer waits for it."""
        if self._held is not None:
            self._awaiting = {k for k in self._awaiting if k[0] != name}
            if not self._awaiting:
                self._release()

    def _check_held(self, now) -> float:
        """Held: after ``lockstep_timeout`` report the pause once (log and diagnostics);
        never guess a command. Returns the executor's wait."""
        late = now - self._held_since - self._p['lockstep_timeout']
        if late < 0:
            return -late
        if not self._paused_reported:
            self._paused_reported = True
            self._lockstep_pauses += 1
            self._log.warning(f'lockstep: paused at t = {self._held / NS:.9g} s: no '
                              f'{self._held_missing()} stamped {self._held_stamp()} for '
                              f'{self._p["lockstep_timeout"]:g} s (lockstep_timeout); waiting '
                              'for it, nothing is extrapolated')
            self._publish_diagnostics()
        return 0.1

    def _held_missing(self) -> str:
        """The commands the held instant still waits for, in words."""
        return ', '.join(sorted(f'{name + "/" if name else ""}{kind}_command'
                                for name, kind in self._awaiting))

    @property
    def lockstep_held(self):
        """Lockstep holding a control instant for its command: why, in words; else None."""
        if not self._lockstep or self._held is None:
            return None
        return (f'lockstep holds t = {self._held / NS:.9g} s until the command stamped '
                f'{self._held_stamp()} arrives ({self._held_missing()})')

    def _held_stamp(self) -> str:
        sec, nsec = divmod(self.stamp_ns(self._held), NS)
        return f'{sec}.{nsec:09d}'

    def _on_lockstep_command(self, craft, header, vector, source, kind='torque'):
        """Apply ``craft``'s command of ``kind`` for the held instant; any other is counted
        and rejected by that spacecraft (stale: an instant already answered, or a second
        command for the held one; unexpected: no instant held with that stamp)."""
        stamp = header.stamp.sec * NS + header.stamp.nanosec
        key = (craft.name, kind)
        check = craft.dipoles if kind == 'dipole' else craft.commands
        held = self._held is not None and stamp == self.stamp_ns(self._held)
        if held and key in self._awaiting:
            value = (vector.x, vector.y, vector.z)
            if kind == 'dipole':
                craft.engine.apply_dipole_command(value)
            else:
                craft.engine.apply_command(value)
            self._awaiting.discard(key)
            if not self._awaiting:
                self._release()
            return
        last = self.stamp_ns(self._instant - self._lockstep)
        reason = 'lockstep_stale' if held or stamp <= last else 'lockstep_unexpected'
        why = 'answered already' if held else (
            f'the held instant\'s stamp is {self._held_stamp()}' if self._held is not None
            else 'no control instant is held')
        check.reject(reason, source, f'stamp {header.stamp.sec}.{header.stamp.nanosec:09d}: '
                     f'{why}')

    def _lockstep_values(self) -> dict:
        held = self._held is not None
        return {'lockstep_paused': held and self._paused_reported,
                'lockstep_held_since_s': time.monotonic() - self._held_since if held else 0.0,
                'lockstep_pauses': self._lockstep_pauses, **self._round_trips.values()}

    def _controllers_missing(self, pubs) -> list:
        """The command topics still without a controller: one with a matched publisher
        whose node this process has seen subscribe to a state topic, so that the rule that
        every discovered subscription be matched now covers its state subscriptions too
        (the subscriber count alone is met by a recorder while the controller is still
        unknown, and the controller then misses the first samples under load). In
        lockstep, each command each spacecraft in the loop owes (torque_command or
        wrench_command; dipole_command); else (wait_for_controller) any one."""
        state = {p.topic_name for p in pubs}
        if not self._lockstep:
            subs = self._command_subs + [s for c in self._crafts.values()
                                         for s in c.command_subs]
            return [] if any(self._has_controller(s, state) for s in subs) else \
                [self._command_subs[0].topic_name]
        missing = []
        for craft in self._crafts.values():
            subs = craft.command_subs + ([] if craft.name else self._command_subs)
            for kind in craft.awaited:
                topics = ('/dipole_command',) if kind == 'dipole' else \
                    ('/torque_command', '/wrench_command')
                own = [s for s in subs if s.topic_name.endswith(topics)]
                if not any(self._has_controller(s, state) for s in own):
                    missing.append(own[0].topic_name)
        return missing

    def _has_controller(self, sub, state) -> bool:
        from rclpy._rclpy_pybind11 import RCLError
        from rclpy.node import NodeNameNonExistentError
        if not sub.get_publisher_count():
            return False
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

    def _lockstep_command_subs(self):
        """The command subscriptions whose commands lockstep waits for."""
        return [s for c in self._crafts.values()
                for s in c.command_subs + ([] if c.name else self._command_subs)
                if s.topic_name.endswith(('/torque_command', '/dipole_command'))]

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
            controller awaited, also a command topic without one (_controllers_missing)."""
            return [p.topic_name for p in pubs if p.get_subscription_count() < max(
                n, len(self.get_subscriptions_info_by_topic(p.topic_name)))] + (
                self._controllers_missing(pubs) if controller else []) + (
                reports.unmatched(self._lockstep_command_subs()) if self._lockstep else [])
        # lockstep: recorders must have matched the controllers (matches.py: why)
        reports = matches.Reports(self)
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
        reports.close()  # read before t = 0 only
        if left:
            self._log.warning(f'starting at t = 0 without {n} subscription(s) on '
                              f'{", ".join(left)} after {timeout:g} s (wait_for_subscribers); '
                              'they miss the first samples')
        else:
            self._log.info('every state topic has its subscribers; starting at t = 0')
        self._refresh_subscribers()
        self._last_diag = (time.monotonic(), self.t_ns)  # the rate leaves the wait out
