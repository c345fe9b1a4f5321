"""The viewer beyond one free body, against the real Foxglove client (see test_viewer): a
formation's spacecraft, one spawned and one deleted while it runs; a scene with an orbit
(the Earth, the orbit, LVLH, the Sun and the field); and a parameter request whose reply
never comes (the viewer asks again)."""
import math
import os
import signal
import subprocess
import sys

import numpy as np

from ros_helpers import spin_until, stamp_ns, venv_exe
from test_viewer import _free_port, _viewer_cmd, _wait_port, client_js, finish_client  # noqa: F401
from test_viewer import run_client

CONFIG = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), 'config')
FORMATION = ('leader', 'wingman', 'tumbler')
INERTIA = {'leader': (10.0, 12.0, 14.0), 'wingman': (1.0, 2.0, 3.0),
           'tumbler': (1.0, 2.0, 3.0), 'rescue': (1.0, 2.0, 2.5)}  # formation.yaml, slew.yaml
EPOCH = '2026-03-20T12:00:00Z'
CLIENT_S = 240.0  # the client's bound; it is stopped (SIGTERM) as soon as the test has seen


def _stop_client(proc):
    proc.send_signal(signal.SIGTERM)
    return finish_client(proc, 0.0)


def _viewer_status(statuses):
    """The latest status of the viewer, as {key: value}."""
    return next((v for name, v in reversed(statuses) if name.startswith('attitude_viewer')),
                {})


def _listen(node, statuses):
    from diagnostic_msgs.msg import DiagnosticArray
    node.create_subscription(DiagnosticArray, '/diagnostics', lambda m: statuses.extend(
        (s.name, {kv.key: kv.value for kv in s.values}) for s in m.status), 100)


def _drawn(statuses):
    text = _viewer_status(statuses).get('spacecraft_drawn', '')
    return {n.strip() for n in text.split(',') if n.strip()}


def _direction(arrow):
    """An arrow's direction: its pose's +x (Foxglove's convention)."""
    from scipy.spatial.transform import Rotation
    o = arrow['pose']['orientation']
    return Rotation.from_quat((o['x'], o['y'], o['z'], o['w'])).apply((1.0, 0.0, 0.0))


def _xyz(p):
    return np.array((p['x'], p['y'], p['z']))


def _box(moments):
    """The display box's edges, longest 1 m: a uniform box has I₁ = m(b² + c²)/12 (cyclic)."""
    m = np.asarray(moments, float)
    a = np.sqrt(m.sum() - 2.0 * m)
    return a / a.max()


def test_formation_draws_each_spacecraft_then_the_spawned_one_not_the_deleted(
        ros_process, namespace, rclpy_node, client_js):  # noqa: F811
    from geometry_msgs.msg import QuaternionStamped
    from simulation_interfaces.msg import Result
    from simulation_interfaces.srv import DeleteEntity
    from ros_helpers import call_service
    port = _free_port()
    sim = ros_process(venv_exe('simulator'), '--ros-args', '-r', f'__ns:={namespace}',
                      '--params-file', os.path.join(CONFIG, 'formation.yaml'))
    viewer = ros_process(*_viewer_cmd(), '--ros-args', '-r', f'__ns:={namespace}',
                         '-p', f'port:={port}')
    node, statuses, attitude = rclpy_node, [], {}
    _listen(node, statuses)
    for name in INERTIA:  # the simulator's own attitude, to compare /tf with
        node.create_subscription(QuaternionStamped, f'{namespace}/{name}/attitude',
                                 lambda m, n=name: attitude.setdefault(n, {}).__setitem__(
                                     stamp_ns(m), (m.quaternion.x, m.quaternion.y,
                                                   m.quaternion.z, m.quaternion.w)), 100)
    _wait_port(port)
    client = run_client(client_js, port, CLIENT_S, '--subscribe', '/tf,/scene', '--scene',
                        '--dump', '/tf', wait=False)
    try:
        assert spin_until(node, lambda: _drawn(statuses) == set(FORMATION), 90.0), \
            (_viewer_status(statuses), viewer.output()[-3000:])
        # a fourth, spawned through SpawnEntity by the example, with the slew scene's body
        spawn = subprocess.run(
            [sys.executable, '-m', 'rigid_body_sim.examples.spawn_spacecraft', '--name',
             'rescue', '--uri', 'slew', '--yaw', '90', '--timeout', '60', '--ros-args', '-r',
             f'__ns:={namespace}'], capture_output=True, text=True, timeout=300)
        assert spawn.returncode == 0, spawn.stdout + spawn.stderr + sim.output()[-3000:]
        assert spin_until(node, lambda: _drawn(statuses) == set(FORMATION) | {'rescue'},
                          60.0), (_viewer_status(statuses), viewer.output()[-3000:])
        # the viewer reports what it draws before its next scene tick sends it: let a scene
        # update with all four go out (10 Hz scene, ≥ 1 s of samples) before the delete
        n = len(attitude.get('rescue', ()))
        assert spin_until(node, lambda: len(attitude.get('rescue', ())) > n + 20, 60.0)
        gone = call_service(node, node.create_client(
            DeleteEntity, f'{namespace}/attitude_simulator/delete_entity'),
            DeleteEntity.Request(entity='wingman'))
        assert gone.result.result == Result.RESULT_OK, gone.result.error_message
        assert spin_until(node, lambda: _drawn(statuses) == {'leader', 'tumbler', 'rescue'},
                          60.0), (_viewer_status(statuses), viewer.output()[-3000:])
        # the client has the scene update that followed (10 Hz scene, ≥ 1 s of samples)
        n = len(attitude['rescue'])
        assert spin_until(node, lambda: len(attitude['rescue']) > n + 20, 60.0)
    finally:
        (s,) = _stop_client(client)
    assert not s['errors'], s['errors']

    def bodies(ids):
        return {i.split('/')[0] for i in ids if i.endswith('/body')}
    history = [bodies(ids) for ids in s['sceneHistory']]
    three = history.index(set(FORMATION))
    four = history.index(set(FORMATION) | {'rescue'})
    assert three < four < history.index({'leader', 'tumbler', 'rescue'}), history
    # the scene a client holds now: the deleted one's entities are gone, every one of the
    # others has its own box (its inertia's), ω, L and label
    scene = s['scene']
    assert not [i for i in scene if i.startswith('wingman/')], sorted(scene)
    for name in ('leader', 'tumbler', 'rescue'):
        assert {f'{name}/{e}' for e in ('body', 'omega', 'angular_momentum', 'label')} <= \
            set(scene), sorted(scene)
        box = scene[f'{name}/body']
        assert box['frameId'] == f'{name}/base_link'
        size = box['cubes'][0]['size']
        np.testing.assert_allclose(np.maximum(_box(INERTIA[name]), 0.01),
                                   (size['x'], size['y'], size['z']), rtol=1e-9)
        assert scene[f'{name}/label']['texts'][0]['text'] == name
    # /tf: world → <name>/base_link with the simulator's attitude at the same stamp, each
    # body in a display slot of its own
    slots, matched = {}, {}
    for t in s['dumped']['/tf']:
        name, _, frame = t['childFrameId'].partition('/')
        assert t['parentFrameId'] == 'world' and frame == 'base_link', t
        q = attitude.get(name, {}).get(int(t['timestamp']['seconds']) * 1_000_000_000
                                       + int(t['timestamp']['nanos']))
        if q is not None:
            r = t['rotation']
            np.testing.assert_allclose((r['x'], r['y'], r['z'], r['w']), q, rtol=0, atol=1e-9)
            matched[name] = matched.get(name, 0) + 1
        slots.setdefault(name, set()).add(tuple(_xyz(t['translation']).round(9)))
    assert set(matched) == set(INERTIA) and min(matched.values()) >= 10, matched
    assert all(len(v) == 1 for v in slots.values()), slots
    live = [slots[n] for n in ('leader', 'tumbler', 'rescue')]
    assert len({next(iter(v)) for v in live}) == 3, slots
    assert viewer.poll() is None and sim.poll() is None
    assert 'Traceback' not in viewer.output()


def test_orbit_scene_draws_earth_orbit_lvlh_sun_and_field(ros_process, namespace, rclpy_node,
                                                         client_js):  # noqa: F811
    """The gravity-gradient scene (circular, 7,000 km, i = 0.9006 rad), stamps = sim time
    (publish_clock), so that the test knows each update's instant without the viewer."""
    from nav_msgs.msg import Odometry
    from rigid_body_sim.physics.environment import magnetic_field, sunlight
    port = _free_port()
    ros_process(venv_exe('simulator'), '--ros-args', '-r', f'__ns:={namespace}',
                '--params-file', os.path.join(CONFIG, 'gravity_gradient.yaml'),
                '-p', 'publish_clock:=true', '-p', f'epoch:={EPOCH}')
    viewer = ros_process(*_viewer_cmd(), '--ros-args', '-r', f'__ns:={namespace}',
                         '-p', f'port:={port}')
    node, statuses, orbit = rclpy_node, [], {}
    _listen(node, statuses)
    node.create_subscription(Odometry, f'{namespace}/orbit', lambda m: orbit.__setitem__(
        stamp_ns(m), m), 1000)
    _wait_port(port)
    client = run_client(client_js, port, CLIENT_S, '--subscribe', '/scene', '--dump',
                        '/scene', '--points', wait=False)
    try:
        assert spin_until(node, lambda: 'orbit: the Sun' in viewer.output(), 90.0), \
            viewer.output()[-3000:]
        n = len(orbit)
        assert spin_until(node, lambda: len(orbit) > n + 300, 60.0)  # 3 s at 100 samples/s
    finally:
        (s,) = _stop_client(client)
    assert not s['errors'], s['errors']
    a, inc, radius = 7.0e6, 0.9006, 6378137.0
    checked = 0
    for update in s['dumped'].get('/scene', []):
        ents = {e['id']: e for e in update['entities']}
        if 'magnetic_field' not in ents:
            continue
        stamp = int(ents['earth']['timestamp']['seconds']) * 1_000_000_000 + int(
            ents['earth']['timestamp']['nanos'])
        msg = orbit.get(stamp)
        if msg is None:
            continue
        p = msg.pose.pose.position
        r = np.array((p.x, p.y, p.z))
        # v from the twist, resolved in LVLH (REP-105): back to world
        from scipy.spatial.transform import Rotation
        o = msg.pose.pose.orientation
        v = Rotation.from_quat((o.x, o.y, o.z, o.w)).apply(
            (msg.twist.twist.linear.x, msg.twist.twist.linear.y, msg.twist.twist.linear.z))
        earth = ents['earth']['spheres'][0]
        centre = _xyz(earth['pose']['position'])
        marker = _xyz(ents['orbit_position']['spheres'][0]['pose']['position']) - centre
        scale = np.linalg.norm(marker) / np.linalg.norm(r)
        np.testing.assert_allclose(marker / np.linalg.norm(marker), r / np.linalg.norm(r),
                                   atol=1e-9)
        # the Earth at the orbit's scale; the path: the circle of radius a in the plane of
        # inclination i, one period (closed), its apoapsis one body size out
        assert abs(earth['size']['x'] / 2.0 / scale - radius) <= 1e-9 * radius
        path = np.array([_xyz(q) for q in ents['orbit_path']['lines'][0]['points']]) - centre
        assert len(path) == 181
        np.testing.assert_allclose(np.linalg.norm(path, axis=1) / scale, a, rtol=1e-7)
        np.testing.assert_allclose(np.linalg.norm(path, axis=1).max(), 1.0, rtol=1e-12)
        np.testing.assert_allclose(path[0], path[-1], atol=1e-9)
        np.testing.assert_allclose(path[0], marker, atol=1e-9)
        normal = np.cross(path[0], path[45])
        assert abs(normal[2] / np.linalg.norm(normal) - math.cos(inc)) < 1e-7
        # LVLH at the body: x along the velocity (circular), z to nadir, y = z × x
        z = -r / np.linalg.norm(r)
        y = -np.cross(r, v) / np.linalg.norm(np.cross(r, v))
        lvlh = [_direction(arr) for arr in ents['lvlh']['arrows']]
        for got, want in zip(lvlh, (np.cross(y, z), y, z)):
            np.testing.assert_allclose(got, want, atol=1e-9)
        np.testing.assert_allclose(lvlh[0], v / np.linalg.norm(v), atol=1e-6)
        # the Sun and the field at the update's instant (stamps are sim time here)
        t = stamp * 1e-9
        sun = np.asarray(sunlight.sun_direction(EPOCH, t))
        np.testing.assert_allclose(_direction(ents['sun']['arrows'][0]), sun, atol=1e-9)
        np.testing.assert_allclose(_direction(ents['orbit_sun']['arrows'][0]), sun, atol=1e-9)
        # (the viewer keeps the dipole's moment for an hour of sim time: ≤ 1e-7 rad)
        b = np.asarray(magnetic_field.field('dipole', r, EPOCH, t))
        np.testing.assert_allclose(_direction(ents['magnetic_field']['arrows'][0]),
                                   b / np.linalg.norm(b), atol=1e-6)
        checked += 1
    assert checked >= 10, (checked, len(s['dumped'].get('/scene', [])), viewer.output()[-3000:])
    assert 'Traceback' not in viewer.output()


def test_a_parameter_request_left_unanswered_is_sent_again(ros_process, namespace):
    """A simulator whose get_parameters never replies (its reply lost, or the node gone
    mid-call: rclpy's future then never settles), then a real one: the viewer asks again
    and gets the body. It used to ask once and wait for ever."""
    import rclpy
    from rcl_interfaces.srv import GetParameters
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.task import Future
    context = rclpy.Context()
    rclpy.init(context=context)
    executor = SingleThreadedExecutor(context=context)
    fake = Node('attitude_simulator', namespace=namespace, context=context)
    executor.add_node(fake)
    asked = []

    async def never(request, response):
        asked.append(list(request.names))
        await Future()  # no reply, ever
        return response
    service = next(s for s in fake.services if s.srv_name.endswith('/get_parameters'))
    fake.destroy_service(service)
    fake.create_service(GetParameters, 'attitude_simulator/get_parameters', never)
    statuses = []
    watcher = Node('watcher', namespace=namespace, context=context)
    executor.add_node(watcher)
    _listen(watcher, statuses)
    port = _free_port()
    viewer = ros_process(*_viewer_cmd(), '--ros-args', '-r', f'__ns:={namespace}',
                         '-p', f'port:={port}')
    try:
        assert spin_until(fake, lambda: ['inertia'] in asked, 60.0, executor), \
            viewer.output()[-3000:]
        fake.destroy_node()
        sim = ros_process(venv_exe('simulator'), '--ros-args', '-r', f'__ns:={namespace}')
        assert spin_until(watcher, lambda: _viewer_status(statuses).get('body_known') == 'true',
                          60.0, executor), (viewer.output()[-3000:], sim.output()[-2000:])
    finally:
        executor.shutdown()
        context.try_shutdown()
    assert 'body: principal moments [1.0, 2.0, 3.0]' in viewer.output()
