"""How the simulator keeps its reliable subscribers from losing a sample when it publishes
faster than they may take them: as fast as possible, or after waiting for a recorder
(``wait_for_subscribers``), the node is *paced* by its readers.

Paced, every reliable topic it publishes per sample or reading keeps ALL unacknowledged
messages (``paced_qos``), and the node waits for acknowledgements once per
KEEP_ALL_WINDOW messages a topic. Nothing is overwritten before every reader has it, so
a wait that times out loses nothing either; the waits only bound the backlog (what a
subscriber sees lags the simulation by at most a window) and let Fast DDS send in bursts
(the node's CPU a sample, nine topics subscribed, loaded machine: median 111 µs over 14
runs, 77-150 but one; waiting every 50 samples 97-152 µs; keep-all never waiting 128-190).

What bounds the rate then is delivery: nine messages a sample to another process cost
Fast DDS's sending thread ~43 µs a sample sent sample by sample (a block is now sent topic
by topic: ``Spacecraft.publish_states``) and a Python subscriber taking every message raw
~70 µs (one deserializing them, ~135). ``tools.live_floor`` measures what a bare rclpy
publisher reaches this way: each wait after 500 samples then takes ~55 ms (the sending
thread and the reader draining), and 2,000 samples between waits did little better, 4,000
worse (a reader's shared-memory queue overflows). The
102-142x of earlier sessions came from keep-last without waits, which loses what it
has not sent yet: to a keep-all subscriber it delivered 1,060 of 4,000 samples.

Why not keep-last with a wait every 50 samples, as before: Fast DDS overwrites a
keep-last history's oldest message acknowledged or not (a subscriber stopped for a
moment got 151 of 1,001 in a row), so the window had to stay within the history, and the
node stopped every 50 samples. Each wait costs a reader's answer to a heartbeat, which
Fast DDS readers hold back by their heartbeat response delay (5 ms): the run spent 74 %
of its wall time in ``wait_for_all_acked`` (py-spy; real-time factor 27-44). A longer
keep-last window lost samples: past a reader's shared-memory queue (512 messages) a burst
loses messages, which go again only at the next heartbeat, and the waits ran into their
timeout while the history moved on.

A reader that acknowledges nothing at all (a stopped process) makes each wait time out
(ACK_TIMEOUT for all topics together); once its history is full (Fast DDS's default
resource limit, 5,000 messages a topic) each publish on that topic fails after Fast
DDS's blocking time (0.1 s), until DDS drops the stopped participant at the end of its
lease (20 s by default; measured: 19.3 s, then publishing went on). The node counts the
failures (``messages_not_sent``), warns (throttled) and goes on.

Real time and not waited for, the topics keep the last STATE_DEPTH messages as any ROS
publisher does; a run switched from real time to as fast as possible keeps those
publishers and waits every KEEP_LAST_WINDOW samples, as before.
"""
import time

from rclpy.duration import Duration
from rclpy.qos import HistoryPolicy, QoSProfile

from ..engine import NS
from .common import qos_profile
from .spacecraft import STATE_DEPTH

KEEP_LAST_WINDOW = STATE_DEPTH // 2  # keep-last publishers: samples between two waits
KEEP_ALL_WINDOW = 500  # keep-all: messages between two waits (the backlog's bound)
ACK_TIMEOUT = Duration(seconds=1.0)  # then go on (a subscriber that hangs stalls no run)
FINAL_ACK_TIMEOUT = Duration(seconds=5.0)  # at the end: what is still in flight
DIAGNOSTICS_ACK_TIMEOUT = Duration(seconds=1.0)  # and then the last diagnostics


def paced_qos(name: str) -> QoSProfile:
    """QoS of the per-sample topics of a paced run: ``reliable`` keeps every
    unacknowledged message; best effort (``sensor_data``) is unchanged (nothing to wait
    for)."""
    qos = qos_profile(name, STATE_DEPTH)
    if name == 'reliable':
        qos.history = HistoryPolicy.KEEP_ALL
    return qos


class Acknowledgements:
    """The node's side of it: ``publishers()`` yields every per-sample publisher; ``log``
    the node's logger. ``keep_all``: the publishers were built with ``paced_qos``."""

    def __init__(self, publishers, log, keep_all: bool):
        self.publishers, self.log, self.keep_all = publishers, log, keep_all
        self.pending = 0  # messages on the busiest topic since the last wait
        self.window = KEEP_ALL_WINDOW if keep_all else KEEP_LAST_WINDOW
        self.waits, self.wait_s = 0, 0.0  # diagnostics: how often, how long in all
        self.not_sent = 0  # publishes refused: a reader's history was full (it lags)
        self._warn_at = 0.0

    def published(self, n: int = 1):
        """``n`` more messages on the busiest topic (1 per sample for the state topics)
        in a paced run: wait when the window is full."""
        self.pending += n
        if self.pending >= self.window:
            self.wait()

    def wait(self, timeout: Duration = ACK_TIMEOUT):
        """Hold until every reader has acknowledged everything published so far, or
        ``timeout`` (for all publishers together). A reader that keeps up answers within
        milliseconds."""
        self.pending = 0
        start = time.monotonic()
        deadline = start + timeout.nanoseconds / NS
        slow = [publisher.topic_name for publisher in self.publishers()
                if not publisher.wait_for_all_acked(Duration(nanoseconds=max(
                    0, int((deadline - time.monotonic()) * NS))))]
        now = time.monotonic()
        self.waits += 1
        self.wait_s += now - start
        if slow:
            kept = ' (their messages are kept)' if self.keep_all else ''
            self._warn(f'subscribers of {", ".join(slow)} acknowledge nothing for '
                       f'{timeout.nanoseconds / NS:g} s; going on without them{kept}')

    def refused(self, topic: str, exc: Exception):
        """A publish that failed because a reader's history was full: counted, warned."""
        self.not_sent += 1
        self._warn(f'{topic}: a subscriber acknowledges nothing and its history is full '
                   f'({exc}); it misses samples ({self.not_sent} messages not sent so far)')

    def _warn(self, text: str):
        now = time.monotonic()
        if now >= self._warn_at:
            self._warn_at = now + 5.0
            self.log.warning(text)

    def values(self) -> dict:
        """For diagnostics."""
        return {'acknowledgement_waits': self.waits,
                'acknowledgement_wait_s': round(self.wait_s, 6),
                'messages_not_sent': self.not_sent}

    def summary(self) -> str:
        kind = 'keep-all' if self.keep_all else 'keep-last'
        return (f'{self.waits} waits for acknowledgements ({self.wait_s:.3g} s in all; '
                f'{kind}, one per {self.window} messages a topic at most), '
                f'{self.not_sent} messages not sent')
