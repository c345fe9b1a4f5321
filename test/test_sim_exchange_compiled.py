"""The simulator's compiled lockstep exchanges (nodes/rcl_loop.py, nodes/sim_rcl.py): the
simulator is built in this process (a real node on the test's ROS domain), its commands
come from this test's node as real messages, and ``_exchanges`` is called by hand."""
import time

import pytest
from geometry_msgs.msg import Vector3Stamped
from rclpy.serialization import serialize_message

from ros_helpers import spin_until
from test_sim_exchange import NS, simulator  # noqa: F401, F811 (a fixture)

pytestmark = pytest.mark.timeout(300)
PERIOD = 20_000_000  # 50 Hz


def _command(stamp_ns, frame='base_link', z=0.01, x=0.0):
    msg = Vector3Stamped()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, NS)
    msg.header.frame_id, msg.vector.x, msg.vector.z = frame, x, z
    return msg


def _started(rclpy_node, build, compiled=True, **more):
    """A lockstep simulator as fast as possible, its compiled loop made, its first
    exchange done the Python way (the command's layout kept); this node's publisher on
    its torque_command, matched; and a subscription to its odometry."""
    from rigid_body_sim.nodes.sim_rcl import Compiled
    sim = build(**dict(dict(lockstep=True, publish_clock=True, real_time_factor=0.0,
                            publish_rate=50.0, control_rate=50.0, lockstep_timeout=30.0),
                       **more))
    pub = rclpy_node.create_publisher(Vector3Stamped, sim._exchange_sub.topic_name, 100)
    states = []
    from nav_msgs.msg import Odometry
    odometry = next(p for p, name in sim._crafts[''].pubs if name == 'odometry')
    rclpy_node.create_subscription(Odometry, odometry.topic_name, states.append, 1000)
    assert spin_until(rclpy_node, lambda: sim._exchange_sub.get_publisher_count() > 0 and
                      odometry.get_subscription_count() > 0, 30)
    if compiled:
        sim._compiled = Compiled(sim._log)
        assert sim._compiled.warm(sim._crafts[''].engine)
    sim.run_once()
    assert sim.lockstep_held is not None and sim.t_ns == 0
    sim._on_torque_bytes(serialize_message(_command(0)))  # the Python way: t = 0
    assert sim.t_ns == PERIOD and sim.lockstep_held is not None
    return sim, pub, states


def test_compiled_exchanges_count_stale_and_unexpected_commands_as_python_does(
        rclpy_node, simulator):  # noqa: F811 (the fixture)
    """Queued while held at t = 20 ms: a command for t = 0 (answered already: stale), one
    for t = 60 ms (not held: unexpected), the held instant's (applied, stepped, published,
    held at 40 ms, all compiled), then its duplicate (stale now). The compiled loop hands
    the others to the Python way, which counts them; the held one and the next run
    compiled; the run waits at the last instant held until ``until`` and returns."""
    sim, pub, states = _started(rclpy_node, simulator)
    for stamp in (0, 60_000_000, PERIOD, PERIOD, 2 * PERIOD):
        pub.publish(_command(stamp))
    rejected = sim._crafts[''].commands.rejected
    until = time.monotonic() + 60.0

    def settled():
        sim._exchanges(min(until, time.monotonic() + 0.2))
        return sim.t_ns == 3 * PERIOD and rejected['lockstep_stale'] == 2
    assert spin_until(rclpy_node, settled, 60), (sim.t_ns, rejected)
    assert rejected['lockstep_unexpected'] == 1, rejected
    assert sim._round_trips.compiled == 2, sim._round_trips.compiled
    assert sim.lockstep_held is not None and sim._held == 3 * PERIOD
    assert sim._held_fields == (0, 3 * PERIOD)
    # every instant's odometry went out once, stamped with its instant
    assert spin_until(rclpy_node, lambda: len(states) >= 4, 30)
    stamps = [m.header.stamp.sec * NS + m.header.stamp.nanosec for m in states]
    assert stamps == [0, PERIOD, 2 * PERIOD, 3 * PERIOD], stamps


def test_compiled_exchanges_leave_the_state_python_would(rclpy_node, simulator,  # noqa: F811
                                                          namespace):
    """The same commands (one clipped by max_torque, one zero: the Python way) through the
    compiled loop and through the Python way leave the same engine state bit for bit, the
    same command hold and counts, the same odometry."""
    from rclpy.parameter import Parameter
    from rigid_body_sim.nodes.simulator import Simulator
    made = []

    def python_way(**values):
        made.append(Simulator(namespace=namespace + '_python', parameter_overrides=[
            Parameter(k, value=v) for k, v in values.items()]))
        return made[-1]
    try:
        results = [_run_commands(rclpy_node, build, compiled)
                   for build, compiled in ((simulator, True), (python_way, False))]
    finally:
        for sim in made:
            sim.destroy_node()
    assert results[0] == results[1]


def _run_commands(rclpy_node, build, compiled):
    sim, pub, states = _started(rclpy_node, build, compiled, max_torque=0.05)
    values = [(0.01, 0.0), (0.02, 0.3), (0.0, 0.0), (-0.01, 0.02), (0.015, -0.01)]
    for k, (z, x) in enumerate(values, start=1):
        pub.publish(_command(k * PERIOD, z=z, x=x))
    last = (len(values) + 1) * PERIOD
    assert spin_until(rclpy_node, lambda: (sim._exchanges(time.monotonic() + 0.2),
                                           sim.t_ns)[1] == last, 60), sim.t_ns
    e = sim._crafts[''].engine
    got = (e._q.tolist(), e._m.tolist(), e.t_ns, e._next_sample, e.steps,
           e.command.torque.tolist(), e.command.expiry, e.command.accepted,
           e.command.saturated, sim._round_trips.count, sim._published)
    # all but the zero command (the Python way: the hold ends)
    assert sim._round_trips.compiled == (4 if compiled else 0), sim._round_trips.compiled
    assert spin_until(rclpy_node, lambda: len(states) >= len(values) + 2, 30)
    odometry = [(m.header.stamp.sec, m.header.stamp.nanosec, m.pose.pose.orientation.x,
                 m.pose.pose.orientation.w, m.twist.twist.angular.y) for m in states]
    return got, odometry


def test_a_pause_while_compiled_is_reported_and_resumed_by_python(rclpy_node, simulator):  # noqa: F811
    """A command that does not come within lockstep_timeout while the exchanges run
    compiled: the compiled call returns at the held instant's timeout, the loop reports
    the pause (once), and the command, when it comes, resumes the run the Python way
    (its log, pacing anew); the next exchanges run compiled again."""
    sim, pub, states = _started(rclpy_node, simulator, lockstep_timeout=0.3)
    pub.publish(_command(PERIOD))  # one compiled exchange, then nothing for 40 ms
    assert spin_until(rclpy_node, lambda: (sim._exchanges(time.monotonic() + 0.2),
                                           sim.t_ns)[1] == 2 * PERIOD, 60), sim.t_ns
    assert sim._round_trips.compiled == 1
    held_since = sim._held_since
    sim._exchanges(time.monotonic() + 5.0)  # returns at held_since + 0.3 s, not 5 s
    assert time.monotonic() < held_since + 5.0 and sim.t_ns == 2 * PERIOD
    assert sim._lockstep_pauses == 0
    sim.run_once()  # the loop's turn reports it
    assert sim._lockstep_pauses == 1 and sim._paused_reported
    pub.publish(_command(2 * PERIOD))
    pub.publish(_command(3 * PERIOD))
    assert spin_until(rclpy_node, lambda: (sim._exchanges(time.monotonic() + 0.2),
                                           sim.t_ns)[1] == 4 * PERIOD, 60), sim.t_ns
    # the resuming command the Python way (paused), the next compiled
    assert sim._round_trips.compiled == 2 and sim._lockstep_pauses == 1
    assert not sim._paused_reported
