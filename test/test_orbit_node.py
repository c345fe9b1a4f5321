"""The simulator node in an orbit: the ``orbit`` topic, the orbit frame on /tf and the
``environment_torque``, exchanged as real messages with a running node (that a free body
has none of them: test_node_interfaces)."""
import math
import os

import numpy as np
from cli_inprocess import run_cli
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


def _scene(tmp_path, **changes):
    """config/gravity_gradient.yaml with some of its simulator keys changed (its node
    section wins over -p, as rcl resolves a node's own entries first)."""
    text = open(os.path.join(REPO, 'config', 'gravity_gradient.yaml')).read()
    for key, value in changes.items():
        lines = [line for line in text.splitlines() if line.strip().startswith(f'{key}:')]
        assert len(lines) == 1, key
        indent = lines[0][:len(lines[0]) - len(lines[0].lstrip())]
        text = text.replace(lines[0], f'{indent}{key}: {value}')
    path = tmp_path / 'gravity_gradient.yaml'
    path.write_text(text)
    return str(path)


def _stamp(msg):
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def test_orbit_topics_carry_the_orbit_its_frame_and_the_torque(ros_process, namespace,
                                                                 rclpy_node, tmp_path):
    """The gravity_gradient scene at 1000x: ``orbit`` holds the Kepler state at each
    sample's sim time (stamps are sim time with publish_clock), /tf the LVLH rotation,
    ``environment_torque`` 3μ/r³ ĉ × (Iĉ) for the attitude published at the same stamp."""
    from tf2_msgs.msg import TFMessage
    lvlh = namespace.strip('/') + '_lvlh'  # /tf is global: our frame tells our messages
    scene_file = _scene(tmp_path, publish_rate=1.0, real_time_factor=50.0)
    ros_process(venv_exe('simulator'), '--ros-args', '-r', f'__ns:={namespace}',
                '--params-file', scene_file, '-p', 'publish_clock:=true',
                '-p', f'orbit.frame_id:={lvlh}', cwd=REPO)
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



def test_an_offline_bag_carries_the_orbit_topics(tmp_path):
    """rigid-body-sim run writes the live node's orbit topics into the bag, stamped with sim
    time: the Kepler position at each sample and the torque for that sample's attitude."""
    from rclpy.serialization import deserialize_message
    from rigid_body_sim.bag.reader import iter_messages
    out = tmp_path / 'run'
    proc = run_cli('run', 'gravity_gradient', '--duration', '200', '--no-plots', '--out', out)
    assert proc.returncode == 0, proc.stderr
    scene = load(os.path.join(REPO, 'config', 'gravity_gradient.yaml'))
    o = EngineConfig.from_parameters(scene.simulator).environment.orbit
    got = {'/orbit': {}, '/environment_torque': {}, '/attitude': {}}
    kinds = {'/orbit': Odometry, '/environment_torque': WrenchStamped,
             '/attitude': QuaternionStamped}
    for m in iter_messages(str(out / 'bag'), topics=list(got)):
        got[m.topic][m.log_time_ns] = deserialize_message(m.data, kinds[m.topic])
    assert len(got['/orbit']) == len(got['/attitude']) == 21  # 0.1 Hz over 200 s
    inertia = np.array(scene.simulator['inertia'])
    for t_ns, odo in got['/orbit'].items():
        r, _ = o.state(t_ns / 1e9)
        p = odo.pose.pose.position
        np.testing.assert_allclose([p.x, p.y, p.z], r, rtol=0, atol=1e-6)
        a = got['/attitude'][t_ns].quaternion
        c = Rotation.from_quat([a.x, a.y, a.z, a.w]).as_matrix().T @ (r / np.linalg.norm(r))
        tau = 3 * orbit.MU / np.linalg.norm(r) ** 3 * np.cross(c, inertia * c)
        tq = got['/environment_torque'][t_ns].wrench.torque
        np.testing.assert_allclose([tq.x, tq.y, tq.z], tau, rtol=1e-9,
                                   atol=1e-12 * np.abs(tau).max())


def test_a_live_recording_carries_the_orbit_topics(ros_process, namespace, tmp_path):
    """The recorder records orbit and environment_torque by default, as offline bags hold
    them: the simulator (waiting for the recorder, 200 s at 1000x) ends, then the bag has
    every sample of both, as many as of the attitude."""
    from test_recorder import start_recorder, wait_output
    from rigid_body_sim.bag.reader import read_info
    bag = tmp_path / 'live'
    rec = start_recorder(ros_process, namespace, bag)
    wait_output(rec, f'subscribed to {namespace}/orbit', timeout=60)
    sim = ros_process(venv_exe('simulator'), '--ros-args', '-r', f'__ns:={namespace}',
                      '--params-file', _scene(tmp_path, duration=200.0),
                      '-p', 'wait_for_subscribers:=1', cwd=REPO,
                      env={'PYTHONUNBUFFERED': '1'})
    assert sim.wait(timeout=120) == 0, sim.output()  # the run ends at its duration
    assert rec.stop() == 0, rec.output()
    counts = {topic: read_info(str(bag)).topics[f'{namespace}/{topic}'].count
              for topic in ('orbit', 'environment_torque', 'attitude')}
    assert counts['attitude'] == 21 and len(set(counts.values())) == 1, counts  # 0.1 Hz


def test_an_offline_bag_carries_the_sum_of_the_environments_torques(tmp_path):
    """explorer1_orbit (gravity gradient + drag on six facets): environment_torque at each
    sample is 3μ/r³ ĉ × (Iĉ) plus Σ r_cp × F_drag, both from the closed forms for the
    attitude recorded at the same stamp (the drag dominates near perigee)."""
    from rclpy.serialization import deserialize_message
    from rigid_body_sim.bag.reader import iter_messages
    from rigid_body_sim.physics.environment import facets as fm
    out = tmp_path / 'run'
    proc = run_cli('run', 'explorer1_orbit', '--duration', '5', '--no-plots', '--out', out)
    assert proc.returncode == 0, proc.stderr
    config = EngineConfig.from_parameters(load(os.path.join(
        REPO, 'config', 'explorer1_orbit.yaml')).simulator)
    env = config.environment
    got = {'/environment_torque': {}, '/attitude': {}}
    kinds = {'/environment_torque': WrenchStamped, '/attitude': QuaternionStamped}
    for m in iter_messages(str(out / 'bag'), topics=list(got)):
        got[m.topic][m.log_time_ns] = deserialize_message(m.data, kinds[m.topic])
    assert len(got['/environment_torque']) == 6
    inertia = np.array([0.04, 0.2, 0.2])
    for t_ns, wrench in got['/environment_torque'].items():
        t = t_ns / 1e9
        r, v = env.orbit.state(t)
        a = got['/attitude'][t_ns].quaternion
        to_body = Rotation.from_quat([a.x, a.y, a.z, a.w]).as_matrix().T
        c = to_body @ (r / np.linalg.norm(r))
        gg = 3 * orbit.MU / np.linalg.norm(r) ** 3 * np.cross(c, inertia * c)
        v_rel = v - np.cross([0.0, 0.0, 7.2921158553e-5], r)
        _, drag = env.sunlight.facets.drag(to_body @ v_rel, fm.exponential_density(fm.height(r)))
        tq = wrench.wrench.torque
        assert np.linalg.norm(drag) > 10 * np.linalg.norm(gg)
        np.testing.assert_allclose([tq.x, tq.y, tq.z], gg + drag, rtol=1e-9,
                                   atol=1e-12 * np.linalg.norm(drag))
