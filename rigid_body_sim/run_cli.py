"""``rigid-body-sim run SCENE``: a scene offline (:func:`.offline.simulate`) from the
command line: the kernels loaded before the clock, the bag (:mod:`.bag_sink`), the plots,
a summary or one JSON object."""
import json
import os
import sys
import time

import numpy as np

from .bag_sink import BagSink
from .offline import effective_parameters, engine_for, simulate, warm_for
from .scene import SceneError, load


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


OUTPUTS = ('omega.png', 'invariants.png', 'poinsot.png', 'flips.png', 'precession.png',
           'nutation.png', 'control.png', 'actuators.png', 'pointing.png')


REHEARSALS = 10  # rehearse: why more than one


def rehearse(scene, engine, keep) -> None:
    """The run's first few periods (``engine.warm.warm_span``) through the run's own code,
    ``offline.simulate`` with ``keep`` but no sink, on a fresh engine of the same
    configuration, last before the clock: the kernels and the caches warm, and the Python
    that handles the blocks (their first and last rows converted, the plot series) run
    once in this process. Without it a 0.3 ms run took 0.40-0.45 ms in the clock, 1.2-1.3x
    the same run in-process; the kernels alone (``warm_for``) left 1.1-1.2x.

    REHEARSALS times: the per-run Python (building the blocks, the end rows, the run's
    set-up) runs once a run, and CPython 3.11 quickens a function's bytecode only at its
    8th call (then specialises it). Explorer 1, 50 s, the run's CPU after 1, 2, 3 and 4
    rehearsals (fresh processes, 4 each, quiet): 347-421, 265-275, 256-320, 247-318 µs;
    in a warm process 230-250. Generated scenes 18 and 11 (5 fresh processes each,
    load 2.5): after 3, 6, 8 and 10 rehearsals 214-325 / 230-244, 188-296 / 207-702,
    180-326 / 200-309, 176-280 / 197-201 µs; the same run in a warm process 165-190 /
    ~215. Ten cost nothing that shows in kernel_load_cpu_seconds (~0.1 s, the kernels'
    loading)."""
    from . import offline
    from .engine import Engine
    from .engine.warm import warm_span
    for _ in range(REHEARSALS):
        copy = Engine(engine.config, block_size=offline.block_size(engine.config),
                      interpolate_samples=engine.interpolate_samples)
        offline.simulate(scene, engine=copy, keep=keep,
                         until_ns=min(copy.end_ns, copy.t_ns + warm_span(engine.config)))


# glibc's mallopt parameters (malloc.h), and its largest mmap threshold on 64 bits
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD, MMAP_THRESHOLD_MAX = -1, -3, 32 << 20
# bytes a sample the run allocates: its block's row (t, q, m, torque: 88), the exact
# grid's times (8), the plot series' copy of it (88) and slack
ROW_BYTES = 256


def warm_heap(engine) -> int:
    """Give the run's sample arrays pages already touched, as a warm process has them: in
    a fresh one each of their 4 KiB pages faulted on first touch inside the clock (~1-2 µs
    each; generated scene 11 at 100 samples/s, 30,001 samples: 505 faults, 2.0 ms against
    0.9-1.1 in-process, where glibc hands a run back the pages the previous run freed).
    glibc is told to serve blocks up to MMAP_THRESHOLD_MAX from its heap and to keep
    what is freed there, for the rest of this short process (as its dynamic thresholds do
    once a process has freed such a block); a buffer as large as the run's arrays is then
    written and freed, before the rehearsal (writing it evicts the caches). Its CPU is
    the warm-up's (kernel_load_cpu_seconds), the run's work stays in cpu_seconds. Bytes
    warmed: 0 where the C library is not glibc (the run then pays the faults)."""
    from .offline import SINK_BATCH, block_size
    try:
        import ctypes
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):  # pragma: no cover - not glibc
        return 0
    # the rows the run holds at once: its sinks take them SINK_BATCH at a time
    rows = min(block_size(engine.config, None), SINK_BATCH)
    # below the threshold (a block of it or more is still mapped apart, and unmapped when
    # freed), and above what SINK_BATCH rows take (~12 MB)
    size = min(rows * ROW_BYTES, MMAP_THRESHOLD_MAX // 2)
    if not (mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD_MAX) and
            mallopt(M_TRIM_THRESHOLD, 2 * MMAP_THRESHOLD_MAX)):
        return 0  # pragma: no cover - refused
    buffer = np.empty(size // 8)
    buffer.fill(0.0)  # every page written (np.zeros would leave them to the kernel)
    del buffer
    return size


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
        keep = 'none' if args.no_plots else 'plot'
        try:
            loaded = kernel_signatures()
            # the same few periods again, now that the bag's set-up has run: it evicts the
            # caches the run's code and kernels were warm in (a 0.25 ms run then cost
            # 0.1-0.2 ms more in the clock); loads nothing the first warm_for did not
            cache0 = time.process_time()
            warm_heap(engine)
            rehearse(scene, engine, keep)
            kernel_load += time.process_time() - cache0
            result = simulate(scene, progress=not args.json, sinks=[bag] if bag else [],
                              keep=keep, engine=engine)
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
