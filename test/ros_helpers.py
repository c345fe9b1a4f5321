"""Helpers for tests that start real node processes and exchange real messages."""
import os
import re
import signal
import subprocess
import sys
import tempfile
import time


def unique_namespace(test_name: str) -> str:
    """A valid ROS namespace derived from the test name plus the pid and a counter."""
    unique_namespace.counter = getattr(unique_namespace, 'counter', 0) + 1
    # ROS names forbid "__"
    base = re.sub(r"_+", "_", re.sub(r"[^A-Za-z0-9_]", "_", test_name))[:40].strip("_")
    return f'/t_{base}_{os.getpid()}_{unique_namespace.counter}'


def venv_exe(name: str) -> str:
    """Path of an installed executable of this package (node or CLI) in this interpreter's
    prefix."""
    for candidate in (os.path.join(sys.prefix, 'lib', 'rigid_body_sim', name),
                      os.path.join(os.path.dirname(sys.executable), name)):
        if os.path.exists(candidate):
            return candidate
    raise FileNotFoundError(f'{name} is not installed in {sys.prefix}; run make venv')


class NodeProcess:
    """A child process in its own process group with captured output.

    ``stop()`` sends SIGINT, waits, then SIGKILLs the group: nothing outlives the test.
    """

    def __init__(self, cmd, env=None, cwd=None):
        self.cmd = cmd
        self._out = tempfile.TemporaryFile(mode='w+b')
        full_env = dict(os.environ)
        full_env.update(env or {})
        self.proc = subprocess.Popen(cmd, stdout=self._out, stderr=subprocess.STDOUT,
                                     env=full_env, cwd=cwd, start_new_session=True)

    @property
    def pid(self):
        return self.proc.pid

    def poll(self):
        return self.proc.poll()

    def output(self) -> str:
        self._out.flush()
        self._out.seek(0)
        return self._out.read().decode(errors='replace')

    def signal(self, sig):
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, sig)

    def wait(self, timeout):
        return self.proc.wait(timeout=timeout)

    def stop(self, timeout=10.0):
        """SIGINT, then SIGKILL after ``timeout``; returns the exit code."""
        if self.proc.poll() is None:
            try:
                os.killpg(self.proc.pid, signal.SIGINT)
                self.proc.wait(timeout=timeout)
            except (subprocess.TimeoutExpired, ProcessLookupError):
                pass
        if self.proc.poll() is None:
            try:
                os.killpg(self.proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            self.proc.wait(timeout=5)
        return self.proc.returncode


def wait_output(proc, text, timeout=60.0):
    """Until ``proc`` (a NodeProcess) has printed ``text``; False after ``timeout`` s. A
    process that ends first fails the test with its output."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and text not in proc.output():
        assert proc.poll() is None, proc.output()[-3000:]
        time.sleep(0.05)
    return text in proc.output()


def spin_until(node, predicate, timeout, executor=None):
    """Spin ``node`` until ``predicate()`` is true or ``timeout`` s pass; returns predicate()."""
    import rclpy
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        if executor is not None:
            executor.spin_once(timeout_sec=0.05)
        else:
            rclpy.spin_once(node, timeout_sec=0.05)
    return predicate()


def call_service(node, client, request, timeout=30.0, resend=None, sends=None):
    """The response of ``client`` to ``request``, spinning ``node`` (asserts it comes).

    ``resend`` (s), for a request the server may take twice: sent again each ``resend``
    seconds until a response comes, the first response kept. A server's response is lost
    where its response writer has not matched the client's reader within 100 ms of
    sending (rmw_fastrtps: "client will not receive response", ros2/rmw_fastrtps#467), and
    service_is_ready says only that the client has discovered the server: a suite run
    under load waited 30 s for a pause's response. ``sends``, a list: the number of
    requests sent is appended to it."""
    assert spin_until(node, client.service_is_ready, 60.0), client.srv_name
    futures = [client.call_async(request)]
    deadline = time.monotonic() + timeout
    while not spin_until(node, lambda: any(f.done() for f in futures),
                         min(resend or timeout, max(deadline - time.monotonic(), 0.0))):
        assert resend is not None and time.monotonic() < deadline, client.srv_name
        futures.append(client.call_async(request))
    if sends is not None:
        sends.append(len(futures))
    return next(f for f in futures if f.done()).result()


def stamp_ns(msg) -> int:
    """A stamped message's header stamp in ns."""
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def pace(samples, expected=1.0):
    """Stamp seconds per wall second of a publisher, from ``samples`` = [(receive time s,
    header stamp s), ...] in arrival order: ``expected`` (1 for stamps on the wall clock,
    the real-time factor for stamps in sim time) when it keeps its pace.

    A receive time lags its stamp's due time by delays that are one-sided (the publisher
    computing late, delivery, the receiver's scheduling: on a loaded machine 0.1-0.5 s at
    times), so the slope between two arrivals reads those delays too. This takes the least
    delayed arrival of the first third and of the last third (lag measured against
    ``expected``) and returns the slope between them: a publisher that falls behind for
    good reads slow, a stall it catches up on does not, unless it covers a whole third."""
    assert len(samples) >= 10, f'{len(samples)} samples: too few to measure a pace'
    lag = [w - st / expected for w, st in samples]
    k = len(samples) // 3
    first = min(range(k), key=lag.__getitem__)
    last = min(range(len(samples) - k, len(samples)), key=lag.__getitem__)
    (w0, s0), (w1, s1) = samples[first], samples[last]
    return (s1 - s0) / (w1 - w0)
