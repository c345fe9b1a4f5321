"""ros_helpers.pace, which the live tests use to judge a publisher's pace on a loaded
machine: on synthetic arrivals (no ROS) with the delays such a machine gives."""
import numpy as np
import pytest

from ros_helpers import pace

pytestmark = pytest.mark.fast

PERIOD = 0.02  # s: a 50 Hz publisher


def _arrivals(rate, seconds, delay):
    """(receive time, stamp) of a publisher whose stamps advance ``rate`` s per wall s,
    each received ``delay(due time)`` s late."""
    stamps = np.arange(0.0, seconds * rate, PERIOD)
    due = stamps / rate
    return [(d + delay(d), s) for d, s in zip(due, stamps)]


def _jitter(seed=1):
    rng = np.random.default_rng(seed)
    return lambda due: float(rng.uniform(0.0, 0.005))


def _stalled(at, length, seed=1):
    """Jitter, and everything due in [at, at + length) held until at + length (a stall of
    the publisher or the receiver, caught up on in one burst)."""
    jitter = _jitter(seed)
    return lambda due: (at + length - due if at <= due < at + length else 0.0) + jitter(due)


def test_a_stall_caught_up_on_is_real_time_where_a_window_count_was_not():
    """A 0.5 s stall near the end of a 2 s window: the arrivals counted in the window read
    25 % slow (the count the 50 Hz check once made); the pace reads real time."""
    got = _arrivals(1.0, 2.0, _stalled(1.6, 0.5))
    in_window = [w for w, _ in got if w < 2.0]
    assert len(in_window) / 2.0 / 50.0 < 0.85
    assert pace(got) == pytest.approx(1.0, abs=0.01)


@pytest.mark.parametrize('at', [0.1, 1.0, 1.9])
def test_a_stall_anywhere_in_the_window_is_not_slowness(at):
    assert pace(_arrivals(1.0, 3.0, _stalled(at, 0.4))) == pytest.approx(1.0, abs=0.01)


@pytest.mark.parametrize('rate', [0.8, 1.0, 2.0])
def test_a_steady_publisher_reads_its_own_rate(rate):
    """Stamps in sim time at a real-time factor (expected = rate): that factor; on the wall
    clock's schedule but falling behind (0.8 of real time): slow, so the 0.9 bound fails."""
    assert pace(_arrivals(rate, 4.0, _jitter()), expected=rate) == pytest.approx(rate, rel=0.01)
    assert pace(_arrivals(rate, 4.0, _jitter())) == pytest.approx(rate, rel=0.01)


def test_falling_behind_for_good_reads_slow_despite_the_stall_rule():
    """Stalls that are not caught up on (each sample later than the one before by 10 %):
    the least delayed arrival at each end still reads the loss."""
    got = _arrivals(1.0, 4.0, lambda due: 0.1 * due)
    assert pace(got) == pytest.approx(1 / 1.1, rel=0.01)


def test_too_few_arrivals_are_an_error_not_a_pace():
    with pytest.raises(AssertionError, match='too few'):
        pace(_arrivals(1.0, 0.1, _jitter()))
