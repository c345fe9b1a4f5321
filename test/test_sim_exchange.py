"""What the simulator does per exchange, beyond what its subscribers receive: no /clock
without a subscriber, one executor turn per lockstep exchange, commands read from their
CDR bytes as rclpy would decode them.

The simulator node is built in this process (a real node on the test's ROS domain) and its
loop is driven by hand (``run_once``), so that what it does per turn can be observed; the
subscribers are this test's own node, exchanging real messages with it.
"""
import pytest
from geometry_msgs.msg import Vector3Stamped
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message

from ros_helpers import spin_until

NS = 1_000_000_000


@pytest.fixture
def simulator(rclpy_node, namespace):
    """Build a Simulator in this process with the given parameters; destroyed at teardown."""
    from rigid_body_sim.nodes.simulator import Simulator
    built = []

    def build(**values):
        sim = Simulator(namespace=namespace, parameter_overrides=[
            Parameter(k, value=v) for k, v in values.items()])
        built.append(sim)
        return sim
    yield build
    for sim in built:
        sim.destroy_node()


def test_clock_goes_only_to_subscribers(rclpy_node, simulator):
    """Without a /clock subscriber the simulator publishes no /clock (before, it published
    one per sample for nobody: ~25 µs of a lockstep exchange); once a use_sim_time node
    subscribes it gets /clock, on the sample grid and increasing (the bytes decode to the
    sim time)."""
    from rosgraph_msgs.msg import Clock
    sim = simulator(publish_clock=True, real_time_factor=0.0, publish_rate=100.0)
    assert spin_until(rclpy_node, lambda: sim._clock_pub.get_subscription_count() == 0, 30)
    sent = []
    publish = sim._clock_pub.publish
    sim._clock_pub.publish = lambda msg: (sent.append(msg), publish(msg))
    for _ in range(5):
        sim.run_once()
    assert sim.t_ns > 0  # the run advanced
    assert sent == []
    clocks = []
    rclpy_node.create_subscription(Clock, '/clock', clocks.append, 1000)

    def turn():
        sim.run_once()
        return len(clocks) >= 5
    assert spin_until(rclpy_node, turn, 60), (len(sent), sim.t_ns)
    ticks = [m.clock.sec * NS + m.clock.nanosec for m in clocks]
    assert all(t % 10_000_000 == 0 for t in ticks), ticks[:5]
    assert ticks == sorted(set(ticks)) and ticks[-1] <= sim.t_ns


def test_the_loop_reads_the_contexts_state_without_rclpys_wrapper(rclpy_node, simulator):
    """``run``'s loop checks at every turn that ROS is still up, from the context's handle:
    rclpy's ``Context.ok`` (its lock, then the handle entered) cost ~10 µs of every
    lockstep exchange on the loaded machine. The run still turns and ends, and the loop
    itself never asks ``Context.ok`` (before, at every turn; the executor's own turns
    still do, once per 20 ms in lockstep)."""
    import sys
    sim = simulator(real_time_factor=1.0, publish_rate=100.0, duration=0.3)
    asked, turns = [], []
    ok, run_once = sim.context.ok, sim.run_once

    def spy():
        caller = sys._getframe(1).f_code
        asked.append((caller.co_name, caller.co_filename.endswith('simulator.py')))
        return ok()
    sim.context.ok = spy
    sim.run_once = lambda: (turns.append(1), run_once())[1]
    try:
        sim.run()
    finally:
        del sim.context.ok
    assert sim.finished and sim.t_ns == 300_000_000
    # several turns (a loaded machine catches up several samples in one): the loop's check
    # ran at each; the executor's turns asked
    assert len(turns) >= 3 and asked, (len(turns), asked)
    assert ('run', True) not in asked, asked


def test_a_held_instant_waits_for_its_command_in_the_same_turn(rclpy_node, simulator):
    """Lockstep as fast as possible: the turn that publishes a control instant's state and
    holds it returns a wait (the executor then blocks until the command arrives), not 0,
    which cost a second, idle turn of the executor per exchange. The command resumes it."""
    from geometry_msgs.msg import Vector3Stamped
    sim = simulator(lockstep=True, publish_clock=True, real_time_factor=0.0,
                    publish_rate=50.0, control_rate=50.0, lockstep_timeout=30.0)
    wait = sim.run_once()
    assert sim.lockstep_held is not None and sim.t_ns == 0
    assert wait > 0
    pub = rclpy_node.create_publisher(Vector3Stamped, sim.get_namespace() + '/torque_command',
                                      10)
    assert spin_until(rclpy_node, lambda: pub.get_subscription_count() > 0, 30)
    pub.publish(Vector3Stamped())  # stamp 0: the held instant's
    from rclpy.executors import SingleThreadedExecutor
    executor = SingleThreadedExecutor(context=sim.context)
    executor.add_node(sim)
    try:
        assert spin_until(rclpy_node, lambda: (executor.spin_once(timeout_sec=0.05),
                                               sim.run_once(), sim.t_ns)[-1] == 20_000_000,
                          30), sim.t_ns
    finally:
        executor.remove_node(sim)
        executor.shutdown()
    assert sim.lockstep_held is not None  # the next instant, held in turn


def test_the_held_instants_command_takes_the_short_way(rclpy_node, simulator):
    """Lockstep as fast as possible, one spacecraft: the command stamped with the held
    instant's stamp is applied and releases the instant without the general path
    (``_route``: message objects, routing, every check; sim_lockstep.py says why), and the
    next instant is held in turn. Every other command still goes the general way and is
    counted there: a wrong frame, a NaN, a second answer to an instant (stale), one for an
    instant not held (unexpected). Before, every command took the general path."""
    from geometry_msgs.msg import Vector3Stamped
    sim = simulator(lockstep=True, publish_clock=True, real_time_factor=0.0,
                    publish_rate=50.0, control_rate=50.0, lockstep_timeout=30.0)
    routed = []
    route = sim._route
    sim._route = lambda header, vector, source: (routed.append(header.frame_id),
                                                 route(header, vector, source))

    def command(stamp_ns, frame='base_link', z=0.01):
        msg = Vector3Stamped()
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, NS)
        msg.header.frame_id, msg.vector.z = frame, z
        sim._on_torque_bytes(serialize_message(msg))
    sim.run_once()
    assert sim.lockstep_held is not None and sim.t_ns == 0
    command(0, frame='other_frame')  # the held stamp, another frame: general, rejected
    command(0, z=float('nan'))       # not finite: general, rejected
    assert routed == ['other_frame', 'base_link'] and sim.lockstep_held is not None
    command(0)                       # the held instant's command: the short way
    assert routed == ['other_frame', 'base_link']
    assert sim._crafts[''].engine.command.torque.tolist() == [0.0, 0.0, 0.01]
    # released, and the next instant stepped to and held (in this call, as fast as
    # possible: test_the_next_instant_is_stepped_to_and_published_at_once)
    sim.run_once()
    assert sim.t_ns == 20_000_000 and sim.lockstep_held is not None
    held = sim.lockstep_held
    command(0)                       # answered already: general, stale
    command(60_000_000)              # not held: general, unexpected
    rejected = sim._crafts[''].commands.rejected
    assert len(routed) == 4 and rejected['wrong_frame'] == 1 and \
        rejected['non_finite'] == 1 and rejected['lockstep_stale'] == 1 and \
        rejected['lockstep_unexpected'] == 1, rejected
    command(20_000_000, frame='')    # an empty frame is the body's: the short way
    assert len(routed) == 4 and sim.lockstep_held != held, held


def test_the_next_instant_is_stepped_to_and_published_at_once(rclpy_node, simulator,
                                                              namespace):
    """Lockstep as fast as possible: the held instant's command steps the engine to the
    next instant in one compiled call, publishes its state and holds it, in the same call
    (``_direct_exchange``), without ``Engine.advance`` (before, the loop's next turn went
    through ``_advance``, ``Engine.advance`` and ``_publish``) or a one-sample block's
    encoding (``_packers``). Every state topic, as a
    subscriber receives it, equals that of a simulator doing the same exchanges the
    general way (every field, stamps included)."""
    from rigid_body_sim.nodes.simulator import Simulator
    from stamp_checks import STATE_TOPICS
    values = dict(lockstep=True, publish_clock=True, real_time_factor=0.0,
                  integrator='splitting4', publish_rate=50.0, control_rate=50.0,
                  lockstep_timeout=30.0, inertia=[2.0, 0.1, 0.0, 0.1, 3.0, 0.2, 0.0, 0.2, 4.0],
                  initial_angular_velocity=[0.3, -0.2, 0.1])
    direct = simulator(**values)
    general = Simulator(namespace=namespace + '_general', parameter_overrides=[
        Parameter(k, value=v) for k, v in values.items()])
    general._direct_exchange = lambda craft: None  # the general way only
    got = {}
    try:
        sims = (direct, general)
        for sim in sims:
            kinds = dict(sim._crafts[''].msgs.topics())  # {name: message}
            for pub, name in sim._crafts[''].pubs:
                if name in STATE_TOPICS:
                    rclpy_node.create_subscription(
                        type(kinds[name]), pub.topic_name,
                        lambda m, key=(sim is direct, name): got.setdefault(key, []).append(m),
                        1000)
        assert spin_until(rclpy_node, lambda: all(
            pub.get_subscription_count() > 0 for sim in sims
            for pub, name in sim._crafts[''].pubs if name in STATE_TOPICS), 30)
        calls, encoded = [], []
        engine = direct._crafts[''].engine
        advance = engine.advance
        engine.advance = lambda *a, **k: (calls.append(a[0]), advance(*a, **k))[1]
        msgs = direct._crafts[''].msgs
        encode = msgs.encoded_block
        msgs.encoded_block = lambda *a, **k: (encoded.append(1), encode(*a, **k))[1]
        for sim in sims:
            sim.run_once()  # t = 0, published and held
            assert sim.lockstep_held is not None and sim.t_ns == 0
        assert calls == [0]
        exchanges = 40
        for k in range(exchanges):
            msg = Vector3Stamped()
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(k * 20_000_000, NS)
            msg.vector.x, msg.vector.z = 0.01 * (k % 3), -0.02 if k % 5 else 0.0
            data = serialize_message(msg)
            direct._on_torque_bytes(data)
            # the next instant at once: stepped to, published, held
            assert direct.t_ns == (k + 1) * 20_000_000 and direct.lockstep_held is not None
            general._on_torque_bytes(data)
            general.run_once()
            assert general.t_ns == direct.t_ns and general.lockstep_held is not None
        assert calls == [0], calls  # no Engine.advance after t = 0
        # each topic packed from the row (_packers), not through a one-sample block
        assert len(encoded) == 1, len(encoded)
        topics = [name for _, name in direct._crafts[''].pubs if name in STATE_TOPICS]
        assert len(topics) >= 9, topics
        assert spin_until(rclpy_node, lambda: all(
            len(got.get((side, name), [])) == exchanges + 1 for side in (True, False)
            for name in topics), 60), {k: len(v) for k, v in got.items()}
    finally:
        general.destroy_node()
    for name in topics:
        assert got[(True, name)] == got[(False, name)], name
    # and counted alike (diagnostics' messages_built)
    assert direct._crafts[''].msgs.built() == general._crafts[''].msgs.built()
    stamps = [m.header.stamp.sec * NS + m.header.stamp.nanosec for m in got[(True, 'odometry')]]
    assert stamps == [k * 20_000_000 for k in range(exchanges + 1)]


def test_lockstep_at_real_time_calls_the_engine_only_when_a_sample_is_due(rclpy_node,
                                                                          simulator):
    """Lockstep at real time: once the held instant's command is in, the next turn before
    the next sample is due leaves the engine alone (before, it called it to find no
    event, at every exchange) and waits until then; once due, the run goes on to the
    next instant, published and held."""
    sim = simulator(lockstep=True, publish_clock=True, real_time_factor=1.0,
                    publish_rate=1.0, control_rate=1.0, command_timeout=2.0,
                    lockstep_timeout=30.0)
    engine = sim._crafts[''].engine
    calls = []
    advance = engine.advance
    engine.advance = lambda *a, **k: (calls.append(a[0]), advance(*a, **k))[1]
    sim.run_once()
    assert sim.lockstep_held is not None and sim.t_ns == 0
    msg = Vector3Stamped()
    msg.header.frame_id, msg.vector.z = 'base_link', 0.01
    sim._on_torque_bytes(serialize_message(msg))  # stamp 0: the held instant's
    assert sim.lockstep_held is None
    del calls[:]
    wait = sim.run_once()  # the next sample is due a second after t = 0
    assert calls == [] and sim.t_ns == 0 and wait > 0, (calls, sim.t_ns, wait)
    assert spin_until(rclpy_node, lambda: (sim.run_once(), sim.t_ns)[-1] == NS, 30), sim.t_ns
    assert calls and sim.lockstep_held is not None


def test_the_loop_waits_for_the_exchanges_command_itself(ros_process, simulator, namespace,
                                                        tmp_path, monkeypatch):
    """Lockstep as fast as possible with the controller (a real process): while an instant
    is held for the node's torque_command, the loop waits for it on its own (an rcl wait
    set of that subscription), never in a turn of the executor, which turns for the rest
    without waiting, once per EXECUTOR_SLICE_S (sim_lockstep.py: why); the exchanges
    follow one another in a loop of their own, not a turn of ``run``'s loop each. Every
    instant is answered. Before, each exchange's wait was a turn of the events executor."""
    import contextlib
    from ros_helpers import venv_exe
    from rigid_body_sim.nodes import simulator as node_module
    from rigid_body_sim.tools.lockstep import SCENE
    turns = []
    opened = node_module.events_executor

    @contextlib.contextmanager
    def counted(node):
        with opened(node) as executor:
            spin = executor.spin_once

            class Counted:  # the executor, its turns recorded
                def __getattr__(self, name):
                    return getattr(executor, name)

                def spin_once(self, timeout_sec=None):
                    turns.append((timeout_sec, node.lockstep_held is not None and
                                  ('', 'torque') in node._awaiting))
                    return spin(timeout_sec=timeout_sec)
            yield Counted()
    monkeypatch.setattr(node_module, 'events_executor', counted)
    over = tmp_path / 'controller.yaml'
    over.write_text('/**/attitude_controller:\n  ros__parameters:\n    lockstep: true\n'
                    '    control_rate: 100.0\n')
    ros_process(venv_exe('controller'), '--ros-args', '-r', f'__ns:={namespace}',
                '--params-file', SCENE, '--params-file', str(over))
    sim = simulator(lockstep=True, publish_clock=True, real_time_factor=0.0,
                    publish_rate=100.0, control_rate=100.0, lockstep_timeout=30.0,
                    duration=1.0, wait_for_subscribers_timeout=60.0)
    once, loop_turns = sim.run_once, []
    sim.run_once = lambda: (loop_turns.append(1), once())[1]
    sim.run()
    assert sim._round_trips.count == 100, sim._round_trips.summary()
    # the exchanges run in a loop of their own (_exchanges), back to run's loop for the
    # executor, diagnostics and subscriber counts (before: a turn of it per exchange)
    assert len(loop_turns) < 50, len(loop_turns)
    assert sim.kernels_after_t0() == 0  # the direct period's too, loaded before t = 0
    held = [t for t, waiting in turns if waiting]
    assert all(t == 0.0 for t in held), held[:10]


@pytest.mark.parametrize('frame, stamp, vector', [
    ('', (0, 0), (0.0, 0.0, 0.0)),
    ('base_link', (12, 340_000_000), (1e-3, -2.5e-7, 3.0)),
    ('b', (2**31 - 1, 999_999_999), (float('inf'), float('nan'), -0.0)),
    ('sc1/base_link_long_name', (1, 1), (5e-324, -1.7976931348623157e308, 1.0))])
def test_commands_decode_from_their_bytes_as_rclpy_does(frame, stamp, vector):
    """The torque command's CDR bytes (little- and big-endian) give the fields rclpy's
    deserialiser gives, bit for bit (NaN included); bytes of another layout are left to it."""
    import math
    import struct
    from geometry_msgs.msg import Vector3Stamped
    from rclpy.serialization import deserialize_message
    from rigid_body_sim.nodes.commands import vector3_stamped
    msg = Vector3Stamped()
    msg.header.frame_id = frame
    msg.header.stamp.sec, msg.header.stamp.nanosec = stamp
    msg.vector.x, msg.vector.y, msg.vector.z = vector
    data = serialize_message(msg)
    big = (b'\x00\x00\x00\x00' + struct.pack('>iII', *stamp, len(frame) + 1) + frame.encode()
           + b'\x00')
    big += b'\x00' * (-(len(big) - 4) % 8) + struct.pack('>3d', *vector)
    for raw in (data, big):
        got = vector3_stamped(raw)
        ref = deserialize_message(data, Vector3Stamped)
        assert got.header.frame_id == ref.header.frame_id
        assert (got.header.stamp.sec, got.header.stamp.nanosec) == stamp
        for a, b in zip((got.vector.x, got.vector.y, got.vector.z),
                        (ref.vector.x, ref.vector.y, ref.vector.z)):
            assert struct.pack('<d', a) == struct.pack('<d', b) or (math.isnan(a) and
                                                                    math.isnan(b))
    with pytest.raises(Exception):
        vector3_stamped(data[:-8])  # truncated: rclpy's own error


@pytest.mark.parametrize('frame, stamp, quaternion', [
    ('world', (0, 0), (0.0, 0.0, 0.0, 1.0)),
    ('w', (3, 20_000_000), (0.1, -0.2, 0.3, 0.9273618495495704)),
    ('a_longer_frame/name', (2**31 - 1, 1), (float('nan'), -0.0, 5e-324, 1e308))])
def test_states_decode_from_their_bytes_as_rclpy_does(frame, stamp, quaternion):
    """The lockstep controller takes the simulator's attitude as CDR bytes: they give the
    fields rclpy's deserialiser gives, bit for bit (NaN included), little- and big-endian;
    bytes of another layout are left to rclpy, which raises for them."""
    import struct
    from geometry_msgs.msg import QuaternionStamped
    from rclpy.serialization import deserialize_message
    from rigid_body_sim.nodes.commands import quaternion_stamped
    msg = QuaternionStamped()
    msg.header.frame_id = frame
    msg.header.stamp.sec, msg.header.stamp.nanosec = stamp
    o = msg.quaternion
    o.x, o.y, o.z, o.w = quaternion
    data = serialize_message(msg)
    ref = deserialize_message(data, QuaternionStamped)
    big = (b'\x00\x00\x00\x00' + struct.pack('>iII', *stamp, len(frame) + 1) + frame.encode()
           + b'\x00')
    big += b'\x00' * (-(len(big) - 4) % 8) + struct.pack('>4d', *quaternion)
    for raw in (data, big):
        got = quaternion_stamped(raw)
        assert got.header.frame_id == ref.header.frame_id
        assert (got.header.stamp.sec, got.header.stamp.nanosec) == stamp
        q, r = got.quaternion, ref.quaternion
        assert struct.pack('<4d', q.x, q.y, q.z, q.w) == struct.pack('<4d', r.x, r.y, r.z, r.w)
    with pytest.raises(Exception):
        quaternion_stamped(data[:-8])  # truncated: rclpy's own error


@pytest.mark.parametrize('frame, child', [
    ('world', 'base_link'), ('w', 'b'), ('abc', 'leader/base_link'), ('wxyz', 'bcdefgh')])
def test_odometry_decodes_to_the_state_rclpy_reads(frame, child):
    """The lockstep controller takes the state as one nav_msgs/Odometry's CDR bytes: the
    attitude (header, orientation) and the body rate (stamp, child_frame_id, twist's
    angular) it decodes are rclpy's fields bit for bit, whatever the frame ids' lengths
    (the doubles' alignment after them); bytes of another layout go to rclpy, which
    raises for them."""
    import struct
    from nav_msgs.msg import Odometry
    from rclpy.serialization import deserialize_message
    from rigid_body_sim.nodes.commands import odometry_state
    msg = Odometry()
    msg.header.frame_id, msg.child_frame_id = frame, child
    msg.header.stamp.sec, msg.header.stamp.nanosec = 7, 20_000_000
    o, w = msg.pose.pose.orientation, msg.twist.twist.angular
    o.x, o.y, o.z, o.w = 0.1, -0.2, float('nan'), 0.9273618495495704
    w.x, w.y, w.z = 5e-324, -0.0, 1e308
    # the fields around them, which must not be read in their place
    msg.pose.pose.position.z, msg.twist.twist.linear.x = 11.0, 12.0
    msg.pose.covariance[35], msg.twist.covariance[0] = 13.0, 14.0
    data = serialize_message(msg)
    ref = deserialize_message(data, Odometry)
    attitude, rate = odometry_state(data)
    assert attitude.header.frame_id == frame and rate.header.frame_id == child
    assert (attitude.header.stamp.sec, attitude.header.stamp.nanosec) == (7, 20_000_000)
    assert (rate.header.stamp.sec, rate.header.stamp.nanosec) == (7, 20_000_000)
    q, r = attitude.quaternion, ref.pose.pose.orientation
    assert struct.pack('<4d', q.x, q.y, q.z, q.w) == struct.pack('<4d', r.x, r.y, r.z, r.w)
    v, r = rate.vector, ref.twist.twist.angular
    assert struct.pack('<3d', v.x, v.y, v.z) == struct.pack('<3d', r.x, r.y, r.z)
    with pytest.raises(Exception):
        odometry_state(data[:-8])  # truncated: rclpy's own error


@pytest.mark.parametrize('frame', ['', 'b', 'base_link', 'abcdefgh', 'sc1/base_link_long'])
def test_commands_encode_to_the_bytes_rclpy_reads(frame):
    """The controller publishes its command as CDR bytes it builds itself: rclpy's
    deserialiser reads them as the message it would have serialised, field for field, and
    they are as long as rclpy's own bytes; our decoder reads them back."""
    from geometry_msgs.msg import Vector3Stamped
    from rclpy.serialization import deserialize_message
    from rigid_body_sim.nodes.commands import vector3_stamped_cdr, vector3_stamped_fields
    msg = Vector3Stamped()
    msg.header.frame_id = frame
    msg.header.stamp.sec, msg.header.stamp.nanosec = 12, 340_000_000
    msg.vector.x, msg.vector.y, msg.vector.z = 1e-3, -2.5e-7, 0.0
    data = vector3_stamped_cdr(12, 340_000_000, frame, 1e-3, -2.5e-7, 0.0)
    assert deserialize_message(data, Vector3Stamped) == msg
    assert len(data) == len(serialize_message(msg))
    assert vector3_stamped_fields(data) == (12, 340_000_000, frame, 1e-3, -2.5e-7, 0.0)
