"""Several spacecraft in one simulator: topics and /tf per spacecraft, commands routed or
rejected, spawning and deleting at run time, the entity services against the state.

Real simulator processes (``config/formation.yaml``), real messages, a real client.
"""
import os

import numpy as np
import pytest

from ros_helpers import call_service as _call, spin_until, stamp_ns as _stamp, venv_exe

from rigid_body_sim.engine import fleet
from rigid_body_sim.scene import SceneError, load

NS = 1_000_000_000
CONFIG = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), 'config')
FORMATION = os.path.join(CONFIG, 'formation.yaml')
CRAFTS = ('leader', 'wingman', 'tumbler')


# ------------------------------------------------------------------ the scene (no ROS)
def test_formation_scene_gives_each_spacecraft_its_own_values_and_inherits_the_rest():
    sc = load('formation')
    assert list(sc.spacecraft) == list(CRAFTS) == sc.simulator['spacecraft']
    assert sc.spacecraft['leader']['inertia'] == [10.0, 12.0, 14.0]
    assert 'inertia' not in sc.spacecraft['wingman']  # the node-level [1, 2, 3]
    assert sc.simulator['inertia'] == [1.0, 2.0, 3.0]
    assert sc.spacecraft['tumbler']['dissipation.model'] == 'double_bracket'
    assert sc.spacecraft['wingman']['sensors.gyro.enabled'] is True
    # node-level values hold no spacecraft key (the engine's config reads them)
    assert not [k for k in sc.simulator if k.split('.')[0] in CRAFTS]
    values = fleet.craft_values({**sc.simulator, 'leader.inertia': [4.0, 5.0, 6.0]}, 'leader')
    assert values['inertia'] == [4.0, 5.0, 6.0] and values['child_frame_id'] == \
        'leader/base_link'


@pytest.mark.parametrize('text, reason', [
    ('spacecraft: [a, a]', "'a' is already in use"),
    ('spacecraft: [inertia]', "simulator parameter's name"),
    ('spacecraft: [9lives]', 'must start with a letter'),
    ('spacecraft: [a]\n    a:\n      publish_rate: 5.0', 'a.publish_rate: unknown parameter'),
    ('spacecraft: [a]\n    a:\n      inertia: [1.0, 2.0, 30.0]',
     'spacecraft a: inertia: principal moments'),
])
def test_bad_fleet_scenes_fail_with_the_key_and_reason(tmp_path, text, reason):
    path = tmp_path / 'bad.yaml'
    path.write_text(f'/**/attitude_simulator:\n  ros__parameters:\n    {text}\n')
    with pytest.raises(SceneError, match=None) as info:
        load(str(path))
    assert reason in str(info.value), str(info.value)


def test_an_engine_started_later_samples_on_the_same_grid_from_its_start():
    """A spawned spacecraft's engine (start_ns): its first sample is the first grid instant
    at or after its start, its state there the one it started with, advanced by the time
    between (torque-free, so the closed form; and a start on the grid is sampled at once)."""
    from rigid_body_sim.engine import Engine, EngineConfig
    config = EngineConfig.from_parameters({'publish_rate': 10.0, 'integrator': 'exact',
                                           'initial_angular_velocity': [0.0, 0.0, 0.5]})
    late = Engine(config, start_ns=1_234_000_000)
    assert late.t_ns == 1_234_000_000
    block = late.advance(2_000_000_000)
    assert list(block.t_ns) == [1_300_000_000 + k * 100_000_000 for k in range(8)]
    # a spin about z: the angle at the first sample is 0.5 rad/s x 0.066 s from identity
    q = block.values(0)[0:4]
    assert np.allclose(q, [0, 0, np.sin(0.5 * 0.066 / 2), np.cos(0.5 * 0.066 / 2)], atol=1e-12)
    on_grid = Engine(config, start_ns=1_300_000_000).advance(1_300_000_000)
    assert list(on_grid.t_ns) == [1_300_000_000]


def test_offline_run_refuses_a_fleet_scene():
    from rigid_body_sim.offline import engine_for
    with pytest.raises(SceneError, match='declares spacecraft .*leader.*simulator node'):
        engine_for(load('formation'), duration=1.0)


# ------------------------------------------------------------------ live
class Fleet:
    """A formation simulator in ``namespace`` and a client of it."""

    def __init__(self, ros_process, namespace, node, *params):
        import simulation_interfaces.srv as srv
        from diagnostic_msgs.msg import DiagnosticArray
        self.srv, self.node, self.ns = srv, node, namespace
        args = [a for p in params for a in ('-p', p)]
        self.proc = ros_process(venv_exe('simulator'), '--ros-args', '-r',
                                f'__ns:={namespace}', '--params-file', FORMATION, *args)
        base = f'{namespace}/attitude_simulator'
        self.clients = {}
        for name in ('get_entities', 'get_entities_states', 'get_entity_info',
                     'get_entity_state', 'spawn_entity', 'delete_entity',
                     'get_simulator_features', 'set_simulation_state'):
            cls = ''.join(w.capitalize() for w in name.split('_'))
            self.clients[name] = node.create_client(getattr(srv, cls), f'{base}/{name}')
        self.att = {}
        self.diagnostics = []
        node.create_subscription(DiagnosticArray, '/diagnostics', self._diag, 100)

    def _diag(self, array):
        if any(s.hardware_id == f'{self.ns}/attitude_simulator' for s in array.status):
            self.diagnostics.append(array)

    def listen(self, craft, topic='attitude', msg_type=None):
        from geometry_msgs.msg import QuaternionStamped
        got = self.att.setdefault((craft, topic), [])
        self.node.create_subscription(msg_type or QuaternionStamped,
                                      f'{self.ns}/{craft}/{topic}', got.append, 1000)
        return got

    def call(self, name, **fields):
        cls = ''.join(w.capitalize() for w in name.split('_'))
        request = getattr(self.srv, cls).Request(**fields)
        return _call(self.node, self.clients[name], request)

    def spawn(self, name, w=1.0, z=0.0, **fields):
        request = self.srv.SpawnEntity.Request(name=name, **fields)
        request.initial_pose.pose.orientation.z = z
        request.initial_pose.pose.orientation.w = w
        return _call(self.node, self.clients['spawn_entity'], request)

    def entities(self):
        return list(self.call('get_entities').entities)

    def status(self, name='simulation'):
        """The latest status ``attitude_simulator: <name>`` and its values, or None."""
        for array in reversed(self.diagnostics):
            for s in array.status:
                if s.name == f'attitude_simulator: {name}':
                    return s, {kv.key: kv.value for kv in s.values}
        return None

    def wait(self, predicate, what, timeout=60.0):
        assert spin_until(self.node, predicate, timeout), \
            f'timed out waiting for {what}\n{self.proc.output()[-3000:]}'


def test_formation_topics_tf_and_commands_per_spacecraft(ros_process, namespace, rclpy_node):
    from geometry_msgs.msg import Vector3Stamped
    from sensor_msgs.msg import Imu, JointState
    from std_msgs.msg import Float64
    from tf2_msgs.msg import TFMessage
    f = Fleet(ros_process, namespace, rclpy_node)
    att = {c: f.listen(c) for c in CRAFTS}
    energy = {c: f.listen(c, 'kinetic_energy', Float64) for c in CRAFTS}
    rate = f.listen('wingman', 'angular_velocity', Vector3Stamped)
    gyro = f.listen('wingman', 'gyro', Imu)
    wheels = f.listen('leader', 'wheel_states', JointState)
    tf = []
    rclpy_node.create_subscription(TFMessage, '/tf', tf.append, 1000)
    f.wait(lambda: all(len(a) >= 5 for a in att.values()) and gyro and wheels
           and len(energy['tumbler']) >= 5, 'every spacecraft\'s topics')
    # the same sample instants for all, each in the inertial frame
    stamps = [{_stamp(m) for m in att[c]} for c in CRAFTS]
    assert stamps[0] & stamps[1] & stamps[2]
    assert {m.header.frame_id for c in CRAFTS for m in att[c]} == {'world'}
    assert {m.header.frame_id for m in rate} == {'wingman/base_link'}
    assert gyro[0].header.frame_id == 'wingman/base_link'
    assert list(wheels[0].name) == ['wheel_1', 'wheel_2', 'wheel_3']
    # each its own inertia, state and dissipation: T = ω·Iω / 2
    assert float(energy['leader'][-1].data) == 0.0
    assert float(energy['wingman'][0].data) == pytest.approx(0.5 * 0.02 ** 2, rel=1e-9)
    tumbler = [float(m.data) for m in energy['tumbler']]
    assert tumbler[0] <= 0.5 * (0.05 ** 2 + 2.0) and tumbler[-1] < tumbler[0]  # dissipating
    q = att['wingman'][0].quaternion
    assert np.allclose([q.x, q.y, q.z, q.w], [0, 0, 0.3826834323650898, 0.9238795325112867],
                       atol=0.05)  # 45° about z, rolling slowly about x (0.02 rad/s)
    # /tf: world -> <name>/base_link for each
    f.wait(lambda: {t.child_frame_id for m in tf for t in m.transforms} >= {
        f'{c}/base_link' for c in CRAFTS}, '/tf of every spacecraft')
    assert {t.header.frame_id for m in tf for t in m.transforms
            if t.child_frame_id.endswith('/base_link')} == {'world'}
    # no unnamed spacecraft: nothing on the node's own state topics
    assert rclpy_node.count_publishers(f'{namespace}/attitude') == 0
    # a command on a spacecraft's own topic moves that one only (about z, body frame)
    pub = rclpy_node.create_publisher(Vector3Stamped, f'{namespace}/wingman/torque_command', 10)
    f.wait(lambda: pub.get_subscription_count() > 0, 'the wingman\'s command subscription')
    command = Vector3Stamped()
    command.vector.z = 0.5
    n = len(rate)

    def turned():
        pub.publish(command)
        return len(rate) > n and rate[-1].vector.z > 0.01
    f.wait(turned, 'the wingman turning about z')
    assert float(energy['leader'][-1].data) == 0.0
    # the node's own topic routes by frame_id; one naming no spacecraft is counted
    route = rclpy_node.create_publisher(Vector3Stamped, f'{namespace}/torque_command', 10)
    f.wait(lambda: route.get_subscription_count() > 0, 'the routing subscription')
    ghost = Vector3Stamped()
    ghost.header.frame_id = 'ghost/base_link'
    ghost.vector.x = 0.1

    def rejected():
        route.publish(ghost)
        got = f.status()
        return got is not None and int(got[1]['commands_rejected.unknown_spacecraft']) >= 1
    f.wait(rejected, 'the unknown spacecraft\'s command counted')
    out = f.proc.output()
    assert 'unknown_spacecraft' in out and 'ghost/base_link' in out
    status, values = f.status()
    assert values['spacecraft'] == '3' and values['spacecraft_names'] == \
        'leader, wingman, tumbler'
    assert int(values['messages_published']) > 0  # what the fleet benchmark reads
    for c in CRAFTS:  # a status of its own each, with its physics
        assert 'integrator' in f.status(c)[1]
    # the leader holds its wheels' momentum; its wheel entities are its
    assert f.entities() == ['leader', 'leader/wheel_1', 'leader/wheel_2', 'leader/wheel_3',
                            'wingman', 'tumbler']


def test_spawn_refusals_delete_and_the_empty_simulation(ros_process, namespace, rclpy_node):
    from simulation_interfaces.msg import Result, SimulatorFeatures
    import simulation_interfaces.srv as srv
    Spawn = srv.SpawnEntity.Response
    f = Fleet(ros_process, namespace, rclpy_node)
    att = {c: f.listen(c) for c in CRAFTS}
    f.wait(lambda: all(len(a) >= 3 for a in att.values()), 'the formation running')
    features = set(f.call('get_simulator_features').features.features)
    assert {SimulatorFeatures.SPAWNING, SimulatorFeatures.DELETING,
            SimulatorFeatures.SPAWNING_RESOURCE_STRING} <= features
    # refused, with the reason; nothing changes
    before = f.entities()
    for got, code, words in (
            (f.spawn('leader'), Spawn.NAME_NOT_UNIQUE, "'leader' is running"),
            (f.spawn('bad name'), Spawn.NAME_INVALID, 'must start with a letter'),
            (f.spawn(''), Spawn.NAME_INVALID, 'give the spacecraft a name'),
            (f.spawn('zero', w=0.0), Spawn.INVALID_POSE, 'zero norm'),
            (f.spawn('nan', w=float('nan')), Spawn.INVALID_POSE, 'not finite'),
            (f.spawn('lost', uri='no_such_scene'), Spawn.NO_RESOURCE, 'no_such_scene'),
            (f.spawn('flat', resource_string='/**/attitude_simulator:\n  ros__parameters:\n'
                     '    inertia: [1.0, 2.0, 30.0]\n'), Spawn.RESOURCE_PARSE_ERROR,
             'triangle inequality'),
            (f.spawn('spun', resource_string='/**/attitude_simulator:\n  ros__parameters:\n'
                     '    initial_angular_velocity: [.nan, 0.0, 0.0]\n'),
             Spawn.RESOURCE_PARSE_ERROR, 'initial_angular_velocity')):
        assert got.result.result == code, (words, got.result.error_message)
        assert words in got.result.error_message, got.result.error_message
    assert f.entities() == before
    n = {c: len(att[c]) for c in CRAFTS}
    f.wait(lambda: all(len(att[c]) > n[c] + 3 for c in CRAFTS), 'the formation running on')
    # spawned while running: the slew scene's body, 90° about z, on the others' sample grid
    rescue = f.listen('rescue')
    got = f.spawn('rescue', w=np.sqrt(0.5), z=np.sqrt(0.5), uri='slew')
    assert got.result.result == Result.RESULT_OK and got.entity_name == 'rescue', \
        got.result.error_message
    f.wait(lambda: len(rescue) >= 3, 'the spawned spacecraft\'s samples')
    q = rescue[0].quaternion
    assert np.allclose([q.x, q.y, q.z, q.w], [0, 0, np.sqrt(0.5), np.sqrt(0.5)], atol=0.05)
    f.wait(lambda: {_stamp(m) for m in rescue} & {_stamp(m) for m in att['leader']},
           'a shared sample instant')
    assert 'rescue' in f.entities()
    info = f.call('get_entity_info', entity='rescue')
    assert info.result.result == Result.RESULT_OK and list(info.info.tags) == ['spacecraft']
    renamed = f.spawn('rescue', w=1.0, allow_renaming=True)
    assert renamed.result.result == Result.RESULT_OK and renamed.entity_name == 'rescue_1'
    # delete: its topics leave the graph; wheels go only with their spacecraft
    for name in ('rescue_1', 'wingman'):
        assert f.call('delete_entity', entity=name).result.result == Result.RESULT_OK
    f.wait(lambda: rclpy_node.count_publishers(f'{namespace}/wingman/attitude') == 0,
           'the wingman\'s topics gone')
    assert f.entities() == ['leader', 'leader/wheel_1', 'leader/wheel_2', 'leader/wheel_3',
                            'tumbler', 'rescue']
    for name in ('wingman', 'leader/wheel_1'):
        got = f.call('delete_entity', entity=name)
        assert got.result.result == Result.RESULT_NOT_FOUND and 'tumbler' in \
            got.result.error_message
    # the last one deleted: an empty simulation that runs and says so
    for name in ('leader', 'tumbler', 'rescue'):
        assert f.call('delete_entity', entity=name).result.result == Result.RESULT_OK
    assert f.entities() == []
    f.wait(lambda: f.status() is not None and f.status()[1]['spacecraft'] == '0'
           and 'without spacecraft' in f.status()[0].message, 'the empty simulation reported')
    assert f.status()[0].level == b'\x01'  # WARN
    k = len(f.diagnostics)
    f.wait(lambda: len(f.diagnostics) > k + 1, 'diagnostics going on')
    assert f.proc.poll() is None
    # and a spacecraft may be spawned into it again
    again = f.listen('again')
    assert f.spawn('again').result.result == Result.RESULT_OK
    f.wait(lambda: len(again) >= 2, 'the spacecraft spawned into the empty simulation')
    assert f.entities() == ['again']
    assert f.proc.poll() is None and 'Traceback' not in f.proc.output()


def test_entity_calls_against_the_simulators_state(ros_process, namespace, rclpy_node):
    from geometry_msgs.msg import Vector3Stamped
    from simulation_interfaces.msg import EntityCategory, Result, SimulationState
    f = Fleet(ros_process, namespace, rclpy_node, 'publish_clock:=true')
    att = {c: f.listen(c) for c in CRAFTS}
    rate = {c: f.listen(c, 'angular_velocity', Vector3Stamped) for c in CRAFTS}
    f.wait(lambda: all(len(a) >= 3 for a in att.values()), 'the formation running')
    request = f.srv.SetSimulationState.Request()
    request.state.state = SimulationState.STATE_PAUSED
    assert f.call('set_simulation_state', state=request.state).result.result == \
        Result.RESULT_OK
    got = f.call('get_entities_states')
    assert got.result.result == Result.RESULT_OK
    states = dict(zip(got.entities, got.states))
    assert list(states) == f.entities()
    # the samples in flight at the pause arrive (waited for: a loaded machine may hold them
    # past any fixed spin): each topic's latest reaches its state's stamp
    assert spin_until(rclpy_node, lambda: all(
        _stamp(topic[c][-1]) >= _stamp(states[c]) for topic in (att, rate) for c in CRAFTS), 30.0)
    for c in CRAFTS:  # each spacecraft's state is its latest sample, at its stamp
        s, last, w = states[c], att[c][-1], rate[c][-1]
        assert _stamp(s) == _stamp(last) and s.header.frame_id == 'world'
        o, q = s.pose.orientation, last.quaternion
        assert np.allclose([o.x, o.y, o.z, o.w], [q.x, q.y, q.z, q.w], atol=1e-12)
        body = f.call('get_entity_state', entity=c)
        assert _stamp(body.state) == _stamp(last)
        # the twist in the world frame is the sample's body rate rotated by the attitude
        from rigid_body_sim.physics import rotation
        world = rotation.rotate(np.array([q.x, q.y, q.z, q.w]), [w.vector.x, w.vector.y,
                                                                 w.vector.z])
        a = s.twist.angular
        assert np.allclose([a.x, a.y, a.z], world, atol=1e-12)
    wheel = states['leader/wheel_2']
    assert wheel.header.frame_id == 'leader/base_link'
    info = f.call('get_entity_info', entity='leader/wheel_2')
    assert info.info.category.category == EntityCategory.CATEGORY_DYNAMIC_OBJECT
    assert 'reaction_wheel' in info.info.tags
    # filters: by expression and by category
    filters = f.srv.GetEntities.Request().filters
    filters.filter = '^leader/'
    assert list(f.call('get_entities', filters=filters).entities) == [
        'leader/wheel_1', 'leader/wheel_2', 'leader/wheel_3']
    robots = f.srv.GetEntities.Request().filters
    robots.categories = [EntityCategory(category=EntityCategory.CATEGORY_ROBOT)]
    assert list(f.call('get_entities', filters=robots).entities) == list(CRAFTS)
    # setting one spacecraft's state sets that one only
    set_request = f.srv.SetEntityState.Request(entity='tumbler')
    set_request.state.header.frame_id = 'tumbler/base_link'
    set_request.state.pose.orientation.w = 1.0
    set_request.state.twist.angular.z = 0.25
    client = rclpy_node.create_client(f.srv.SetEntityState,
                                      f'{namespace}/attitude_simulator/set_entity_state')
    assert _call(rclpy_node, client, set_request).result.result == Result.RESULT_OK
    after = f.call('get_entity_state', entity='tumbler').state.twist.angular
    assert np.allclose([after.x, after.y, after.z], [0.0, 0.0, 0.25], atol=1e-12)
    other = f.call('get_entity_state', entity='wingman').state
    assert other.pose.orientation == states['wingman'].pose.orientation


def test_reset_spawned_brings_back_the_scenes_spacecraft(ros_process, namespace, rclpy_node):
    from simulation_interfaces.msg import Result, SimulatorFeatures
    f = Fleet(ros_process, namespace, rclpy_node)
    scene = ['leader', 'leader/wheel_1', 'leader/wheel_2', 'leader/wheel_3', 'wingman',
             'tumbler']
    assert f.entities() == scene
    assert SimulatorFeatures.SIMULATION_RESET_SPAWNED in set(
        f.call('get_simulator_features').features.features)
    assert f.spawn('extra').result.result == Result.RESULT_OK
    assert f.call('delete_entity', entity='wingman').result.result == Result.RESULT_OK
    assert f.entities() == [e for e in scene if e != 'wingman'] + ['extra']
    client = rclpy_node.create_client(f.srv.ResetSimulation,
                                      f'{namespace}/attitude_simulator/reset_simulation')
    got = _call(rclpy_node, client, f.srv.ResetSimulation.Request(
        scope=f.srv.ResetSimulation.Request.SCOPE_SPAWNED))
    assert got.result.result == Result.RESULT_OK
    assert 'removed extra' in got.result.error_message and 'back: wingman' in \
        got.result.error_message
    assert f.entities() == scene  # in the scene's order
    wingman = f.listen('wingman')
    f.wait(lambda: wingman, 'the wingman publishing again')


def test_a_failing_spacecraft_is_named_and_deleting_it_lets_the_others_run(
        ros_process, namespace, rclpy_node):
    """A spawned body whose state overflows (|w| = 1e200 rad/s) stops the simulation: its
    own status is ERROR, the others' WARN (held); deleted, the others run on."""
    from simulation_interfaces.msg import Result
    f = Fleet(ros_process, namespace, rclpy_node)
    att = f.listen('leader')
    f.wait(lambda: len(att) >= 2, 'the formation running')
    wild = f.spawn('wild', resource_string='/**/attitude_simulator:\n  ros__parameters:\n'
                   '    initial_angular_velocity: [1.0e200, 1.0e200, 0.0]\n')
    assert wild.result.result == Result.RESULT_OK

    def stopped():
        got = f.status('wild')
        return got is not None and got[0].level == b'\x02'
    f.wait(stopped, 'the wild spacecraft\'s fault')
    assert 'wild/integrator failed' in f.status()[0].message and f.status()[0].level == b'\x02'
    assert f.status('leader')[0].level == b'\x01' and 'held' in f.status('leader')[0].message
    # stopped: the leader's last sample (its entity state's stamp, the held state) arrives,
    # waited for (more than one may be in flight when the fault's status comes on a loaded
    # machine), and none after it
    last = _stamp(f.call('get_entity_state', entity='leader').state)
    f.wait(lambda: att and _stamp(att[-1]) >= last, "the leader's last sample")
    n = len(att)
    spin_until(rclpy_node, lambda: False, 1.0)
    assert len(att) == n and _stamp(att[-1]) == last, (len(att) - n, _stamp(att[-1]) - last)
    assert f.call('delete_entity', entity='wild').result.result == Result.RESULT_OK
    n = len(att)
    f.wait(lambda: len(att) >= n + 5, 'the others running on')
    f.wait(lambda: f.status()[0].level == b'\x00', 'the simulation OK again')


def test_an_empty_simulation_steps_its_clock(ros_process, namespace, rclpy_node):
    """All deleted, paused, stepped 8 sample periods: /clock advances exactly 8 periods,
    one message each (an empty simulation still keeps time; /clock's history is 10 deep, so
    a longer burst may lose messages on the way)."""
    import simulation_interfaces.srv as srv
    from rosgraph_msgs.msg import Clock
    from simulation_interfaces.msg import Result, SimulationState
    sim = ros_process(venv_exe('simulator'), '--ros-args', '-r', f'__ns:={namespace}',
                      '-p', 'spacecraft:=[solo]', '-p', 'publish_clock:=true',
                      '-p', 'publish_rate:=10.0')
    base = f'{namespace}/attitude_simulator'
    clock = []
    rclpy_node.create_subscription(Clock, '/clock', clock.append, 1000)

    def call(cls, name, request):
        return _call(rclpy_node, rclpy_node.create_client(cls, f'{base}/{name}'), request)
    assert spin_until(rclpy_node, lambda: len(clock) >= 2, 60.0), sim.output()[-2000:]
    assert call(srv.DeleteEntity, 'delete_entity', srv.DeleteEntity.Request(entity='solo')) \
        .result.result == Result.RESULT_OK
    k = len(clock)
    assert spin_until(rclpy_node, lambda: len(clock) >= k + 2, 30.0)  # time runs on, empty
    request = srv.SetSimulationState.Request()
    request.state.state = SimulationState.STATE_PAUSED
    assert call(srv.SetSimulationState, 'set_simulation_state', request).result.result == \
        Result.RESULT_OK
    n = len(clock)
    assert call(srv.StepSimulation, 'step_simulation', srv.StepSimulation.Request(steps=8)) \
        .result.result == Result.RESULT_OK

    def last_nine():
        return [m.clock.sec * NS + m.clock.nanosec for m in clock[-9:]]
    # the paused instant and 8 periods after it, one message each: waited for, since a
    # /clock from before the pause may arrive late on a loaded machine (in order: it comes
    # before the steps'), then none more (the 0.5 s spin) and no step's instant twice
    assert spin_until(rclpy_node, lambda: len(clock) >= n + 8 and all(
        b - a == NS // 10 for a, b in zip(last_nine(), last_nine()[1:])), 30.0), last_nine()
    spin_until(rclpy_node, lambda: False, 0.5)
    t = last_nine()
    after = [m.clock.sec * NS + m.clock.nanosec for m in clock[n - 1:]]
    assert all(b - a == NS // 10 for a, b in zip(t, t[1:])), t
    assert len([c for c in after if c > t[0]]) == 8, (t, after)
    # more steps than one engine call's 16 in one request: the last /clock is 20 periods on
    assert call(srv.StepSimulation, 'step_simulation', srv.StepSimulation.Request(steps=20)) \
        .result.result == Result.RESULT_OK
    last = t[-1] + 20 * NS // 10
    assert spin_until(rclpy_node, lambda: clock[-1].clock.sec * NS + clock[-1].clock.nanosec
                      == last, 30.0), clock[-1]


@pytest.mark.parametrize('params, reason', [
    # lockstep holds a formation's instants too, under the same checks (the formation
    # publishes at 10 Hz, the control rate is 50 Hz)
    (['--params-file', FORMATION, '-p', 'lockstep:=true', '-p', 'publish_clock:=true'],
     'lockstep: control_rate 50 Hz must divide publish_rate 10 Hz'),
    (['-p', 'spacecraft:=[one, 9lives]'], "spacecraft name '9lives' is invalid"),
])
def test_a_fleet_the_node_cannot_run_stops_it_with_the_reason(ros_process, namespace,
                                                              params, reason):
    sim = ros_process(venv_exe('simulator'), '--ros-args', '-r', f'__ns:={namespace}',
                      *params)
    assert sim.wait(120) == 2, sim.output()[-3000:]
    out = sim.output()
    assert reason in out and 'Traceback' not in out, out[-3000:]

