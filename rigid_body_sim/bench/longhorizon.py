"""Long horizon: T and |L| drift against time over many rotation periods (generic tumble).

Fixed-step methods use h = P/20 (P the ω period of the exact solution); dop853 takes one
adaptive call per sample interval at rtol 1e-10; ``exact`` is evaluated at the sample times
directly (it needs no stepping). A method stops early if it blows up, drifts beyond 100 %,
or would exceed its CPU budget; the CSV says how far it got.
"""
import math

import numpy as np

from ..physics import INTEGRATORS, IntegrationError, create
from ..physics.exact import TorqueFreeSolution
from .common import cpu
from .scenes import SCENE_BY_NAME

FIELDS = ('method', 'h', 'period', 't', 'periods', 'energy_drift', 'momentum_drift', 'cpu_s',
          'note')


def run(quick, log=print):
    scene = SCENE_BY_NAME['tumble']
    moments = np.asarray(scene.moments, float)
    sol = TorqueFreeSolution(moments, scene.q0_array, scene.m0)
    period = float(np.ravel(sol.omega_period)[0])
    periods = 100 if quick else 10_000
    h = period / 20
    n_total = periods * 20
    samples = np.unique(np.geomspace(1, n_total, 40 if quick else 80).astype(int))
    budget = 0.5 if quick else 20.0
    t0_T, g0 = 0.5 * float(np.sum(scene.m0 ** 2 / moments)), float(np.linalg.norm(scene.m0))
    rows = []

    def record(method, k, m, spent, note=''):
        e = 0.5 * float(np.sum(m * m / moments))
        g = float(np.linalg.norm(m))
        rows.append({'method': method, 'h': h, 'period': period, 't': k * h, 'periods': k / 20,
                     'energy_drift': abs(e - t0_T) / t0_T, 'momentum_drift': abs(g - g0) / g0,
                     'cpu_s': spent, 'note': note})

    for name, cls in INTEGRATORS.items():
        if cls.requires_actuators:  # the body alone here (bench/actuators.py has them)
            continue
        spent = 0.0
        if name == 'exact':
            c = cpu()
            _, m = sol.at(samples * h)
            spent = cpu() - c
            for k, mk in zip(samples, m):
                record(name, int(k), mk, spent)
            continue
        integ = create(name, scene.dynamics,
                       **({'rtol': 1e-10, 'atol': 1e-13} if cls.adaptive else {}))
        q, m = scene.q0_array, scene.m0
        k = 0
        note = ''
        for target in samples:
            c = cpu()
            try:
                if cls.adaptive:
                    q, m = integ.step(q, m, (target - k) * h, t=k * h)
                    k = int(target)
                else:
                    while k < target:
                        q, m = integ.step(q, m, h, t=k * h)
                        k += 1
            except IntegrationError as exc:
                note = f'blown up at t={exc.t:.4g}: {exc.reason}'
            spent += cpu() - c
            if note:
                break
            record(name, k, m, spent)
            if rows[-1]['energy_drift'] > 1.0 or rows[-1]['momentum_drift'] > 1.0:
                note = 'stopped: drift > 100 %'
                break
            nxt = samples[samples > k]
            if len(nxt) and spent / k * nxt[0] > budget:
                note = f'stopped at {k / 20:.4g} periods (CPU budget {budget:g} s)'
                break
        if note:
            if rows and rows[-1]['method'] == name:
                rows[-1]['note'] = note
            else:
                rows.append({'method': name, 'h': h, 'period': period, 't': 0.0, 'periods': 0.0,
                             'energy_drift': math.nan, 'momentum_drift': math.nan,
                             'cpu_s': spent, 'note': note})
        log(f'  long horizon {name}: {rows[-1]["periods"]:.4g} periods, '
            f'T drift {rows[-1]["energy_drift"]:.2e}, '
            f'|L| drift {rows[-1]["momentum_drift"]:.2e} {note}')
    return rows, periods
