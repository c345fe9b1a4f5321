"""The suite's sections, in the order ``rigid-body-sim bench`` runs them.

Each section measures, writes its file(s) into the run's directory and keeps its result on
the run; its ``targets`` turn that result into rows of ``targets.csv``. The targets table
lists them in ``TARGET_ORDER`` (the table's historical order, not the run order).
"""
import json
import math
import os
import time
from dataclasses import dataclass, field
from typing import Callable

from . import batch as batch_mod
from . import compile as compile_cost
from . import (basilisk_gg, basilisk_mtb_sweep, exact_horizon, generated, generated_peers,
               live, longhorizon, perstep, sampling, selection, stability, targets, term_off,
               workprecision)
from .common import reference, write_csv

BUDGETS = {True: {'ours': 0.2, 'peer': 0.2}, False: {'ours': 4.0, 'peer': 3.0}}


@dataclass
class Run:
    """What the sections share: the options, the output directory and each one's result."""
    quick: bool
    out: str
    scenes: tuple
    peer_methods: dict
    generated_count: int | None
    log: Callable[[str], None]
    results: dict = field(default_factory=dict)
    refs: dict = field(default_factory=dict)

    def csv(self, name, fields, rows):
        write_csv(os.path.join(self.out, name), fields, rows)


@dataclass(frozen=True)
class Section:
    name: str
    title: str
    run: Callable[[Run], object]
    targets: Callable[[Run], list] = lambda run: []


def _work_precision(run):
    rows = []
    budget = BUDGETS[run.quick]
    for scene in run.scenes:
        c = time.process_time()
        ref = reference(scene)
        run.refs[scene.name] = ref
        run.log(f'{scene.name}: {scene.description}; reference {ref[2]}'
                + (f' (dop853 rtol 1e-13 differs from it by {ref[3]:.2g} rad)'
                   if ref[2] == 'exact' else f' (own error estimate {ref[3]:.2g} rad)')
                + f' [{time.process_time() - c:.1f} s]')
        scale = 1.0 if run.quick else scene.budget_scale
        rows += workprecision.sweep_ours(scene, ref, budget['ours'] * scale, run.quick, run.log)
        rows += workprecision.sweep_peers(scene, run.peer_methods, ref,
                                          budget['peer'] * scale, run.quick, run.log)
    run.csv('work_precision.csv', workprecision.FIELDS, rows)
    workprecision.print_best(rows, run.scenes, run.log)
    return rows


def _basilisk(run):
    rows, t_rows, _ = basilisk_gg.run(run.quick, run.log)
    if rows:
        run.csv('basilisk.csv', basilisk_gg.FIELDS, rows)
    mtb_rows, mtb_targets, _ = basilisk_mtb_sweep.run(run.quick, run.log)
    if mtb_rows:
        run.csv('basilisk_mtb.csv', basilisk_gg.FIELDS, mtb_rows)
    return t_rows + mtb_targets


def _stability(run):
    rows = stability.run(run.quick, run.log)
    run.csv('stability.csv', stability.FIELDS, rows)
    for scene, method, text in stability.summary(rows):
        run.log(f'  {scene:18s} {method:18s} {text}')
    return rows


def _stability_targets(run):
    split = [r for r in run.results['stability']
             if r['method'].startswith('splitting') and r['status'] == 'ok']
    if not split:
        return []
    worst = max(split, key=lambda r: r['max_momentum_drift'])
    return [targets.simple(
        'splitting* |L| drift at any step (stability sweep)',
        worst['max_momentum_drift'], 1e-12, worst['max_momentum_drift'] <= 1e-12,
        f'worst: {worst["method"]} on {worst["scene"]} at x = {worst["x"]:g}')]


def _long_horizon(run):
    rows, _periods = longhorizon.run(run.quick, run.log)
    run.csv('long_horizon.csv', longhorizon.FIELDS, rows)
    return rows


def _batch(run):
    rows = batch_mod.run(run.quick, run.log)
    run.csv('batch.csv', batch_mod.FIELDS, rows)
    return rows


def _batch_targets(run):
    name = 'batch body-steps/s at N = 1e6 (one core)'
    big = [r for r in run.results['batch'] if r['bodies'] == 1_000_000]
    if not big:
        return [targets.simple(name, math.nan, 1e7, None, 'not measured in --quick (N ≤ 1e4)')]
    best = max(big, key=lambda r: r['body_steps_per_s'])
    ok = best['body_steps_per_s'] >= 1e7
    return [targets.simple(name, best['body_steps_per_s'], 1e7, ok,
                           f'{best["method"]}.{best["path"]}()'
                           + ('' if ok else f'; short by {1e7 / best["body_steps_per_s"]:.3g}x'))]


def _perstep(run):
    rows, fig = perstep.run(run.quick, run.log)
    run.csv('perstep.csv', perstep.FIELDS, rows)
    return fig


def _term_off(run):
    rows, t_rows = term_off.run(run.quick, run.log)
    run.csv('term_off.csv', term_off.FIELDS, rows)
    return t_rows


def _sampling(run):
    rows, sm_targets = sampling.run(run.quick, run.log, run.generated_count)
    run.csv('sampling.csv', sampling.FIELDS, rows)
    return sm_targets


def _live(run):
    res = {'simulator': live.simulator(run.quick, run.log),
           'recorder': live.recorder(run.quick, run.log),
           'viewer': live.viewer(run.quick, run.log)}
    for k, v in res.items():
        run.log(f'  live {k}: ' + (v['status'] if v['status'] != 'ok' else
                                   json.dumps({a: b for a, b in v.items() if a != 'output'})))
    with open(os.path.join(run.out, 'live.json'), 'w') as f:
        json.dump(res, f, indent=1)
    return res


def _selection(run):
    rows, sel_targets = selection.run(run.quick, run.log)
    run.csv('selection.csv', selection.FIELDS, rows)
    return sel_targets


def _generated(run):
    rows, gen_targets, _ = generated.run(run.quick, run.log, count=run.generated_count)
    run.csv('generated.csv', generated.FIELDS, rows)
    return gen_targets


def _generated_peers(run):
    rows, t_rows = generated_peers.run(run.quick, run.log, count=run.generated_count)
    run.csv('generated_peers.csv', generated_peers.FIELDS, rows)
    return t_rows


def _compile(run):
    rows = compile_cost.run(run.quick, run.log)
    if rows:
        run.csv('compile.csv', compile_cost.FIELDS, rows)
    return rows


def _compile_targets(run):
    return compile_cost.targets(run.results['compile'])


def _exact_horizon(run):
    rows, eh_targets = exact_horizon.run(run.quick, run.log)
    if rows:
        run.csv('exact_horizon.csv', exact_horizon.FIELDS, rows)
    return eh_targets


def _returned(name):
    """Targets a section returned itself (its run gives the rows)."""
    return lambda run: list(run.results[name])


SECTIONS = (
    Section('work_precision', '1. work-precision', _work_precision,
            lambda run: targets.work_precision(run.results['work_precision'], run.scenes)),
    Section('basilisk', '1b. Basilisk 2.12: gravity gradient, magnetorquers (bsk)', _basilisk,
            _returned('basilisk')),
    Section('stability', '2. stability where methods fail', _stability, _stability_targets),
    Section('long_horizon', '3. long horizon (generic tumble)', _long_horizon),
    Section('batch', '4. batch throughput', _batch, _batch_targets),
    Section('perstep', '4b. cost per step (one body) and per offline sample', _perstep,
            lambda run: perstep.targets_from(run.results['perstep'], run.quick)),
    Section('term_off', '4d. a term that is off costs nothing (free body vs an orbit, no '
            'term)', _term_off, _returned('term_off')),
    Section('sampling', '4c. sampling and CLI overhead (samples kept; the CLI in a fresh '
            'process)', _sampling, _returned('sampling')),
    Section('live', '5. live', _live, lambda run: live.targets_from(run.results['live'])),
    Section('selection', '6. model selection (integrator: auto)', _selection,
            _returned('selection')),
    Section('generated', f'6b. generalisation: auto on generated scenes (seed '
            f'{generated.SEED})', _generated, _returned('generated')),
    Section('generated_peers', '6c. generalisation: scipy against auto on the generated '
            'scenes', _generated_peers, _returned('generated_peers')),
    Section('compile', '7. compile cost (numba kernels)', _compile, _compile_targets),
    Section('exact_horizon', '8. exact at long horizons (40-digit reference)', _exact_horizon,
            _returned('exact_horizon')),
)
SECTION_BY_NAME = {s.name: s for s in SECTIONS}
TARGET_ORDER = ('work_precision', 'basilisk', 'selection', 'generated', 'generated_peers',
                'exact_horizon', 'stability', 'batch', 'perstep', 'term_off', 'sampling', 'live',
                'compile')
