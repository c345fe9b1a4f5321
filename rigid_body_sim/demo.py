"""``make demo`` / ``rigid-body-sim demo``: the live graph on a scene, with a status line.

Starts the recorder, then the simulator and controller, as separate processes (the
installed node executables, as ``ros2 run`` would), loaded with the scene's params file.
An in-process rclpy node watches the state and prints sim time, real-time factor,
attitude error, |ω|, T and |L|. After ``--duration`` simulated seconds from the simulator's
t = 0 (or Ctrl-C, or the simulator reaching its ``duration``) the nodes are stopped cleanly
and a summary is printed: the phase it ended in, final pointing error, T and |L| drift during
the free phase, messages recorded, and where the bag and plots are.
"""
import os
import shutil
import signal
import sys
import threading
import time

import numpy as np

from .demo_nodes import (CONTROLLER_ID, STARTUP_TIMEOUT, Process, check_lost,
                         controllers_file, judge_simulator, shown_spacecraft,
                         stop_nodes, wait_for_nodes)
from .demo_summary import summarize
from .demo_watch import Watcher
from .scene import SceneError, load, spacecraft_scene


def _ends_run(scene, args) -> bool:
    """Whether the demo gives the simulator ``duration = --duration``: the run then ends at
    that sim time itself (its last sample recorded) instead of when the demo stops it, unless
    ``--set duration=...`` chose, or the scene ends sooner."""
    if any(s.split('=', 1)[0].strip() == 'duration' for s in args.set or []):
        return False
    scene_duration = scene.simulator['duration']
    return not 0.0 < scene_duration <= args.duration


# Set by Ctrl-C and SIGTERM. The handler also raises KeyboardInterrupt where the main thread
# is, but Python runs a handler wherever bytecode runs, a finalizer (__del__, a weakref
# callback) among them, and there the KeyboardInterrupt is printed and dropped: a fresh
# clone's CI once saw the demo run on for 42 s after two Ctrl-C, until the simulator's own
# end. The loop reads the flag each turn, so no interrupt is lost.
_SIGNALLED = threading.Event()


def _interrupt(signum, frame):
    """Ctrl-C and SIGTERM end the demo: nodes stopped, bag finished, summary printed. Only
    the first raises: a second (impatient users, `timeout -s INT`) arriving before the
    shutdown ignores signals would otherwise break into it with a traceback."""
    if _SIGNALLED.is_set():
        return
    _SIGNALLED.set()
    raise KeyboardInterrupt


def raise_if_interrupted():
    """KeyboardInterrupt if Ctrl-C or SIGTERM came, whether or not its own was dropped."""
    if _SIGNALLED.is_set():
        raise KeyboardInterrupt


def _typed_like(value, like, key):
    """``value`` (typed as rcl types a params-file value) in the rcl type of ``like`` (the
    value the scene file gives ``key``): a second file's value of another type is dropped
    by rcl without a word, so 2 over 1.0 becomes 2.0 and 2.0 over [1.0] becomes [2.0].
    SceneError when no such conversion keeps the value."""
    from . import params_file
    want = params_file.rcl_type(like)
    numbers = (int, float)
    if want == 'double' and isinstance(value, list) and len(value) == 1:
        value = value[0]
    if want == 'double_array' and isinstance(value, numbers) and not isinstance(value, bool):
        value = [value]
    if want == 'double' and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if want == 'double_array' and isinstance(value, list) and all(
            isinstance(v, numbers) and not isinstance(v, bool) for v in value):
        value = [float(v) for v in value]
    if params_file.rcl_type(value) != want:
        raise SceneError(f'--set {key}: the scene gives {key} as {want.replace("_", " ")} '
                         f'({like!r}); rcl would keep that over a {params_file.rcl_type(value)}')
    return value


def _spec_typed(value, spec):
    """A value for a key the scene file does not set: numbers as the spec's doubles."""
    if spec.kind in ('float', 'float_array'):
        if isinstance(value, list):
            return [float(v) for v in value]
        return float(value)
    return value


def overrides(scene, sets):
    """{section: {key: value}}: only the ``--set`` keys, for each node of the scene that
    declares them, in the section of the scene file that gives the node its value (so rcl
    merges it into that very entry) and typed like that value (see :func:`_typed_like`)."""
    from . import params_file
    from .engine import specs
    nodes = [('/attitude_simulator', '/**/attitude_simulator', specs.SIMULATOR)]
    if scene.controlled:
        nodes.append(('/attitude_controller', '/**/attitude_controller', specs.CONTROLLER))
    out = {}
    for text in sets:
        key, value = params_file.parse_override(text)
        for fqn, section, node_specs in nodes:
            spec = next((s for s in node_specs if s.name == key), None)
            if spec is None:
                continue
            if value is False and spec.false_is is not None:  # YAML's off for mode: off
                value = spec.false_is
            raw = params_file.node_parameters(scene.path, fqn).get(key)
            if raw is None:
                out.setdefault(section, {})[key] = _spec_typed(value, spec)
            else:
                out.setdefault(raw.section, {})[key] = _typed_like(value, raw.value, key)
    return out


def _overrides_file(scene, sets, out) -> str:
    """The ``--set`` values as a params file read after the scene's own."""
    import yaml
    path = os.path.join(out, 'overrides.yaml')
    data = {section: {'ros__parameters': values}
            for section, values in overrides(scene, sets).items()}
    with open(path, 'w') as f:
        yaml.safe_dump(data, f)
    return path


def add_arguments(parser):
    parser.add_argument('--scene', default='default',
                        help='scene name or params file (default: default)')
    from .cli import number
    parser.add_argument('--duration', type=number(0.0, 1e9, low_open=True),
                        default=os.environ.get('DEMO_DURATION', '40'),
                        help='simulated seconds to run, counted from the simulator\'s t = 0 '
                             '(start-up is not included; default: $DEMO_DURATION or 40)')
    parser.add_argument('--out', default=os.path.join('out', 'demo'),
                        help='output directory (default out/demo)')
    from .offline import add_set_argument
    add_set_argument(parser)
    parser.add_argument('--no-viewer', dest='viewer', action='store_false',
                        help='do not start the Foxglove viewer node')
    parser.add_argument('--viewer-port', type=int,
                        default=os.environ.get('DEMO_VIEWER_PORT', '8765'),
                        help='port of the Foxglove viewer (default: $DEMO_VIEWER_PORT or 8765)')
    parser.add_argument('--no-plots', dest='plots', action='store_false',
                        help='skip the PNG plots (the summary is the same)')
    parser.add_argument('--lockstep', action='store_true',
                        help='the simulator holds each control instant until the '
                             'controller\'s command for it (docs/live-nodes.md, Lockstep)')


def run(args) -> int:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    try:
        scene = load(args.scene, args.set)
    except SceneError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    if not args.duration > 0:
        print('error: --duration must be > 0 simulated seconds', file=sys.stderr)
        return 2
    lockstep = getattr(args, 'lockstep', False)
    if lockstep:  # both nodes' parameters, as --set gives them
        from .launch_plan import lockstep_parameters
        try:
            if not scene.controlled:
                raise ValueError(f'scene {scene.name} runs no controller')
            extra, _ = lockstep_parameters(scene)
        except ValueError as exc:
            print(f'error: --lockstep: {exc}', file=sys.stderr)
            return 2
        args.set = list(args.set or []) + [f'{k}={str(v).lower()}' for k, v in extra.items()]
        scene = load(args.scene, args.set)
    if _ends_run(scene, args):  # the simulator ends at --duration: bag and summary agree
        args.set = list(args.set or []) + [f'duration={args.duration!r}']
        scene = load(args.scene, args.set)
    # a demo stays on this machine
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    out = os.path.abspath(args.out)
    bag = os.path.join(out, 'bag')
    shutil.rmtree(bag, ignore_errors=True)  # each demo replaces the previous one's bag
    os.makedirs(out, exist_ok=True)
    # one controller, or a formation's: one per spacecraft, in its namespace (launch_plan)
    from .launch_plan import controllers
    ctls = controllers(scene, scene.path, lockstep=lockstep) if scene.controlled else []
    shown = shown_spacecraft(scene, ctls)
    view = spacecraft_scene(scene, shown, next(
        (c.parameters for c in ctls if c.namespace == shown), None)) if shown else scene
    params = ['--ros-args', '--params-file', os.path.abspath(scene.path)]
    if args.set:  # a second params file: each value lands in the scene's entry (see overrides)
        try:
            params += ['--params-file', _overrides_file(scene, args.set, out)]
        except SceneError as exc:
            print(f'error: {exc}', file=sys.stderr)
            return 2
    if any(c.namespace for c in ctls):  # each spacecraft's controller's own values, last
        params += ['--params-file', controllers_file(ctls, out)]
    target = np.asarray(scene.controller.get('target_attitude', (0.0, 0.0, 0.0, 1.0)), float)
    print(f'demo: scene {scene.name} — {scene.description}')
    print(f'demo: logs and output in {out}; stopping after {args.duration:g} simulated s '
          'from t = 0 (Ctrl-C stops earlier)')

    # Ctrl-C and SIGTERM raise KeyboardInterrupt here (rclpy's own handler would shut the
    # context down under the loop instead); the nodes run in their own sessions and are
    # stopped below, whatever ends the demo.
    from rclpy.signals import SignalHandlerOptions
    _SIGNALLED.clear()
    previous_term = signal.signal(signal.SIGTERM, _interrupt)
    previous_int = signal.signal(signal.SIGINT, _interrupt)
    procs, node, executor, watcher, interrupted = [], None, None, None, False
    try:
        procs.append(Process('recorder', ['--ros-args', '-p', f'output:={bag}',
                                          '-p', f'scene:={scene.name}']
                             # a formation's topics are each spacecraft's: record them all
                             + (['-p', 'all:=true'] if scene.spacecraft else []), out))
        rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
        node = Node('demo_status')
        p = scene.simulator
        watcher = Watcher(node, target, None if p['publish_clock'] else
                          (p['real_time_factor'] or 1.0), shown + '/' if shown else '',
                          f'/{shown}{CONTROLLER_ID}' if shown else CONTROLLER_ID)
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        # The recorder and the controller run before the simulator, which holds its t = 0
        # until they are matched on its topics: the bag and the controller's mission clock
        # start with the first sample.
        for c in ctls:
            procs.append(Process('controller', params + (
                ['-r', f'__ns:=/{c.namespace}'] if c.namespace else []), out, c.namespace))
        wait_for_nodes(node, executor, ['/mcap_recorder'] + [
            (f'/{c.namespace}' if c.namespace else '') + CONTROLLER_ID for c in ctls], procs)
        procs.append(Process('simulator', params + ['-p', 'wait_for_subscribers:=1'] + (
            ['-p', 'wait_for_controller:=true'] if scene.controlled else []), out))
        sim = procs[-1]
        if getattr(args, 'viewer', False):  # its own process: a viewer problem stops nothing
            procs.append(Process('viewer', ['--ros-args', '-p', f'port:={args.viewer_port}'],
                                 out))
            url = f'ws://127.0.0.1:{args.viewer_port}'
            print(f'demo: live 3D view: open {url} in Foxglove (app: Open connection → '
                  f'Foxglove WebSocket; web: https://app.foxglove.dev/?ds=foxglove-websocket'
                  f'&ds.url={url}); layout: config/foxglove_layout.json')
        tty = sys.stdout.isatty()
        start, last_print = time.monotonic(), 0.0
        while watcher.t0 is None or watcher.t < args.duration:
            raise_if_interrupted()
            executor.spin_once(timeout_sec=0.05)
            if sim.exited():
                break  # its duration reached, or lost: judged once its last samples are in
            # a lost recorder or controller makes the rest of the run worthless; a lost
            # viewer is reported and the run goes on
            if any(p.name != 'viewer' for p in check_lost(procs, sim)):
                break
            now = time.monotonic()
            if watcher.t0 is None and now - start > STARTUP_TIMEOUT:
                print(f'demo: no sample from the simulator after {STARTUP_TIMEOUT:g} s; see '
                      f'{sim.log_path}', flush=True)
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
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        interrupted = interrupted or _SIGNALLED.is_set()
        if sys.stdout.isatty():
            print()
        if interrupted:
            print('demo: interrupted; stopping the nodes (the recorder finishes its bag)',
                  flush=True)
        sim = next((p for p in procs if p.name == 'simulator'), None)
        check_lost(procs, sim)  # those that exited since the loop's last look
        sim_ended = sim is not None and sim.exited()  # on its own, not stopped below
        codes = stop_nodes(procs, lambda seconds: _spin_for(executor, seconds), sim_ended,
                           interrupted)
        if sim_ended:
            judge_simulator(sim, watcher.t, scene.simulator['duration'],
                            1.0 / scene.simulator['publish_rate'])
        if procs:
            codes['recorder'] = procs[0].stop()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
        signal.signal(signal.SIGINT, previous_int)
        signal.signal(signal.SIGTERM, previous_term)

    # a lost node fails the demo whatever its code (SIGINT from elsewhere ends one with 0);
    # one the demo stopped fails when it did not stop cleanly
    failed = {p.name: p.lost for p in procs if p.lost is not None}
    failed.update({n: c for n, c in codes.items()
                   if n not in failed and c not in (0, None, -signal.SIGINT)})
    code = summarize(view, bag, out, watcher, target, failed,
                     {p.name: p.log_path for p in procs}, interrupted,
                     f'/{shown}' if shown else '', list(scene.spacecraft), args.plots,
                     [f'/{c.namespace}/torque_command' if c.namespace else '/torque_command'
                      for c in ctls] if lockstep else None)
    return exit_code(code, interrupted, watcher.t0 is not None)


def _spin_for(executor, seconds):
    """Turn the demo's node for ``seconds`` (wall): the status and the last messages."""
    end = time.monotonic() + seconds
    while executor is not None and time.monotonic() < end:
        executor.spin_once(timeout_sec=0.05)


def exit_code(summary_code: int, interrupted: bool, started: bool) -> int:
    """The demo's exit status: the summary's failure code if any; 130 after Ctrl-C; 1 when
    no sample ever arrived (the run never started: 'no sample from the simulator'), even
    if every node exited cleanly; else 0."""
    if summary_code:
        return summary_code
    if interrupted:
        return 130
    return 0 if started else 1
