"""What the launch file starts (rigid_body_sim.launch_plan), and those nodes run for real.

The `launch` package is not on PyPI, so `ros2 launch` cannot run here; the launch file
only turns this plan into actions (test_package checks that), and here the planned nodes
are started as the launch would start them: same executables, names and params files.
"""
import os

import pytest

from ros_helpers import spin_until, venv_exe
from stamp_checks import gaps_from_t0

from rigid_body_sim.launch_plan import lockstep_parameters, plan
from rigid_body_sim.scene import SceneError, list_scenes, load


@pytest.mark.parametrize('name', [n for n, _, _ in list_scenes()])
def test_every_scene_plans_its_nodes(name):
    nodes, summary = plan(name)
    names = [n.executable for n in nodes]
    assert names[0] == 'simulator' and names[-1] == 'recorder'
    scene = load(name)
    # one controller, or a formation's: one per spacecraft, in its namespace
    controllers = [n.namespace for n in nodes if n.executable == 'controller']
    assert controllers == ((list(scene.spacecraft) or ['']) if scene.controlled else [])
    assert all(os.path.isabs(f) and os.path.isfile(f) for n in nodes for f in n.params_files)
    assert 'when the simulator exits' in summary
    # recording: the simulator holds t = 0 until the recorder is matched (a full bag), and
    # the controller when there is one (its mission clock starts with t = 0)
    assert nodes[0].parameters == {'wait_for_subscribers': 1,
                                   **({'wait_for_controller': True} if 'controller' in names
                                      else {})}
    forced = [n.executable for n in plan(name, controller='true', record='false')[0]]
    assert forced == ['simulator'] + ['controller'] * max(1, len(scene.spacecraft))
    viewed = plan(name, record='false', controller='false', viewer='true', viewer_port='9001')[0]
    assert [(n.executable, n.parameters) for n in viewed] == [
        ('simulator', {}), ('viewer', {'port': 9001})]


def test_unknown_scene_and_bad_arguments_fail_at_once():
    with pytest.raises(SceneError,
                       match="unknown scene 'bogus'; built-in scenes: .*default, detumble"):
        plan('bogus')
    with pytest.raises(ValueError, match='controller:=maybe'):
        plan('default', controller='maybe')
    with pytest.raises(ValueError, match='record:=yes please'):
        plan('default', record='yes please')
    with pytest.raises(ValueError, match='viewer_port:=70000'):
        plan('default', viewer='true', viewer_port='70000')


def test_free_tumble_scene_gets_no_torque_and_ends(ros_process, namespace, rclpy_node,
                                                   tmp_path):
    """tennis_racket as launched: no controller, zero torque commands while the simulator
    runs, and the simulator exits by itself at the scene's duration (the launch's
    shutdown trigger); the recorder then stops on SIGINT with a bag that holds every
    sample from the simulator's t = 0."""
    from geometry_msgs.msg import QuaternionStamped, Vector3Stamped
    from rigid_body_sim.bag.reader import read_info
    nodes, _ = plan('tennis_racket', output=str(tmp_path / 'bag'))
    assert [n.executable for n in nodes] == ['simulator', 'recorder']
    torques, states = [], []
    rclpy_node.create_subscription(Vector3Stamped, f'{namespace}/torque_command',
                                   torques.append, 100)
    rclpy_node.create_subscription(QuaternionStamped, f'{namespace}/attitude', states.append,
                                   100)
    procs = {}
    for n in reversed(nodes):  # recorder first, as the demo does, so it sees the start
        cmd = [venv_exe(n.executable), *n.ros_arguments(namespace)]
        if n.executable == 'simulator':  # the scene's 10 s, 5x faster for the test (a
            # second file: -p would go to '/**', which the scene's own section overrides)
            faster = tmp_path / 'faster.yaml'
            faster.write_text('/**/attitude_simulator:\n  ros__parameters:\n'
                              '    real_time_factor: 5.0\n')
            cmd += ['--params-file', str(faster)]
        procs[n.executable] = ros_process(*cmd)
    sim = procs['simulator']
    # the run is 2 s of wall time: this test's own subscriptions may match after it on a
    # loaded machine (50 samples seen), so the bag, waited for, is what shows every sample
    assert spin_until(rclpy_node, lambda: sim.poll() is not None, 60.0), 'simulator never ended'
    assert sim.poll() == 0, sim.output()[-2000:]
    assert torques == []
    rec = procs['recorder']
    rec.signal(2)  # what the launch's Shutdown does to the remaining processes
    assert rec.wait(30) == 0, rec.output()[-2000:]
    info = read_info(str(tmp_path / 'bag'))
    assert info.message_count > 0
    # every sample from t = 0: the scene's 10 s at 100 Hz, stamps 10 ms / 5 apart
    assert gaps_from_t0(tmp_path / 'bag', 2_000_000, count=1001) == []


def test_lockstep_argument_runs_the_scene_in_lockstep(ros_process, namespace, tmp_path):
    """lockstep:=true: the simulator holds the controller's instants (its control_rate, sim
    time stamps) and the controller answers each; the planned nodes run for real, as fast
    as possible: every instant is exchanged once and the bag has every sample from t = 0.
    A scene without a controller, or whose rates cannot lock, is refused at once."""
    nodes, summary = plan('slew', output=str(tmp_path / 'bag'), lockstep='true')
    assert 'in lockstep' in summary
    params = {n.executable: n.parameters for n in nodes}
    assert params['simulator'] == {'wait_for_subscribers': 1, 'wait_for_controller': True,
                                   'lockstep': True,
                                   'publish_clock': True, 'control_rate': 50.0}
    assert params['controller'] == {'lockstep': True}
    with pytest.raises(ValueError, match='lockstep:=true: scene tennis_racket runs no controller'):
        plan('tennis_racket', lockstep='true')
    with pytest.raises(ValueError, match='scene slew: lockstep: control_rate 50 Hz must divide'):
        lockstep_parameters(load('slew', ['publish_rate=40.0']))
    with pytest.raises(ValueError, match='lockstep:=maybe'):
        plan('slew', lockstep='maybe')
    procs = _start_planned(nodes, ros_process, namespace, tmp_path)
    sim = procs['simulator']
    assert sim.wait(180) == 0, sim.output()[-3000:]
    assert 'lockstep: 50 exchanges' in sim.output(), sim.output()[-3000:]
    assert 'paused' not in sim.output(), sim.output()[-3000:]
    assert procs['recorder'].stop() == 0
    assert gaps_from_t0(tmp_path / 'bag', 20_000_000, count=51) == []


def test_a_formation_in_lockstep_gets_a_controller_per_spacecraft(ros_process, namespace,
                                                                    tmp_path):
    """lockstep:=true on the formation: one controller per spacecraft in the loop, in that
    spacecraft's namespace, with its body frame and inertia (a spacecraft with
    <name>.lockstep: false gets none). The planned nodes run for real, as fast as
    possible: the simulator answers every instant of every spacecraft and ends. Before,
    the plan started one controller in the launch's namespace, which answered none."""
    nodes, summary = plan('formation', output=str(tmp_path / 'bag'), lockstep='true')
    ctls = [n for n in nodes if n.executable == 'controller']
    assert [(n.namespace, n.parameters) for n in ctls] == [
        ('leader', {'child_frame_id': 'leader/base_link', 'inertia': [10.0, 12.0, 14.0],
                    'lockstep': True}),
        ('wingman', {'child_frame_id': 'wingman/base_link', 'inertia': [1.0, 2.0, 3.0],
                     'lockstep': True}),
        ('tumbler', {'child_frame_id': 'tumbler/base_link', 'inertia': [1.0, 2.0, 3.0],
                     'lockstep': True})]
    assert 'controller (leader), controller (wingman), controller (tumbler)' in summary
    assert ['-r', f'__ns:={namespace}/wingman'] == ctls[1].ros_arguments(namespace)[3:5]
    out_of_loop = tmp_path / 'out_of_loop.yaml'
    out_of_loop.write_text(open(ctls[0].params_files[0]).read().replace(
        '    tumbler:', '    tumbler:\n      lockstep: false'))
    assert [n.namespace for n in plan(str(out_of_loop), lockstep='true')[0]
            if n.executable == 'controller'] == ['leader', 'wingman']
    procs = _start_planned(nodes, ros_process, namespace, tmp_path)
    sim = procs['simulator']
    assert sim.wait(240) == 0, sim.output()[-3000:]
    # 10 Hz control, 1 s: the instants t = 0 ... 0.9 s held, each for all three
    assert 'lockstep: 10 exchanges' in sim.output(), sim.output()[-3000:]
    assert 'paused' not in sim.output(), sim.output()[-3000:]


def _start_planned(nodes, ros_process, namespace, tmp_path):
    """The planned nodes started for real, recorder first, the simulator as fast as possible
    for 1 s; keyed by namespace, else executable."""
    faster = tmp_path / 'faster.yaml'
    faster.write_text('/**/attitude_simulator:\n  ros__parameters:\n'
                      '    real_time_factor: 0.0\n    duration: 1.0\n')
    procs = {}
    for n in reversed(nodes):  # recorder first
        cmd = [venv_exe(n.executable), *n.ros_arguments(namespace)]
        if n.executable == 'simulator':
            cmd += ['--params-file', str(faster)]
        procs[n.namespace or n.executable] = ros_process(*cmd, env={'PYTHONUNBUFFERED': '1'})
    return procs
