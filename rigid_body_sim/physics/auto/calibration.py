"""``auto``'s per-step costs measured on the machine it runs on, once per machine and kernels.

:func:`calibrate` times every candidate's compiled loop (torque-free, weak double-bracket
and weak viscous damping) and keeps its cost as a ratio to ``splitting2`` torque-free
(REFERENCE): only ratios steer ``auto``, and a ratio survives a machine that is uniformly
slower or busier where an absolute µs does not. :func:`save` writes them as a small JSON
beside numba's cache of the kernels (``__pycache__`` next to the kernel files, or under
NUMBA_CACHE_DIR), keyed by the kernels' source hash, the CPU model and numba's version:
a change of any of them makes the cache stale (``python -m rigid_body_sim.compiled``
calibrates again). :func:`current` is what ``auto`` reads: the calibrated costs, or the
classes' own constants (``Candidate.cost``) with a short note of why.

Robust to load: each figure is the least CPU time of REPEATS timings (the run least
disturbed by the rest of the machine), and each calibrated cost is clamped to within
CLAMP of its class constant: a calibration taken while another process preempted one
method's timings (or a throttled core) cannot move a method by more than that, so it can
re-rank only methods whose costs are that close anyway (the classes' constants, measured
on a 2-core AMD EPYC, and the loops' own work bound how far a real machine differs).
"""
import functools
import hashlib
import inspect
import json
import math
import os
import platform
import sys
import time
from dataclasses import dataclass, field
from typing import Mapping, Optional, Tuple

import numpy as np

FILE_NAME = 'auto_costs.json'
FORMAT = 3                 # the measurement scheme below: a change of it recalibrates
REFERENCE = 'splitting2'   # costs are stored as ratios to this method's torque-free cost
CLAMP = (0.25, 4.0)        # a calibrated cost stays within this factor of its class constant
REPEATS = 5
STEPS = 20_000             # per timing: 2–40 ms a method, the whole calibration ~1–3 s
ENV = 'RIGID_BODY_SIM_AUTO_COSTS'  # 'constants': the classes' constants (the tests' setting)
# The timed scene: Explorer 1's body and state at h = 0.01 s (hΩ = 0.63) with damping weak
# at the step (inside the compositions, one substep outside them), as candidate_costs times
MOMENTS = (0.04, 0.2, 0.2)
M0 = (2.5132741228718345, 0.04386936299713697, 0.0)
STEP = 0.01
DAMPING = {'double_bracket': 1.0678e-05, 'viscous': 1e-3}
# exact's closed form costs ~5× more on a triaxial body (elliptic functions, Carlson
# integrals) than on Explorer 1's symmetric one (0.4–0.5 against 2.5–2.7 µs a step, Intel
# Xeon): timed on a triaxial body, the general case (a symmetric body then reads high)
EXACT_MOMENTS = (0.04, 0.15, 0.2)
KINDS = ('free', 'double_bracket', 'viscous')
DAMP_SUBSTEP = 0.068       # µs per double-bracket substep outside a composition, uncalibrated
VISCOUS_FACTOR = 1.3       # splitting2's viscous cost / free cost, uncalibrated
ADAPTIVE_EVALS = 12        # evaluations per step of the adaptive method (DOP853)
# µs per evaluation of an environment torque, uncalibrated (the class constants' units):
# the gravity gradient solves Kepler's equation and turns the conic into the inertial frame
# at each evaluation: 0.25–0.27 µs on an Intel Xeon where splitting2's free step took
# 0.097 (2.7× it; rk4, euler and the splittings alike, per kick or stage), where the
# classes' constants had the environment cost nothing and auto took splitting6 (14
# evaluations a step) over rk4 (4)
# The other terms as measured the same way (rk4, 200,000 steps, least of 5, load ~8; not
# yet in the calibration): the rods' m x B 0.08 (dipole closed form), drag on explorer1_orbit's
# six facets 0.22, solar radiation pressure with the Sun's almanac position 0.27
TERM_COSTS = {'gravity gradient': 0.25, 'magnetorquers': 0.08, 'solar radiation pressure': 0.27,
              'drag': 0.22}
TERM_ORBIT = (7.0e6, 0.1, 0.9, 0.3, 0.5, 0.7)  # the timed orbit: a, e, i, node, periapsis, ν
# An event (sample instant) of the engine's compiled closed loop, measured by the engine
# (``engine.event_cost``, passed in: physics does not import the engine), is kept within
# these µs in the classes' units: 0.08–0.2 µs measured at load 8 on an Intel Xeon, where
# auto's constant (model.EVENT_COST + Candidate.call: the event-by-event loop) is 17.5
EVENT_RANGE = (0.01, 20.0)


@dataclass(frozen=True)
class Costs:
    """What ``auto``'s cost model reads: µs per step per method (free, weak dissipation),
    splitting2's viscous/free factor, and where they come from (said in ``reason``)."""
    per_step: Mapping[str, Tuple[float, float]] = field(default_factory=dict)
    viscous_factor: float = VISCOUS_FACTOR
    damp_substep: Optional[float] = None  # µs per double-bracket substep (None: DAMP_SUBSTEP)
    source: str = 'class constants'
    environment: Mapping[str, float] = field(default_factory=dict)  # µs per evaluation
    event: Optional[float] = None  # µs per event of the compiled closed loop (None: unknown)

    def cost(self, candidate) -> Tuple[float, float]:
        """µs per step of ``candidate`` (free, weakly damped): calibrated, else its own."""
        return self.per_step.get(candidate.name, candidate.cost)

    def term_cost(self, term: str) -> float:
        """µs per evaluation of the environment's torque ``term`` ('gravity gradient'; a
        model in parentheses, 'drag (nrlmsis)', costs as its term)."""
        return self.environment.get(term, TERM_COSTS[term.split(' (')[0]])


def _candidates():
    from ..integrators import AUTO_CANDIDATES  # the registry's, as the cost model's
    return AUTO_CANDIDATES


def kernel_files():
    """Source files whose change changes a candidate's compiled loop (or its shell, or
    this calibration)."""
    from .. import jit
    from ..integrators import INTEGRATORS
    from ..orbit import kernel as orbit_kernel
    files = {jit.__file__, __file__, orbit_kernel.__file__}  # this file: how they are timed
    # the engine's compiled loop and how an event is timed in it (``events``): by path, as
    # physics does not import the engine
    engine = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(
        os.path.abspath(__file__)))), 'engine')
    files.update(os.path.join(engine, f) for f in ('closed_loop.py', 'event_cost.py')
                 if os.path.exists(os.path.join(engine, f)))
    for cls in INTEGRATORS.values():
        files.add(inspect.getsourcefile(cls))
        files.update(m.__file__ for m in cls.kernel_modules)
    return sorted(os.path.abspath(f) for f in files)


def cpu_model() -> str:
    try:
        with open('/proc/cpuinfo', encoding='utf-8', errors='replace') as f:
            for line in f:
                if line.lower().startswith(('model name', 'hardware', 'cpu model')):
                    return line.split(':', 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or 'unknown'


@functools.lru_cache(maxsize=None)
def key() -> str:
    """The calibration's key: kernels' sources, CPU model, numba version, FORMAT."""
    try:
        import numba
        numba_version = numba.__version__
    except Exception:  # noqa: BLE001 - no numba: nothing compiled, no calibration to key
        numba_version = 'none'
    digest = hashlib.sha256(f'{FORMAT}|{cpu_model()}|numba {numba_version}'.encode())
    for path in kernel_files():
        with open(path, 'rb') as f:
            digest.update(f.read())
    return digest.hexdigest()


def cache_dir() -> str:
    """numba's cache directory for the reference method's kernels (where it writes its own
    index files), else NUMBA_CACHE_DIR or the ``__pycache__`` beside the kernel files."""
    from ..integrators import get_integrator
    module = get_integrator(REFERENCE).kernel_modules[0]
    try:  # numba's own choice (in-tree if writable, else NUMBA_CACHE_DIR or per user)
        from numba.core import caching
        impl = getattr(caching, 'CacheImpl', None) or getattr(caching, '_CacheImpl')
        source = inspect.getsourcefile(module)
        function = next(v.py_func for v in vars(module).values() if hasattr(v, 'py_func'))
        for locator in impl._locator_classes:  # the first that can write, as numba picks
            found = locator.from_function(function, source)
            if found is not None:
                return found.get_cache_path()
    except Exception:  # noqa: BLE001 - numba missing or changed: its documented defaults
        pass
    base = os.environ.get('NUMBA_CACHE_DIR')
    folder = os.path.dirname(os.path.abspath(module.__file__))
    if base:
        return os.path.join(base, folder.lstrip(os.sep))
    return os.path.join(folder, '__pycache__')


def cache_path() -> str:
    return os.path.join(cache_dir(), FILE_NAME)


def measure(steps=STEPS, repeats=REPEATS, methods=None) -> dict:
    """µs per step of each candidate's compiled loop, per kind of dynamics (KINDS): the
    least CPU time of ``repeats`` timings. An adaptive method integrates the whole span at
    its own steps (counted by its evaluations). ``exact`` runs its split steps (its
    'free' kind under a zero torque: torque-free it is evaluated, not stepped) on a
    triaxial body (EXACT_MOMENTS)."""
    from ..dynamics import Dissipation, Dynamics
    from ..integrators import create
    q0, m0 = np.array([0.0, 0.0, 0.0, 1.0]), np.array(M0)
    names = methods or [c.name for c in _candidates()]
    measured = {name: {} for name in names}
    for kind in KINDS:
        dissipation = Dissipation(kind, DAMPING[kind]) if kind in DAMPING else Dissipation()
        for name in names:
            integ = create(name, Dynamics(np.array(
                EXACT_MOMENTS if name == 'exact' else MOMENTS), dissipation))
            torque = np.zeros(3) if name == 'exact' and kind == 'free' else None
            integ.run(q0, m0, STEP, 10, torque)  # compiled (or loaded) before timing
            best, taken = math.inf, steps
            for _ in range(repeats):
                nfev, t0 = integ.nfev, time.process_time()
                integ.run(q0, m0, STEP, steps, torque)
                best = min(best, time.process_time() - t0)
                if integ.adaptive:  # its own steps, not the output intervals (its constant's)
                    taken = max(1.0, (integ.nfev - nfev) / ADAPTIVE_EVALS)
            measured[name][kind] = 1e6 * best / taken
    return measured


def measure_environment(steps=STEPS, repeats=REPEATS) -> dict:
    """µs per evaluation of each environment torque (TERM_COSTS): rk4's compiled loop with
    the term on less the same loop with none, over its 4 evaluations a step, the least of
    ``repeats`` timings each."""
    from ..dynamics import Dynamics
    from ..integrators import create
    from ..orbit import KeplerOrbit, kernel as orbit_kernel
    elements = KeplerOrbit(*TERM_ORBIT).elements(0.0)
    elements[orbit_kernel.ON] = 1.0
    q0, m0 = np.array([0.0, 0.0, 0.0, 1.0]), np.array(M0)
    timed = {}
    for label, env in (('off', None), ('on', elements)):
        integ = create('rk4', Dynamics(np.array(MOMENTS), environment=env))
        integ.run(q0, m0, STEP, 10)
        best = math.inf
        for _ in range(repeats):
            t0 = time.process_time()
            integ.run(q0, m0, STEP, steps)
            best = min(best, time.process_time() - t0)
        timed[label] = 1e6 * best / steps
    evals = type(integ).environment_evaluations
    return {'gravity gradient': max(timed['on'] - timed['off'], 0.0) / evals}


def calibrate(steps=STEPS, repeats=REPEATS, events=None) -> Optional[dict]:
    """The calibration record (ratios to REFERENCE torque-free, keyed), or None where the
    kernels are not compiled (NUMBA_DISABLE_JIT: Python loops say nothing of their cost).
    ``events``: a function measuring µs per event of the engine's compiled closed loop
    (``engine.event_cost.measure``), kept as a ratio like the steps."""
    from .. import jit
    if not jit.COMPILED:
        return None
    measured = measure(steps, repeats)
    terms = measure_environment(steps, repeats)
    base = measured[REFERENCE]['free']
    record = {'key': key(), 'cpu': cpu_model(), 'reference': REFERENCE, 'steps': steps,
              'repeats': repeats, 'measured_us': measured, 'environment_us': terms,
              'ratios': {n: {k: v / base for k, v in kinds.items()}
                         for n, kinds in measured.items()},
              'environment': {t: v / base for t, v in terms.items()}}
    if events is not None:
        record['event_us'] = events()
        record['event'] = record['event_us'] / base
    return record


def save(record, path=None) -> str:
    """Write ``record`` atomically (readers never see half a file); its path."""
    path = path or cache_path()
    os.makedirs(os.path.dirname(path), exist_ok=True)
    tmp = f'{path}.{os.getpid()}.tmp'
    with open(tmp, 'w', encoding='utf-8') as f:
        json.dump(record, f, indent=1, sort_keys=True)
    os.replace(tmp, path)
    return path


def load(path=None) -> Tuple[Optional[dict], str]:
    """(record, '') if the cache at ``path`` is current, else (None, why not)."""
    path = path or cache_path()
    try:
        with open(path, encoding='utf-8') as f:
            record = json.load(f)
    except FileNotFoundError:
        return None, 'not calibrated'
    except (OSError, ValueError) as exc:
        return None, f'calibration unreadable ({type(exc).__name__})'
    if not isinstance(record, dict) or record.get('key') != key():
        return None, 'calibration stale (kernels or CPU changed)'
    return record, ''


def ensure(path=None, log=print, events=None) -> Optional[dict]:
    """The current calibration, measured and saved if missing or stale (the setup's step;
    ``events``: see :func:`calibrate`)."""
    record, why = load(path)
    if record is not None:
        return record
    record = calibrate(events=events)
    if record is None:
        log('auto costs: kernels not compiled (NUMBA_DISABLE_JIT), not calibrated')
        return None
    try:
        where = save(record, path)
    except OSError as exc:
        log(f'auto costs: cannot write the calibration ({exc}); auto uses the class '
            'constants')
        return record
    log(f'auto costs: {why}, calibrated on {record["cpu"]} → {where}')
    current.cache_clear()
    return record


def costs_from(record) -> Costs:
    """The cost model of a calibration record: each ratio times REFERENCE's torque-free
    class constant (the model's absolute scale: RUN_COST, call, … are in the same µs),
    clamped to within CLAMP of the method's own constant (see the module docstring)."""
    candidates = {c.name: c for c in _candidates()}
    unit = candidates[record['reference']].cost[0]
    ratios = record['ratios']
    per_step = {}
    for name, c in candidates.items():
        r = ratios.get(name)
        if r is None:
            continue  # a method newer than the record
        per_step[name] = tuple(_clamp(r[kind] * unit, own)
                               for kind, own in zip(('free', 'double_bracket'), c.cost))
    ref = ratios[record['reference']]
    viscous = _clamp(ref['viscous'] / ref['free'], VISCOUS_FACTOR)
    # splitting2 damped at the timed step: its free step and one substep (two half-steps)
    substep = _clamp((ref['double_bracket'] - ref['free']) * unit / 2, DAMP_SUBSTEP)
    environment = {t: _clamp(r * unit, TERM_COSTS[t])
                   for t, r in record.get('environment', {}).items() if t in TERM_COSTS}
    event = record.get('event')
    event = None if event is None else min(max(event * unit, EVENT_RANGE[0]), EVENT_RANGE[1])
    return Costs(per_step, viscous, substep,
                 f'costs calibrated on {record.get("cpu", "this CPU")}', environment, event)


def _clamp(value, own):
    return min(max(value, own * CLAMP[0]), own * CLAMP[1])


@functools.lru_cache(maxsize=None)
def current() -> Costs:
    """The costs ``auto`` uses in this process (read once): calibrated, else the classes'
    constants, with why in ``source`` (auto's ``reason`` quotes it)."""
    from .. import jit
    if os.environ.get(ENV, '').strip() == 'constants':
        return Costs(source=f'class-constant costs ({ENV}=constants)')
    if not jit.COMPILED:
        return Costs(source='class-constant costs (kernels not compiled)')
    try:
        record, why = load()
    except OSError as exc:  # no cache directory at all (read-only install)
        record, why = None, f'no calibration ({type(exc).__name__})'
    if record is None:
        return Costs(source=f'class-constant costs ({why}: python -m rigid_body_sim.compiled)')
    try:
        return costs_from(record)
    except (KeyError, TypeError, ValueError) as exc:
        print(f'warning: rigid_body_sim: auto cost calibration {cache_path()} is malformed '
              f'({type(exc).__name__}: {exc}); using the class constants', file=sys.stderr)
        return Costs(source='class-constant costs (calibration malformed)')
