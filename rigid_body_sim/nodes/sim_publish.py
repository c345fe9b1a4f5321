"""The simulator's publishing path: its publishers, samples to the wire, /clock,
subscriber counts, the waits for acknowledgements and diagnostics. A mixin of the node
(``simulator.py``), which decides when a sample is due; this module sends it.

Time stamps. Every message carries the sim time of the state it holds, mapped to ROS time
in one way: with ``publish_clock: true`` the stamp is the sim time (and equals /clock);
otherwise it is the wall-clock time at which the run started plus sim time divided by
``real_time_factor`` (1 when running as fast as possible). Consecutive samples are
therefore exactly one sample period apart whatever the load, and all topics of one sample
share the stamp. A sample published later than ``deadline_tolerance`` (wall time) after
its due time counts as a missed deadline in diagnostics, with the worst lateness of each
diagnostics period; it never bends a stamp.
"""
import time

from rclpy._rclpy_pybind11 import RCLError

from diagnostic_msgs.msg import DiagnosticArray
from rosgraph_msgs.msg import Clock

from .common import qos_profile
from .sim_acks import DIAGNOSTICS_ACK_TIMEOUT, FINAL_ACK_TIMEOUT, paced_qos
from .sim_status import diagnostics
from .spacecraft import STATE_DEPTH
from .state_messages import clock_cdr

try:  # /tf only where tf2_msgs exists (a full ROS install); the PyPI venv has none
    from tf2_msgs.msg import TFMessage
except ImportError:  # pragma: no cover - depends on the installation
    TFMessage = None


class Publishing:
    """Publishing for :class:`~rigid_body_sim.nodes.simulator.Simulator`."""

    def _create_publishers(self) -> bool:
        """The node's own publishers (/tf, /clock, /diagnostics) and the state topics' QoS;
        returns whether the per-sample topics keep every message (``sim_acks``)."""
        self._clock_ns, self._clock_subscribed = -1, False
        # paced (as fast as possible, or a recorder waited for): keep every unacknowledged
        # message, so that no reliable reader loses one and the node never stops to ask
        keep_all = self._paced and self._p['qos'] == 'reliable'  # sim_acks: why
        self._state_qos = paced_qos(self._p['qos']) if self._paced else \
            qos_profile(self._p['qos'], STATE_DEPTH)
        self._tf_qos = paced_qos('reliable') if self._paced else qos_profile('reliable', 100)
        pub = self.create_publisher
        self._tf_pub = pub(TFMessage, '/tf', self._tf_qos) if TFMessage is not None else None
        self._clock_pub = None
        if self._p['publish_clock']:
            self._clock_pub = pub(Clock, '/clock', qos_profile('reliable'))
        self._diag_pub = pub(DiagnosticArray, '/diagnostics', qos_profile('reliable'))
        return keep_all

    def _base_stamp(self, epoch_ns: int):
        """Stamps from now on: epoch_ns at the current sim time, then sim time / rtf."""
        self._stamp0, self._sim0 = int(epoch_ns), self.t_ns
        self._rtf = self._p['real_time_factor'] or 1.0

    def stamp_ns(self, t_ns: int) -> int:
        """The header stamp (ns) of the state at sim time ``t_ns`` (see module docstring)."""
        if self._p['publish_clock']:
            return t_ns
        return self._stamp0 + round((t_ns - self._sim0) / self._rtf)

    def stamps_ns(self, times: list) -> list:
        """``stamp_ns`` of each sim time of ``times`` (ints, ns)."""
        if self._p['publish_clock']:
            return times
        stamp0, sim0, rtf = self._stamp0, self._sim0, self._rtf
        return [stamp0 + round((t - sim0) / rtf) for t in times]

    def _tick_clock(self, t_ns):
        """/clock at each sample instant, once however many spacecraft reach it, when it has
        subscribers (counted with the state topics': a use_sim_time node that joins gets it
        from the next refresh on, as a late state subscriber does; none: nothing to send,
        and a publish cost ~25 µs of the ~600 µs of a lockstep exchange)."""
        if t_ns <= self._clock_ns:
            return False
        self._clock_ns = t_ns
        if self._clock_subscribed:
            self._clock_pub.publish(clock_cdr(t_ns))
        return True

    def _publish(self, craft, block, late=True):
        rtf = self._p['real_time_factor'] if late else 0
        try:
            sensors = craft.publish_sensors(block, self.stamp_ns)
        except RCLError as exc:  # a paced reader's history is full (sim_acks)
            sensors = 0
            self._acks.refused('sensor topics', exc)
        # paced: every message counts toward the next wait for acknowledgements (sim_acks)
        count = self._paced
        if count and sensors:  # readings on the busiest sensor topic, before the samples'
            self._acks.published(sensors)
        n = len(block)
        if not n:
            return
        times = block.t_ns.tolist()
        active = craft.active
        # the block's messages on the subscribed topics only, made at once
        states = craft.msgs.encoded_block(block, self.stamps_ns(times),
                                          craft.active_names) if active else None
        # several samples: topic by topic (Spacecraft.publish_states: why); not in lockstep
        # or to a /clock subscriber, which see each sample's topics before the next one's
        by_topic = active and n > 1 and not (self._lockstep or self._clock_subscribed)
        if by_topic:
            craft.publish_states(states, self._acks.refused)
        if (by_topic or not active) and rtf == 0 and craft.orbit is None and \
                not self._clock_subscribed:
            # nothing more goes out sample by sample, and no deadline to check: the
            # bookkeeping of every sample at once (~2 µs a sample of a loop otherwise)
            self._clock_ns = max(self._clock_ns, times[-1])
            self._published += n * len(active)
            for _ in range(n if count else 0):
                self._acks.published()
            return
        for i, t_ns in enumerate(times):
            new = self._tick_clock(t_ns)  # the first spacecraft at this sample instant
            if active and not by_topic:
                craft.publish_states(states, self._acks.refused, i)
            if craft.orbit is not None:
                try:
                    craft.orbit.publish(block, i, self.stamp_ns(t_ns))
                except RCLError as exc:
                    self._acks.refused('orbit topics', exc)
            self._published += len(active)
            if count:
                self._acks.published()
            if rtf > 0 and new:
                late = time.monotonic() - self._due_wall(t_ns)
                self._worst_late = max(self._worst_late, late)
                if late > self._p['deadline_tolerance']:
                    self._missed += 1

    @property
    def _paced(self) -> bool:
        """Publishing waits for acknowledgements: as fast as possible, or when subscribers
        were waited for (a recorder: it must get every sample, even if it lags)."""
        return not self._p['real_time_factor'] or self._p['wait_for_subscribers'] > 0

    def _acked_publishers(self):
        """Every publisher the spacecraft publish on per sample or reading (one without
        readers answers at once)."""
        for c in self._crafts.values():
            yield from c.publishers()
            if c.orbit is not None:
                yield from (p for p, _ in c.orbit.pubs)

    def _wait_acked(self, timeout=FINAL_ACK_TIMEOUT):
        """Hold until reliable subscribers have acknowledged what was published
        (``sim_acks``), the last diagnostics included: the run's summary, which a recorder
        keeps beside the samples (a run as fast as possible may publish no other)."""
        self._acks.wait(timeout)
        self._diag_pub.wait_for_all_acked(DIAGNOSTICS_ACK_TIMEOUT)

    def _refresh_subscribers(self):
        for craft in self._crafts.values():
            craft.refresh()
        self._clock_subscribed = self._clock_pub is not None and \
            self._clock_pub.get_subscription_count() > 0

    def _publish_diagnostics(self):
        self._diag_pub.publish(diagnostics(self))

