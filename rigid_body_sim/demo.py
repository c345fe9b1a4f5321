"""``make demo`` / ``rigid-body-sim demo``: the live graph on a scene, with a status line.

Starts the recorder, then the simulator and controller, as separate processes (the
installed node executables, as ``ros2 run`` would), loaded with the scene's params file.
An in-process rclpy node watches the state and prints sim time, real-time factor,
attitude error, |ω|, T and |L|. After ``--duration`` simulated seconds from the first
sample (or Ctrl-C, or the simulator reaching its ``duration``) the nodes are stopped cleanly
and a summary is printed: the phase it ended in, final pointing error, T and |L| drift during
the free phase, messages recorded, and where the bag and plots are.
"""
import math
import os
import shutil
import signal
import subprocess
import sys
import time

import numpy as np

from .scene import SceneError, load

STARTUP_TIMEOUT = 60.0  # wall s for the first sample (imports, kernels from cache, discovery)


def _executable(name):
    """The installed node executable (ament layout), else the module behind it."""
    path = os.path.join(sys.prefix, 'lib', 'rigid_body_sim', name)
    return ([path] if os.path.exists(path)
            else [sys.executable, '-m', f'rigid_body_sim.nodes.{name}'])


class _Process:
    def __init__(self, name, args, log_dir):
        self.name = name
        self.log_path = os.path.join(log_dir, f'{name}.log')
        self.log = open(self.log_path, 'wb')
        self.proc = subprocess.Popen(_executable(name) + args, stdout=self.log,
                                     stderr=subprocess.STDOUT, start_new_session=True)

    def stop(self, timeout=10.0):
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGINT)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait()
        self.log.close()
        return self.proc.returncode


class _Watcher:
    """Subscribes to the simulator's state and the controller's command; keeps what the
    summary needs."""

    def __init__(self, node, target, time_scale=1.0):
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import QuaternionStamped, Vector3Stamped
        from std_msgs.msg import Float64
        from .nodes.common import qos_profile
        self.target = target
        self.q = self.w = self.L = None
        self.T = None
        self.t = 0.0
        self.t0 = None  # first stamp: the status shows time since the simulation started
        self.time_scale = time_scale  # sim seconds per stamp second (rtf without /clock)
        self.phase = None  # the controller's mission phase (free, detumble, slew), if any
        self.slew_start = None  # sim time at which the controller reported the slew
        self.rtf = math.nan
        self._rtf_reports = 0
        self.torque_seen = False
        self.free = {'T': [], 'L': []}  # T and |L| while no torque has been commanded yet
        qos = qos_profile('reliable', 100)
        node.create_subscription(QuaternionStamped, 'attitude', self._on_attitude, qos)
        node.create_subscription(Vector3Stamped, 'angular_velocity', self._on_w, qos)
        node.create_subscription(Vector3Stamped, 'angular_momentum', self._on_L, qos)
        node.create_subscription(Float64, 'kinetic_energy', self._on_T, qos)
        node.create_subscription(Vector3Stamped, 'torque_command', self._on_torque, qos)
        node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag, qos)

    def _on_attitude(self, msg):
        o = msg.quaternion
        self.q = np.array((o.x, o.y, o.z, o.w))
        stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        self.t0 = stamp if self.t0 is None else self.t0
        self.t = (stamp - self.t0) * self.time_scale

    def _on_w(self, msg):
        v = msg.vector
        self.w = np.array((v.x, v.y, v.z))

    def _on_L(self, msg):
        v = msg.vector
        self.L = np.array((v.x, v.y, v.z))
        if not self.torque_seen:
            self.free['L'].append(float(np.linalg.norm(self.L)))

    def _on_T(self, msg):
        self.T = msg.data
        if not self.torque_seen:
            self.free['T'].append(msg.data)

    def _on_torque(self, msg):
        v = msg.vector
        if v.x or v.y or v.z:
            self.torque_seen = True

    def _on_diag(self, msg):
        for status in msg.status:
            if status.name.startswith('attitude_controller'):
                for kv in status.values:
                    if kv.key == 'mission_phase' and kv.value != 'waiting':
                        if kv.value == 'slew' and self.phase != 'slew':
                            self.slew_start = self.t
                        self.phase = kv.value
            if status.name.startswith('attitude_simulator'):
                for kv in status.values:
                    # the simulator's first report spans its start-up, not its pacing
                    if kv.key == 'real_time_factor_achieved':
                        self._rtf_reports += 1
                        try:
                            if self._rtf_reports > 1:
                                self.rtf = float(kv.value)
                        except ValueError:
                            pass

    def error_deg(self):
        if self.q is None:
            return math.nan
        from .physics import rotation
        return math.degrees(float(rotation.angle_between(self.q, self.target)))

    def ended_in(self):
        """The phase the run is in: the controller's mission phase when it reported one."""
        if self.phase:
            return self.phase
        return 'controlled' if self.torque_seen else 'free'

    def status(self):
        """The status line; empty until the first sample (no NaN placeholders)."""
        if self.t0 is None or self.w is None or self.L is None or self.T is None:
            return ''
        parts = [f't = {self.t:7.2f} s']
        # the first diagnostics come after 1 s, and their rate covers the start-up wait
        if math.isfinite(self.rtf) and self.t >= 1.0:
            parts.append(f'rtf {self.rtf:5.2f}')
        parts += [f'error {self.error_deg():7.3f}°', f'|ω| {np.linalg.norm(self.w):.3e} rad/s',
                  f'T {self.T:.6e} J', f'|L| {np.linalg.norm(self.L):.6e} kg·m²/s',
                  f'[{self.ended_in()}]']
        return '  '.join(parts)


def _phase_hint(watcher, scene):
    """Why the pointing error is still large, when the run ended before the slew."""
    if not scene.controlled or watcher.ended_in() == 'off':
        return ''
    if watcher.ended_in() == 'slew':
        from .control import critical_settling_time
        wn = np.mean(scene.controller.get('natural_frequency', 0.5))
        settle = critical_settling_time(wn)
        if watcher.slew_start is None or watcher.t - watcher.slew_start >= settle:
            return ''
        return (f' — the slew began at t ≈ {watcher.slew_start:.1f} s and settles to 2 % in '
                f'5.83/ω_n = {settle:.1f} s (try a longer --duration)')
    free = scene.controller.get('mission.free_time', 0.0)
    return (f' — the slew had not begun: the free phase lasts {free:g} s, then the detumble; '
            'the error is the tumble\'s, not the controller\'s (try a longer --duration)')


def _drift(values):
    if len(values) < 2 or values[0] == 0:
        return math.nan
    v = np.asarray(values)
    return float(np.max(np.abs(v - v[0])) / abs(v[0]))


def _plots_from_bag(bag, scene, out_dir):
    """The recorded state → the offline plots (same figures as `rigid-body-sim run`).

    Topics are joined by their header stamps (every topic of one sample carries the same
    stamp), and time is sim time: stamps advance by sim time / real_time_factor."""
    from rclpy.serialization import deserialize_message
    from .bag.reader import iter_messages
    from .bag.schema import message_class
    from .engine import EngineConfig
    from .plots import write_plots
    body = EngineConfig.from_parameters(scene.simulator).body
    p = scene.simulator
    rtf = 1.0 if p['publish_clock'] else (p['real_time_factor'] or 1.0)
    series = {'/attitude': {}, '/angular_velocity': {}, '/angular_momentum': {}}
    first_torque = None  # stamp of the first nonzero command: the end of the free phase
    commands = []  # (stamp, torque): held from its stamp on
    for m in iter_messages(bag, topics=list(series) + ['/torque_command']):
        msg = deserialize_message(m.data, message_class(m.type))
        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        if m.topic == '/torque_command':
            v = msg.vector
            if first_torque is None and (v.x or v.y or v.z):
                first_torque = stamp
            commands.append((stamp, (v.x, v.y, v.z)))
        elif m.topic == '/attitude':
            o = msg.quaternion
            series[m.topic][stamp] = (o.x, o.y, o.z, o.w)
        else:
            v = msg.vector
            series[m.topic][stamp] = (v.x, v.y, v.z)
    stamps = sorted(set.intersection(*(set(v) for v in series.values())))
    if len(stamps) < 2:
        return []
    t0 = stamps[0]
    w = np.array([series['/angular_velocity'][s] for s in stamps])
    torque = np.zeros_like(w)
    if commands:
        commands.sort(key=lambda c: c[0])
        k = np.searchsorted([c[0] for c in commands], stamps, side='right') - 1
        held = np.array([c[1] for c in commands])
        torque[k >= 0] = held[k[k >= 0]]
    samples = {'t': (np.array(stamps) - t0) * 1e-9 * rtf,
               'attitude': np.array([series['/attitude'][s] for s in stamps]),
               'angular_velocity': w,
               'angular_momentum': np.array([series['/angular_momentum'][s] for s in stamps]),
               'kinetic_energy': 0.5 * np.einsum('ni,ij,nj->n', w, body.inertia, w),
               'torque': torque}
    free_end = np.inf if first_torque is None else (first_torque - t0) * 1e-9 * rtf
    return write_plots(samples, body, out_dir, f'{scene.name} (live)', free_end, scene)


def _interrupt(signum, frame):
    """SIGTERM ends the demo like Ctrl-C: nodes stopped, bag finished, summary printed."""
    raise KeyboardInterrupt


def _overrides_file(scene, out) -> str:
    """The scene's values after --set, as a params file read after the scene's own."""
    import yaml
    path = os.path.join(out, 'overrides.yaml')
    data = {'/**/attitude_simulator': {'ros__parameters': scene.simulator}}
    if scene.controlled:
        data['/**/attitude_controller'] = {'ros__parameters': scene.controller}
    with open(path, 'w') as f:
        yaml.safe_dump(data, f)
    return path


def add_arguments(parser):
    parser.add_argument('--scene', default='default',
                        help='scene name or params file (default: default)')
    from .cli import number
    parser.add_argument('--duration', type=number(0.0, 1e9, low_open=True),
                        default=os.environ.get('DEMO_DURATION', '40'),
                        help='simulated seconds to run, counted from the first sample (start-up '
                             'is not included; default: $DEMO_DURATION or 40)')
    parser.add_argument('--out', default=os.path.join('out', 'demo'),
                        help='output directory (default out/demo)')
    from .offline import add_set_argument
    add_set_argument(parser)
    parser.add_argument('--no-viewer', dest='viewer', action='store_false',
                        help='do not start the Foxglove viewer node')
    parser.add_argument('--viewer-port', type=int, default=8765,
                        help='port of the Foxglove viewer (default 8765)')


def run(args) -> int:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from .bag.errors import BagError
    from .bag.reader import read_info
    try:
        scene = load(args.scene, args.set)
    except SceneError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    if not args.duration > 0:
        print('error: --duration must be > 0 simulated seconds', file=sys.stderr)
        return 2
    # a demo stays on this machine
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    out = os.path.abspath(args.out)
    bag = os.path.join(out, 'bag')
    shutil.rmtree(bag, ignore_errors=True)  # each demo replaces the previous one's bag
    os.makedirs(out, exist_ok=True)
    params = ['--ros-args', '--params-file', os.path.abspath(scene.path)]
    if args.set:  # a second params file: its node sections win over the scene's (rcl order)
        params += ['--params-file', _overrides_file(scene, out)]
    target = np.asarray(scene.controller.get('target_attitude', (0.0, 0.0, 0.0, 1.0)), float)
    print(f'demo: scene {scene.name} — {scene.description}')
    print(f'demo: logs and output in {out}; stopping after {args.duration:g} simulated s '
          'from the first sample (Ctrl-C stops earlier)')

    # Ctrl-C and SIGTERM raise KeyboardInterrupt here (rclpy's own handler would shut the
    # context down under the loop instead); the nodes run in their own sessions and are
    # stopped below, whatever ends the demo.
    from rclpy.signals import SignalHandlerOptions
    previous_term = signal.signal(signal.SIGTERM, _interrupt)
    procs, node, executor, watcher, interrupted = [], None, None, None, False
    try:
        procs.append(_Process('recorder', ['--ros-args', '-p', f'output:={bag}',
                                           '-p', f'scene:={scene.name}'], out))
        rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
        node = Node('demo_status')
        p = scene.simulator
        watcher = _Watcher(node, target, 1.0 if p['publish_clock'] else
                           (p['real_time_factor'] or 1.0))
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        # Give the recorder a moment to be discovered so it sees the first messages.
        deadline = time.monotonic() + 2.0
        while time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.1)
        procs.append(_Process('simulator', params, out))
        if scene.controlled:
            procs.append(_Process('controller', params, out))
        if getattr(args, 'viewer', False):  # its own process: a viewer problem stops nothing
            procs.append(_Process('viewer', ['--ros-args', '-p', f'port:={args.viewer_port}'],
                                  out))
            url = f'ws://127.0.0.1:{args.viewer_port}'
            print(f'demo: live 3D view: open {url} in Foxglove (app: Open connection → '
                  f'Foxglove WebSocket; web: https://app.foxglove.dev/?ds=foxglove-websocket'
                  f'&ds.url={url}); layout: config/foxglove_layout.json')
        tty = sys.stdout.isatty()
        start, last_print = time.monotonic(), 0.0
        while watcher.t0 is None or watcher.t < args.duration:
            executor.spin_once(timeout_sec=0.05)
            if procs[1].proc.poll() is not None:
                break  # the simulator reached its duration (or failed: see its log)
            now = time.monotonic()
            if watcher.t0 is None and now - start > STARTUP_TIMEOUT:
                print(f'demo: no sample from the simulator after {STARTUP_TIMEOUT:g} s; see '
                      f'{procs[1].log_path}', flush=True)
                break
            line = watcher.status()
            if line and now - last_print >= (0.25 if tty else 2.0):
                last_print = now
                print(('\r' if tty else '') + line, end='' if tty else '\n', flush=True)
    except KeyboardInterrupt:
        interrupted = True
    finally:
        # A second Ctrl-C while closing must not leave nodes running or the bag unfinished:
        # the shutdown runs with SIGINT and SIGTERM ignored.
        previous_int = signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        if sys.stdout.isatty():
            print()
        if interrupted:
            print('demo: interrupted; stopping the nodes (the recorder finishes its bag)',
                  flush=True)
        codes = {p.name: p.stop() for p in procs[1:]}
        end = time.monotonic() + (0.2 if interrupted else 1.0)  # the last messages
        while executor is not None and time.monotonic() < end:
            executor.spin_once(timeout_sec=0.05)
        if procs:
            codes['recorder'] = procs[0].stop()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
        signal.signal(signal.SIGINT, previous_int)
        signal.signal(signal.SIGTERM, previous_term)

    if codes.get('viewer') not in (0, None, -signal.SIGINT):  # reported, not a demo failure
        print(f'  viewer: exited with {codes.pop("viewer")} (log: {out}/viewer.log)')
    failed = {n: c for n, c in codes.items() if c not in (0, None, -signal.SIGINT)}
    print('demo: summary' + (' (interrupted)' if interrupted else ''))
    if watcher is not None:
        print(f'  ended at t = {watcher.t:.2f} s (sim time) in the {watcher.ended_in()} phase'
              + _phase_hint(watcher, scene))
        print(f'  final pointing error: {watcher.error_deg():.4f}° '
              f'(target {np.round(target, 6).tolist()})')
        print(f'  free phase: {len(watcher.free["T"])} samples, '
              f'relative drift T {_drift(watcher.free["T"]):.2e}, '
              f'|L| {_drift(watcher.free["L"]):.2e}')
    try:
        info = read_info(bag)
        print(f'  messages recorded: {info.message_count} on {len(info.topics)} topics, '
              f'{info.duration_s:.2f} s — bag: {bag}')
        plots = _plots_from_bag(bag, scene, out)
        for path in plots:
            print(f'  plot: {path}')
    except BagError as exc:
        print(f'  bag: not readable ({exc}); recorder log: {procs[0].log_path}')
        return 1
    if failed:
        print(f'  node exit codes: {failed} (logs in {out})')
        return 1
    return 130 if interrupted else 0
