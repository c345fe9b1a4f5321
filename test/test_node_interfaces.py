"""The table the reference pages are generated from (rigid_body_sim/node_interfaces.py) is
exactly what the running nodes publish, subscribe to and serve: real nodes, real graph."""
import time

from ros_helpers import venv_exe
from rigid_body_sim import node_interfaces as ni

# what rclpy gives every node
AUTOMATIC_TOPICS = {'/rosout', '/parameter_events'}
AUTOMATIC_SERVICES = {'describe_parameters', 'get_parameter_types', 'get_parameters',
                      'get_type_description', 'list_parameters', 'set_parameters',
                      'set_parameters_atomically'}

# wheels, the CMG pyramid, both sensors and /clock: every conditional simulator entry
EVERYTHING_ON = """\
/**:
  ros__parameters:
    inertia: [1.0, 2.0, 2.5]
/**/attitude_simulator:
  ros__parameters:
    real_time_factor: 1.0
    publish_rate: 10.0
    publish_clock: true
    sensors.gyro.enabled: true
    sensors.star_tracker.enabled: true
    actuators.wheels.axes: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    actuators.cmgs.cluster: pyramid
"""


def _resolve(name, ns, node):
    if name.startswith('/'):
        return name
    if name.startswith('~/'):
        return f'{ns}/{node}/{name[2:]}'
    return f'{ns}/{name}'


def expected(table, ns, active):
    """({(topic, type)} published, subscribed, served) by ``table`` with conditions
    ``active`` on."""
    on = [e for e in table.topics + table.services if e.when in ('',) + tuple(active)]
    pub = {(_resolve(t.name, ns, table.name), t.type) for t in on
           if isinstance(t, ni.Topic) and t.direction == 'pub'}
    sub = {(_resolve(t.name, ns, table.name), t.type) for t in on
           if isinstance(t, ni.Topic) and t.direction == 'sub'}
    srv = {(_resolve(s.name, ns, table.name), s.type) for s in on if isinstance(s, ni.Service)}
    return pub, sub, srv


def observed(probe, node, ns):
    """What the graph shows of ``node`` (None until it is discovered)."""
    from rclpy._rclpy_pybind11 import NodeNameNonExistentError

    from rclpy.action import get_action_server_names_and_types_by_node

    def flat(pairs, automatic):
        """Without an action's own topics and services (``.../_action/...``): the action
        server is listed instead, among the services, as in the table."""
        return {(name, t) for name, types in pairs for t in types
                if name not in automatic and name.rsplit('/', 1)[-1] not in automatic
                and '/_action/' not in name}
    try:
        return (flat(probe.get_publisher_names_and_types_by_node(node, ns), AUTOMATIC_TOPICS),
                flat(probe.get_subscriber_names_and_types_by_node(node, ns), AUTOMATIC_TOPICS),
                flat(probe.get_service_names_and_types_by_node(node, ns), AUTOMATIC_SERVICES)
                | flat(get_action_server_names_and_types_by_node(probe, node, ns), ()))
    except NodeNameNonExistentError:
        return None


def test_running_nodes_match_the_table(ros_process, rclpy_node, namespace, tmp_path):
    from rigid_body_sim.nodes.sim_services import AVAILABLE
    scene = tmp_path / 'everything.yaml'
    scene.write_text(EVERYTHING_ON)
    ns_truth, ns_sensors = namespace, namespace + '_s'
    runs = [  # (table, namespace, active conditions, command)
        (ni.SIMULATOR, ns_truth,
         (ni.CLOCK, ni.WHEELS, ni.CMGS, ni.ACTUATORS, ni.GYRO, ni.STAR_TRACKER)
         + ((ni.SIM_INTERFACES,) if AVAILABLE else ()),
         [venv_exe('simulator'), '--ros-args', '-r', f'__ns:={ns_truth}',
          '--params-file', str(scene)]),
        (ni.CONTROLLER, ns_truth, (ni.FEEDBACK_TRUTH,),
         [venv_exe('controller'), '--ros-args', '-r', f'__ns:={ns_truth}']),
        (ni.CONTROLLER, ns_truth + '_lockstep', (ni.LOCKSTEP,),  # the state as odometry
         [venv_exe('controller'), '--ros-args', '-r', f'__ns:={ns_truth}_lockstep',
          '-p', 'lockstep:=true']),
        (ni.CONTROLLER, ns_sensors, (ni.FEEDBACK_SENSORS,),
         [venv_exe('controller'), '--ros-args', '-r', f'__ns:={ns_sensors}',
          '--params-file', 'config/gyro_pointing.yaml']),
        (ni.VIEWER, ns_truth, (),
         [venv_exe('viewer'), '--ros-args', '-r', f'__ns:={ns_truth}', '-p', 'port:=0']),
        (ni.SIMULATOR, ns_truth + '_orbit',  # an orbit with the gravity gradient, a sun sensor
         (ni.ORBIT, ni.GRAVITY_GRADIENT, ni.ENVIRONMENT_TORQUE, ni.SUN_SENSOR)
         + ((ni.SIM_INTERFACES,) if AVAILABLE else ()),
         [venv_exe('simulator'), '--ros-args', '-r', f'__ns:={ns_truth}_orbit',
          '--params-file', 'config/gravity_gradient.yaml', '-p', 'sun_sensor.enabled:=true',
          '-p', 'epoch:=2026-03-20T12:00:00Z']),
        (ni.SIMULATOR, ns_truth + '_mag',  # magnetorquers and a magnetometer, no gradient
         (ni.ORBIT, ni.MAGNETORQUERS, ni.MAGNETOMETER, ni.ENVIRONMENT_TORQUE)
         + ((ni.SIM_INTERFACES,) if AVAILABLE else ()),
         [venv_exe('simulator'), '--ros-args', '-r', f'__ns:={ns_truth}_mag',
          '--params-file', 'config/bdot_detumble.yaml']),
        (ni.CONTROLLER, ns_truth + '_mag', (ni.FEEDBACK_TRUTH, ni.BDOT),
         [venv_exe('controller'), '--ros-args', '-r', f'__ns:={ns_truth}_mag',
          '--params-file', 'config/bdot_detumble.yaml']),
    ]
    import os
    repo = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    procs = [ros_process(*cmd, cwd=repo) for *_, cmd in runs]
    want = [expected(table, ns, active) for table, ns, active, _ in runs]
    got = [None] * len(runs)
    deadline = time.monotonic() + 90.0
    while time.monotonic() < deadline:
        got = [observed(rclpy_node, table.name, ns) for table, ns, *_ in runs]
        if got == want or any(p.poll() is not None for p in procs):
            break
        time.sleep(0.5)
    for (table, ns, *_), proc, g, w in zip(runs, procs, got, want):
        assert proc.poll() is None, f'{table.name} in {ns} exited:\n{proc.output()}'
        assert g is not None, f'{table.name} in {ns} never appeared:\n{proc.output()}'
        for what, gi, wi in zip(('publishes', 'subscribes to', 'serves'), g, w):
            assert gi == wi, (f'{table.name} {what}: not in the table {sorted(gi - wi)}, '
                              f'in the table but not running {sorted(wi - gi)}')
    # and the conditions are real: the truth controller does not listen to the sensors
    assert (f'{ns_truth}/gyro', 'sensor_msgs/msg/Imu') not in got[1][1]
    assert (f'{ns_truth}_lockstep/attitude', 'geometry_msgs/msg/QuaternionStamped') \
        not in got[2][1]


def test_recorder_parameters_coerce_their_defaults_and_refuse_bad_lists():
    from rigid_body_sim.param_spec import coerce_all
    values = coerce_all(ni.RECORDER_PARAMETERS, {'topics': ['attitude'], 'all': True})
    assert values['topics'] == ['attitude'] and values['exclude'] == ['']
    try:
        coerce_all(ni.RECORDER_PARAMETERS, {'topics': 'attitude'}, where='recorder')
    except ValueError as exc:
        assert 'topics must be a list of strings' in str(exc)
    else:
        raise AssertionError('a string where a list of strings is meant was accepted')
