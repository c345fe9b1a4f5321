"""Lockstep: the simulator holds every control instant until it has that instant's command.

Real processes (simulator, controller, recorder) and real messages. A lockstep run gives
the messages of another lockstep run and of the offline run of the same scene, as fast as
possible, at real time and beside a process that keeps both cores busy; a controller that
does not answer pauses the simulator, which reports it and resumes on the answer.
"""
import os
import re
import signal
import sys

import pytest
from rclpy.serialization import deserialize_message

from ros_helpers import spin_until, venv_exe, wait_output
from stamp_checks import STATE_TOPICS
from test_sim_exchange import NS, simulator  # noqa: F401 (a fixture)

from rigid_body_sim import offline
from rigid_body_sim.bag.reader import iter_messages
from rigid_body_sim.bag.schema import message_class
from rigid_body_sim.scene import load

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENE = os.path.join(REPO, 'config', 'slew.yaml')
# a fixed method here; test_lockstep_with_auto_chooses_as_the_offline_run runs auto
OVERRIDES = ['integrator=splitting4', 'duration=3.0']


def _state_messages(bag, topics=STATE_TOPICS):
    """{topic name: [decoded message, ...]} of the state topics (rclpy leaves CDR padding
    uninitialised, so messages are compared decoded, every field, stamps included)."""
    out = {}
    for m in iter_messages(str(bag)):
        name = m.topic.rsplit('/', 1)[-1]
        if name in topics:
            out.setdefault(name, []).append(deserialize_message(m.data, message_class(m.type)))
    return out


def _offline_bag(tmp_path, overrides=OVERRIDES, path=SCENE, scene=None, label='offline'):
    scene = scene or load(path, overrides)
    sink = offline.BagSink(scene, str(tmp_path / label), {}, scene.simulator)
    result = offline.simulate(scene, sinks=[sink], keep='none')
    sink.finish(result)
    sink.close()
    return tmp_path / label


def _live_bag(ros_process, namespace, tmp_path, label, rtf, integrator='splitting4',
              path=SCENE, recorder=(), duration=3.0, topics=('torque_command',), busy=0,
              compiled=False):
    """Recorder, controller and simulator in lockstep on the scene; the bag.
    ``recorder``: more arguments for the recorder (``-p name:=value``). ``busy``: processes
    busy-looping from the simulator's kernels loaded (before t = 0) to its end.
    ``compiled``: check that the exchanges ran compiled (``nodes/sim_rcl.py``)."""
    rate = load(path).controller['control_rate']
    over = tmp_path / f'{label}.yaml'
    over.write_text('/**/attitude_simulator:\n  ros__parameters:\n'
                    f'    real_time_factor: {rtf}\n    publish_clock: true\n'
                    f'    integrator: {integrator}\n    duration: {duration}\n'
                    '    wait_for_subscribers: 1\n    wait_for_subscribers_timeout: 60.0\n'
                    f'    lockstep: true\n    control_rate: {rate}\n    lockstep_timeout: 30.0\n'
                    '/**/attitude_controller:\n  ros__parameters:\n    lockstep: true\n')
    ns = f'{namespace}_{label}'
    bag = tmp_path / label
    env = {'PYTHONUNBUFFERED': '1'}
    rec = ros_process(venv_exe('recorder'), '--ros-args', '-r', f'__ns:={ns}',
                      '-p', f'output:={bag}', *recorder, env=env)
    assert wait_output(rec, 'recording to', 180.0), rec.output()
    ctl = ros_process(venv_exe('controller'), '--ros-args', '-r', f'__ns:={ns}',
                      '--params-file', path, '--params-file', str(over), env=env)
    sim = ros_process(venv_exe('simulator'), '--ros-args', '-r', f'__ns:={ns}',
                      '--params-file', path, '--params-file', str(over), env=env)
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
    # the control instants: t = 0 … the duration less one period
    assert f'lockstep: {round(duration * rate)} exchanges' in out, out[-3000:]
    assert 'paused' not in out, out[-3000:]
    if compiled:  # as fast as possible: most exchanges ran in one compiled call (sim_rcl),
        # so the comparison below covers that way. Not all: the first is the Python way's
        # (its layout), the last the run's end, and an exchange where acknowledgements are
        # due or the loop's wall time ran out goes the Python way too; how many depends on
        # the machine's timing (a fresh clone's suite: 105 of 150). That both ways give the
        # same messages bit for bit, exchange by exchange: test_sim_exchange_compiled.py.
        got = re.search(r'; (\d+) compiled', out)
        assert got and int(got.group(1)) >= 0.5 * duration * rate, out[-3000:]
    assert ctl.stop() == 0, ctl.output()[-3000:]
    assert rec.stop() == 0, rec.output()[-3000:]
    return bag, _state_messages(bag, STATE_TOPICS + tuple(topics))


def test_lockstep_runs_equal_each_other_and_the_offline_run(ros_process, namespace, tmp_path):
    """As fast as possible (its exchanges compiled: sim_rcl), then at real time beside two
    busy-looping processes: both lockstep runs give the offline run's state messages
    (every field, stamps included), and the same commands as each other. Before
    lockstep, the controller's commands landed wherever the wall clock put them, and the
    runs differed from the first command on."""
    expected = _state_messages(_offline_bag(tmp_path))
    assert len(expected['attitude']) == 151  # t = 0 … 3 s at 50 Hz
    fast_bag, fast = _live_bag(ros_process, namespace, tmp_path, 'fast', 0.0, compiled=True)
    # both cores kept busy through the real-time run
    slow_bag, slow = _live_bag(ros_process, namespace, tmp_path, 'loaded', 1.0, busy=2)
    for topic, messages in expected.items():
        assert fast[topic] == messages, topic
        assert slow[topic] == messages, topic
    # the controller answered every control instant (the end's too, which the simulator
    # does not wait for), stamped with the state's stamp
    assert fast['torque_command'] == slow['torque_command']
    stamps = [(m.header.stamp.sec, m.header.stamp.nanosec) for m in fast['torque_command']]
    assert stamps == [(m.header.stamp.sec, m.header.stamp.nanosec)
                      for m in expected['attitude']]


def test_a_recorder_slow_to_match_the_controller_still_records_every_command(
        ros_process, namespace, tmp_path):
    """The flake of the test above (1 run in ~10 of make test): as fast as possible the
    run lasts ~0.2 s, and the recorder had not yet matched the controller (discovery, a
    pair the simulator cannot see) when the controller was stopped: the commands' history
    went with it and the bag held none. Here the recorder looks for new publishers only
    every 20 s, so it matches the controller (subscribing for its history) long after the
    simulator could start. The simulator waits for the recorder's report that it has
    matched the controller: the bag holds every command. Before, it held none."""
    _, fast = _live_bag(ros_process, namespace, tmp_path, 'slow_recorder', 0.0,
                        recorder=('-p', 'discovery_period:=20.0'))
    stamps = [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec
              for m in fast.get('torque_command', [])]
    assert stamps == [k * 20_000_000 for k in range(151)], (len(stamps), stamps[:3])


@pytest.mark.parametrize('name', ['slew', 'detumble', 'wheel_slew'])
def test_lockstep_with_auto_chooses_as_the_offline_run(ros_process, namespace, tmp_path, name):
    """The scenes as shipped (``integrator: auto``): the simulator reads its controller's
    gains from the same params files, so ``auto`` expects the law's torque as the offline
    run's in-process law tells it, and chooses the same method and step (splitting4 at
    10 ms on slew; with √(√3·max_torque/I_min) as the torque's rate it chose splitting6 at
    20 ms, and the messages differed). The wheels' method carries the commands alike."""
    path = os.path.join(REPO, 'config', f'{name}.yaml')
    assert load(path).simulator['integrator'] == 'auto'
    expected = _state_messages(_offline_bag(tmp_path, ['duration=3.0'], path))
    assert expected['attitude'] and expected['attitude'][0].header.stamp.sec == 0
    _, live = _live_bag(ros_process, namespace, tmp_path, name, 0.0, integrator='auto',
                        path=path)
    for topic, messages in expected.items():
        assert live[topic] == messages, topic


def test_bdot_in_lockstep_gives_the_offline_run(ros_process, namespace, tmp_path):
    """The B-dot detumble (magnetorquers, a noisy magnetometer, IGRF on a J2 orbit) for
    20 s, as shipped but for the duration, in lockstep: the controller answers each
    instant once its magnetometer reading is in too, with a dipole_command stamped like
    the state, and the simulator holds the instant for both. The state and the readings
    are the offline run's (its in-process B-dot), every field. Before, the dipole went
    around the handshake, landing wherever the wall clock put it."""
    path = os.path.join(REPO, 'config', 'bdot_detumble.yaml')
    topics = STATE_TOPICS + ('magnetic_field',)
    expected = _state_messages(_offline_bag(tmp_path, ['duration=20.0'], path), topics)
    assert len(expected['attitude']) == 41 and len(expected['magnetic_field']) == 41
    _, live = _live_bag(ros_process, namespace, tmp_path, 'bdot', 0.0, integrator='auto',
                        path=path, duration=20.0, topics=('magnetic_field', 'dipole_command'))
    for topic, messages in expected.items():
        assert live[topic] == messages, topic
    dipoles = live['dipole_command']
    assert [m.header.stamp for m in dipoles] == [m.header.stamp for m in live['attitude']]
    # the law acted from its second reading on: the rods' dipole changed the run
    assert all(m.vector.x == m.vector.y == m.vector.z == 0.0 for m in dipoles[:1])
    assert all(max(abs(m.vector.x), abs(m.vector.y), abs(m.vector.z)) > 0 for m in dipoles[1:])


def test_a_recorder_discovered_after_t0_still_records_every_command(ros_process, namespace,
                                                                     tmp_path):
    """Discovery between two processes can take seconds on a loaded machine, and the
    simulator cannot see whether the controller has discovered a recorder: in 1 of 6 loaded
    runs of the test above the controller first answered with only the simulator matched,
    and the bag lacked the first 0.26 s of commands. Here the recorder starts only after
    t = 0, the extreme case: its bag still holds every command from t = 0, once and in
    order (the controller keeps them for late joiners; the recorder asks for them). Before,
    it began wherever the recorder joined."""
    over = tmp_path / 'late.yaml'
    over.write_text('/**/attitude_simulator:\n  ros__parameters:\n'
                    '    real_time_factor: 1.0\n    publish_clock: true\n'
                    '    integrator: splitting4\n    duration: 5.0\n'
                    '    wait_for_subscribers: 0\n    wait_for_subscribers_timeout: 60.0\n'
                    '    lockstep: true\n    control_rate: 50.0\n    lockstep_timeout: 30.0\n'
                    '/**/attitude_controller:\n  ros__parameters:\n    lockstep: true\n')
    env = {'PYTHONUNBUFFERED': '1'}
    args = ['--ros-args', '-r', f'__ns:={namespace}', '--params-file', SCENE,
            '--params-file', str(over)]
    ctl = ros_process(venv_exe('controller'), *args, env=env)
    sim = ros_process(venv_exe('simulator'), *args, env=env)
    assert wait_output(sim, 'starting at t = 0', 120), sim.output()[-3000:]
    bag = tmp_path / 'bag'
    rec = ros_process(venv_exe('recorder'), '--ros-args', '-r', f'__ns:={namespace}',
                      '-p', f'output:={bag}', env=env)
    assert wait_output(rec, f'subscribed to {namespace}/torque_command', 60), rec.output()
    assert sim.wait(240) == 0, sim.output()[-3000:]
    assert 'lockstep: 250 exchanges' in sim.output(), sim.output()[-3000:]
    assert ctl.stop() == 0, ctl.output()[-3000:]
    assert rec.stop() == 0, rec.output()[-3000:]
    commands = _state_messages(bag, ('torque_command',))['torque_command']
    stamps = [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in commands]
    assert stamps[:3] == [0, 20_000_000, 40_000_000], stamps[:3]
    assert stamps == [k * 20_000_000 for k in range(251)], (len(stamps), stamps[-3:])


def test_a_controller_that_does_not_answer_pauses_the_simulator(ros_process, namespace,
                                                                 rclpy_node):
    """No controller: the simulator publishes t = 0, holds, and after lockstep_timeout
    says it is paused (log and diagnostics) without advancing. A command stamped with the
    held state's stamp resumes it up to the next instant only (two samples at 100 Hz); the
    same command again is rejected as stale and moves nothing."""
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import QuaternionStamped, Vector3Stamped
    sim = ros_process(venv_exe('simulator'), '--ros-args', '-r', f'__ns:={namespace}',
                      '-p', 'lockstep:=true', '-p', 'publish_clock:=true',
                      '-p', 'control_rate:=50.0', '-p', 'lockstep_timeout:=0.5',
                      '-p', 'real_time_factor:=0.0', '-p', 'wait_for_subscribers:=0',
                      '-p', 'wait_for_subscribers_timeout:=60.0',
                      env={'PYTHONUNBUFFERED': '1'})
    stamps, status = [], {}
    rclpy_node.create_subscription(QuaternionStamped, f'{namespace}/attitude', lambda m: (
        stamps.append(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec)), 100)

    def on_diag(msg):
        for s in msg.status:
            if s.name.startswith('attitude_simulator') and s.hardware_id.startswith(namespace):
                status.update({kv.key: kv.value for kv in s.values}, message=s.message)
    rclpy_node.create_subscription(DiagnosticArray, '/diagnostics', on_diag, 100)
    pub = rclpy_node.create_publisher(Vector3Stamped, f'{namespace}/torque_command', 10)
    assert spin_until(rclpy_node, lambda: 'lockstep: paused at t = 0 s' in sim.output(), 90), \
        sim.output()[-3000:]
    assert spin_until(rclpy_node, lambda: status.get('lockstep_paused') == 'true', 30), status
    assert 'paused at t = 0 s' in status['message']
    assert stamps == [0]  # nothing past the held instant

    def command(stamp_ns):
        msg = Vector3Stamped()
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 10**9)
        msg.vector.z = 0.1
        pub.publish(msg)
    command(0)
    assert spin_until(rclpy_node, lambda: stamps == [0, 10_000_000, 20_000_000], 30), stamps
    assert spin_until(rclpy_node, lambda: 'resuming' in sim.output(), 30), sim.output()[-3000:]
    command(0)  # a duplicate: the instant was answered
    assert spin_until(rclpy_node, lambda: status.get('commands_rejected.lockstep_stale') == '1',
                      30), status
    assert spin_until(rclpy_node, lambda: 'paused at t = 0.02 s' in status.get('message', ''),
                      30), status
    assert stamps == [0, 10_000_000, 20_000_000] and status['lockstep_exchanges'] == '1'


def test_the_lockstep_controller_answers_one_odometry_message(ros_process, namespace,
                                                              rclpy_node):
    """In lockstep the controller takes the state as one nav_msgs/Odometry (orientation
    and the twist's body rate), so that the simulator publishes one message per exchange
    instead of attitude and angular_velocity (before: it subscribed to those two and
    answered only once both were in). It subscribes to odometry and to neither of them,
    and answers an odometry state with a command stamped like it, in the body frame."""
    from geometry_msgs.msg import Vector3Stamped
    from nav_msgs.msg import Odometry
    ctl = ros_process(venv_exe('controller'), '--ros-args', '-r', f'__ns:={namespace}',
                      '-p', 'lockstep:=true', '-p', 'control_rate:=50.0',
                      '-p', 'mode:=detumble', env={'PYTHONUNBUFFERED': '1'})
    commands = []
    rclpy_node.create_subscription(Vector3Stamped, f'{namespace}/torque_command',
                                   commands.append, 100)
    pub = rclpy_node.create_publisher(Odometry, f'{namespace}/odometry', 10)

    def subscribed():
        try:
            return {name for name, _ in rclpy_node.get_subscriber_names_and_types_by_node(
                'attitude_controller', namespace)}
        except Exception:  # noqa: BLE001 - not discovered yet
            return set()
    assert spin_until(rclpy_node, lambda: f'{namespace}/odometry' in subscribed() and
                      pub.get_subscription_count() > 0, 90), (subscribed(), ctl.output()[-2000:])
    assert not subscribed() & {f'{namespace}/attitude', f'{namespace}/angular_velocity'}
    msg = Odometry()
    msg.header.frame_id, msg.child_frame_id = 'world', 'base_link'
    msg.header.stamp.sec, msg.header.stamp.nanosec = 1, 20_000_000  # a control instant
    msg.pose.pose.orientation.w = 1.0
    msg.twist.twist.angular.x = 0.5  # tumbling: detumble answers with a torque against it
    pub.publish(msg)
    assert spin_until(rclpy_node, lambda: commands, 60), ctl.output()[-2000:]
    got = commands[0]
    assert (got.header.stamp.sec, got.header.stamp.nanosec) == (1, 20_000_000)
    assert got.header.frame_id == 'base_link' and got.vector.x < 0.0, got


@pytest.mark.parametrize('change, reason', [
    ({'publish_clock': False}, 'publish_clock'),
    ({'control_rate': 30.0}, 'must divide publish_rate'),
    ({'command_timeout': 0.01}, 'shorter than the control period')])
def test_lockstep_refuses_what_it_cannot_hold(change, reason):
    """The checks name the parameter and why (the node refuses to start with them)."""
    from rigid_body_sim.engine import lockstep, specs
    from rigid_body_sim.param_spec import coerce_all
    p = coerce_all(specs.SIMULATOR, {'lockstep': True, 'publish_clock': True, **change})
    with pytest.raises(ValueError, match=reason):
        lockstep.period_ns(p)


def test_lockstep_awaits_the_commands_each_spacecraft_owes():
    """Torque from a spacecraft in the loop, the dipole too with rods and a B-dot
    controller, nothing from one left out; B-dot whose magnetometer misses a control
    instant is refused with the reason (the law answers an instant from its reading)."""
    from rigid_body_sim.engine import lockstep, specs
    from rigid_body_sim.param_spec import coerce_all
    p = coerce_all(specs.SIMULATOR, {'lockstep': True, 'publish_clock': True,
                                     'control_rate': 2.0, 'publish_rate': 2.0,
                                     'magnetometer.enabled': True, 'magnetometer.rate': 2.0})
    bdot = {'mode': 'bdot'}
    assert lockstep.awaited(p, True, bdot) == ('torque', 'dipole')
    assert lockstep.awaited(p, False, bdot) == ('torque',)
    assert lockstep.awaited(p, True, {'mode': 'slew'}) == ('torque',)
    assert lockstep.awaited({**p, 'lockstep': False}, True, bdot) == ()
    with pytest.raises(ValueError, match='magnetometer.rate 1 Hz .* must read at every '
                       'control instant'):
        lockstep.awaited({**p, 'magnetometer.rate': 1.0}, True, bdot)


def test_the_lockstep_benchmark_reports_the_simulators_figures():
    """tools/lockstep.py runs a simulator and a controller in lockstep (real processes) and
    reads the simulator's own figures: every period exchanged, round trip and CPU > 0, and
    the part of that CPU in the simulator's own thread."""
    from rigid_body_sim.tools.lockstep import exchange
    got = exchange(50.0, 0.0, 0.4)
    assert got['exchanges'] == 20, got  # t = 0 ... 0.38 s
    assert got['round_trip_wall_us'] > 0 and got['sim_cpu_per_period_us'] > 0, got
    # its own thread's share, within the process's (the rest: the middleware's threads)
    assert 0 < got['sim_thread_cpu_per_period_us'] <= got['sim_cpu_per_period_us'], got
    assert got['achieved_rate_hz'] > 0, got
    # and where the rest went: each thread's part (RoundTrips.thread_parts), Fast DDS's
    # among them (named dds.*), and each thread's wake-ups: the exchange thread sleeps for a
    # command it has not got yet, but under load (or a fast controller) it finds most
    # already there (a fresh clone's CI read 0.05 a period), so only the whole process is
    # held to waking: Fast DDS's receiver blocks between the 20 commands it delivers (at
    # load 17 the exchange thread found all 19 there and 'main' was not listed at all)
    parts, wakes = got['sim_threads_us'], got['sim_wakes_per_period']
    assert parts['main'] > 0 and any(k.startswith('dds.') for k in parts), got
    assert any(k.startswith('dds.') for k in wakes), got
    assert all(v >= 0 for v in wakes.values()) and sum(wakes.values()) > 0, got


def test_the_floor_tool_measures_a_bare_rclpy_exchange():
    """tools/lockstep_floor.py: a bare rclpy node in its own process exchanges states and
    commands with the controller (real processes); its CPU per exchange, its own thread's
    within it, and the wall time are reported, and each thread's part."""
    from rigid_body_sim.tools.lockstep_floor import floor
    got = floor('ASYNCHRONOUS', True, 20, 1)
    assert got['exchanges'] == 20 and got['command_taken_as'] == 'bytes', got
    assert 0 < got['thread_cpu_per_exchange_us'] <= got['cpu_per_exchange_us'], got
    assert got['wall_per_exchange_us'] > 0 and len(got['cpu_per_exchange_us_runs']) == 1, got
    # the other options: shared memory only, the command read from a wait set; each
    # thread's share (by Fast DDS's thread names), this one's as 'main'
    got = floor('SYNCHRONOUS', True, 20, 1, 'shm', 'waitset')
    assert (got['transport'], got['loop'], got['exchanges']) == ('shm', 'waitset', 20), got
    threads = got['threads_us_runs'][0]
    assert 0 < threads['main'] <= got['cpu_per_exchange_us'], got
    assert sum(threads.values()) <= got['cpu_per_exchange_us'] * 1.01 + 1, got


def test_the_floor_tool_interleaves_its_runs_and_has_a_compiled_loop():
    """--interleave: each configuration's runs in rounds, a row per configuration;
    'rcl': every exchange in one compiled call of rcl's functions, which exchanges with
    the controller as the wait set does (real processes)."""
    from rigid_body_sim.tools.lockstep_floor import interleaved
    rows = interleaved([('SYNCHRONOUS', 'bytes', 'default', 'waitset'),
                        ('SYNCHRONOUS', 'bytes', 'default', 'rcl')], 20, 2)
    assert [r['loop'] for r in rows] == ['waitset', 'rcl'], rows
    for r in rows:
        assert r['exchanges'] == 20 and len(r['cpu_per_exchange_us_runs']) == 2, r
        assert 0 < r['thread_cpu_per_exchange_us'] <= r['cpu_per_exchange_us'], r


def test_the_parts_tool_times_each_part_of_the_simulators_exchange(capsys):
    """tools/lockstep_parts.py runs the exchange with the simulator in a process of its own
    and a controller (real processes) and reports its thread's CPU per exchange and each
    part's: every part spent something (but the exchanges' own loop, which may find every
    command already taken), and the nested ones fit in what holds them."""
    import re
    from rigid_body_sim.tools.lockstep_parts import PARTS, main
    assert main(['--periods', '20', '--runs', '1']) == 0
    out = capsys.readouterr().out
    total = float(re.search(r'simulator thread per exchange .*: ([\d.]+) µs', out).group(1))
    parts = {m.group(1): float(m.group(2))
             for m in re.finditer(r'^  (\S+) +([-\d.]+) µs', out, re.M)}
    assert set(parts) == {p[0] for p in PARTS} | {'loop'}, out
    # a command is taken at the top of a turn (take) or, while an instant is held, by the
    # exchanges' own loop: where every command was in before the loop waited (a suite run
    # under load, 20 exchanges) the second way had nothing to do
    assert all(v > 0 for k, v in parts.items() if k not in ('loop', 'exchanges')), out
    assert parts['exchanges'] >= 0, out
    # the bytes and their write: the general way's publish (t = 0) or the direct one's
    assert parts['bytes'] + parts['write'] <= parts['publish'] + parts['direct'], out
    assert parts['direct.step'] <= parts['direct'] <= parts['held'] <= parts['command'], out
    assert parts['command'] <= parts['take'] + parts['exchanges'], out
    assert parts['exchanges'] <= parts['wait'] and parts['run_once'] <= total, out


def test_lockstep_nodes_publish_synchronously(tmp_path):
    """The simulator and the controller choose Fast DDS's synchronous publication when
    their ``--ros-args`` set ``lockstep: true`` (a params file section that matches the
    node, renamed and namespaced or not, or a ``-p`` rule, the later winning), and the
    asynchronous one otherwise; a mode the user set in the environment is kept. Checked
    in a process of its own: the choice is the environment's, made before rclpy.init."""
    import subprocess
    over = tmp_path / 'lockstep.yaml'
    over.write_text('/**/attitude_simulator:\n  ros__parameters:\n    lockstep: true\n'
                    '/**/attitude_controller:\n  ros__parameters:\n    lockstep: false\n')
    probe = ('import os, sys\n'
             'from rigid_body_sim.nodes import process\n'
             'name, args = sys.argv[1], sys.argv[2:]\n'
             'assert process.start_ros(name, ["x"] + args, lockstep=True) is None\n'
             'print(os.environ["RMW_FASTRTPS_PUBLICATION_MODE"])\n'
             'import rclpy; rclpy.try_shutdown()\n')

    def mode(name, *args, env=()):
        environ = {k: v for k, v in os.environ.items()
                   if k != 'RMW_FASTRTPS_PUBLICATION_MODE'}
        out = subprocess.run([sys.executable, '-c', probe, name, '--ros-args', *args],
                             env={**environ, **dict(env)}, capture_output=True, text=True,
                             timeout=120)
        assert out.returncode == 0, out.stderr[-2000:]
        return out.stdout.split()[-1]
    files = ('--params-file', str(over))
    assert mode('attitude_simulator', '-r', '__ns:=/sat1', *files) == 'SYNCHRONOUS'
    assert mode('attitude_simulator', *files, '-p', 'lockstep:=false') == 'ASYNCHRONOUS'
    assert mode('attitude_simulator', '-p', 'lockstep:=true') == 'SYNCHRONOUS'
    assert mode('attitude_simulator') == 'ASYNCHRONOUS'
    assert mode('attitude_controller', *files) == 'ASYNCHRONOUS'
    assert mode('attitude_controller', *files, '-p', 'lockstep:=true') == 'SYNCHRONOUS'
    assert mode('sim', '-r', '__node:=attitude_simulator', *files) == 'SYNCHRONOUS'
    assert mode('attitude_simulator', *files,
                env={'RMW_FASTRTPS_PUBLICATION_MODE': 'ASYNCHRONOUS'}) == 'ASYNCHRONOUS'


def test_the_lockstep_benchmark_writes_its_target_rows():
    """tools/lockstep.py's rows of targets.csv: the simulator's CPU per exchange as fast as
    possible (the worse rate's median, against 100 µs) and the achieved rate at real time
    at each control rate (against the rate, 1 % short allowed), with the load."""
    from rigid_body_sim.tools.lockstep import targets_from

    def row(rate, cpu, achieved):
        fast = {'sim_cpu_per_period_us': cpu, 'sim_thread_cpu_per_period_us': cpu / 2,
                'sim_threads_us': {'main': cpu / 2, 'dds.ev': 0.2 * cpu, 'dds.shm': 0.3 * cpu}}
        return {'control_rate_hz': rate, 'as_fast_as_possible': fast,
                'real_time': {'achieved_rate_hz': achieved}}
    got = targets_from([row(100.0, 90.0, 99.5), row(1000.0, 140.0, 900.0)], [3.0, 4.0])
    assert [(r['measured'], r['required'], r['verdict']) for r in got] == [
        (140.0, 100.0, 'MISS'), (99.5, 100.0, 'PASS'), (900.0, 1000.0, 'MISS')]
    assert '1000 Hz: 140 (70 in its thread, dds.shm 42, dds.ev 28)' in got[0]['note'] and \
        'load 3.0-4.0' in got[0]['note']
    got = targets_from([row(100.0, 90.0, 98.0)], [3.0, 4.0])
    assert [r['verdict'] for r in got] == ['PASS', 'MISS']


def test_round_trips_read_the_cpu_clocks_only_now_and_then(monkeypatch):
    """The simulator's CPU per exchange is a difference of CPU clocks over a window of
    exchanges: the clocks (system calls, ~0.5 µs each hot) are read at the first
    CPU_EVERY commands, then at every CPU_EVERY-th, not at every one (before: two reads
    per exchange). The figure is the mean over the window, and the wall figures still
    count every exchange."""
    from rigid_body_sim.engine import lockstep
    clock = {'cpu': 0.0, 'reads': 0, 'wall': 0.0}

    def cpu():
        clock['reads'] += 1
        return clock['cpu']
    monkeypatch.setattr(lockstep.time, 'process_time', cpu)
    monkeypatch.setattr(lockstep.time, 'thread_time', lambda: clock['cpu'] / 2)
    monkeypatch.setattr(lockstep.time, 'monotonic', lambda: clock['wall'])
    trips = lockstep.RoundTrips()
    n = 10 * lockstep.CPU_EVERY + 5
    for _ in range(n):
        trips.sent()
        clock['wall'] += 1e-4  # 100 µs from state to command
        clock['cpu'] += 7e-5   # 70 µs of CPU per exchange
        trips.applied()
    assert clock['reads'] == lockstep.CPU_EVERY + 9, clock
    v = trips.values()
    assert v['lockstep_exchanges'] == n
    assert abs(v['lockstep_round_trip_wall_us'] - 100.0) < 1e-6, v
    assert abs(v['lockstep_cpu_per_period_us'] - 70.0) < 1e-6, v
    assert abs(v['lockstep_thread_cpu_per_period_us'] - 35.0) < 1e-6, v


def test_round_trips_give_each_threads_part_of_the_cpu():
    """``RoundTrips.thread_parts``: from the first command whose CPU was read to the end,
    the CPU per period of each kind of thread (its name without trailing numbers, as Fast
    DDS names its threads), this one's as 'main', and what threads that ended meanwhile
    spent as 'ended' (the process's CPU less the others'); and ``wakes``, how often each
    kind slept and was woken. Two threads started after the first read burn 50 ms each:
    one then sleeps 20 times and is still there at the end, one ended."""
    import threading
    import time
    from rigid_body_sim.engine import lockstep
    trips = lockstep.RoundTrips()
    trips.sent()
    trips.applied()  # the first read: the threads there are then
    done, spent = threading.Event(), {}

    def burn(name, keep):
        with open(f'/proc/self/task/{threading.get_native_id()}/comm', 'w') as f:
            f.write(name)
        t0 = time.thread_time()
        while time.thread_time() - t0 < 0.05:
            pass
        spent[name] = time.thread_time()  # all of it after the first read
        if keep:
            for _ in range(20):  # slept and woken 20 times at least (RoundTrips.wakes)
                time.sleep(0.001)
            spent['slept'] = True
            done.wait(60)
    kept = threading.Thread(target=burn, args=('burner.7', True))
    ended = threading.Thread(target=burn, args=('gone.3', False))
    kept.start()
    ended.start()
    ended.join(60)
    while 'slept' not in spent and kept.is_alive():
        time.sleep(0.001)
    for _ in range(9):
        trips.sent()
        trips.applied()
    try:
        parts, wakes = trips.thread_parts(), trips.wakes()
    finally:
        done.set()
        kept.join(60)
    n = 9  # periods from the first read
    assert abs(parts['burner'] * n / 1e6 - spent['burner.7']) < 1e-3, (parts, spent)
    assert abs(parts['ended'] * n / 1e6 - spent['gone.3']) < 0.01, (parts, spent)
    assert 'gone' not in parts and parts['main'] > 0, parts
    # how often each kind slept and was woken, per period: the ended thread is not counted
    assert wakes['burner'] * n >= 20 and 'gone' not in wakes and 'main' in wakes, wakes


# one side of a lockstep-like ping-pong between two processes, with Fast DDS's synchronous
# publication and the profile FASTRTPS_DEFAULT_PROFILES_FILE names, each reading from an rcl
# wait set of its one subscription as the simulator does (sim_lockstep), keep-last 1:
# 'echo' answers each ping with a pong; 'ping' sends N pings, each after the last one's
# pong, and prints how often its timed-events threads (dds.ev.*) woke per ping (voluntary
# context switches)
_PING_PONG = r'''
import os, sys, time
import rclpy
from geometry_msgs.msg import Vector3Stamped
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
role, n, ns = sys.argv[1], int(sys.argv[2]), sys.argv[3]
rclpy.init()
node = rclpy.create_node(f'ping_pong_{role}', namespace=ns)
qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)
out, back = ('pong', 'ping') if role == 'echo' else ('ping', 'pong')
pub = node.create_publisher(Vector3Stamped, out, qos)
sub = node.create_subscription(Vector3Stamped, back, lambda m: None, qos, raw=True)
waits = _rclpy.WaitSet(1, 0, 0, 0, 0, 0, node.context.handle)


def take(timeout):
    waits.clear_entities()
    waits.add_subscription(sub.handle)
    waits.wait(int(timeout * 1e9))
    got = sub.handle.take_message(Vector3Stamped, True)
    return None if got is None else got[0]


if role == 'echo':
    while rclpy.ok():
        data = take(1.0)
        if data is not None:
            pub.publish(data)
    sys.exit(0)


def wakes():
    total = 0
    for tid in os.listdir('/proc/self/task'):
        with open(f'/proc/self/task/{tid}/comm') as f:
            if not f.read().startswith('dds.ev'):
                continue
        with open(f'/proc/self/task/{tid}/status') as f:
            total += sum(int(x.split()[1]) for x in f if x.startswith('voluntary_ctxt'))
    return total


deadline = time.monotonic() + 120
while (pub.get_subscription_count() == 0 or sub.get_publisher_count() == 0) and \
        time.monotonic() < deadline:
    time.sleep(0.01)
message = serialize_message(Vector3Stamped())


def exchange():
    pub.publish(message)
    while take(1.0) is None:
        assert time.monotonic() < deadline, 'no pong within 120 s'


for _ in range(20):  # matched and warm
    exchange()
before = wakes()
for _ in range(n):
    exchange()
print((wakes() - before) / n)
'''


def _event_thread_wakes(profile: str, pings: int = 500) -> float:
    """The pinging process's timed-events thread's wake-ups per ping (_PING_PONG) with the
    Fast DDS profile of text ``profile``, both processes publishing synchronously."""
    import subprocess
    from rigid_body_sim.nodes import process
    env = dict(os.environ, RMW_FASTRTPS_PUBLICATION_MODE='SYNCHRONOUS',
               FASTRTPS_DEFAULT_PROFILES_FILE=process.heartbeat_profile(profile))
    ns = f'/ping_pong_{os.getpid()}_{len(profile)}'
    echo = subprocess.Popen([sys.executable, '-c', _PING_PONG, 'echo', '0', ns], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        ping = subprocess.run([sys.executable, '-c', _PING_PONG, 'ping', str(pings), ns],
                              env=env, capture_output=True, text=True, timeout=240)
    finally:
        echo.send_signal(signal.SIGINT)
        try:
            echo.wait(timeout=30)
        except subprocess.TimeoutExpired:
            echo.kill()
            echo.wait()
    assert ping.returncode == 0, ping.stderr[-2000:]
    return float(ping.stdout.split()[-1])


def test_a_synchronous_writer_does_not_wake_its_event_thread_per_message():
    """The Fast DDS profile of the lockstep nodes (``process.heartbeat_profile``): a
    writer's nack suppression lasts a heartbeat period, so that a message sent does not
    wake the timed-events thread to end a suppression of 0 s (Fast DDS's default). Counted
    in a ping-pong of two processes as lockstep exchanges (synchronous publication): the
    pinging process's event-thread wake-ups per ping, with the profile and with the same
    profile without that element (0.05-0.06 against 1.1-3.9, 3 runs at load 6)."""
    from rigid_body_sim.nodes import process
    element = (f'        <nackSupressionDuration>\n          <sec>0</sec><nanosec>'
               f'{process.NACK_SUPPRESSION_NS}</nanosec>\n        </nackSupressionDuration>\n')
    without = process._PROFILE.replace(element, '')
    assert without != process._PROFILE  # the element this test is about
    ours, default = _event_thread_wakes(process._PROFILE), _event_thread_wakes(without)
    # a ratio of two runs, not a bound: under load the exchanges slow down and the
    # periodic heartbeat's wake-ups (every 20 ms with unacknowledged data) add to both
    assert ours <= default / 2, (ours, default)


def test_a_synchronous_writer_sends_no_heartbeat_its_reader_must_answer_per_message():
    """The same profile turns Fast DDS's piggybacked heartbeats off: with them, many of a
    lockstep exchange's messages carry a heartbeat that the reader must answer, its
    timed-events thread woken for each answer. The pinging process's event-thread
    wake-ups per ping, with the profile and with the same profile without that element.

    Both with the heartbeat period and the nack suppression at 0.5 s instead of 20 ms:
    their timers' wake-ups grow with the run's wall time and under load hid the element
    (0.142 against 0.088 beside three CPU hogs; CI once 0.102 against 0.108; with only
    the period at 0.5 s, 0.216/0.224 against 0.192/0.196 in a suite beside two hogs at
    load 10-14). Two runs of each, alternated and summed: beside five CPU hogs at load 7
    the ratio was 0.06-0.17 in 5 such sets (each run 0.004-0.038 against 0.06-0.15)."""
    from rigid_body_sim.nodes import process
    element = '      <qos><disable_heartbeat_piggyback>true</disable_heartbeat_piggyback></qos>\n'
    timers = f'<nanosec>{process.HEARTBEAT_PERIOD_NS}</nanosec>'
    slow = '<nanosec>500000000</nanosec>'
    ours = process._PROFILE.replace(timers, slow)
    assert element in ours and ours.count(slow) == 2  # what it is about: both timers slow
    piggybacked = ours.replace(element, '')
    runs = [_event_thread_wakes(profile) for profile in (ours, piggybacked) * 2]
    assert runs[0] + runs[2] <= 0.6 * (runs[1] + runs[3]), runs


@pytest.mark.parametrize('frame', ['', 'b', 'base_link', '/base_link', 'body_frame_1',
                                   'ωβ_frame', 'x' * 15])
def test_a_commands_layout_decodes_as_stamped_fields(frame):
    """``sim_lockstep.command_layout``: the layout of one command's bytes, made once,
    decodes each next command of that layout (frame id) in one struct call to exactly
    what ``commands.stamped_fields`` reads from it (frame ids of every padding), and
    tells a command of another frame by its (size, bytes); big-endian bytes and bytes
    past the doubles have no layout (they go ``stamped_fields``' way)."""
    from geometry_msgs.msg import Vector3Stamped
    from rclpy.serialization import serialize_message
    from rigid_body_sim.nodes.commands import stamped_fields, vector3_stamped_cdr
    from rigid_body_sim.nodes.sim_lockstep import command_layout

    def cdr(sec, nanosec, frame_id, x, y, z):
        m = Vector3Stamped()
        m.header.stamp.sec, m.header.stamp.nanosec, m.header.frame_id = sec, nanosec, frame_id
        m.vector.x, m.vector.y, m.vector.z = x, y, z
        return serialize_message(m)
    first = cdr(0, 0, frame, 0.0, 0.0, 0.0)
    layout = command_layout(first, stamped_fields(first, 3))
    assert layout is not None and layout[0] == len(first) and layout[3] == frame
    for sec, nanosec, x, y, z in [(0, 0, 0.0, 0.0, 0.0), (12, 340_000_000, 1e-3, -2.5e-7, 0.0),
                                  (-3, 999_999_999, float('nan'), float('inf'), -0.0),
                                  (2**31 - 1, 1, 5e-324, -1.7976931348623157e308, 1.0)]:
        data = cdr(sec, nanosec, frame, x, y, z)
        assert len(data) == layout[0]
        got = layout[1](data)
        assert got[2:4] == layout[2], (got, layout)
        want = stamped_fields(data, 3)
        assert repr(got[:2] + (layout[3],) + got[4:]) == repr(want), (got, want)
    other = cdr(0, 0, frame + 'x', 0.0, 0.0, 0.0)
    if len(other) == layout[0]:  # same length (padding): told apart by the frame's bytes
        assert layout[1](other)[2:4] != layout[2]
    little = vector3_stamped_cdr(0, 0, frame, 0.0, 0.0, 0.0)
    assert command_layout(little, stamped_fields(little, 3)) is not None
    big = b'\x00\x00' + little[2:]  # (the encapsulation says big-endian)
    assert command_layout(big, (0, 0, frame, 0.0, 0.0, 0.0)) is None
    assert command_layout(first + bytes(8), stamped_fields(first, 3)) is None


def test_the_held_instants_commands_are_read_by_their_layout(
        rclpy_node, simulator, monkeypatch):  # noqa: F811 (test_sim_exchange's fixture)
    """Lockstep as fast as possible: once the short way took a command, the next held
    instants' commands of the same frame are decoded by its layout
    (``command_layout``) without ``stamped_fields``; a command of another frame, stale
    or for another instant still goes the general way and is counted as before
    (test_sim_exchange: every other case and the messages, bit for bit)."""
    from geometry_msgs.msg import Vector3Stamped
    from rclpy.serialization import serialize_message
    from rigid_body_sim.nodes import sim_lockstep
    sim = simulator(lockstep=True, publish_clock=True, real_time_factor=0.0,
                    publish_rate=50.0, control_rate=50.0, lockstep_timeout=30.0)
    calls = []
    decode = sim_lockstep.stamped_fields
    monkeypatch.setattr(sim_lockstep, 'stamped_fields',
                        lambda *a: (calls.append(1), decode(*a))[1])

    def command(k, frame='base_link', z=0.01):
        msg = Vector3Stamped()
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(k * 20_000_000, NS)
        msg.header.frame_id, msg.vector.z = frame, z * (k + 1)
        sim._on_torque_bytes(serialize_message(msg))
    sim.run_once()
    assert sim.lockstep_held is not None and sim.t_ns == 0
    command(0)  # the first: stamped_fields, and its layout kept
    assert calls == [1] and sim.t_ns == 20_000_000
    for k in range(1, 6):
        command(k)
        assert sim.t_ns == (k + 1) * 20_000_000 and sim.lockstep_held is not None
        assert sim._crafts[''].engine.command.torque.tolist() == [0.0, 0.0, 0.01 * (k + 1)]
    assert calls == [1], calls  # the layout's, not stamped_fields'
    rejected = sim._crafts[''].commands.rejected
    command(3)                      # answered already, same layout: general, stale
    command(6, z=float('nan'))      # the held stamp, not finite: general, rejected
    assert calls == [1] and rejected['lockstep_stale'] == 1 and \
        rejected['non_finite'] == 1, rejected
    command(6, frame='other_frame')  # another layout: stamped_fields, general
    assert calls == [1, 1] and rejected['wrong_frame'] == 1, rejected
    command(6, frame='')            # the body's too: short way, its layout kept
    assert sim.t_ns == 7 * 20_000_000 and calls == [1, 1, 1]
    command(7, frame='')
    assert sim.t_ns == 8 * 20_000_000 and calls == [1, 1, 1]
