"""The simulator node in an orbit: the ``orbit`` topic, the orbit frame on /tf and the
``environment_torque``, exchanged as real messages with a running node (that a free body
has none of them: test_node_interfaces)."""
import math
import os

import numpy as np
from ros_helpers import spin_until, venv_exe
from scipy.spatial.transform import Rotation

from geometry_msgs.msg import QuaternionStamped, WrenchStamped
from nav_msgs.msg import Odometry
from rclpy.qos import QoSProfile, ReliabilityPolicy

from rigid_body_sim.engine import EngineConfig
from rigid_body_sim.physics import orbit
from rigid_body_sim.physics.orbit import frames
from rigid_body_sim.scene import load

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _stamp(msg):
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def test_orbit_topics_carry_the_orbit_its_frame_and_the_torque(ros_process, namespace,
                                                                 rclpy_node):
    """The gravity_gradient scene at 1000x: ``orbit`` holds the Kepler state at each
    sample's sim time (stamps are sim time with publish_clock), /tf the LVLH rotation,
    ``environment_torque`` 3μ/r³ ĉ × (Iĉ) for the attitude published at the same stamp."""
    from tf2_msgs.msg import TFMessage
    lvlh = namespace.strip('/') + '_lvlh'  # /tf is global: our frame tells our messages
    ros_process(venv_exe('simulator'), '--ros-args', '-r', f'__ns:={namespace}',
                '--params-file', 'config/gravity_gradient.yaml', '-p', 'publish_clock:=true',
                '-p', f'orbit.frame_id:={lvlh}', '-p', 'publish_rate:=1.0',
                '-p', 'real_time_factor:=50.0', cwd=REPO)
    got = {'orbit': [], 'environment_torque': [], 'attitude': [], 'tf': []}
    qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    for name, kind in (('orbit', Odometry), ('environment_torque', WrenchStamped),
                       ('attitude', QuaternionStamped)):
        rclpy_node.create_subscription(kind, f'{namespace}/{name}',
                                       lambda m, name=name: got[name].append(m), qos)
    rclpy_node.create_subscription(
        TFMessage, '/tf', lambda m: got['tf'].extend(t for t in m.transforms
                                                     if t.child_frame_id == lvlh), qos)
    assert spin_until(rclpy_node, lambda: all(len(v) >= 5 for v in got.values()), 60.0), \
        {k: len(v) for k, v in got.items()}
    scene = load(os.path.join(REPO, 'config', 'gravity_gradient.yaml'))
    config = EngineConfig.from_parameters(scene.simulator)
    o = config.environment.orbit
    attitude = {_stamp(m): m.quaternion for m in got['attitude']}
    tf = {_stamp(t): t for t in got['tf']}
    checked = 0
    for odo, wrench in zip(got['orbit'], got['environment_torque']):
        t = _stamp(odo)
        assert _stamp(wrench) == t and odo.header.frame_id == 'world'
        assert odo.child_frame_id == lvlh and wrench.header.frame_id == 'base_link'
        r, v = o.state(t)
        p = odo.pose.pose.position
        np.testing.assert_allclose([p.x, p.y, p.z], r, rtol=0, atol=1e-6)
        axes = frames.lvlh_axes(r, v)
        w = odo.twist.twist.linear  # the inertial velocity, resolved in the orbit frame
        np.testing.assert_allclose(axes @ [w.x, w.y, w.z], v, rtol=0, atol=1e-9)
        assert abs(math.hypot(w.x, w.y, w.z) - math.sqrt(orbit.MU / o.a)) < 1e-6  # circular
        q = odo.pose.pose.orientation
        np.testing.assert_allclose(Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix(), axes,
                                   atol=1e-12)
        if t in tf:
            r_tf = tf[t].transform.rotation
            assert tf[t].header.frame_id == 'world'
            assert [r_tf.x, r_tf.y, r_tf.z, r_tf.w] == [q.x, q.y, q.z, q.w]
        if t in attitude:  # the torque for the attitude of that sample (body = principal)
            a = attitude[t]
            body = Rotation.from_quat([a.x, a.y, a.z, a.w]).as_matrix()
            c = body.T @ (r / np.linalg.norm(r))
            inertia = np.array(scene.simulator['inertia'])
            tau = 3 * orbit.MU / np.linalg.norm(r) ** 3 * np.cross(c, inertia * c)
            tq = wrench.wrench.torque
            np.testing.assert_allclose([tq.x, tq.y, tq.z], tau, rtol=1e-9,
                                       atol=1e-12 * np.abs(tau).max())
            assert np.abs(tau).max() > 1e-8  # it acts: the start is off the equilibrium
            checked += 1
    assert checked >= 3

