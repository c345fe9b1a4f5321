"""A scene offline, as fast as the machine allows: :func:`simulate` and its result.

The same engine as the live simulator node (``rigid_body_sim.engine``): same events, same
steps, same samples. For controlled scenes the controller node's law runs in-process as a
torque source, held over each control period. The samples stream into sinks (the bag in
the recorder's format: :mod:`.bag_sink`) and into the plots, so memory does not grow with
the length of the run. The ``rigid-body-sim run`` command is :mod:`.run_cli`; its names
and the sink's are still importable from here.
"""
import math
import sys
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Optional

# the engine core and the integrators are imported where a run is built (engine_for), not
# here, where a refused argument or scene file does not need them (the scene's checks still
# import numba through the parameter specs: 0.61 → 0.55 CPU-s for a bad file)
from .engine.samples import SampleBlock
from .lazy_exports import lazy_exports
from .scene import SceneError, SceneFile

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
    # loading the compiled kernels before the run, and warming the caches and the run's
    # memory just before it
    kernel_load_cpu_seconds: float = 0.0
    # numba kernel signatures loaded or compiled inside the clock (the CLI loads every one
    # before it: warm_for); None where nobody counted
    kernels_loaded_during_run: Optional[int] = None
    output_cpu_seconds: float = 0.0  # the sinks (bag encoding and writing), not in cpu_seconds
    # minor page faults inside the clock (the sinks' not counted): pages the run touched
    # first (~1-2 µs each here); None where the platform does not count them
    page_faults: Optional[int] = None
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
                'page_faults_during_run': self.page_faults,
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
        # Every stride-th sample of the stream is kept: a slice of each block, copied (so
        # that the block is not held). When this block would take the count past the limit
        # the stride doubles (once an add): the samples kept so far are halved and this
        # block is sliced at the new stride, never copied whole first. Taken by index
        # arrays and halved after, 30,001 samples at 100 samples/s cost ~1.9 ms beside the
        # run's own 0.8.
        def kept(stride):
            return range(-self.seen % stride, len(block), stride)
        if self.count + len(kept(self.stride)) > self.limit:
            self.stride *= 2
            self.blocks = [SampleBlock.concatenate(self.blocks).take(slice(0, None, 2),
                                                                     copy=True)]
            self.count = len(self.blocks[0])
        rows = kept(self.stride)
        self.seen += len(block)
        if len(rows):
            self.blocks.append(block.take(slice(rows.start, None, rows.step), copy=True))
            self.count += len(rows)

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


# samples per block offline at most: each block costs ~60 µs of Python (the compiled loop's
# set-up), 1.8 ms of a 6 ms run of 30,000 samples at 1,024; 1.4 MB at 16,384. A shorter run
# gets a block of its own length (block_size), which it takes without a copy (BlockBuilder)
OFFLINE_BLOCK = 16384
# The sinks (a bag) take the blocks after the run, or this many rows at a time in a longer
# one (memory stays bounded): a bag written between two blocks left the run's code and data
# cold in the caches, and the rest of the run paid for it in its clock (generated scene 19,
# 300 s at 100 samples/s: 0.52 ms in-process, 0.83 ms in the CLI beside a 48 ms bag).
SINK_BATCH = 1 << 17  # ~11 MB of blocks (OFFLINE_BLOCK: ~85 bytes a row)


def block_size(config, limit=OFFLINE_BLOCK) -> int:
    """Samples per block for an offline run of ``config``: all of them (t = 0, every sample
    instant, the end when off the grid) up to ``limit`` (None: all)."""
    d, p = config.duration_ns, config.sample_period_ns
    n = max(1, d // p + 1 + (d % p != 0))
    return n if limit is None else min(limit, n)


def engine_for(scene: SceneFile, duration=None, integrator=None, step=None, accuracy=None,
               integrator_options=None, check_stability=False,
               interpolate_samples=True) -> 'Engine':
    """The engine for ``scene`` with CLI overrides; SceneError naming the problem.
    ``check_stability``: refuse or warn about a fixed method's step before the run: its
    stability, and its error predicted against the accuracy (``Engine.check_method``; the
    CLI does; the benchmarks run unstable steps on purpose). It also refuses a fixed
    method's step longer than the sample (or control) period, which the engine would
    otherwise shorten to that period without a word. ``interpolate_samples``: samples
    between a fixed method's steps (``Engine``; False: the state lands on every sample, as
    in the live node)."""
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
    # samples interpolated between the steps: the sample rate changes neither the steps
    # nor auto's choice (engine.sample_kernel)
    engine = Engine(config, check_method=check_stability, block_size=block_size(config),
                    interpolate_samples=interpolate_samples)
    if check_stability:
        _check_step_fits(engine, 'step' if step is None else '--step')
    for verdict, message in engine.method_warnings:
        if verdict == 'refuse':
            raise SceneError(message)
        print(f'warning: {message}', file=sys.stderr)
    return engine


def _check_step_fits(engine, where) -> None:
    """SceneError when a fixed method's step exceeds the spacing of the events it must land
    on: the control period, and the sample period where samples cannot be interpolated
    between steps (``sample_kernel.interpolation_allowed``: the interpolant's error against
    the accuracy) — the engine would otherwise run a step of 0.5 s at 100 samples/s at
    0.01 s without a word."""
    from .engine.sample_kernel import interpolation_allowed
    from .engine.specs import AUTO
    config = engine.config
    if config.integrator == AUTO or config.actuators is not None:
        return
    spacing, what = config.step, None
    if config.control is not None and config.control.period_ns / 1e9 < spacing:
        spacing, what = config.control.period_ns / 1e9, 'control period'
    if config.sample_period < spacing and not (
            engine.integrator is not None and engine.integrator.loop_code is not None
            and interpolation_allowed(engine, engine.principal_state[1])):
        spacing, what = config.sample_period, 'sample period'
    if what is None or config.step <= spacing * (1 + 1e-9):
        return
    raise SceneError(
        f'{where} {config.step:g} s is longer than the {what} {spacing:g} s: the engine stops '
        f'at every sample and control instant, so {config.integrator} would run at '
        f'{spacing:g} s. Use a step <= {spacing:g} s, or fewer samples (--set publish_rate='
        f'{1.0 / config.step:g} for one sample per step)')


def simulate(scene: SceneFile, duration=None, integrator=None, step=None, accuracy=None,
             progress=False, integrator_options=None, sinks=(), keep='all',
             check_stability=False, engine=None, until_ns=None) -> RunResult:
    """Run ``scene`` to its end; CLI overrides replace the scene's values when given.

    Every block of samples goes to each callable in ``sinks`` as it is produced.
    ``keep``: 'all' keeps every sample in the result, 'plot' a decimated series, 'none'
    nothing but the first and last sample (memory then does not grow with the run).
    ``integrator_options`` go to a fixed integrator (e.g. dop853 rtol/atol for a reference).
    ``engine``: one already built by :func:`engine_for` (its build, auto's selection
    included, then counts before the clock: the CLI checks the method before it replaces
    a previous run); the overrides are then ignored. ``until_ns``: stop at that sim time
    (the CLI's rehearsal of a run's first periods) instead of the end.
    """
    faults0 = _faults()
    cpu0 = time.process_time()
    chosen = engine.selection_cpu if engine is not None else 0.0  # before this clock
    if engine is None:
        engine = engine_for(scene, duration, integrator, step, accuracy, integrator_options,
                            check_stability)
    kept = [] if keep == 'all' else Decimated() if keep == 'plot' else None
    if keep == 'all' and until_ns is None:  # every sample kept: one block, no copies
        engine.reserve(block_size(engine.config, limit=None))
    bar = _Progress(engine.config.duration, progress)
    first = last = final = None
    count = 0
    output = 0.0  # the sinks' CPU (a bag: encoding and writing), reported on its own
    out_faults = [0]  # the sinks' page faults, likewise
    pending, rows = [], 0  # blocks for the sinks, handed over SINK_BATCH rows at a time
    try:
        for block in engine.run(until_ns):
            if first is None:
                first = block
            final = block  # its last row converted once, after the run: ~70 µs a block
            count += len(block)
            if sinks:
                pending.append(block)
                rows += len(block)
                if rows >= SINK_BATCH:
                    output += _to_sinks(sinks, pending, out_faults)
                    pending, rows = [], 0
            if kept is not None:
                (kept.append if keep == 'all' else kept.add)(block)
            bar.update(engine.t)
        if final is not None:
            first, last = _end_rows(first, final)
        cpu = time.process_time() - cpu0 - output
        faults = None if faults0 is None else _faults() - faults0 - out_faults[0]
    finally:  # an interrupted run's sinks still get every sample it made
        if pending:
            output += _to_sinks(sinks, pending, out_faults)
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
                     output_cpu_seconds=output, page_faults=faults)


def _to_sinks(sinks, blocks, faults) -> float:
    """Every block to each sink, in order; the CPU it took (s); its page faults are
    added to ``faults[0]``."""
    f0 = _faults()
    out0 = time.process_time()
    for block in blocks:
        for sink in sinks:
            sink(block)
    spent = time.process_time() - out0
    if f0 is not None:
        faults[0] += _faults() - f0
    return spent


def _faults() -> Optional[int]:
    """This process's minor page faults so far; None where getrusage is not had."""
    try:
        import resource
    except ImportError:  # pragma: no cover - not POSIX
        return None
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt


def _end_rows(first: SampleBlock, final: SampleBlock):
    """(first row of ``first``, last row of ``final``) as dicts (SampleBlock.row). From one
    block (a run that keeps every sample), both converted in one pass over a 2-row block:
    each conversion costs ~60 µs of numpy calls, a tenth of a short run."""
    if first is not final:
        return first.row(0), final.row(len(final) - 1)
    ends = final.take([0, len(final) - 1])
    return ends.row(0), ends.row(1)


def warm_for(engine: 'Engine') -> set:
    """The run's warm-up (``engine.warm.warm_for``), imported with the engine."""
    from .engine.warm import warm_for as warm
    return warm(engine)


# the command and the bag sink, split from this module: their names stay importable here
__getattr__, __dir__ = lazy_exports(__name__.rpartition('.')[0], globals(), {
    **dict.fromkeys(('BagSink', 'run_record', 'ran', 'scene_from_record'), 'bag_sink'),
    **dict.fromkeys(('run', 'add_arguments', 'add_set_argument', 'choices_epilog', 'OUTPUTS',
                     'kernel_signatures'), 'run_cli')})
