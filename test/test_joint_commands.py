"""ros2_control's topic contract: JointState commands on ``robot_joint_commands``.

ros2_control is not on PyPI, so the node test speaks the contract of
``joint_state_topic_hardware_interface`` (``JointStateTopicSystem::write``) itself: one
JointState naming every joint of the ``<ros2_control>`` tag, with ``effort`` holding the
wheels' torques and ``velocity`` the gimbals' rates, each in ``name`` order, published
reliable with depth 1. Real simulator, real messages: the wheel speeds and gimbal rates
move in ``wheel_states`` / ``gimbal_states``, bad commands are counted by reason.
"""
import math

import pytest

from ros_helpers import spin_until
from test_simulator import Probe, start_simulator

from rigid_body_sim.engine.actuators import ActuatorConfig
from rigid_body_sim.engine import specs
from rigid_body_sim.nodes.joint_commands import JointCommandError, forward_values
from rigid_body_sim.param_spec import coerce_all

WHEELS = ['rw_a', 'rw_b', 'rw_c']
GIMBALS = ['gimbal_1', 'gimbal_2', 'gimbal_3', 'gimbal_4']
SCENE = dict(actuators__command='forward', actuators__wheels__names=', '.join(WHEELS),
             actuators__wheels__axes=[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
             actuators__wheels__inertia=[0.01], actuators__wheels__max_torque=[0.1],
             actuators__cmgs__cluster='pyramid', actuators__cmgs__momentum=[50.0],
             inertia=[900.0, 1000.0, 700.0], initial_angular_velocity=[0.0, 0.0, 0.0],
             publish_rate=20.0, step=0.01)


def _config():
    p = coerce_all(specs.SIMULATOR, {k.replace('__', '.'): v for k, v in SCENE.items()
                                     if k.startswith('actuators')})
    return ActuatorConfig.from_parameters(p)


@pytest.mark.parametrize('msg, values', [
    # the hardware interface's form: every joint named, effort for the wheels, velocity for
    # the gimbals, each in name order
    (dict(name=WHEELS + GIMBALS, effort=[0.1, 0.2, 0.3], velocity=[1, 2, 3, 4]),
     [0.1, 0.2, 0.3, 1, 2, 3, 4]),
    # a subset, in any order: the others keep their last command
    (dict(name=['gimbal_3', 'rw_c'], effort=[-0.5], velocity=[0.7]),
     [9, 9, -0.5, 9, 9, 0.7, 9]),
    # one entry per name (the usual JointState form) naming only gimbals
    (dict(name=['gimbal_2', 'gimbal_1'], velocity=[0.2, 0.1]), [9, 9, 9, 0.1, 0.2, 9, 9]),
])
def test_forward_values_follow_the_hardware_interfaces_arrays(msg, values):
    last = [9.0] * 3, [9.0] * 4
    got = forward_values(_config(), msg['name'], msg.get('position', []),
                         msg.get('velocity', []), msg.get('effort', []), *last)
    assert got == pytest.approx(values)


@pytest.mark.parametrize('msg, reason, text', [
    (dict(name=['rw_a', 'rw_x'], effort=[0, 0]), 'unknown_joint', "'rw_x'"),
    (dict(name=['rw_a', 'rw_a'], effort=[0, 0]), 'duplicate_joint', "'rw_a' is named twice"),
    (dict(name=WHEELS, effort=[0, 0]), 'wrong_length', 'effort has 2 entries for the 3'),
    (dict(name=['gimbal_1'], velocity=[]), 'wrong_length', 'velocity has 0 entries'),
    (dict(name=['rw_a', 'gimbal_1'], effort=[0], velocity=[1, 2]), 'unsupported_interface',
     "velocity given for wheel 'rw_a'"),
    (dict(name=['gimbal_1'], position=[0.3]), 'unsupported_interface', 'position given'),
    (dict(name=['rw_a', 'gimbal_1'], effort=[math.nan], velocity=[0]), 'non_finite',
     "effort of 'rw_a' is nan"),
    (dict(name=[]), 'wrong_length', 'no joint'),
])
def test_bad_joint_commands_name_the_reason(msg, reason, text):
    with pytest.raises(JointCommandError, match=text) as info:
        forward_values(_config(), msg['name'], msg.get('position', []), msg.get('velocity', []),
                       msg.get('effort', []), [0.0] * 3, [0.0] * 4)
    assert info.value.reason == reason


def test_joint_state_commands_drive_wheels_and_gimbals(ros_process, namespace, rclpy_node):
    """The hardware interface's message spins the wheels and turns the gimbals at the
    commanded rates (seen in wheel_states and gimbal_states, whose joint names it uses);
    unknown joints, NaN and wrong lengths are counted by reason in diagnostics and logged,
    and the last valid command keeps acting."""
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState
    sim = start_simulator(ros_process, namespace, **SCENE)
    wheels, gimbals = [], []
    qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    for topic, into in (('wheel_states', wheels), ('gimbal_states', gimbals)):
        rclpy_node.create_subscription(JointState, f'{namespace}/{topic}',
                                       lambda m, into=into: into.append(m), qos)
    probe = Probe(rclpy_node, namespace)
    # as the hardware interface publishes: rclcpp::QoS(1), reliable
    pub = rclpy_node.create_publisher(JointState, f'{namespace}/robot_joint_commands', 1)
    probe.wait_for(lambda: wheels and gimbals and pub.get_subscription_count() > 0, 60.0,
                   'wheel_states, gimbal_states and the robot_joint_commands subscription')
    assert list(wheels[-1].name) == WHEELS and list(gimbals[-1].name) == GIMBALS

    def send(name, position=(), velocity=(), effort=()):
        msg = JointState(name=list(name), position=list(position), velocity=list(velocity),
                         effort=list(effort))
        msg.header.stamp = rclpy_node.get_clock().now().to_msg()
        pub.publish(msg)
        spin_until(rclpy_node, lambda: False, 0.05)  # depth 1: let each one go out

    send(WHEELS + GIMBALS, effort=[0.05, 0.0, -0.02], velocity=[0.2, 0.2, 0.2, 0.2])
    probe.wait_for(lambda: wheels[-1].velocity[0] > 2.0 and gimbals[-1].position[0] > 0.2,
                   60.0, 'rw_a spinning up and the gimbals turning')
    assert list(gimbals[-1].velocity) == pytest.approx([0.2] * 4)
    assert wheels[-1].velocity[2] < -0.5
    send(['rw_x'] + GIMBALS, effort=[0.1], velocity=[0.0] * 4)        # unknown joint
    send(WHEELS, effort=[0.0, math.nan, 0.0])                         # not finite
    send(WHEELS + GIMBALS, effort=[0.0, 0.0], velocity=[0.0] * 4)     # effort too short
    probe.wait_diag(lambda d, s: d.get('joint_commands_rejected.wrong_length') == '1', 30.0,
                    'the three rejections in diagnostics')
    d = probe.diag()
    assert d['joint_commands_rejected.unknown_joint'] == '1'
    assert d['joint_commands_rejected.non_finite'] == '1'
    assert d['joint_commands_accepted'] == '1'
    out = sim.output()
    assert "robot_joint_commands rejected (unknown_joint): joint 'rw_x'" in out
    assert 'robot_joint_commands rejected (non_finite)' in out
    n, before = len(gimbals), gimbals[-1].position[0]
    probe.wait_for(lambda: len(gimbals) > n + 10, 30.0, 'more gimbal states')
    assert gimbals[-1].position[0] > before and gimbals[-1].velocity[0] == pytest.approx(0.2)
    # a partial command: the gimbals only; the wheels keep their torques
    send(GIMBALS, velocity=[-0.1] * 4)
    probe.wait_for(lambda: gimbals[-1].velocity[0] == pytest.approx(-0.1), 30.0,
                   'the gimbals reversed')
    w = wheels[-1].velocity[0]
    probe.wait_for(lambda: wheels[-1].velocity[0] > w + 0.5, 60.0, 'rw_a still spinning up')
