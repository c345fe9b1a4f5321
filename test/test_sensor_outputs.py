"""What sensor scenes produce outside the engine: the offline bag's sensor topics (read by
rosbags), the pointing plot, and the scene running with ROS made unimportable. Slower than
test_sensors.py (subprocesses, plots), so not in the fast subset."""
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from rigid_body_sim import offline, scene as S
from rigid_body_sim.sensors import noise as N

CONFIG = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), 'config')
POINTING = os.path.join(CONFIG, 'gyro_pointing.yaml')


def load(*overrides):
    return S.load(POINTING, overrides)


def test_gyro_pointing_runs_without_ros():
    """The sensors, the estimator and the scene need no ROS (rclpy and the message packages
    made unimportable); only the bag writer does."""
    mods = ('rclpy', 'builtin_interfaces', 'geometry_msgs', 'std_msgs', 'sensor_msgs',
            'nav_msgs', 'diagnostic_msgs', 'rosgraph_msgs', 'std_srvs', 'rcl_interfaces')
    code = ('import sys; ' + '; '.join(f'sys.modules[{m!r}] = None' for m in mods) + '\n'
            'import rigid_body_sim.scene as S, rigid_body_sim.offline as O\n'
            f'r = O.simulate(S.load({POINTING!r}), duration=1.0, keep="none")\n'
            'print(r.sample_count)\n')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ['51']


def test_offline_bag_carries_the_sensor_topics_for_an_independent_reader(tmp_path):
    """`rigid-body-sim run gyro_pointing` for 2 s: the bag read with rosbags (a reader we
    did not write) has /gyro as sensor_msgs/msg/Imu (101 readings, base_link, covariance
    N²/h + σ_gm², orientation covariance[0] = −1) and /star_tracker as
    geometry_msgs/msg/QuaternionStamped (11 fixes, world), in time order with the state."""
    pytest.importorskip('rclpy')
    from rosbags.highlevel import AnyReader
    scene = load()
    bag = offline.BagSink(scene, str(tmp_path / 'bag'), {})
    try:
        offline.simulate(scene, duration=2.0, sinks=[bag], keep='none')
    finally:
        bag.close()
    with AnyReader([tmp_path / 'bag']) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        assert types['/gyro'] == 'sensor_msgs/msg/Imu'
        assert types['/star_tracker'] == 'geometry_msgs/msg/QuaternionStamped'
        gyro, star, times = [], [], []
        for conn, t, raw in reader.messages():
            times.append(t)
            if conn.topic == '/gyro':
                gyro.append(reader.deserialize(raw, conn.msgtype))
            elif conn.topic == '/star_tracker':
                star.append(reader.deserialize(raw, conn.msgtype))
    assert len(gyro) == 101 and len(star) == 11
    assert times == sorted(times)
    p = scene.simulator
    variance = p['sensors.gyro.angle_random_walk'] ** 2 / 0.02 + \
        N.gauss_markov_sigma(p['sensors.gyro.bias_instability']) ** 2
    m = gyro[3]
    assert m.header.frame_id == 'base_link' and m.orientation_covariance[0] == -1.0
    np.testing.assert_allclose(m.angular_velocity_covariance.reshape(3, 3),
                               variance * np.eye(3), rtol=1e-12)
    assert all(s.header.frame_id == 'world' for s in star)
    assert [s.header.stamp.nanosec + s.header.stamp.sec * 10 ** 9 for s in star] == \
        [k * 200_000_000 for k in range(11)]


def test_run_plots_the_pointing_error_of_a_sensor_scene(tmp_path):
    """`rigid-body-sim run gyro_pointing` adds pointing.png (error against time and its
    distribution against the prediction) to the usual three plots; slew (truth) does not.
    In the test's process (cli_inprocess): what the command writes, not its process."""
    from cli_inprocess import run_cli
    out = run_cli('run', POINTING, '--duration', '30', '--out', tmp_path, '--no-bag')
    assert out.returncode == 0, out.stderr
    assert f'plot: {tmp_path / "pointing.png"}' in out.stdout
    assert (tmp_path / 'pointing.png').stat().st_size > 20_000
    out = run_cli('run', os.path.join(CONFIG, 'slew.yaml'), '--duration', '1', '--out',
                  tmp_path / 'slew', '--no-bag')
    assert out.returncode == 0 and 'pointing.png' not in out.stdout, out.stderr
    assert 'plot:' in out.stdout  # the usual plots, without the pointing one


def test_an_offline_bag_carries_sun_direction_as_the_live_recorder_would(tmp_path):
    """The offline bag, read with rosbags (not our reader): /sun_direction is
    geometry_msgs/msg/Vector3Stamped in base_link, one per lit reading; the live recorder
    records it by default too."""
    pytest.importorskip('rclpy')
    from rosbags.highlevel import AnyReader
    from rigid_body_sim import node_interfaces
    assert 'sun_direction' in node_interfaces.RECORDED_BY_DEFAULT
    scene = S.load('gravity_gradient', ['sun_sensor.enabled=true', 'sun_sensor.rate=0.1',
                                        'epoch=2026-03-20T12:00:00Z'])
    bag = offline.BagSink(scene, str(tmp_path / 'bag'), {})
    try:
        offline.simulate(scene, duration=600.0, sinks=[bag], keep='none')
    finally:
        bag.close()
    with AnyReader([tmp_path / 'bag']) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        assert types['/sun_direction'] == 'geometry_msgs/msg/Vector3Stamped'
        got = [reader.deserialize(raw, conn.msgtype) for conn, _, raw in reader.messages()
               if conn.topic == '/sun_direction']
    assert len(got) == 61 and all(m.header.frame_id == 'base_link' for m in got)
    assert all(abs(math.hypot(m.vector.x, m.vector.y, m.vector.z) - 1.0) < 1e-12 for m in got)
