"""Lockstep with several spacecraft: the simulator holds each control instant until every
spacecraft in the loop has its command, one controller per spacecraft namespace.

Real processes (simulator, one controller per spacecraft, recorder) and real messages.
"""
import signal
import sys

import pytest
from rclpy.serialization import deserialize_message

from ros_helpers import spin_until, venv_exe, wait_output
from stamp_checks import STATE_TOPICS

from rigid_body_sim import offline
from rigid_body_sim.bag.reader import iter_messages
from rigid_body_sim.bag.schema import message_class
from rigid_body_sim.scene import SceneError, load, spacecraft_scene

# leader and wingman slew and detumble under their own controllers; tumbler is left out of
# the loop (lockstep: false) and runs free beside them
FORMATION = '''/**:
  ros__parameters:
    scene:
      name: formation_lockstep
/**/attitude_simulator:
  ros__parameters:
    spacecraft: [leader, wingman, tumbler]
    inertia: [1.0, 2.0, 3.0]
    integrator: splitting4
    step: 0.005
    publish_rate: 50.0
    duration: 2.0
    leader:
      inertia: [10.0, 12.0, 14.0]
      initial_angular_velocity: [0.0, 0.0, 0.0]
    wingman:
      initial_attitude: [0.0, 0.0, 0.3826834323650898, 0.9238795325112867]
      initial_angular_velocity: [0.2, -0.1, 0.05]
    tumbler:
      lockstep: false
      initial_angular_velocity: [0.05, 1.0, 0.0]
/**/attitude_controller:
  ros__parameters:
    control_rate: 25.0
    mode: slew
    target_attitude: [0.0, 0.0, 0.7071067811865476, 0.7071067811865476]
'''
# what each spacecraft's own controller is given (its params file, its namespace)
CONTROLLERS = {'leader': {'inertia': [10.0, 12.0, 14.0], 'child_frame_id': 'leader/base_link'},
               'wingman': {'mode': 'detumble', 'child_frame_id': 'wingman/base_link'}}
TOPICS = tuple(t for t in STATE_TOPICS if t != 'tf')  # /tf is shared by the spacecraft


def _messages(bag, prefix=''):
    """{(spacecraft, topic name): [decoded message, ...]} (the spacecraft: the topic's
    namespace after ``prefix``; '' for an offline bag's)."""
    out = {}
    for m in iter_messages(str(bag)):
        craft, _, name = m.topic[len(prefix):].strip('/').rpartition('/')
        if name in TOPICS + ('torque_command',):
            out.setdefault((craft, name), []).append(
                deserialize_message(m.data, message_class(m.type)))
    return out


def _yaml(values):
    return '/**/attitude_controller:\n  ros__parameters:\n' + ''.join(
        f'    {k}: {v!r}\n'.replace("'", '') for k, v in values.items())


def _live(ros_process, namespace, tmp_path, label, rtf, busy=0):
    """The formation's bag, live in lockstep. ``busy``: processes busy-looping from the
    simulator's kernels loaded (before t = 0) to its end."""
    scene = tmp_path / 'formation.yaml'
    over = tmp_path / f'{label}.yaml'
    over.write_text('/**/attitude_simulator:\n  ros__parameters:\n'
                    f'    real_time_factor: {rtf}\n    publish_clock: true\n'
                    '    wait_for_subscribers: 1\n    wait_for_subscribers_timeout: 60.0\n'
                    '    lockstep: true\n    control_rate: 25.0\n    lockstep_timeout: 30.0\n'
                    '/**/attitude_controller:\n  ros__parameters:\n    lockstep: true\n')
    ns, env = f'{namespace}_{label}', {'PYTHONUNBUFFERED': '1'}
    bag = tmp_path / label
    rec = ros_process(venv_exe('recorder'), '--ros-args', '-r', f'__ns:={ns}',
                      '-p', f'output:={bag}', '-p', 'all:=true', env=env)
    assert wait_output(rec, 'recording to'), rec.output()
    controllers = []
    for craft, values in CONTROLLERS.items():
        own = tmp_path / f'{label}_{craft}.yaml'
        own.write_text(_yaml(values))
        controllers.append(ros_process(
            venv_exe('controller'), '--ros-args', '-r', f'__ns:={ns}/{craft}',
            '--params-file', str(scene), '--params-file', str(over), '--params-file', str(own),
            env=env))
    sim = ros_process(venv_exe('simulator'), '--ros-args', '-r', f'__ns:={ns}',
                      '--params-file', str(scene), '--params-file', str(over), env=env)
    loops = []
    if busy:  # the run, not the nodes' start-up, is what they load (and their CPU is spent)
        assert wait_output(sim, 'kernels loaded', 120.0), sim.output()[-3000:]
        loops = [ros_process(sys.executable, '-c', 'while True: pass') for _ in range(busy)]
    assert sim.wait(240) == 0, sim.output()[-3000:]
    assert all(loop.poll() is None for loop in loops)  # they were busy until the end
    for loop in loops:
        loop.signal(signal.SIGKILL)
    out = sim.output()
    assert 'every state topic has its subscribers; starting at t = 0' in out, out[-3000:]
    assert 'lockstep: 50 exchanges' in out and 'paused' not in out, out[-3000:]
    for ctl in controllers:
        assert ctl.stop() == 0, ctl.output()[-3000:]
    assert rec.stop() == 0, rec.output()[-3000:]
    return _messages(bag, ns)


def test_a_formation_in_lockstep_gives_the_offline_run_of_each_spacecraft(
        ros_process, namespace, tmp_path):
    """Three spacecraft, two in the loop (each with its own controller in its namespace)
    and one left out: as fast as possible, and at real time beside two busy-looping
    processes, every spacecraft's state
    messages are those of the offline run of that spacecraft (every field, stamps
    included), and the two runs' commands are the same, one per control instant of each
    spacecraft in the loop. Before, a scene with spacecraft refused lockstep."""
    (tmp_path / 'formation.yaml').write_text(FORMATION)
    scene = load(str(tmp_path / 'formation.yaml'))
    expected = {}
    for craft in ('leader', 'wingman', 'tumbler'):
        one = spacecraft_scene(scene, craft, CONTROLLERS.get(craft))
        if craft == 'tumbler':  # out of the loop: no controller
            one.controller = {}
        sink = offline.BagSink(one, str(tmp_path / f'offline_{craft}'), {}, one.simulator)
        sink.finish(offline.simulate(one, sinks=[sink], keep='none'))
        sink.close()
        expected.update({(craft, t): m for (_, t), m in  # (its commands: per sample)
                         _messages(tmp_path / f'offline_{craft}').items() if t in TOPICS})
    assert len(expected['leader', 'attitude']) == 101  # t = 0 … 2 s at 50 Hz
    fast = _live(ros_process, namespace, tmp_path, 'fast', 0.0)
    # both cores kept busy through the real-time run
    slow = _live(ros_process, namespace, tmp_path, 'loaded', 1.0, busy=2)
    for key, messages in expected.items():
        assert fast[key] == messages, key
        assert slow[key] == messages, key
    for craft in CONTROLLERS:
        commands = fast[craft, 'torque_command']
        assert commands == slow[craft, 'torque_command'], craft
        # every control instant (25 Hz: every other state), the end's too
        assert [m.header.stamp for m in commands] == [
            m.header.stamp for m in expected[craft, 'attitude'][::2]], craft
        assert any(m.vector.x or m.vector.y or m.vector.z for m in commands), craft
    assert ('tumbler', 'torque_command') not in fast


def test_a_formation_in_lockstep_counts_each_spacecrafts_rejections(
        ros_process, namespace, tmp_path, rclpy_node):
    """No controllers: the simulator holds t = 0 for both spacecraft in the loop. The
    leader's answer alone moves nothing; its duplicate is counted stale for the leader
    only; the wingman's answer releases the instant, up to the next one; a command for an
    instant not held is counted unexpected, one already answered stale, each for the
    spacecraft it was sent to."""
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import QuaternionStamped, Vector3Stamped
    (tmp_path / 'formation.yaml').write_text(FORMATION)
    sim = ros_process(venv_exe('simulator'), '--ros-args', '-r', f'__ns:={namespace}',
                      '--params-file', str(tmp_path / 'formation.yaml'),
                      '-p', 'lockstep:=true', '-p', 'publish_clock:=true',
                      '-p', 'control_rate:=25.0', '-p', 'lockstep_timeout:=0.3',
                      '-p', 'real_time_factor:=0.0', '-p', 'wait_for_subscribers:=0',
                      '-p', 'wait_for_subscribers_timeout:=60.0',
                      env={'PYTHONUNBUFFERED': '1'})
    stamps, status = [], {}
    rclpy_node.create_subscription(QuaternionStamped, f'{namespace}/leader/attitude', lambda m: (
        stamps.append(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec)), 100)

    def on_diag(msg):
        for s in msg.status:
            if s.hardware_id.startswith(namespace):
                status[s.name.split(': ')[-1]] = {kv.key: kv.value for kv in s.values}
                status[s.name.split(': ')[-1]]['message'] = s.message
    rclpy_node.create_subscription(DiagnosticArray, '/diagnostics', on_diag, 100)
    pubs = {c: rclpy_node.create_publisher(Vector3Stamped, f'{namespace}/{c}/torque_command', 10)
            for c in ('leader', 'wingman')}

    def command(craft, stamp_ns):
        msg = Vector3Stamped()
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 10**9)
        msg.header.frame_id = f'{craft}/base_link'
        msg.vector.z = 0.01
        pubs[craft].publish(msg)

    def count(craft, reason):
        return status.get(craft, {}).get(f'commands_rejected.lockstep_{reason}')
    assert spin_until(rclpy_node, lambda: 'lockstep: paused at t = 0 s' in sim.output(), 90), \
        sim.output()[-3000:]
    assert 'no leader/torque_command, wingman/torque_command stamped 0.000000000' in \
        sim.output(), sim.output()[-3000:]
    assert spin_until(rclpy_node, lambda: pubs['leader'].get_subscription_count() == 1
                      and pubs['wingman'].get_subscription_count() == 1, 30)
    command('leader', 0)
    assert spin_until(rclpy_node, lambda: 'waiting for wingman/torque_command' in
                      status.get('simulation', {}).get('message', ''), 30), status
    command('leader', 0)  # a duplicate: the leader answered t = 0 already
    assert spin_until(rclpy_node, lambda: count('leader', 'stale') == '1', 30), status
    assert stamps == [0] and count('wingman', 'stale') == '0'
    command('wingman', 0)  # the last answer: on to t = 0.04 s (two samples at 50 Hz)
    assert spin_until(rclpy_node, lambda: stamps == [0, 20_000_000, 40_000_000], 30), stamps
    command('wingman', 0)  # an instant already answered
    command('leader', 80_000_000)  # an instant not held
    assert spin_until(rclpy_node, lambda: count('wingman', 'stale') == '1' and
                      count('leader', 'unexpected') == '1', 30), status
    assert count('leader', 'stale') == '1' and count('wingman', 'unexpected') == '0'
    assert stamps == [0, 20_000_000, 40_000_000]
    assert spin_until(rclpy_node, lambda: status.get('simulation', {}).get(
        'lockstep_exchanges') == '1', 30), status


def test_one_spacecrafts_scene_takes_its_values_and_refuses_a_stranger(tmp_path):
    """scene.spacecraft_scene: the spacecraft's own values over the node's, its body frame,
    its controller's own values; a name that is not one of the scene's is refused."""
    (tmp_path / 'formation.yaml').write_text(FORMATION)
    scene = load(str(tmp_path / 'formation.yaml'))
    leader = spacecraft_scene(scene, 'leader', CONTROLLERS['leader'])
    assert leader.simulator['inertia'] == [10.0, 12.0, 14.0]
    assert leader.simulator['child_frame_id'] == 'leader/base_link'
    assert leader.controller['inertia'] == [10.0, 12.0, 14.0]
    assert spacecraft_scene(scene, 'tumbler').simulator['inertia'] == [1.0, 2.0, 3.0]
    with pytest.raises(SceneError, match="no spacecraft 'nobody' .*leader, wingman, tumbler"):
        spacecraft_scene(scene, 'nobody')
