"""``rigid-body-sim run SCENE``: a scene offline, as fast as the machine allows.

The same engine as the live simulator node (``rigid_body_sim.engine``): same events, same
steps, same samples. For controlled scenes the controller node's law runs in-process as a
torque source, held over each control period. The samples stream into a bag in the
recorder's format (same topics, types and stamps as live) and into the plots, so memory
does not grow with the length of the run.
"""
import json
import math
import os
import sys
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Optional

import numpy as np

# the engine core and the integrators are imported where a run is built (engine_for), not
# here, where a refused argument or scene file does not need them (the scene's checks still
# import numba through the parameter specs: 0.61 → 0.55 CPU-s for a bad file)
from .engine.samples import SampleBlock
from .scene import SceneError, SceneFile, content_sha256, load
from .sensors.specs import SensorSettings

if TYPE_CHECKING:
    from .engine import Engine

PLOT_POINTS = 20_000  # samples kept for the plots (a long run is decimated evenly)


@dataclass
class RunResult:
    """An offline run: what ran, what it cost, and the samples (``samples`` is a
    SampleBlock with every sample, or the decimated plot series for a streamed run)."""
    scene: str
    integrator: str
    reason: str
    duration: float
    step: float
    steps: int
    cpu_seconds: float
    selection_cpu_seconds: float
    samples: SampleBlock
    initial: dict
    final: dict
    sample_count: int
    body: object = None
    bag: Optional[str] = None
    plots: list = field(default_factory=list)
    # auto's choice (physics.auto.Selection: predicted error and run cost, the pilot's
    # predicted cost, a deterministic measure of what choosing cost), None for a fixed method
    selection: object = None
    # loading the compiled kernels before the run, and warming the caches just before it
    kernel_load_cpu_seconds: float = 0.0
    # numba kernel signatures loaded or compiled inside the clock (the CLI loads every one
    # before it: warm_for); None where nobody counted
    kernels_loaded_during_run: Optional[int] = None
    output_cpu_seconds: float = 0.0  # the sinks (bag encoding and writing), not in cpu_seconds
    actuators: object = None  # the scene's ActuatorConfig (wheels / CMGs), or None
    # right-hand-side evaluations or sub-flows (closed-form evaluations for exact), the pilot's
    # not included: comparable across methods where ``steps`` (outputs for dop853) is not
    evaluations: int = 0

    @property
    def pilot_steps(self) -> int:
        """Steps auto's pilot ran (0 for a fixed method)."""
        return self.selection.pilot_steps if self.selection else 0

    def summary(self) -> dict:
        keep = ('attitude', 'angular_velocity', 'angular_momentum', 'kinetic_energy')
        return {'scene': self.scene, 'integrator': self.integrator, 'reason': self.reason,
                'duration': self.duration, 'step': self.step, 'steps': self.steps,
                'samples': self.sample_count, 'cpu_seconds': round(self.cpu_seconds, 6),
                'selection_cpu_seconds': round(self.selection_cpu_seconds, 6),
                'evaluations': self.evaluations, 'pilot_steps': self.pilot_steps,
                # inf: auto said it cannot know (a libration): null in JSON
                'predicted_error': self.selection.predicted_error if self.selection and
                math.isfinite(self.selection.predicted_error) else None,
                'selection_planned_cpu_seconds': (self.selection.planned_cost if self.selection
                                                  else None),
                'kernel_load_cpu_seconds': round(self.kernel_load_cpu_seconds, 6),
                'kernels_loaded_during_run': self.kernels_loaded_during_run,
                'output_cpu_seconds': round(self.output_cpu_seconds, 6),
                'initial': {k: self.initial[k] for k in keep},
                'final': {k: self.final[k] for k in keep}, 'bag': self.bag, 'plots': self.plots}


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


class Decimated:
    """At most ~``limit`` samples of a stream, evenly spaced: when full, every other one is
    dropped and the stride doubles. Memory stays bounded however long the run."""

    def __init__(self, limit=PLOT_POINTS):
        self.limit, self.stride, self.seen = limit, 1, 0
        self.blocks = []
        self.count = 0

    def add(self, block: SampleBlock):
        idx = np.flatnonzero((self.seen + np.arange(len(block))) % self.stride == 0)
        self.seen += len(block)
        if idx.size:
            self.blocks.append(block.take(idx))
            self.count += idx.size
        if self.count > self.limit:
            whole = SampleBlock.concatenate(self.blocks)
            keep = np.arange(0, len(whole), 2)
            self.blocks = [whole.take(keep)]
            self.count, self.stride = len(keep), self.stride * 2

    def block(self) -> SampleBlock:
        return SampleBlock.concatenate(self.blocks)


def effective_parameters(scene: SceneFile, duration=None, integrator=None, step=None,
                         accuracy=None) -> dict:
    """The simulator's parameters of a run: the scene's (``--set`` included) with the CLI
    overrides that were given."""
    p = dict(scene.simulator)
    for key, value in (('duration', duration), ('integrator', integrator), ('step', step),
                       ('accuracy', accuracy)):
        if value is not None:
            p[key] = value
    return p


# samples per block offline: each block costs ~60 µs of Python (the compiled loop's set-up,
# the block's copies), 1.8 ms of a 6 ms run of 30,000 samples at 1,024; 1.4 MB at 16,384
OFFLINE_BLOCK = 16384


def engine_for(scene: SceneFile, duration=None, integrator=None, step=None, accuracy=None,
               integrator_options=None, check_stability=False) -> 'Engine':
    """The engine for ``scene`` with CLI overrides; SceneError naming the problem.
    ``check_stability``: refuse or warn about a fixed method's step before the run: its
    stability, and its error predicted against the accuracy (``Engine.check_method``; the
    CLI does; the benchmarks run unstable steps on purpose). It also refuses a fixed
    method's step longer than the sample (or control) period, which the engine would
    otherwise shorten to that period without a word."""
    from .engine import Engine, EngineConfig
    p = effective_parameters(scene, duration, integrator, step, accuracy)
    if scene.spacecraft:
        raise SceneError(f'{scene.path}: declares spacecraft ({", ".join(scene.spacecraft)}); '
                         'an offline run takes one: run it with the simulator node')
    if not p['duration'] > 0:
        raise SceneError(f'{scene.path}: an offline run needs duration > 0 (scene has '
                         f'{p["duration"]:g}); use --duration')
    try:
        config = EngineConfig.from_parameters(p, scene.controller if scene.controlled else None)
    except ValueError as exc:
        raise SceneError(f'{scene.path}: {exc}') from None
    if integrator_options:
        config = config.replace(integrator_options=dict(integrator_options))
    if check_stability:
        _check_step_fits(config, 'step' if step is None else '--step')
    engine = Engine(config, check_method=check_stability, block_size=OFFLINE_BLOCK)
    for verdict, message in engine.method_warnings:
        if verdict == 'refuse':
            raise SceneError(message)
        print(f'warning: {message}', file=sys.stderr)
    return engine


def _check_step_fits(config, where) -> None:
    """SceneError when a fixed method's step exceeds the event spacing: the engine stops at
    every sample (and control instant), so a step of 0.5 s at 100 samples/s ran at 0.01 s."""
    from .engine.specs import AUTO
    spacing = config.event_spacing()
    if config.integrator == AUTO or config.actuators is not None or \
            config.step <= spacing * (1 + 1e-9):
        return
    what = 'sample period' if spacing == config.sample_period else 'control period'
    raise SceneError(
        f'{where} {config.step:g} s is longer than the {what} {spacing:g} s: the engine stops '
        f'at every sample and control instant, so {config.integrator} would run at '
        f'{spacing:g} s. Use a step <= {spacing:g} s, or fewer samples (--set publish_rate='
        f'{1.0 / config.step:g} for one sample per step)')


def simulate(scene: SceneFile, duration=None, integrator=None, step=None, accuracy=None,
             progress=False, integrator_options=None, sinks=(), keep='all',
             check_stability=False, engine=None) -> RunResult:
    """Run ``scene`` to its end; CLI overrides replace the scene's values when given.

    Every block of samples goes to each callable in ``sinks`` as it is produced.
    ``keep``: 'all' keeps every sample in the result, 'plot' a decimated series, 'none'
    nothing but the first and last sample (memory then does not grow with the run).
    ``integrator_options`` go to a fixed integrator (e.g. dop853 rtol/atol for a reference).
    ``engine``: one already built by :func:`engine_for` (its build, auto's selection
    included, then counts before the clock: the CLI checks the method before it replaces
    a previous run); the overrides are then ignored.
    """
    cpu0 = time.process_time()
    chosen = engine.selection_cpu if engine is not None else 0.0  # before this clock
    if engine is None:
        engine = engine_for(scene, duration, integrator, step, accuracy, integrator_options,
                            check_stability)
    kept = [] if keep == 'all' else Decimated() if keep == 'plot' else None
    bar = _Progress(engine.config.duration, progress)
    first = last = final = None
    count = 0
    output = 0.0  # the sinks' CPU (a bag: encoding and writing), reported on its own
    for block in engine.run():
        if first is None:
            first = block.row(0)
        final = block  # its last row converted once, after the run: ~70 µs a block
        count += len(block)
        if sinks:
            out0 = time.process_time()
            for sink in sinks:
                sink(block)
            output += time.process_time() - out0
        if kept is not None:
            (kept.append if keep == 'all' else kept.add)(block)
        bar.update(engine.t)
    if final is not None:
        last = final.row(len(final) - 1)
    cpu = time.process_time() - cpu0 - output
    bar.update(engine.config.duration, force=True)
    samples = SampleBlock.concatenate(kept) if keep == 'all' else \
        kept.block() if kept is not None else SampleBlock.concatenate([])
    return RunResult(scene.name, engine.method, engine.reason, engine.config.duration,
                     engine.step_max, engine.steps + engine.evaluations,
                     cpu - (engine.selection_cpu - chosen), engine.selection_cpu, samples,
                     first, last,
                     count, engine.body,
                     selection=engine.selected,
                     actuators=engine.config.actuators, evaluations=engine.total_evaluations,
                     output_cpu_seconds=output)


def warm_for(engine: 'Engine') -> set:
    """The run's warm-up (``engine.warm.warm_for``), imported with the engine."""
    from .engine.warm import warm_for as warm
    return warm(engine)


def _integration_error() -> tuple:
    """(IntegrationError,) once the integrators are imported, else (): none can have been
    raised before, and importing them to check would load numba for a bad scene file."""
    base = sys.modules.get('rigid_body_sim.physics.integrators.base')
    return (base.IntegrationError,) if base is not None else ()


def kernel_signatures() -> int:
    """Compiled signatures held by the package's numba kernels now (0 without numba's JIT):
    their growth over a stretch is what that stretch compiled or loaded from the cache."""
    try:
        from numba.core.registry import CPUDispatcher
    except ImportError:  # pragma: no cover - numba is a dependency
        return 0
    return sum(len(v.signatures) for name, module in list(sys.modules.items())
               if name.startswith('rigid_body_sim') and module is not None
               for v in list(vars(module).values()) if isinstance(v, CPUDispatcher))


class BagSink:
    """Samples → the recorder's bag format: same topics, types, frames and stamps as live."""

    def __init__(self, scene: SceneFile, directory: str, extra: dict, parameters=None):
        from .bag.writer import BagWriter
        from .engine import EngineConfig
        from .engine.actuators import ActuatorConfig
        from .param_spec import coerce_all
        from .engine.specs import SIMULATOR
        from .nodes.state_messages import StateMessages
        p = scene.simulator
        self.msgs = StateMessages(p['frame_id'], p['child_frame_id'], torque=scene.controlled,
                                  actuators=ActuatorConfig.from_parameters(
                                      coerce_all(SIMULATOR, p)))
        self.writer = BagWriter(directory, name=os.path.basename(os.path.normpath(directory)))
        self.path = os.path.abspath(directory)
        for topic, type_name in self.msgs.topic_types():
            self.writer.add_topic(f'/{topic}', type_name)
        self.sensors = None  # the scene's gyro / star tracker topics, if it has sensors
        settings = SensorSettings.from_parameters(p)
        if settings is not None:
            from .nodes.sensor_messages import SensorMessages
            self.sensors = SensorMessages(settings, p['frame_id'], p['child_frame_id'])
            for topic, type_name in self.sensors.topic_types():
                self.writer.add_topic(f'/{topic}', type_name)
        self.orbit = None  # the orbit's topics, for a scene with an orbit (as live)
        config = EngineConfig.from_parameters(p)
        if config.environment is not None:
            from .nodes.orbit_messages import OrbitMessages
            self.orbit = OrbitMessages(config, p['frame_id'], p['child_frame_id'],
                                       p['orbit.frame_id'])
            for topic, name in self.orbit.topic_types():
                self.writer.add_topic(f'/{topic}', name)
        self.magnetometer = None  # magnetic_field, for a scene with a magnetometer
        magnetic = None if config.environment is None else config.environment.magnetic
        if magnetic is not None and magnetic.magnetometer is not None:
            from .nodes import magnetic_messages
            self.magnetometer = magnetic_messages.MagnetometerMessages(
                magnetic.magnetometer, p['child_frame_id'])
            self.writer.add_topic(f'/{magnetic_messages.TOPIC}', magnetic_messages.TYPE)
        self.msgs.prepare()  # the encoder's templates now, not in the first sample's time
        self.record = run_record(scene, parameters or scene.simulator, extra)
        self.writer.add_run_configuration(self.record)

    def finish(self, result: 'RunResult'):
        """Complete the run record with what ran (readers use the last record)."""
        self.record.update(ran(result))
        self.writer.add_run_configuration(self.record)

    def __call__(self, block: SampleBlock):
        write = self.writer.write
        sensed = self.sensors is not None and block.sensors is not None
        magnetic = self.magnetometer is not None and block.magnetometer is not None
        if sensed or magnetic:  # readings at their own instants, merged in time order
            records = [(int(block.t_ns[i]), topic, data) for i in range(len(block))
                       for topic, data in self.msgs.serialized(block, i, int(block.t_ns[i]))]
            if sensed:
                records += self.sensors.serialized(block.sensors)
            if magnetic:
                records += self.magnetometer.serialized(block.magnetometer)
            if self.orbit is not None:
                records += [(int(block.t_ns[i]), topic, data) for i in range(len(block))
                            for topic, data in self.orbit.serialized(block, i,
                                                                     int(block.t_ns[i]))]
            for ns, topic, data in sorted(records, key=lambda r: r[0]):  # stable: time order
                write(f'/{topic}', data, ns, ns)
            return
        for i in range(len(block)):
            ns = int(block.t_ns[i])
            for topic, data in self.msgs.serialized(block, i, ns):
                write(f'/{topic}', data, ns, ns)
            if self.orbit is not None:
                for topic, data in self.orbit.serialized(block, i, ns):
                    write(f'/{topic}', data, ns, ns)

    def close(self):
        self.writer.close()


OUTPUTS = ('omega.png', 'invariants.png', 'poinsot.png', 'flips.png', 'precession.png',
           'nutation.png', 'control.png', 'actuators.png', 'pointing.png')


def _replace_previous(out: str) -> None:
    """A run writes into ``out`` what the previous one there wrote (bag/ and the figures):
    say so and remove them, so that no figure of the previous run stays beside this one's
    (a poinsot.png this run does not draw). Other files in ``out`` are left alone."""
    import shutil
    bag = os.path.join(out, 'bag')
    figures = [f for f in OUTPUTS if os.path.isfile(os.path.join(out, f))]
    if not (os.path.isdir(bag) or figures):
        return
    print(f'note: replacing the previous run in {out} (its bag and figures); --out DIR '
          'keeps runs apart', file=sys.stderr)
    if os.path.isdir(bag):
        shutil.rmtree(bag)
    for f in figures:
        os.remove(os.path.join(out, f))


def run_record(scene: SceneFile, parameters: dict, extra: dict) -> dict:
    """The run configuration stored in the bag: the scene (name, file, content hash) and
    the effective parameters, enough to run it again (:func:`scene_from_record`)."""
    try:
        digest = content_sha256([scene.path])
    except OSError:
        digest = None  # an inline scene (tests, campaigns): no file
    return {'scene': scene.name, 'scene_file': os.path.abspath(scene.path),
            'scene_sha256': digest, 'mode': 'offline',
            'simulator_parameters': parameters, 'controller_parameters': scene.controller,
            **extra}


def ran(result: 'RunResult') -> dict:
    """What actually ran: the method, its step and auto's reason (or the scene's)."""
    return {'integrator': result.integrator, 'step': result.step, 'reason': result.reason,
            'steps': result.steps, 'duration': result.duration, 'samples': result.sample_count}


def scene_from_record(config: dict) -> SceneFile:
    """The scene a bag's run record describes, to run it again (its parameters as they
    ran, CLI overrides included); SceneError if the record lacks them."""
    from .engine import specs
    from .param_spec import coerce_all
    sim = config.get('simulator_parameters')
    if not isinstance(sim, dict):
        raise SceneError('the run record has no simulator_parameters (not an offline run\'s '
                         'bag?)')
    ctl = config.get('controller_parameters') or {}
    try:
        sim = coerce_all(specs.SIMULATOR, sim)
        ctl = coerce_all(specs.CONTROLLER, ctl) if ctl else {}
    except ValueError as exc:
        raise SceneError(f'run record: {exc}') from None
    return SceneFile(str(config.get('scene') or 'recorded'), '',
                     config.get('scene_file') or 'recorded', sim, ctl)


def add_arguments(parser):
    from .cli import number
    from .engine import specs
    from .physics.choices import BODY_ONLY
    spec = {s.name: s for s in specs.SIMULATOR}
    parser.add_argument('scene', help='built-in scene name (listed below) or a params file')
    parser.add_argument('--duration', type=number(0.0, 1e12, low_open=True),
                        help='simulated seconds, s (default: the scene\'s)')
    parser.add_argument('--integrator', choices=('auto',) + BODY_ONLY,
                        help='integrator (default: the scene\'s): %(choices)s')
    parser.add_argument('--step', type=number(spec['step'].low, spec['step'].high),
                        help='largest physics step, s')
    parser.add_argument('--accuracy', type=number(spec['accuracy'].low, spec['accuracy'].high),
                        help='attitude-error budget for auto, rad')
    parser.add_argument('--out', help='output directory (default: out/<scene>)')
    parser.add_argument('--json', action='store_true',
                        help='print one JSON object with the results')
    parser.add_argument('--no-bag', action='store_true', help='skip writing the bag')
    parser.add_argument('--no-plots', action='store_true', help='skip the PNG plots')
    add_set_argument(parser)
    parser.add_argument('--namespace', default='/', metavar='NS',
                        help='the nodes\' namespace, for params files whose sections name it '
                             '(/NS/attitude_simulator), as -r __ns:=NS runs them')


def add_set_argument(parser):
    """--set, and an epilog listing the choices a newcomer needs (with their units)."""
    parser.epilog = choices_epilog()
    parser.add_argument('--set', action='append', default=[], metavar='KEY=VALUE',
                        help='override a scene parameter after the file (repeatable), typed '
                             'as in a params file: --set accuracy=1e-9 --set '
                             'initial_angular_velocity=[0.1,2.0,0.0]')


def choices_epilog() -> str:
    from .physics.choices import BODY_ONLY, DISSIPATION_MODELS, INTEGRATOR_NAMES as INTEGRATORS
    carried = ', '.join(n for n in INTEGRATORS if n not in BODY_ONLY)
    from .scene import list_scenes
    try:
        scenes = ', '.join(name for name, _, _ in list_scenes())
    except (OSError, SceneError):
        scenes = '(config/ not found)'
    return (f'scenes: {scenes}. integrators (--set integrator=NAME): auto, '
            f'{", ".join(BODY_ONLY)} (with wheels or CMGs: {carried}). dissipation models '
            f'(--set dissipation.model=NAME, '
            f'dissipation.coefficient in s/(kg·m²) for double_bracket, N·m·s for viscous): '
            f'{", ".join(DISSIPATION_MODELS)}. Units are SI: s, rad, rad/s, kg·m², N·m, J; '
            'quaternions (x, y, z, w).')


def run(args) -> int:
    from .bag.errors import BagError
    bag = None
    try:
        scene = load(args.scene, args.set, args.namespace)
        out = args.out or os.path.join('out', scene.name)
        # The kernels the run can use come from numba's disk cache before the clock
        # starts: loaded lazily they landed in the first method's run or in auto's pilot
        # (0.22 s of a 0.23 s "selection" on explorer1, whose pilot proper takes 1 ms).
        from .engine.warm import load_kernels, start_numba, warm_selection
        p = effective_parameters(scene, args.duration, args.integrator)
        load0 = time.process_time()
        start_numba()
        warm_selection(p['integrator'], p['dissipation.model'])
        kernel_load = time.process_time() - load0
        # the checks (step, stability, predicted error) before anything is replaced: a
        # refused run leaves the previous one in place
        engine = engine_for(scene, args.duration, args.integrator, args.step, args.accuracy,
                            check_stability=True)
        load0 = time.process_time()
        load_kernels(engine.config, warm_for(engine))
        kernel_load += time.process_time() - load0
        _replace_previous(out)
        if not args.no_bag:
            bag = BagSink(scene, os.path.join(out, 'bag'), {
                'integrator_requested': args.integrator or scene.simulator['integrator'],
                'command_line': {k: v for k, v in (
                    ('duration', args.duration), ('integrator', args.integrator),
                    ('step', args.step), ('accuracy', args.accuracy), ('set', args.set))
                    if v}}, effective_parameters(scene, args.duration, args.integrator,
                                                 args.step, args.accuracy))
        try:
            loaded = kernel_signatures()
            # the same few periods again, now that the bag's set-up has run: it evicts the
            # caches the run's code and kernels were warm in (a 0.25 ms run then cost
            # 0.1-0.2 ms more in the clock); loads nothing the first warm_for did not
            cache0 = time.process_time()
            warm_for(engine)
            kernel_load += time.process_time() - cache0
            result = simulate(scene, progress=not args.json, sinks=[bag] if bag else [],
                              keep='none' if args.no_plots else 'plot', engine=engine)
            result.kernels_loaded_during_run = kernel_signatures() - loaded
            if bag is not None:
                bag.finish(result)
        finally:
            if bag is not None:
                bag.close()
        result.bag = bag.path if bag else None
        result.kernel_load_cpu_seconds = kernel_load
        if not args.no_plots:
            from .plots import free_until, write_plots
            s = result.samples
            result.plots = [os.path.abspath(pth) for pth in write_plots(
                s, result.body, out, scene.name, free_until(s.t, s.torque), scene)]
            if result.actuators is not None:
                from .plots import write_actuator_plot
                result.plots.append(os.path.abspath(write_actuator_plot(
                    s, result.actuators, out, scene.name)))
            if scene.controlled and scene.controller['feedback'] == 'sensors':
                from .sensors.plots import write_pointing_plot
                result.plots.append(os.path.abspath(write_pointing_plot(s, scene, out)))
    except (SceneError, ValueError, BagError, *_integration_error()) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    for note in result.actuators.notes if result.actuators is not None else ():
        print(f'note: {note}', file=sys.stderr)
    summary = result.summary()
    if args.json:
        print(json.dumps(summary))
        return 0
    f = summary['final']
    print(f'{scene.name}: {result.integrator} (step {result.step:.3g} s), {result.steps} steps, '
          f'{result.cpu_seconds:.3g} CPU s for {result.duration:g} simulated s '
          f'(+ {result.selection_cpu_seconds:.3g} CPU s choosing the method, '
          f'{result.kernel_load_cpu_seconds:.2g} s loading the compiled kernels'
          + (f', {result.output_cpu_seconds:.3g} s writing the bag' if result.bag else '')
          + ')')
    print(f'  why: {result.reason}')
    print(f'  final: T = {f["kinetic_energy"]:.9g} J, |L| = '
          f'{np.linalg.norm(f["angular_momentum"]):.9g} kg·m²/s, '
          f'ω = {np.round(f["angular_velocity"], 6).tolist()} rad/s')
    if result.bag:
        print(f'  bag: {result.bag}')
    for pth in result.plots:
        print(f'  plot: {pth}')
    return 0
