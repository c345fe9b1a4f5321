"""The simulation_interfaces services of the simulator, called over DDS by a real client.

Play, pause, step while paused, entity state get/set, reset, stop and quit on a real
simulator process; the samples it publishes show what each call did.
"""
import time

import numpy as np
import pytest

from ros_helpers import spin_until, venv_exe

import simulation_interfaces.srv as srv  # noqa: E402  (built by make venv)
from simulation_interfaces.msg import Result, SimulationState, SimulatorFeatures  # noqa: E402

NS = 1_000_000_000


def _call(node, client, request, timeout=30.0):
    assert spin_until(node, client.service_is_ready, 60.0), client.srv_name
    future = client.call_async(request)
    assert spin_until(node, future.done, timeout), client.srv_name
    return future.result()


def _stamp(msg):
    return msg.header.stamp.sec * NS + msg.header.stamp.nanosec


def test_play_pause_step_state_reset_quit(ros_process, namespace, rclpy_node):
    from geometry_msgs.msg import QuaternionStamped, Vector3Stamped
    sim = ros_process(venv_exe('simulator'), '--ros-args', '-r', f'__ns:={namespace}',
                      '-p', 'publish_rate:=50.0', '-p', 'publish_clock:=true',
                      '-p', 'integrator:=exact')
    base = f'{namespace}/attitude_simulator'
    clients = {name: rclpy_node.create_client(getattr(srv, cls), f'{base}/{name}')
               for name, cls in (('get_simulator_features', 'GetSimulatorFeatures'),
                                 ('get_simulation_state', 'GetSimulationState'),
                                 ('set_simulation_state', 'SetSimulationState'),
                                 ('step_simulation', 'StepSimulation'),
                                 ('reset_simulation', 'ResetSimulation'),
                                 ('get_entity_state', 'GetEntityState'),
                                 ('set_entity_state', 'SetEntityState'))}
    att, rates = [], []
    rclpy_node.create_subscription(QuaternionStamped, f'{namespace}/attitude', att.append, 1000)
    rclpy_node.create_subscription(Vector3Stamped, f'{namespace}/angular_velocity',
                                   rates.append, 1000)
    assert spin_until(rclpy_node, lambda: len(att) >= 5, 60.0), sim.output()[-2000:]

    features = _call(rclpy_node, clients['get_simulator_features'],
                     srv.GetSimulatorFeatures.Request()).features.features
    assert {SimulatorFeatures.STEP_SIMULATION_MULTIPLE, SimulatorFeatures.ENTITY_STATE_SETTING,
            SimulatorFeatures.SIMULATION_STATE_PAUSE} <= set(features)
    state = _call(rclpy_node, clients['get_simulation_state'], srv.GetSimulationState.Request())
    assert state.state.state == SimulationState.STATE_PLAYING

    def set_state(value):
        req = srv.SetSimulationState.Request()
        req.state.state = value
        return _call(rclpy_node, clients['set_simulation_state'], req).result

    # stepping while playing is refused
    step = srv.StepSimulation.Request(steps=3)
    assert _call(rclpy_node, clients['step_simulation'], step).result.result == \
        Result.RESULT_OPERATION_FAILED
    # pause: no new samples
    assert set_state(SimulationState.STATE_PAUSED).result == Result.RESULT_OK
    spin_until(rclpy_node, lambda: False, 0.5)
    paused_at = len(att)
    spin_until(rclpy_node, lambda: False, 1.0)
    assert len(att) == paused_at
    last = _stamp(att[-1])
    # step 7: exactly 7 samples, one period apart
    step = srv.StepSimulation.Request(steps=7)
    assert _call(rclpy_node, clients['step_simulation'], step).result.result == Result.RESULT_OK
    assert spin_until(rclpy_node, lambda: len(att) >= paused_at + 7, 30.0)
    spin_until(rclpy_node, lambda: False, 0.5)
    assert [_stamp(m) for m in att[paused_at:]] == [last + k * 20_000_000 for k in range(1, 8)]
    # entity state: the latest sample's attitude, twist in the world frame
    got = _call(rclpy_node, clients['get_entity_state'],
                srv.GetEntityState.Request(entity='base_link'))
    assert got.result.result == Result.RESULT_OK
    o = got.state.pose.orientation
    q = att[-1].quaternion
    assert [o.x, o.y, o.z, o.w] == [q.x, q.y, q.z, q.w]
    missing = _call(rclpy_node, clients['get_entity_state'],
                    srv.GetEntityState.Request(entity='robot'))
    assert missing.result.result == Result.RESULT_NOT_FOUND and 'base_link' in \
        missing.result.error_message
    # set a new state (twist in the body frame), step once: the sample starts from it
    req = srv.SetEntityState.Request(entity='base_link')
    req.state.header.frame_id = 'base_link'
    req.state.pose.orientation.w = 1.0
    req.state.twist.angular.z = 0.5
    assert _call(rclpy_node, clients['set_entity_state'], req).result.result == Result.RESULT_OK
    n = len(rates)
    _call(rclpy_node, clients['step_simulation'], srv.StepSimulation.Request(steps=1))
    assert spin_until(rclpy_node, lambda: len(rates) > n, 30.0)
    w = rates[-1].vector
    assert np.allclose([w.x, w.y, w.z], [0.0, 0.0, 0.5], atol=1e-12)  # a spin about z stays
    # play again: samples advance with the wall clock
    assert set_state(SimulationState.STATE_PLAYING).result == Result.RESULT_OK
    n = len(att)
    assert spin_until(rclpy_node, lambda: len(att) >= n + 20, 30.0)
    # reset: back to the initial state (|L| of ω0 = (0.05, 1, 0), I = (1, 2, 3)), sim time
    # still increasing
    before = _stamp(att[-1])
    reset = _call(rclpy_node, clients['reset_simulation'], srv.ResetSimulation.Request())
    assert reset.result.result == Result.RESULT_OK
    n = len(rates)
    assert spin_until(rclpy_node, lambda: len(rates) >= n + 3, 30.0)
    w = rates[-1].vector
    inertia = np.array([1.0, 2.0, 3.0])
    assert np.linalg.norm(inertia * [w.x, w.y, w.z]) == pytest.approx(
        np.linalg.norm(inertia * [0.05, 1.0, 0.0]), rel=1e-12) and _stamp(att[-1]) > before
    # quit: the node exits by itself, cleanly
    assert set_state(SimulationState.STATE_QUITTING).result == Result.RESULT_OK
    deadline = time.monotonic() + 20
    while sim.poll() is None and time.monotonic() < deadline:
        time.sleep(0.1)
    assert sim.poll() == 0, sim.output()[-2000:]
