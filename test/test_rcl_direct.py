"""nodes/rcl_direct.py: rcl's publish, take and wait called from compiled code on rclpy's
handles (one process, a real Fast DDS participant, the session's own ROS domain)."""
import ctypes
import time

import numpy as np
import pytest

pytestmark = pytest.mark.timeout(120)


def _matched(node, pub, sub, within=30.0):
    """Wait until ``pub`` and ``sub`` have matched each other (bounded)."""
    until = time.monotonic() + within
    while pub.get_subscription_count() < 1 or sub.get_publisher_count() < 1:
        assert time.monotonic() < until, 'the publisher and subscription did not match'
        time.sleep(0.02)


def _loopback(node, topic):
    from geometry_msgs.msg import Vector3Stamped
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    pub = node.create_publisher(Vector3Stamped, topic, qos)
    sub = node.create_subscription(Vector3Stamped, topic, lambda m: None, qos, raw=True)
    _matched(node, pub, sub)
    return pub, sub


def test_the_compiled_loop_publishes_each_frame_and_takes_what_came(rclpy_node):
    """floor_loop's exchanges on a topic the node both writes and reads: each frame
    published is the one taken next, byte for byte, and the loop reports all done."""
    from geometry_msgs.msg import Vector3Stamped
    from rclpy.serialization import serialize_message
    from rigid_body_sim.nodes import rcl_direct
    pub, sub = _loopback(rclpy_node, 'loopback')
    frames = []
    for k in range(6):
        m = Vector3Stamped()
        m.header.stamp.sec, m.header.frame_id, m.vector.x = k, 'body', 0.5 * k
        frames.append(serialize_message(m))
    direct = rcl_direct.Exchange(rclpy_node.context, sub, pub)
    try:
        arrays, data = rcl_direct.frames_array(frames, direct.allocator)
        out = np.zeros(2, dtype=np.int64)
        loop = direct.loops['floor_loop']
        for k in range(6):  # one exchange per call: each taken is the one just sent
            loop(direct.wait_set, direct.sub, direct.pub, ctypes.addressof(arrays), k, k + 1,
                 direct.into, 10_000_000_000, out)
            assert out.tolist() == [k + 1, rcl_direct.RET_OK]
            assert direct.taken() == frames[k], k
    finally:
        direct.close()


def test_a_wait_with_nothing_to_take_times_out_and_says_so(rclpy_node):
    """take_or_wait on a subscription nobody writes to returns rcl's timeout (not a
    message, not an error); an rcl error's text names the call and the code."""
    from rigid_body_sim.nodes import rcl_direct
    pub, sub = _loopback(rclpy_node, 'silent')
    direct = rcl_direct.Exchange(rclpy_node.context, sub)
    try:
        ret = direct.loops['take_or_wait'](direct.wait_set, direct.sub, direct.into,
                                           20_000_000)
        assert ret == rcl_direct.RET_TIMEOUT
        # a publish on a null publisher: rcl refuses it with its error state set
        lib = direct.lib
        ret = lib['publish'](0, direct.into, 0)
        assert ret != rcl_direct.RET_OK
        text = rcl_direct.error(lib, ret, 'publish on nothing')
        assert text.startswith(f'publish on nothing: rcl returned {ret}'), text
        assert 'publisher' in text.lower(), text
    finally:
        direct.close()


def test_a_library_not_loaded_is_refused_with_the_reason():
    """rcl's library is taken from this process's own mappings, never loaded a second
    time: one not mapped is Unavailable, naming it."""
    from rigid_body_sim.nodes import rcl_direct
    with pytest.raises(rcl_direct.Unavailable, match='libnot_there.so is not loaded'):
        rcl_direct._mapped('libnot_there.so')


def test_without_rcls_functions_the_simulator_keeps_the_python_way(monkeypatch):
    """Where librcl cannot be had (here: not mapped), the compiled exchanges say why, once
    in the log, and never run (``Compiled.run`` leaves every exchange to Python)."""
    from rigid_body_sim.nodes import rcl_direct, sim_rcl

    def missing(name):
        raise rcl_direct.Unavailable(f'{name} is not loaded in this process')
    logged = []

    class Log:
        def info(self, text):
            logged.append(text)
    rcl_direct.load.cache_clear()
    monkeypatch.setattr(rcl_direct, '_mapped', missing)
    try:
        compiled = sim_rcl.Compiled(Log())
    finally:
        rcl_direct.load.cache_clear()  # the next load reads the real mappings
    assert compiled.loop is None and 'librcl.so is not loaded' in compiled.why
    assert logged == [f'lockstep: exchanges taken in Python ({compiled.why})'], logged

    class Craft:
        engine = None

    class Node:  # what unable reads before its first check
        _direct = _round_trips = _acks = None
    assert compiled.unable(Node(), Craft()) == compiled.why


def test_the_setup_compiles_the_exchanges_for_the_scenes_a_node_runs():
    """``python -m rigid_body_sim.compiled`` (the setup) compiles the lockstep exchanges'
    loop for the argument types a lockstep node passes, so no node compiles it (~10 CPU-s)
    before its first instant: warming it for each built-in scene's engine afterwards adds
    no compiled version."""
    import logging
    from rigid_body_sim import compiled, offline, scene
    from rigid_body_sim.engine import Engine, EngineConfig
    from rigid_body_sim.nodes import rcl_loop, sim_rcl
    config = EngineConfig.from_parameters(
        {'integrator': 'rk4', 'duration': 0.1, 'publish_rate': 20.0},
        {'mode': 'slew', 'target_attitude': [0.0, 0.0, 0.6, 0.8]})
    compiled._warm_exchanges(Engine(config))
    versions = len(rcl_loop.loop.signatures)
    assert versions >= 1
    for name in ('slew', 'detumble', 'wheel_slew', 'explorer1'):
        sim_rcl.Compiled(logging.getLogger(__name__)).warm(offline.engine_for(scene.load(name)))
        assert len(rcl_loop.loop.signatures) == versions, name
