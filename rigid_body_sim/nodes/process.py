"""How a node's process starts and stops: signals, the entry point, the events executor.

Every node runs through :func:`run_node` (the recorder and replay use its parts):
SIGINT/SIGTERM stop a node between callbacks with exit code 0 and no traceback, a second
one while it shuts down is ignored, and bad ``--ros-args`` or parameters end it with 2 and
the reason. ``nodes.entry`` covers the time before a node's module is imported.
"""
import contextlib
import os
import signal
import sys

import rclpy
import rclpy.logging
from rclpy.executors import ExternalShutdownException
from rclpy.experimental import EventsExecutor

from . import log_caller


@contextlib.contextmanager
def signals_ignored():
    """SIGINT and SIGTERM ignored from here to the end of the process: a second Ctrl-C
    (impatient users, `timeout -s INT`, launch escalating) must not interrupt a recorder
    finishing its bag, nor kill a node that has already shut down cleanly (its exit code
    stays 0). Used around each node's shutdown, the last thing its process does."""
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, signal.SIG_IGN)
    yield


_ROS_STARTED = []  # set once rclpy.init has run (see stop_between_callbacks)


def stop_between_callbacks() -> None:
    """Call just before ``rclpy.init``: from then on SIGINT/SIGTERM stop the node between
    callbacks, never inside one.

    By default Python raises KeyboardInterrupt wherever the interpreter is; a recorder hit
    inside the MCAP writer finished a file whose chunk index pointed past a chunk (a strict
    reader, rosbags, refused it). This handler does nothing once ROS is up: rclpy's own
    handler, which ``init`` installs on top of it and which calls it, shuts the context
    down, and the executor stops at its next turn (ExternalShutdownException). Before
    ``init`` it raises KeyboardInterrupt, as Ctrl-C always did."""
    def handler(signum, frame):
        if not _ROS_STARTED:
            raise KeyboardInterrupt
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, handler)
    _ROS_STARTED.clear()


def ros_started() -> None:
    """Mark rclpy as initialised for stop_between_callbacks' handler."""
    _ROS_STARTED.append(True)


def quiet_interrupted_futures() -> None:
    """Ctrl-C can land inside rclpy's ``Future.__init__`` (the executor makes one per
    callback) before it has set ``_exception``; when the half-made object is collected its
    ``__del__`` raises AttributeError, which Python prints as "Exception ignored ... Traceback"
    on a clean stop. Only that case is silenced; every other unraisable error is reported
    as before."""
    from rclpy.task import Future
    previous = sys.unraisablehook

    def hook(unraisable):
        if unraisable.exc_type is AttributeError and \
                getattr(unraisable.object, '__qualname__', '') == Future.__del__.__qualname__:
            return
        previous(unraisable)
    sys.unraisablehook = hook


def prefer_asynchronous_publication(synchronous: bool = False):
    """Call before ``rclpy.init``: Fast DDS (Jazzy's default RMW) sends from its own thread
    unless the user chose otherwise (``RMW_FASTRTPS_PUBLICATION_MODE``; other RMWs ignore
    it). Why: a synchronous write delivers to every matched reader inside ``publish``;
    measured here, one raw publish to a subscriber in another process cost 7.1 µs
    synchronous and 3.2 µs asynchronous, and the simulator with every state topic
    subscribed went from 4.7 % to 3.0 % of a core at real time and from 64× to 145× as
    fast as possible (``python -m rigid_body_sim.tools.live_simulator --subscribe``).
    Delivery guarantees are the QoS's either way (reliable history, acknowledgements).

    ``synchronous`` (lockstep, ``lockstep_requested``): a node that publishes a few
    messages and then waits for the answer gains nothing from handing them to a sending
    thread, and pays for it: a wake-up of that thread per exchange, and its spinning
    while the writer is locked, which grows with the load (the simulator's CPU per
    lockstep exchange, ``tools.lockstep``: docs/live-nodes.md gives the figures). The
    mode is Fast DDS's per participant, read when the first node is made, so it is
    chosen from the command line before ROS starts.

    Synchronous, the writers also send a heartbeat every HEARTBEAT_PERIOD_NS
    (``heartbeat_profile``) unless the user gave Fast DDS profiles of their own."""
    mode = os.environ.setdefault('RMW_FASTRTPS_PUBLICATION_MODE',
                                 'SYNCHRONOUS' if synchronous else 'ASYNCHRONOUS')
    if mode == 'SYNCHRONOUS' and not os.environ.get('FASTRTPS_DEFAULT_PROFILES_FILE'):
        os.environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = heartbeat_profile()


# Why: a synchronous writer asks its readers for acknowledgements (a heartbeat) only
# periodically, every 3 s by default, or once it has sent about a socket buffer's worth
# of data; an asynchronous one after every burst it sends. So synchronous, the
# simulator's waits for acknowledgements (sim_acks, one per 500 messages a topic) ran
# into their 1 s timeout (4.99 s of a 2,000-exchange lockstep run, profiled), and a
# message a reader's full shared-memory queue lost went again only seconds later.
HEARTBEAT_PERIOD_NS = 20_000_000
# And why: after each message a writer sends, Fast DDS restarts its nack suppression timer
# (its default duration 0) on the timed-events thread, which wakes for it: 1.8-4.3 wake-ups
# of that thread per exchange of a lockstep-like ping-pong, 0.35-0.99 with this duration
# (test_lockstep: test_a_synchronous_writer_does_not_wake_its_event_thread_per_message),
# and the simulator's CPU per lockstep exchange 156-200 -> 124-136 µs (tools.lockstep,
# alternating runs, load 10). A repair it delays waits for a heartbeat anyway.
NACK_SUPPRESSION_NS = HEARTBEAT_PERIOD_NS
# And why no piggybacked heartbeats: Fast DDS's writer adds heartbeats to the messages it
# sends (in a lockstep exchange, to many of them: a small history of unacknowledged
# messages fills between two periodic heartbeats), and each one its reader must answer:
# the reader's timed-events thread wakes for it, and an acknowledgement goes back to the
# writer's shared-memory receiver. The periodic heartbeat (HEARTBEAT_PERIOD_NS) still
# asks for every acknowledgement and repair. Measured, alternating runs with and without
# it: the timed-events thread's wake-ups per ping of a lockstep-like ping-pong 0.05
# against 0.11-0.15 (test_lockstep); in the simulator's lockstep run that thread's part
# 1.1-4.6 against 2.4-6.6 µs of the CPU per exchange, lower in each of 15 pairs; the
# process's CPU per exchange lower in each of 8 pairs at 1 kHz (tools.lockstep.exchange,
# 5,000 exchanges, load 4.7-6.6: median 108 against 113 µs) but within the noise at
# 100 Hz (7 pairs of 10,000 exchanges, load 6-11: median 118 against 116).
_PROFILE = f"""<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <profiles>
    <data_writer profile_name="rigid_body_sim_heartbeat" is_default_profile="true">
      <qos><disable_heartbeat_piggyback>true</disable_heartbeat_piggyback></qos>
      <times>
        <heartbeatPeriod><sec>0</sec><nanosec>{HEARTBEAT_PERIOD_NS}</nanosec></heartbeatPeriod>
        <nackSupressionDuration>
          <sec>0</sec><nanosec>{NACK_SUPPRESSION_NS}</nanosec>
        </nackSupressionDuration>
      </times>
    </data_writer>
  </profiles>
</dds>
"""


def heartbeat_profile(text: str = _PROFILE) -> str:
    """The path of a Fast DDS XML profile that makes every data writer's heartbeat period
    HEARTBEAT_PERIOD_NS, its nack suppression NACK_SUPPRESSION_NS, and sends no
    piggybacked heartbeats
    (``FASTRTPS_DEFAULT_PROFILES_FILE``; rmw_fastrtps then sets the ROS QoS over it, as over
    Fast DDS's defaults), or with ``text`` that profile (a test's). Written once per content
    into the temporary directory, atomically (processes start together)."""
    import hashlib
    import tempfile
    path = os.path.join(tempfile.gettempdir(), 'rigid_body_sim_fastdds_%s.xml' % hashlib.sha256(
        text.encode()).hexdigest()[:12])
    if not os.path.isfile(path):
        with tempfile.NamedTemporaryFile('w', dir=os.path.dirname(path), suffix='.xml',
                                         delete=False) as f:
            f.write(text)
        os.replace(f.name, path)
    return path


def lockstep_requested(node_name: str, argv=None) -> bool:
    """Whether the ``--ros-args`` in ``argv`` (default sys.argv) give the node
    ``node_name`` (renamed by ``-r __node:=``, in the namespace of ``-r __ns:=``)
    ``lockstep: true``, read from its params files and ``-p`` rules as rcl reads them.
    False when they cannot be read: the node then reports why itself."""
    from ..params_file import ParamsFileError, fully_qualified, given_values
    from .usage import ros_sources
    argv = sys.argv if argv is None else list(argv)
    name, ns = node_name, '/'
    for flag, rule in zip(argv, argv[1:]):
        if flag in ('-r', '--remap'):
            key, _, value = rule.rpartition(':=')
            key = key.rsplit(':', 1)[-1]  # 'node:__ns' applies to that node only; taken alike
            if key == '__node':
                name = value
            elif key == '__ns':
                ns = value
    try:
        _, kept = given_values(ros_sources(argv), fully_qualified(name, ns))
    except (ParamsFileError, OSError):
        return False
    value = kept.get('lockstep')
    return value is not None and value.value is True


def pin_process(core: int, name: str = 'cpu_affinity') -> None:
    """Every thread of this process (the node's and the middleware's, which exist once
    the node does) on CPU ``core``, and the threads they start after, which inherit it;
    nothing for -1. ValueError naming ``name`` for a core this process cannot run on
    (one the machine does not have, or one outside the set it was started with). Why:
    in lockstep the simulator's thread and Fast DDS's receiver take turns with the
    controller; with the controller on the same core the simulator's CPU per exchange
    was lower, apart on two cores it was not (docs/live-nodes.md: the figures, and the
    real-time rate it cost beside other processes on that core)."""
    if core < 0:
        return
    allowed = os.sched_getaffinity(0)
    if core not in allowed:
        count = os.cpu_count() or 0
        why = f'this machine has {count} (0-{count - 1})' if core >= count else \
            'this process may run on ' + ', '.join(map(str, sorted(allowed))) + ' only'
        raise ValueError(f'{name} = {core}: no such CPU core for this process: {why}')
    for tid in os.listdir('/proc/self/task'):
        try:
            os.sched_setaffinity(int(tid), {core})
        except ProcessLookupError:  # the thread ended meanwhile
            pass


_KEPT_EXECUTORS = []  # events executors rclpy could not tear down (see events_executor)


@contextlib.contextmanager
def events_executor(node):
    """rclpy's C++ events executor turning ``node``, torn down on leaving.

    Why the care: a Ctrl-C just after start-up shuts the context down while the executor
    takes the node's callbacks on, and the executor, destroyed with a callback still
    registered, aborted the process ("Destroying callback manager with callbacks
    remaining", exit -6: 2 in 25 stops aimed at that moment), even after a teardown that
    raised nothing. So after a signal or an error the executor is kept, and
    ``nodes.entry`` ends the process without the interpreter's teardown, which would
    destroy it too (the node has been closed and destroyed by then)."""
    executor = EventsExecutor(context=node.context)
    clean = False
    try:
        executor.add_node(node)
        yield executor
        clean = True
    finally:
        # after a signal or an error its callback table may be inconsistent (rclpy updates
        # it inside spin_once, which the shutdown can cut short)
        try:
            executor.remove_node(node)
            clean = executor.shutdown(timeout_sec=1.0) and clean and node.context.ok()
        except Exception:  # noqa: BLE001 - rclpy could not tear it down: keep it
            clean = False
        if not clean:
            _KEPT_EXECUTORS.append(executor)


def executors_kept() -> bool:
    """Whether an events executor could not be torn down (``events_executor``)."""
    return bool(_KEPT_EXECUTORS)


def start_ros(node_name: str, args=None, lockstep: bool = False):
    """``rclpy.init`` with the package's signal handling (``stop_between_callbacks``);
    None once ROS is up, else the exit code: 0 for a Ctrl-C before rclpy's handler was up
    (a stop like any other), 2 with the reason for bad ``--ros-args`` (e.g. a bad remap,
    a params file that does not exist)."""
    from .usage import ros_arguments_problem
    problem = ros_arguments_problem(sys.argv if args is None else args)
    if problem:  # rcl's own answer is a raw error with C source paths
        print(f'[FATAL] [{node_name}]: {problem}', file=sys.stderr)
        return 2
    # lockstep (simulator, controller): synchronous publication, when the args ask for it
    prefer_asynchronous_publication(lockstep and lockstep_requested(
        node_name, sys.argv if args is None else args))
    stop_between_callbacks()
    try:
        rclpy.init(args=args)
    except KeyboardInterrupt:
        return 0
    except Exception as exc:  # noqa: BLE001 - rclpy's own error, with its reason: no traceback
        print(f'[FATAL] [{node_name}]: cannot initialise ROS: {exc}', file=sys.stderr)
        return 2
    ros_started()
    quiet_interrupted_futures()
    log_caller.install()  # log calls at ~0.02 ms, not rclpy's 1.5-3 ms (log_caller.py)
    return None


def run_node(node_name: str, build, run=None, args=None, fatal=(ValueError,),
             exit_codes=None, close=None, lockstep: bool = False) -> int:
    """Every node's entry point (``ros2 run``); returns the exit code.

    ``rclpy.init`` failing on bad ``--ros-args`` → 2 with the reason; ``build()`` raising
    one of ``fatal`` (bad parameters) → 2 with the reason; an exception type in
    ``exit_codes`` ({type: code}) → that code with its message; then ``run(node)``
    (default rclpy.spin). SIGINT/SIGTERM end the node with 0 and no traceback, between
    callbacks once ROS is up (``stop_between_callbacks``: a Ctrl-C while numba loaded the
    kernels raised KeyboardInterrupt inside llvmlite's ctypes callback, printed as an
    ignored exception with its traceback), also in ``rclpy.init`` and when they land in
    the middle of an rclpy call (rclpy shut the context down, so the call raised); before
    the node's module is imported, ``nodes.entry`` ends it. Shutdown runs with the signals
    ignored: ``close(node)``, then destroy. ``lockstep``: the node has a ``lockstep``
    parameter; when the args set it, it publishes synchronously (``start_ros``)."""
    code = start_ros(node_name, args, lockstep)
    if code is not None:
        return code
    node = None
    try:
        try:
            node = build()
        except fatal as exc:
            if not rclpy.ok():  # SIGINT/SIGTERM shut the context down under the build:
                return 0        # a stop, not bad parameters
            rclpy.logging.get_logger(node_name).fatal(f'invalid parameters: {exc}')
            return 2
        except tuple(exit_codes or ()) as exc:
            rclpy.logging.get_logger(node_name).fatal(str(exc))
            return next(c for t, c in exit_codes.items() if isinstance(exc, t))
        (run or rclpy.spin)(node)
        return 0
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    except Exception:
        if not rclpy.ok():  # SIGINT/SIGTERM shut the context down in the middle of a call
            return 0
        raise
    finally:
        with signals_ignored():  # a second Ctrl-C while shutting down: no traceback
            if node is not None:
                try:
                    if close is not None:
                        close(node)
                    node.destroy_node()
                except Exception:  # noqa: BLE001 - context already gone; nothing to release
                    pass
            rclpy.try_shutdown()
