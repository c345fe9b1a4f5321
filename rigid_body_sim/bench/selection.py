"""Model selection (``integrator: auto``) on the built-in scenes.

For each scene (over a horizon short enough for a DOP853 rtol 1e-12 reference), ``auto``
must meet the scene's attitude budget and be at most 1.5× slower than the cheapest fixed
choice that also meets it, and its selection must cost at most 10 % of the run it picked
(medians of 9 runs; also Explorer 1 over 1–6,900 s). Fixed choices: every method at steps
from the event spacing (the sample or control period, the largest step auto considers)
and from the scene's step, halved until the budget is met. auto's CPU time includes its
selection pilot. The cheapest fixed choice found, auto is timed against it again, the two
runs interleaved (A/B): timed alone and first, just after the reference run, auto read up to
0.2 ms high on a 1–2 ms run against fixed runs timed after dozens of others (default).
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
LIMIT = 1.5  # auto CPU / cheapest fixed choice meeting the budget
SHARE = 0.10  # auto's selection CPU / the CPU of the run it picked
# further horizons of Explorer 1 for the selection's share (no reference needed): from a
# run whose fixed cost dominates (1 s) to the whole orbit (6,900 s, the scene's own duration)
SHARE_HORIZONS = (1.0, 10.0, 100.0, 690.0, 6900.0)


def _steps(scene, halvings):
    """Fixed steps to try, coarse to fine: the event spacing and the scene's step, halved."""
    spacing = 1.0 / scene.simulator['publish_rate']
    if scene.controlled:
        spacing = min(spacing, 1.0 / scene.controller['control_rate'])
    grid = {round(h / 2 ** k, 15) for h in (spacing, min(scene.simulator['step'], spacing))
            for k in range(halvings)}
    return sorted(grid, reverse=True)


def _timed_run(scene, duration, **kw):
    """(result, CPU s): the least of up to 5 runs while they take < 0.3 s in all (a run of a
    few ms is otherwise mostly timing noise)."""
    best, total = math.inf, 0.0
    for _ in range(5):
        t0 = time.process_time()
        result = simulate(scene, duration=duration, **kw)
        cpu = time.process_time() - t0
        best, total = min(best, cpu), total + cpu
        if total > 0.3:
            break
    return result, best


def _interleaved(scene, duration, fixed, pairs=9):
    """(auto's CPU s, the fixed choice's CPU s): the least of each over up to ``pairs`` runs
    taken in turns (auto, fixed, auto, ...), while they take < 0.6 s in all, so that both
    see the same state of the process and of the machine's load."""
    best, total = [math.inf, math.inf], 0.0
    for _ in range(pairs):
        for i, kw in enumerate(({}, fixed)):
            t0 = time.process_time()
            simulate(scene, duration=duration, **kw)
            cpu = time.process_time() - t0
            best[i], total = min(best[i], cpu), total + cpu
        if total > 0.6:
            break
    return best[0], best[1]


def share(scene, duration, runs=9):
    """(selection CPU / run CPU, the last result): medians over ``runs`` runs (each a few
    ms at most, where one run's figure is mostly timing noise)."""
    sel, cpu = [], []
    for _ in range(runs):
        result = simulate(scene, duration=duration)
        sel.append(result.selection_cpu_seconds)
        cpu.append(result.cpu_seconds)
    return float(np.median(sel) / np.median(cpu)), result


# what the share rows measure, said in their notes: the process is warm (kernels loaded,
# calibration read, the per-kind candidate facts of physics/auto/kinds.py kept since its
# first selection), but no choice is kept: each run chooses afresh
SHARE_NOTE = ('median of 9 runs in one warm process (kernels, costs and per-kind candidate '
              'facts loaded), each choosing afresh; all of its choosing counted (the free '
              'body\'s choice at the start and building the selection\'s arguments '
              'included); a fresh process\'s first selection, '
              'which also reads the calibration, is not among them')


def _share_row(targets, name, duration, log):
    ratio, result = share(load(name), duration)
    note = (f'{duration:g} s: auto → {result.integrator} h={result.step:.3g}, '
            f'{result.pilot_steps} pilot steps; {SHARE_NOTE}')
    log(f'  {name:14s} {"PASS" if ratio <= SHARE else "MISS"}  selection share {ratio:.1%} '
        f'({note})')
    return targets.simple('auto selection CPU / CPU of the run it picked', ratio, SHARE,
                          ratio <= SHARE, note, scene=name)


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
        auto_row = dict(scene=name, method=f'auto→{auto.integrator}', step=auto.step,
                        cpu_s=auto_cpu, attitude_error=auto_err, budget=budget,
                        meets_budget=auto_err <= budget)
        rows.append(auto_row)
        best = None
        for method in FIXED:
            for step in _steps(scene, 3 if quick else 5):
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
                        best = (f'{method} h={step:.3g}', cpu, dict(integrator=method,
                                                                    step=step))
                    break  # smaller steps only cost more
        if best is None:
            t_rows.append(targets.simple('auto CPU / cheapest fixed choice meeting the budget',
                                         math.nan, LIMIT, None,
                                         f'no fixed choice met {budget:g} rad', scene=name))
            continue
        auto_cpu, fixed_cpu = _interleaved(scene, duration, best[2])
        best, auto_row['cpu_s'] = (best[0], fixed_cpu), auto_cpu
        ratio = auto_cpu / fixed_cpu
        ok = auto_err <= budget and ratio <= LIMIT
        note = (f'auto → {auto.integrator} h={auto.step:.3g} '
                f'({auto_cpu:.3g} s, error {auto_err:.2g}) vs '
                f'{best[0]} ({best[1]:.3g} s), timed in turns; budget {budget:g} rad' +
                ('' if auto_err <= budget else '; auto MISSED the budget'))
        t_rows.append(targets.simple('auto CPU / cheapest fixed choice meeting the budget',
                                     ratio, LIMIT, ok, note, scene=name))
        log(f'  {name:14s} {"PASS" if ok else "MISS"}  {note}; ratio {ratio:.2f}')
        t_rows.append(_share_row(targets, name, duration, log))
    if not quick:
        for duration in SHARE_HORIZONS:
            t_rows.append(_share_row(targets, 'explorer1', duration, log))
    return rows, t_rows


def update(folder, log=print):
    """Re-run this section (full) into a full run's ``folder``
    (:func:`.common.replace_section`): selection.csv and this section's target rows."""
    from .common import replace_section
    rows, t_rows = run(False, log)
    return replace_section(folder, 'selection.csv', FIELDS, rows, t_rows,
                           ('auto CPU / cheapest', 'auto selection CPU'))


if __name__ == '__main__':
    from .common import section_main
    section_main(__doc__, lambda quick: run(quick)[1], update)
