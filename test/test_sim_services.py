"""The simulation_interfaces services of the simulator, called over DDS by a real client.

Play, pause, step while paused, entity state get/set, reset, stop and quit on a real
simulator process; the samples it publishes show what each call did.
"""
import time

import numpy as np
import pytest
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

from ros_helpers import call_service as _call, spin_until, stamp_ns as _stamp, venv_exe

import simulation_interfaces.srv as srv  # noqa: E402  (built by make venv)
from simulation_interfaces.msg import Result, SimulationState, SimulatorFeatures  # noqa: E402

NS = 1_000_000_000


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
            SimulatorFeatures.SIMULATION_STATE_PAUSE, SimulatorFeatures.STEP_SIMULATION_ACTION,
            SimulatorFeatures.ENTITY_INFO_GETTING, SimulatorFeatures.ENTITY_TAGS,
            SimulatorFeatures.ENTITY_CATEGORIES, SimulatorFeatures.AVAILABLE_WORLDS,
            SimulatorFeatures.WORLD_LOADING, SimulatorFeatures.WORLD_INFO_GETTING,
            SimulatorFeatures.WORLD_RESOURCE_STRING} <= set(features)
    assert {SimulatorFeatures.SPAWNING, SimulatorFeatures.DELETING} <= set(features)  # fleet
    # what is not served is not claimed
    assert not {SimulatorFeatures.SPAWNING_ENTITIES,
                SimulatorFeatures.ENTITY_BOUNDS, SimulatorFeatures.WORLD_UNLOADING,
                SimulatorFeatures.SIMULATION_RESET_TIME,
                SimulatorFeatures.NAMED_POSES} & set(features)
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
    _pause(rclpy_node, base, att)
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
    # the same instant (a different state would differ by far more); the sample may differ
    # from the engine's state in the last bit (seen: 1 ulp)
    assert _stamp(got.state) == _stamp(att[-1])
    assert np.allclose([o.x, o.y, o.z, o.w], [q.x, q.y, q.z, q.w], rtol=0, atol=1e-12)
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


def _pause(node, base, *received):
    """Pause the simulator at ``base``; then wait until each list of ``received`` messages
    (a topic's, stamped per sample) holds the last sample published before the pause, the
    stamp of the entity state: on a loaded machine it may still be in flight after any
    fixed spin, and arrive after the count the test takes."""
    req = srv.SetSimulationState.Request()
    req.state.state = SimulationState.STATE_PAUSED
    client = node.create_client(srv.SetSimulationState, f'{base}/set_simulation_state')
    # sent again if its response is lost (ros_helpers.call_service): a second request
    # finds the simulator paused by the first
    sends = []
    got = _call(node, client, req, resend=5.0, sends=sends).result.result
    assert got == Result.RESULT_OK or sends[0] > 1 and \
        got == srv.SetSimulationState.Response.ALREADY_IN_TARGET_STATE, (got, sends)
    client = node.create_client(srv.GetEntityState, f'{base}/get_entity_state')
    last = _stamp(_call(node, client, srv.GetEntityState.Request(entity='base_link'),
                        resend=5.0).state)
    assert spin_until(node, lambda: all(r and _stamp(r[-1]) >= last for r in received), 30.0), \
        [(_stamp(r[-1]) - last) / NS for r in received if r]


def _send_goal(node, client, steps, feedback):
    from simulation_interfaces.action import SimulateSteps
    assert spin_until(node, client.server_is_ready, 60.0)
    future = client.send_goal_async(SimulateSteps.Goal(steps=steps), feedback_callback=lambda m:
                                    feedback.append(m.feedback))
    assert spin_until(node, future.done, 30.0)
    handle = future.result()
    assert handle.accepted
    return handle


def _goal_result(node, handle):
    future = handle.get_result_async()
    assert spin_until(node, future.done, 60.0)
    return future.result()


def test_simulate_steps_action_feedback_and_cancellation(ros_process, namespace, rclpy_node):
    """The SimulateSteps action: refused while playing; n steps paused, each published, with
    feedback after each; a long goal cancelled halfway stops at once and says where."""
    from action_msgs.msg import GoalStatus
    from geometry_msgs.msg import QuaternionStamped
    from rclpy.action import ActionClient
    from simulation_interfaces.action import SimulateSteps
    sim = ros_process(venv_exe('simulator'), '--ros-args', '-r', f'__ns:={namespace}',
                      '-p', 'publish_rate:=50.0', '-p', 'publish_clock:=true')
    base = f'{namespace}/attitude_simulator'
    att = []
    # keep all: the cancelled goal publishes its steps in one burst, over 1000 under load
    keep_all = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
    rclpy_node.create_subscription(QuaternionStamped, f'{namespace}/attitude', att.append,
                                   keep_all)
    assert spin_until(rclpy_node, lambda: len(att) >= 5, 60.0), sim.output()[-2000:]
    client = ActionClient(rclpy_node, SimulateSteps, f'{base}/simulate_steps')
    # every feedback message on the wire: rclpy's client drops those of a goal whose result
    # came first (another channel), so the client's callback may miss the last ones
    wire = []
    rclpy_node.create_subscription(SimulateSteps.Impl.FeedbackMessage,
                                   f'{base}/simulate_steps/_action/feedback', wire.append, 1000)

    def sent(handle):
        return [(m.feedback.completed_steps, m.feedback.remaining_steps) for m in wire
                if bytes(m.goal_id.uuid) == bytes(handle.goal_id.uuid)]
    # while playing: aborted with the reason
    feedback = []
    done = _goal_result(rclpy_node, _send_goal(rclpy_node, client, 3, feedback))
    assert done.status == GoalStatus.STATUS_ABORTED
    assert done.result.result.result == Result.RESULT_INCORRECT_STATE
    assert 'not paused' in done.result.result.error_message and not feedback
    _pause(rclpy_node, base, att)
    before = len(att)
    last = _stamp(att[-1])
    # 7 steps: 7 samples one period apart, feedback 1..7
    handle = _send_goal(rclpy_node, client, 7, feedback)
    done = _goal_result(rclpy_node, handle)
    assert done.status == GoalStatus.STATUS_SUCCEEDED, done.result.result.error_message
    assert done.result.result.result == Result.RESULT_OK
    assert spin_until(rclpy_node, lambda: len(att) >= before + 7 and len(sent(handle)) >= 7,
                      30.0), (len(att) - before, sent(handle))
    spin_until(rclpy_node, lambda: False, 0.5)
    assert [_stamp(m) for m in att[before:]] == [last + k * 20_000_000 for k in range(1, 8)]
    assert sent(handle) == [(k, 7 - k) for k in range(1, 8)] and feedback
    # a long goal, cancelled after some feedback: it stops there, and says so
    feedback.clear()
    before, n = len(att), 1_000_000
    handle = _send_goal(rclpy_node, client, n, feedback)
    assert spin_until(rclpy_node, lambda: len(feedback) >= 5, 60.0)
    cancel = handle.cancel_goal_async()
    assert spin_until(rclpy_node, cancel.done, 30.0)
    assert len(cancel.result().goals_canceling) == 1
    done = _goal_result(rclpy_node, handle)
    assert done.status == GoalStatus.STATUS_CANCELED
    message = done.result.result.error_message
    assert message.startswith('canceled after ') and message.endswith(f' of {n} steps')
    completed = int(message.split()[2])
    assert 5 <= completed < n
    # the state topics keep the last STATE_DEPTH samples (reliable): a loaded reader may
    # miss some of a fast goal's, never the last; it is the state after `completed` steps
    start = _stamp(att[before - 1])
    spin_until(rclpy_node, lambda: _stamp(att[-1]) >= start + completed * 20_000_000, 30.0)
    spin_until(rclpy_node, lambda: False, 1.0)  # nothing more comes: it stopped
    final = _stamp(att[-1])
    assert final == start + completed * 20_000_000, (final - start, completed)
    assert before < len(att) <= before + completed
    # each step's feedback in order; a fast goal may overwrite some in the server's history
    # before they are acknowledged (KEEP_LAST), never the last
    got = sent(handle)
    assert got[-1] == (completed, n - completed), got[-3:]
    assert all(c + r == n for c, r in got) and [c for c, _ in got] == sorted({c for c, _ in got})
    assert sim.poll() is None, sim.output()[-2000:]


ACTUATED = """\
/**/attitude_simulator:
  ros__parameters:
    inertia: [1.0, 2.0, 2.5]
    initial_angular_velocity: [0.1, -0.2, 0.3]
    publish_rate: 20.0
    actuators.command: forward
    actuators.wheels.axes: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0]
    actuators.wheels.initial_speed: [10.0, -20.0]
    actuators.cmgs.cluster: pyramid
    actuators.cmgs.initial_angles: [0.1, -0.2, 0.3, 0.4]
"""


def _filters(pattern='', categories=(), tags=(), all_tags=False):
    from simulation_interfaces.msg import EntityCategory, EntityFilters, TagsFilter
    return EntityFilters(filter=pattern, categories=[EntityCategory(category=c)
                                                     for c in categories],
                         tags=TagsFilter(tags=list(tags), filter_mode=int(all_tags)))


def test_entities_are_the_spacecraft_its_wheels_and_cmgs(ros_process, namespace, rclpy_node,
                                                          tmp_path):
    """GetEntities / GetEntitiesStates / GetEntityInfo / GetEntityState against what the
    simulator itself publishes (attitude, wheel_states, gimbal_states), filters honoured."""
    from geometry_msgs.msg import QuaternionStamped, Vector3Stamped
    from sensor_msgs.msg import JointState
    from simulation_interfaces.msg import EntityCategory
    scene = tmp_path / 'actuated.yaml'
    scene.write_text(ACTUATED)
    sim = ros_process(venv_exe('simulator'), '--ros-args', '-r', f'__ns:={namespace}',
                      '--params-file', str(scene))
    base = f'{namespace}/attitude_simulator'
    topics = {'attitude': (QuaternionStamped, []), 'angular_velocity': (Vector3Stamped, []),
              'wheel_states': (JointState, []), 'gimbal_states': (JointState, [])}
    for name, (kind, store) in topics.items():
        rclpy_node.create_subscription(kind, f'{namespace}/{name}', store.append, 1000)
    got = {name: store for name, (_, store) in topics.items()}
    assert spin_until(rclpy_node, lambda: all(len(s) >= 3 for s in got.values()), 60.0), \
        sim.output()[-2000:]
    _pause(rclpy_node, base, *got.values())  # the state stays that of the last sample
    att, rate = got['attitude'][-1], got['angular_velocity'][-1]
    wheels, gimbals = got['wheel_states'][-1], got['gimbal_states'][-1]
    assert _stamp(att) == _stamp(wheels) == _stamp(gimbals)
    client = {name: rclpy_node.create_client(getattr(srv, cls), f'{base}/{name}')
              for name, cls in (('get_entities', 'GetEntities'),
                                ('get_entities_states', 'GetEntitiesStates'),
                                ('get_entity_info', 'GetEntityInfo'),
                                ('get_entity_state', 'GetEntityState'))}

    def names(**kw):
        out = _call(rclpy_node, client['get_entities'],
                    srv.GetEntities.Request(filters=_filters(**kw)))
        assert out.result.result == Result.RESULT_OK, out.result.error_message
        return list(out.entities)
    wheel_names = ['base_link/wheel_1', 'base_link/wheel_2']
    cmg_names = [f'base_link/gimbal_{k}' for k in range(1, 5)]
    assert names() == ['base_link'] + wheel_names + cmg_names
    assert names(pattern='wheel') == wheel_names
    assert names(pattern='^base_link$') == ['base_link']
    assert names(categories=[EntityCategory.CATEGORY_ROBOT]) == ['base_link']
    assert names(tags=['reaction_wheel', 'cmg']) == wheel_names + cmg_names  # any
    assert names(tags=['actuator', 'cmg'], all_tags=True) == cmg_names
    assert names(tags=['actuator', 'spacecraft'], all_tags=True) == []
    bad = _call(rclpy_node, client['get_entities'],
                srv.GetEntities.Request(filters=_filters(pattern='(')))
    assert bad.result.result == Result.RESULT_OPERATION_FAILED and \
        'not a valid regular expression' in bad.result.error_message

    # states: the spacecraft in frame_id, the actuators in the body frame
    states = _call(rclpy_node, client['get_entities_states'],
                   srv.GetEntitiesStates.Request(filters=_filters()))
    assert states.result.result == Result.RESULT_OK
    by_name = dict(zip(states.entities, states.states))
    assert list(by_name) == ['base_link'] + wheel_names + cmg_names
    body = by_name['base_link']
    q = att.quaternion
    o = body.pose.orientation
    assert body.header.frame_id == 'world' and _stamp(body) == _stamp(att)
    # the same instant; the sample went through the block's rounding
    assert np.allclose([o.x, o.y, o.z, o.w], [q.x, q.y, q.z, q.w], rtol=0, atol=1e-12)
    w_body = np.array([rate.vector.x, rate.vector.y, rate.vector.z])
    from rigid_body_sim.physics import rotation
    w = body.twist.angular
    assert np.allclose([w.x, w.y, w.z], rotation.rotate([q.x, q.y, q.z, q.w], w_body),
                       atol=1e-12)
    axes = np.eye(3)[:2]
    for k, name in enumerate(wheel_names):
        st = by_name[name]
        w = st.twist.angular
        assert st.header.frame_id == 'base_link'
        assert np.allclose([w.x, w.y, w.z], axes[k] * wheels.velocity[k], rtol=1e-12, atol=0)
        assert abs(wheels.velocity[k]) > 1.0  # the scene's initial speeds, give or take
    for k, name in enumerate(cmg_names):
        o = by_name[name].pose.orientation
        angle = 2 * np.arctan2(np.linalg.norm([o.x, o.y, o.z]), o.w)
        assert angle == pytest.approx(abs(gimbals.position[k]), abs=1e-12)
        assert gimbals.position[k] == pytest.approx([0.1, -0.2, 0.3, 0.4][k], abs=1e-12)
    # one by one, and their info
    one = _call(rclpy_node, client['get_entity_state'],
                srv.GetEntityState.Request(entity=wheel_names[1]))
    assert one.result.result == Result.RESULT_OK and one.state == by_name[wheel_names[1]]
    info = _call(rclpy_node, client['get_entity_info'],
                 srv.GetEntityInfo.Request(entity=cmg_names[0]))
    assert info.result.result == Result.RESULT_OK and set(info.info.tags) == {'actuator', 'cmg'}
    assert info.info.category.category == EntityCategory.CATEGORY_DYNAMIC_OBJECT
    info = _call(rclpy_node, client['get_entity_info'],
                 srv.GetEntityInfo.Request(entity='base_link'))
    assert info.info.category.category == EntityCategory.CATEGORY_ROBOT
    missing = _call(rclpy_node, client['get_entity_info'],
                    srv.GetEntityInfo.Request(entity='base_link/wheel_9'))
    assert missing.result.result == Result.RESULT_NOT_FOUND and \
        'base_link/wheel_2' in missing.result.error_message


SPUN = """\
/**/attitude_simulator:
  ros__parameters:
    scene: {name: spun}
    inertia: [1.0, 2.0, 2.5]
    initial_angular_velocity: [0.0, 0.0, 3.0]
    publish_rate: 20.0
"""


def test_worlds_are_scenes_loaded_live(ros_process, namespace, rclpy_node):
    """GetAvailableWorlds lists the scenes; LoadWorld switches to one without a restart (its
    parameters, then its initial state); one the node cannot apply live is refused with the
    reason and changes nothing; GetCurrentWorld follows."""
    from geometry_msgs.msg import Vector3Stamped
    from simulation_interfaces.msg import TagsFilter
    sim = ros_process(venv_exe('simulator'), '--ros-args', '-r', f'__ns:={namespace}',
                      '-p', 'publish_rate:=20.0')
    base = f'{namespace}/attitude_simulator'
    rates = []
    rclpy_node.create_subscription(Vector3Stamped, f'{namespace}/angular_velocity',
                                   rates.append, 1000)
    assert spin_until(rclpy_node, lambda: len(rates) >= 3, 60.0), sim.output()[-2000:]
    client = {name: rclpy_node.create_client(getattr(srv, cls), f'{base}/{name}')
              for name, cls in (('get_available_worlds', 'GetAvailableWorlds'),
                                ('load_world', 'LoadWorld'),
                                ('get_current_world', 'GetCurrentWorld'))}
    listed = _call(rclpy_node, client['get_available_worlds'], srv.GetAvailableWorlds.Request())
    assert listed.result.result == Result.RESULT_OK
    worlds = {w.name: w for w in listed.worlds}
    assert {'default', 'detumble', 'slew', 'wheel_slew', 'cmg_slew'} <= set(worlds)
    assert worlds['wheel_slew'].world_resource.uri.endswith('wheel_slew.yaml')
    assert 'wheels' in worlds['wheel_slew'].tags and 'wheels' not in worlds['detumble'].tags
    wheeled = _call(rclpy_node, client['get_available_worlds'], srv.GetAvailableWorlds.Request(
        filter=TagsFilter(tags=['wheels'], filter_mode=TagsFilter.FILTER_MODE_ANY)))
    assert [w.name for w in wheeled.worlds] == ['wheel_slew']
    none = _call(rclpy_node, client['get_current_world'], srv.GetCurrentWorld.Request())
    assert none.result.result == srv.GetCurrentWorld.Response.NO_WORLD_LOADED

    # detumble, live: its inertia and initial rate, |I w| = |L0| from the next samples on
    loaded = _call(rclpy_node, client['load_world'], srv.LoadWorld.Request(uri='detumble'))
    assert loaded.result.result == Result.RESULT_OK, loaded.result.error_message
    assert loaded.world.name == 'detumble'
    inertia, w0 = np.array([1.0, 2.0, 2.5]), np.array([1.0, -2.0, 1.5])

    def l_norm(v):
        return np.linalg.norm(inertia * [v.x, v.y, v.z])
    # the old world's samples may still be in the queue on a loaded machine (5 were, at
    # load 10): wait for the new world's (within 1e-3), then they must be exact
    assert spin_until(rclpy_node, lambda: abs(l_norm(rates[-1].vector) / np.linalg.norm(
        inertia * w0) - 1) < 1e-3, 30.0), [l_norm(r.vector) for r in rates[-8:]]
    w = rates[-1].vector
    assert np.linalg.norm(inertia * [w.x, w.y, w.z]) == pytest.approx(
        np.linalg.norm(inertia * w0), rel=1e-9)
    current = _call(rclpy_node, client['get_current_world'], srv.GetCurrentWorld.Request())
    assert current.result.result == Result.RESULT_OK and current.world.name == 'detumble'

    # wheels need other topics: refused, named, nothing changed
    refused = _call(rclpy_node, client['load_world'], srv.LoadWorld.Request(uri='wheel_slew'))
    assert refused.result.result == srv.LoadWorld.Response.UNSUPPORTED_ELEMENTS
    assert 'actuators.wheels.axes' in refused.result.error_message and \
        '--params-file' in refused.result.error_message
    current = _call(rclpy_node, client['get_current_world'], srv.GetCurrentWorld.Request())
    assert current.world.name == 'detumble'
    n = len(rates)
    assert spin_until(rclpy_node, lambda: len(rates) >= n + 3, 30.0)
    w = rates[-1].vector
    assert np.linalg.norm(inertia * [w.x, w.y, w.z]) == pytest.approx(
        np.linalg.norm(inertia * w0), rel=1e-9)
    # no such scene, no uri
    gone = _call(rclpy_node, client['load_world'], srv.LoadWorld.Request(uri='detumbel'))
    assert gone.result.result == srv.LoadWorld.Response.NO_RESOURCE and \
        'detumble' in gone.result.error_message
    empty = _call(rclpy_node, client['load_world'], srv.LoadWorld.Request())
    assert empty.result.result == srv.LoadWorld.Response.NO_RESOURCE
    # a params file's text: a spin about the major axis stays exactly that spin
    spun = _call(rclpy_node, client['load_world'], srv.LoadWorld.Request(resource_string=SPUN))
    assert spun.result.result == Result.RESULT_OK, spun.result.error_message
    assert spun.world.name == 'spun'
    n = len(rates)
    assert spin_until(rclpy_node, lambda: len(rates) >= n + 3, 30.0)
    w = rates[-1].vector
    assert [w.x, w.y, w.z] == [0.0, 0.0, 3.0]
    broken = _call(rclpy_node, client['load_world'],
                   srv.LoadWorld.Request(resource_string='attitude_simulator: [\n'))
    assert broken.result.result == srv.LoadWorld.Response.RESOURCE_PARSE_ERROR and \
        broken.result.error_message.startswith('resource_string'), broken.result.error_message
    current = _call(rclpy_node, client['get_current_world'], srv.GetCurrentWorld.Request())
    assert current.world.name == 'spun'
    assert sim.poll() is None, sim.output()[-2000:]


def test_simulate_steps_in_lockstep_waits_for_each_control_instants_command(
        ros_process, namespace, rclpy_node):
    """Lockstep holds the clock at each control instant until its command: SimulateSteps
    then steps up to the instant, waits there for the command (serving a cancel meanwhile),
    and goes on when it comes; step_simulation, which cannot wait, stops at the instant and
    says how far it got. Before, a step at a held instant advanced nothing and the action
    still reported it done."""
    from action_msgs.msg import GoalStatus
    from geometry_msgs.msg import QuaternionStamped, Vector3Stamped
    from rclpy.action import ActionClient
    from simulation_interfaces.action import SimulateSteps
    sim = ros_process(venv_exe('simulator'), '--ros-args', '-r', f'__ns:={namespace}',
                      '-p', 'publish_rate:=50.0', '-p', 'publish_clock:=true',
                      '-p', 'lockstep:=true', '-p', 'control_rate:=25.0',
                      '-p', 'integrator:=splitting4', '-p', 'lockstep_timeout:=60.0',
                      '-p', 'wait_for_subscribers_timeout:=60.0')
    base = f'{namespace}/attitude_simulator'
    att = []
    rclpy_node.create_subscription(QuaternionStamped, f'{namespace}/attitude', att.append, 1000)
    pub = rclpy_node.create_publisher(Vector3Stamped, f'{namespace}/torque_command', 10)

    def answer(t_ns):  # the controller's command for the state stamped t_ns
        msg = Vector3Stamped()
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t_ns, NS)
        msg.vector.z = 0.01
        pub.publish(msg)
    assert spin_until(rclpy_node, lambda: len(att) >= 1, 60.0), sim.output()[-2000:]
    _pause(rclpy_node, base)
    client = ActionClient(rclpy_node, SimulateSteps, f'{base}/simulate_steps')
    feedback = []
    handle = _send_goal(rclpy_node, client, 4, feedback)
    spin_until(rclpy_node, lambda: False, 1.0)  # held at t = 0: nothing moves
    assert [_stamp(m) for m in att] == [0] and not feedback
    answer(0)  # steps 1-2 reach the instant 0.04 s, which holds step 3
    assert spin_until(rclpy_node, lambda: len(att) >= 3, 30.0)
    spin_until(rclpy_node, lambda: False, 0.5)
    assert [_stamp(m) for m in att] == [0, 20_000_000, 40_000_000]
    answer(40_000_000)
    done = _goal_result(rclpy_node, handle)
    assert done.status == GoalStatus.STATUS_SUCCEEDED, done.result.result.error_message
    assert spin_until(rclpy_node, lambda: len(att) >= 5, 30.0)
    assert [_stamp(m) for m in att] == [k * 20_000_000 for k in range(5)]
    # step_simulation at the held instant 0.08 s: stops there, with the reason
    step = rclpy_node.create_client(srv.StepSimulation, f'{base}/step_simulation')
    got = _call(rclpy_node, step, srv.StepSimulation.Request(steps=3)).result
    assert got.result == Result.RESULT_OPERATION_FAILED
    assert got.error_message.startswith('stepped 0 of 3: lockstep holds t = 0.08 s'), \
        got.error_message
    # a goal waiting at the instant is cancelled there
    handle = _send_goal(rclpy_node, client, 2, feedback)
    spin_until(rclpy_node, lambda: False, 0.5)
    cancel = handle.cancel_goal_async()
    assert spin_until(rclpy_node, cancel.done, 30.0)
    done = _goal_result(rclpy_node, handle)
    assert done.status == GoalStatus.STATUS_CANCELED
    assert done.result.result.error_message == 'canceled after 0 of 2 steps'
    assert len(att) == 5 and sim.poll() is None, sim.output()[-2000:]
