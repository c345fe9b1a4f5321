"""``rigid-body-sim run SCENE``: a scene offline, as fast as the machine allows.

Same physics as the live simulator node (Propagator, auto selection, per-axis torque
saturation) and, for controlled scenes, the controller node's law in-process with the
torque zero-order held over each control period. Writes a bag in the recorder's format
(same topics and types as the live simulator), PNG plots, and optionally one JSON object.
"""
import json
import math
import os
import sys
import time
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from .physics import Propagator
from .physics.selection import select
from .scene import SceneError, SceneFile, load


@dataclass
class RunResult:
    scene: str
    integrator: str
    reason: str
    duration: float
    step: float
    steps: int
    cpu_seconds: float
    samples: dict
    body: object = None
    bag: Optional[str] = None
    plots: list = field(default_factory=list)

    def state(self, k):
        s = self.samples
        return {'attitude': s['attitude'][k].tolist(), 'angular_velocity': s['angular_velocity'][k].tolist(),
                'angular_momentum': s['angular_momentum'][k].tolist(),
                'kinetic_energy': float(s['kinetic_energy'][k])}

    def summary(self) -> dict:
        return {'scene': self.scene, 'integrator': self.integrator, 'reason': self.reason,
                'duration': self.duration, 'step': self.step, 'steps': self.steps,
                'cpu_seconds': round(self.cpu_seconds, 6), 'initial': self.state(0), 'final': self.state(-1),
                'bag': self.bag, 'plots': self.plots}


class _Progress:
    """A one-line progress bar on a terminal (silent otherwise)."""

    def __init__(self, total, enabled):
        self.total, self.enabled, self.last = total, enabled and sys.stderr.isatty(), 0.0

    def update(self, t, force=False):
        now = time.monotonic()
        if not self.enabled or (now - self.last < 0.2 and not force):
            return
        self.last = now
        frac = min(1.0, t / self.total) if self.total else 1.0
        bar = '#' * int(30 * frac)
        sys.stderr.write(f'\r[{bar:<30s}] {100 * frac:5.1f}%  t = {t:.6g} s ')
        if force:
            sys.stderr.write('\n')
        sys.stderr.flush()


def simulate(scene: SceneFile, duration=None, integrator=None, step=None, accuracy=None,
             progress=False, integrator_options=None) -> RunResult:
    """Run ``scene``; CLI overrides replace the scene's values when given.

    ``integrator_options`` go to a fixed integrator (e.g. dop853 rtol/atol for a reference).
    """
    from .nodes.simulator import build_scene
    p = dict(scene.simulator)
    for key, value in (('duration', duration), ('integrator', integrator), ('step', step), ('accuracy', accuracy)):
        if value is not None:
            p[key] = value
    model = build_scene(p)
    horizon = float(p['duration'])
    if not horizon > 0:
        raise SceneError(f'{scene.path}: an offline run needs duration > 0 (scene has {horizon:g}); use --duration')
    sample_period = 1.0 / p['publish_rate']
    controller = mission = None
    control_period = math.inf
    if scene.controlled:
        from .control import mission_from_parameters
        controller, mission, control_period = mission_from_parameters(scene.controller)
    max_step = min(p['step'], sample_period, control_period)
    name = p['integrator']
    if name == 'auto':
        choice = select(model.body, model.dissipation, model.attitude, model.angular_velocity,
                        torque=scene.controlled, accuracy=p['accuracy'], duration=horizon, max_step=max_step)
        name, h, reason = choice.name, min(choice.step, max_step), choice.reason
        if name == 'exact':  # no stepping error: one evaluation per sample
            h, reason = sample_period, reason + '; evaluated once per sample'
    else:
        h, reason = max_step, f'set by the scene or --integrator ({name})'
    # Like the live node under auto: until the first torque the motion is free, so the exact
    # flow runs (no stepping error); the selected method takes over at the first torque.
    free_first = p['integrator'] == 'auto' and controller is not None and not model.dissipation.active
    prop = Propagator(model.body, model.attitude, model.angular_velocity, model.dissipation,
                      integrator='exact' if free_first else name, **(integrator_options or {}))
    if free_first:
        reason += '; exact flow until the first torque'
    limit = p['max_torque']

    n_samples = int(math.floor(horizon / sample_period + 1e-9)) + 1
    keys = ('t', 'attitude', 'angular_velocity', 'angular_momentum', 'angular_momentum_body', 'kinetic_energy',
            'torque')
    out = {k: [] for k in keys}
    torque = np.zeros(3)
    bar = _Progress(horizon, progress)
    steps = 0
    next_control = 0.0
    cpu0 = time.process_time()
    for k in range(n_samples):
        t_sample = min(k * sample_period, horizon)
        # advance to the sample, stopping at control instants to update the held torque
        while True:
            if controller is not None and next_control <= prop.t + 1e-12:
                free, _ = mission.update(controller, prop.t, prop.angular_velocity)
                torque = np.zeros(3) if free else \
                    np.clip(controller.torque(prop.attitude, prop.angular_velocity), -limit, limit)
                if free_first and np.any(torque != 0.0):
                    prop.set_integrator(name)
                    free_first = False
                next_control += control_period
            target = min(t_sample, next_control) if controller is not None else t_sample
            if target - prop.t <= 1e-12:
                if t_sample - prop.t <= 1e-12:
                    break
                continue
            span = target - prop.t
            n = 1 if free_first else max(1, int(math.ceil(span / h - 1e-9)))
            prop.advance(span, span / n, torque if controller is not None and not free_first else None)
            prop.t = target  # land exactly on the event (no accumulated rounding in t)
            steps += n
        out['t'].append(prop.t)
        out['attitude'].append(prop.attitude)
        out['angular_velocity'].append(prop.angular_velocity)
        out['angular_momentum'].append(prop.angular_momentum_inertial)
        out['angular_momentum_body'].append(prop.angular_momentum_body)
        out['kinetic_energy'].append(float(prop.kinetic_energy))
        out['torque'].append(torque.copy())
        bar.update(prop.t)
    cpu = time.process_time() - cpu0
    bar.update(horizon, force=True)
    samples = {k: np.asarray(v) for k, v in out.items()}
    return RunResult(scene.name, name, reason, horizon, float(h), steps, cpu, samples, model.body)


def write_bag(result: RunResult, scene: SceneFile, directory: str) -> str:
    """The run as a bag in the recorder's format: same topics, types and frames as live."""
    from rclpy.serialization import serialize_message
    from geometry_msgs.msg import Vector3Stamped
    from .bag.writer import BagWriter
    from .nodes.state_messages import StateMessages, type_name
    p = scene.simulator
    msgs = StateMessages(p['frame_id'], p['child_frame_id'])
    topics = [(f'/{name}', msg) for name, msg in msgs.topics()]
    torque_msg = Vector3Stamped()
    torque_msg.header.frame_id = p['child_frame_id']
    if scene.controlled:
        topics.append(('/torque_command', torque_msg))
    writer = BagWriter(directory, name=os.path.basename(os.path.normpath(directory)))
    try:
        for topic, msg in topics:
            writer.add_topic(topic, type_name(msg))
        writer.add_run_configuration({
            'scene': scene.name, 'scene_file': os.path.abspath(scene.path), 'mode': 'offline',
            'integrator': result.integrator, 'integrator_reason': result.reason, 'step': result.step,
            'simulator_parameters': scene.simulator, 'controller_parameters': scene.controller})
        s = result.samples
        for k in range(len(s['t'])):
            ns = int(round(s['t'][k] * 1e9))
            msgs.fill(ns, s['attitude'][k], s['angular_velocity'][k], s['angular_momentum'][k],
                      s['angular_momentum_body'][k], s['kinetic_energy'][k])
            torque_msg.header.stamp = msgs.stamp
            v = torque_msg.vector
            v.x, v.y, v.z = (float(x) for x in s['torque'][k])
            for topic, msg in topics:
                writer.write(topic, serialize_message(msg), ns, ns)
    finally:
        writer.close()
    return os.path.abspath(directory)


def add_arguments(parser):
    parser.add_argument('scene', help='built-in scene name (see `rigid-body-sim scenes`) or a params file')
    parser.add_argument('--duration', type=float, help='simulated seconds (default: the scene\'s)')
    parser.add_argument('--integrator', help='integrator name or auto (default: the scene\'s)')
    parser.add_argument('--step', type=float, help='largest physics step, s')
    parser.add_argument('--accuracy', type=float, help='attitude-error budget for auto, rad')
    parser.add_argument('--out', help='output directory (default: out/<scene>)')
    parser.add_argument('--json', action='store_true', help='print one JSON object with the results')
    parser.add_argument('--no-bag', action='store_true', help='skip writing the bag')
    parser.add_argument('--no-plots', action='store_true', help='skip the PNG plots')


def run(args) -> int:
    from .physics import IntegrationError
    from .bag.errors import BagError
    try:
        scene = load(args.scene)
        if args.integrator is not None and args.integrator != 'auto':
            from .physics import get_integrator
            get_integrator(args.integrator)
        result = simulate(scene, args.duration, args.integrator, args.step, args.accuracy, progress=not args.json)
        out = args.out or os.path.join('out', scene.name)
        if not args.no_bag:
            bag_dir = os.path.join(out, 'bag')
            if os.path.isdir(bag_dir):
                import shutil
                shutil.rmtree(bag_dir)  # a rerun replaces its own previous output
            result.bag = write_bag(result, scene, bag_dir)
        if not args.no_plots:
            from .plots import free_until, write_plots
            free_end = free_until(result.samples['t'], result.samples['torque'])
            result.plots = [os.path.abspath(pth) for pth in
                            write_plots(result.samples, result.body, out, scene.name, free_end)]
    except (SceneError, ValueError, IntegrationError, BagError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    summary = result.summary()
    if args.json:
        print(json.dumps(summary))
    else:
        f = summary['final']
        print(f'{scene.name}: {result.integrator} (step {result.step:.3g} s), {result.steps} steps, '
              f'{result.cpu_seconds:.3g} CPU s for {result.duration:g} simulated s')
        print(f'  why: {result.reason}')
        print(f'  final: T = {f["kinetic_energy"]:.9g} J, |L| = {np.linalg.norm(f["angular_momentum"]):.9g} '
              f'kg·m²/s, ω = {np.round(f["angular_velocity"], 6).tolist()} rad/s')
        if result.bag:
            print(f'  bag: {result.bag}')
        for pth in result.plots:
            print(f'  plot: {pth}')
    return 0
