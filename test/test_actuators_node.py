"""The simulator node with reaction wheels and CMGs: real node, real messages.

JointState out (wheel_states, gimbal_states), Float64MultiArray in (actuator_command, the
ros2_control forward-command convention), bad commands counted in diagnostics with the
last valid command held, the singularity measure published.
"""
import time

import pytest

from ros_helpers import spin_until
from test_simulator import Probe, start_simulator

from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

WHEELS = dict(actuators__command='forward', actuators__wheels__names='rw_a, rw_b, rw_c',
              actuators__wheels__axes=[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
              actuators__wheels__inertia=[0.01], actuators__wheels__max_torque=[0.1],
              inertia=[4.0, 5.0, 3.0], initial_angular_velocity=[0.0, 0.0, 0.0],
              publish_rate=20.0, step=0.01)


def joints(node, namespace, topic, into):
    qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    node.create_subscription(JointState, f'{namespace}/{topic}',
                             lambda m: into.append((time.monotonic(), m)), qos)


def test_wheel_commands_move_the_wheels_and_bad_ones_are_counted(ros_process, namespace,
                                                                 rclpy_node):
    sim = start_simulator(ros_process, namespace, **WHEELS)
    states = []
    joints(rclpy_node, namespace, 'wheel_states', states)
    probe = Probe(rclpy_node, namespace)
    pub = rclpy_node.create_publisher(Float64MultiArray, f'{namespace}/actuator_command', 10)
    probe.wait_for(lambda: len(states) > 2 and pub.get_subscription_count() > 0, 30.0,
                   'wheel_states and the actuator_command subscription')
    first = states[-1][1]
    assert list(first.name) == ['rw_a', 'rw_b', 'rw_c'] and list(first.position) == []
    assert first.header.frame_id == 'base_link' and list(first.velocity) == [0.0] * 3
    pub.publish(Float64MultiArray(data=[0.05, 0.0, -0.02]))
    # 0.05 N·m on J = 0.01: rw_a gains 5 rad/s per second (relative, minus the body's
    # reaction 0.05/4 per second), rw_c loses 2 − 0.02/3
    probe.wait_for(lambda: states[-1][1].velocity[0] > 5.0, 30.0, 'rw_a spun up')
    v = states[-1][1].velocity
    assert v[2] == pytest.approx(-v[0] * (0.02 * (1 / 0.01 + 1 / 3.0))
                                 / (0.05 * (1 / 0.01 + 1 / 4.0)), rel=1e-6)
    assert v[1] == 0.0
    for bad in ([0.1, 0.0], [float('nan'), 0.0, 0.0]):
        pub.publish(Float64MultiArray(data=bad))
    probe.wait_diag(lambda d, s: d.get('actuator_commands_rejected') == '2', 30.0,
                    'two rejected actuator commands in diagnostics')
    d = probe.diag()
    assert d['actuator_commands_accepted'] == '1'
    assert 'not finite' in d['actuator_last_rejection']  # the last of the two
    before = states[-1][1].velocity[0]
    # the valid command still acts: waited for (a fixed 1 s of this probe's time held too
    # few samples when the simulator or the probe stalled on a loaded machine)
    assert spin_until(rclpy_node, lambda: states[-1][1].velocity[0] > before + 1.0, 30.0), \
        (before, states[-1][1].velocity[0])
    assert 'actuator_command rejected' in sim.output()


def test_cmg_pyramid_publishes_gimbal_states_and_the_singularity_measure(ros_process, namespace,
                                                                        rclpy_node):
    start_simulator(ros_process, namespace, actuators__command='forward',
                    actuators__cmgs__cluster='pyramid', actuators__cmgs__momentum=[50.0],
                    inertia=[900.0, 1000.0, 700.0], initial_angular_velocity=[0.0, 0.0, 0.0],
                    publish_rate=20.0, step=0.01)
    states = []
    joints(rclpy_node, namespace, 'gimbal_states', states)
    probe = Probe(rclpy_node, namespace)
    pub = rclpy_node.create_publisher(Float64MultiArray, f'{namespace}/actuator_command', 10)
    probe.wait_for(lambda: states and pub.get_subscription_count() > 0, 30.0, 'gimbal_states')
    assert list(states[-1][1].name) == ['gimbal_1', 'gimbal_2', 'gimbal_3', 'gimbal_4']
    pub.publish(Float64MultiArray(data=[0.2, 0.2, 0.2, 0.2]))
    probe.wait_for(lambda: states[-1][1].position[0] > 0.3, 30.0, 'gimbals turning')
    m = states[-1][1]
    assert list(m.velocity) == pytest.approx([0.2] * 4) and len(set(m.position)) == 1
    # at equal angles δ the pyramid's det(AAᵀ) is a function of δ only; it is published
    start = 32 / 27  # det(AAᵀ) at δ = 0 for the 54.73° pyramid
    probe.wait_diag(lambda d, s: abs(float(d.get('cmg_singularity_measure', start)) - start)
                    > 0.01, 30.0, 'the singularity measure moving off its δ = 0 value')


def test_offline_run_records_joint_states_and_plots_the_actuators(tmp_path):
    """``rigid-body-sim run`` on the wheel scene: the bag has /wheel_states
    (sensor_msgs/JointState, read back by mcap-ros2-support) with the scene's joint names,
    every sample, and the speeds of the run; actuators.png is written; the run says that
    the skewed wheel's axis given as (1, 1, 1) was normalised."""
    import os
    from cli_inprocess import run_cli
    from mcap_ros2.reader import read_ros2_messages
    config = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), 'config')
    out = run_cli('run', os.path.join(config, 'wheel_slew.yaml'), '--duration', '5',
                  '--out', tmp_path, '--set', 'actuators.wheels.axes=[1,0,0,0,1,0,0,0,1,1,1,1]')
    assert out.returncode == 0, out.stderr
    assert 'rw_skew' in out.stderr and 'normalised' in out.stderr
    assert (tmp_path / 'actuators.png').stat().st_size > 10_000
    bag = next((tmp_path / 'bag').glob('*.mcap'))
    msgs = [m for m in read_ros2_messages(str(bag)) if m.channel.topic == '/wheel_states']
    assert len(msgs) == 101  # 20 Hz for 5 s, both ends
    last = msgs[-1].ros_msg
    assert list(last.name) == ['rw_x', 'rw_y', 'rw_z', 'rw_skew']
    assert msgs[-1].schema.name == 'sensor_msgs/msg/JointState'
    assert any(abs(v) > 1.0 for v in last.velocity) and list(last.position) == []
    assert last.header.stamp.sec == 5


def test_the_recorder_records_the_joint_states_by_default(ros_process, namespace, rclpy_node,
                                                          tmp_path):
    """Recorder (default topics) + simulator with CMGs: /gimbal_states and the
    actuator_command sent are in the bag, read back by rosbags (a reader we did not write)."""
    from pathlib import Path
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore
    from ros_helpers import venv_exe
    bag = tmp_path / 'bag'
    rec = ros_process(venv_exe('recorder'), '--ros-args', '-r', f'__ns:={namespace}',
                      '-p', f'output:={bag}', env={'PYTHONUNBUFFERED': '1'})
    # as the docs record: the simulator holds t = 0 until the recorder is matched (under
    # load that match once came after the run had ended, and the bag had no gimbal_states)
    start_simulator(ros_process, namespace, actuators__command='forward',
                    actuators__cmgs__cluster='pyramid', publish_rate=20.0, step=0.01,
                    initial_angular_velocity=[0.0, 0.0, 0.0], wait_for_subscribers=1)
    states = []
    joints(rclpy_node, namespace, 'gimbal_states', states)
    pub = rclpy_node.create_publisher(Float64MultiArray, f'{namespace}/actuator_command', 10)
    deadline = time.monotonic() + 60.0
    while 'subscribed to ' + f'{namespace}/gimbal_states' not in rec.output():
        assert time.monotonic() < deadline, rec.output()
        spin_until(rclpy_node, lambda: False, 0.2)
    spin_until(rclpy_node, lambda: pub.get_subscription_count() >= 2, 30.0)  # sim + recorder
    pub.publish(Float64MultiArray(data=[0.1, 0.1, 0.1, 0.1]))
    # the gimbals turn at 0.1 rad/s: this probe sees 0.2 rad about 1 s after 0.1, so the
    # recorder, another process, has had that second to take the 0.1 samples before its
    # stop (stopping at this probe's first 0.1 once left the bag at 0.095)
    assert spin_until(rclpy_node, lambda: states and states[-1][1].position[0] > 0.2, 30.0)
    assert rec.stop() == 0, rec.output()
    got = {}
    with AnyReader([Path(bag)], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as r:
        for conn, _, raw in r.messages(connections=r.connections):
            got.setdefault(conn.topic, []).append(r.deserialize(raw, conn.msgtype))
    gimbals = got[f'{namespace}/gimbal_states']
    assert list(gimbals[-1].name) == ['gimbal_1', 'gimbal_2', 'gimbal_3', 'gimbal_4']
    assert max(m.position[0] for m in gimbals) > 0.1
    assert [list(m.data) for m in got[f'{namespace}/actuator_command']] == [[0.1] * 4]
