"""Model selection (``integrator: auto``) on the built-in scenes.

For each scene (over a horizon short enough for a DOP853 rtol 1e-12 reference), ``auto``
must meet the scene's attitude budget and be at most 2× slower than the cheapest fixed
choice (method and step, the scene's step halved up to 4 times) that also meets it.
auto's CPU time includes its selection pilot.
"""
import math
import time

import numpy as np

from ..offline import simulate
from ..physics import IntegrationError, rotation
from ..scene import load

FIELDS = ('scene', 'method', 'step', 'cpu_s', 'attitude_error', 'budget', 'meets_budget')
FIXED = ('splitting2', 'splitting4', 'splitting6', 'rk4', 'implicit_midpoint', 'exact')
DURATIONS = {'default': 30.0, 'slew': 15.0, 'detumble': 15.0, 'tennis_racket': 10.0,
             'symmetric_top': 20.0, 'explorer1': 30.0, 'rigid_earth': 86164.0905 * 30}
QUICK = ('slew', 'tennis_racket', 'explorer1')


def _timed_run(scene, duration, **kw):
    t0 = time.process_time()
    result = simulate(scene, duration=duration, **kw)
    return result, time.process_time() - t0


def run(quick, log=print):
    """(rows, target rows) — rows per (scene, method, step); one target row per scene."""
    from . import targets
    rows, t_rows = [], []
    for name in (QUICK if quick else tuple(DURATIONS)):
        scene = load(name)
        duration = DURATIONS[name] / (3 if quick else 1)
        budget = scene.simulator['accuracy']
        ref = simulate(scene, duration=duration, integrator='dop853',
                       integrator_options={'rtol': 1e-12, 'atol': 1e-14}).samples['attitude']

        def error(result):
            return float(np.max(rotation.angle_between(result.samples['attitude'], ref)))

        auto, auto_cpu = _timed_run(scene, duration)
        auto_err = error(auto)
        rows.append(dict(scene=name, method=f'auto→{auto.integrator}', step=auto.step,
                         cpu_s=auto_cpu, attitude_error=auto_err, budget=budget,
                         meets_budget=auto_err <= budget))
        best = None
        for method in FIXED:
            step = scene.simulator['step']
            for _ in range(5 if not quick else 3):
                try:
                    result, cpu = _timed_run(scene, duration, integrator=method, step=step)
                    err = error(result)
                except IntegrationError:
                    err, cpu = math.inf, math.nan
                ok = err <= budget
                rows.append(dict(scene=name, method=method, step=step, cpu_s=cpu,
                                 attitude_error=err, budget=budget, meets_budget=ok))
                if ok:
                    if best is None or cpu < best[1]:
                        best = (f'{method} h={step:.3g}', cpu)
                    break  # smaller steps only cost more
                step /= 2
        if best is None:
            t_rows.append(targets.simple('auto CPU / cheapest fixed choice meeting the budget',
                                         math.nan, 2.0, None,
                                         f'no fixed choice met {budget:g} rad', scene=name))
            continue
        ratio = auto_cpu / best[1]
        ok = auto_err <= budget and ratio <= 2.0
        note = (f'auto → {auto.integrator} h={auto.step:.3g} '
                f'({auto_cpu:.3g} s, error {auto_err:.2g}) vs '
                f'{best[0]} ({best[1]:.3g} s); budget {budget:g} rad' +
                ('' if auto_err <= budget else '; auto MISSED the budget'))
        t_rows.append(targets.simple('auto CPU / cheapest fixed choice meeting the budget',
                                     ratio, 2.0, ok, note, scene=name))
        log(f'  {name:14s} {"PASS" if ok else "MISS"}  {note}; ratio {ratio:.2f}')
    return rows, t_rows
