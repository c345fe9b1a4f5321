"""Work-precision sweep: every method on every scene, CPU seconds against final error.

Fixed-step methods sweep h coarse → fine, adaptive ones rtol loose → tight. Each
(scene, method) has a CPU budget: a finer run is skipped when its predicted cost (from the
previous run, scaled by the step count) would exceed it, and a sweep stops once the
attitude error is at the float64 floor (≤ 1e-13 rad) or stops improving.
"""
import math


from ..physics import INTEGRATORS, IntegrationError
from ..physics.integrators import BODY_ONLY
from .common import engine_for, metrics, timed, timed_engine

FIELDS = ('scene', 'method', 'family', 'kind', 'param', 'steps', 'cpu_s', 'nfev', 'attitude_error',
          'omega_error', 'energy_drift', 'momentum_drift', 'status')
FLOOR = 1e-13
# a run shorter than 0.05 s is timed this many times, the least kept; --quick (the test
# suite's run, whose figures are checked finite, not judged) times each run once: the
# repeats were 8 of its sweep's 18 CPU-s
REPEATS = {True: 1, False: 3}


def our_methods():
    return list(BODY_ONLY)  # the gyrostat needs actuators: bench/actuators.py


def _params(scene, name, quick):
    cls = INTEGRATORS[name]
    if cls.adaptive:
        return 'rtol', list(scene.rtols if not quick else scene.rtols[::2])
    if name == 'exact' and scene.torque_free:  # no stepping error: a few step counts
        return 'h', [scene.t_end / n for n in (1, 10, 100, 1000)]
    steps = scene.steps(quick)
    return 'h', steps


def _row(scene, method, family, kind, param, steps, cpu_s, nfev, err, status='ok'):
    row = {'scene': scene.name, 'method': method, 'family': family, 'kind': kind, 'param': param,
           'steps': steps, 'cpu_s': cpu_s, 'nfev': nfev, 'status': status}
    row.update(err or {k: float('nan') for k in FIELDS[8:12]})
    return row


def _n_steps(scene, h):
    return int(round(scene.t_end / h))


def _over_budget(last, steps, kind, spent, budget, label, log):
    """True (and logged) when the next run, predicted from the last one's cost, would pass the
    budget."""
    if last is None:
        return False
    predicted = last[0] * (steps / last[1] if kind == 'h' and last[1] else 1.5)
    if spent + predicted <= budget:
        return False
    log(f'  {label} skipped (predicted {predicted:.2g} s CPU > budget)')
    return True


def sweep_ours(scene, ref, budget, quick, log=print):
    rows = []
    q_ref, m_ref = ref[0], ref[1]
    for name in our_methods():
        kind, params = _params(scene, name, quick)
        spent, last = 0.0, None  # last = (cost, steps)
        best_err = math.inf
        stale = 0
        for p in params:
            steps = _n_steps(scene, p) if kind == 'h' else 0
            if _over_budget(last, steps, kind, spent, budget,
                            f'{scene.name}/{name}: {kind}={p:.3g}', log):
                break
            opts = {'rtol': p, 'atol': p * 1e-3} if kind == 'rtol' else {}
            try:
                cost, (q, m, engine) = timed_engine(
                    lambda: engine_for(scene, name, None if kind == 'rtol' else p, **opts),
                    repeats=REPEATS[quick])
            except IntegrationError as exc:
                rows.append(_row(scene, name, 'ours', kind, p, steps, float('nan'), 0, None,
                                 f'blown up at h={p:.3g}: {exc.reason}'))
                continue
            spent += cost
            last = (cost, steps)
            err = metrics(scene, q, m, q_ref, m_ref)
            rows.append(_row(scene, name, 'ours', kind, p, steps, cost,
                             engine.integrator.nfev + engine.evaluations, err))
            e = err['attitude_error']
            if e <= FLOOR:
                break
            stale = stale + 1 if e > 0.5 * best_err else 0
            best_err = min(best_err, e)
            if stale >= 2 and e < 1e-6:  # round-off floor reached
                break
    return rows


def sweep_peers(scene, peers, ref, budget, quick, log=print):
    rows = []
    q_ref, m_ref = ref[0], ref[1]
    for name, peer in peers.items():
        if not peer.supports(scene):
            log(f'  {scene.name}/{name}: n/a '
                '(the double-bracket dissipation model is not built into it)')
            continue
        if peer.kind == 'adaptive':
            kind, params = 'rtol', list(scene.rtols if not quick else scene.rtols[::2])
        else:
            kind, params = 'h', scene.steps(quick)
        spent, last = 0.0, None
        best_err, stale = math.inf, 0
        for p in params:
            steps = _n_steps(scene, p) if kind == 'h' else 0
            if _over_budget(last, steps, kind, spent, budget,
                            f'{scene.name}/{name}: {kind}={p:.3g}', log):
                break
            try:
                if name.startswith('scipy'):
                    cost, (q, m, nfev) = timed(lambda: peer.run(scene, p),
                                               repeats=REPEATS[quick])
                else:  # model set-up excluded: the runner times its own stepping
                    best = None
                    for _ in range(REPEATS[quick]):
                        q, m, nfev, c = peer.run(scene, p)
                        best = c if best is None else min(best, c)
                        if best > 0.05:
                            break
                    cost = best
            except Exception as exc:  # noqa: BLE001 - a peer's failure is a data point
                rows.append(_row(scene, name, 'peer', kind, p, steps, float('nan'), float('nan'),
                                 None,
                                 f'blown up at {kind}={p:.3g}: {type(exc).__name__}: {exc}'[:200]))
                continue
            spent += cost
            last = (cost, steps)
            err = metrics(scene, q, m, q_ref, m_ref)
            rows.append(_row(scene, name, 'peer', kind, p, steps, cost, nfev, err))
            e = err['attitude_error']
            if e <= FLOOR:
                break
            stale = stale + 1 if e > 0.5 * best_err else 0
            best_err = min(best_err, e)
            if stale >= 2 and e < 1e-6:
                break
    return rows


def print_best(rows, scenes, log):
    """Per scene and method: the best attitude error reached and what it cost."""
    log('\nbest attitude error reached per method (CPU s for it; nfev):')
    for scene in scenes:
        log(f'  {scene.name}')
        for method in dict.fromkeys(r['method'] for r in rows if r['scene'] == scene.name):
            rs = [r for r in rows
                  if r['scene'] == scene.name and r['method'] == method and r['status'] == 'ok']
            fails = [r for r in rows
                     if r['scene'] == scene.name and r['method'] == method and r['status'] != 'ok']
            if not rs:
                log(f'    {method:20s} no successful run ({fails[0]["status"] if fails else "-"})')
                continue
            b = min(rs, key=lambda r: (r['attitude_error'], r['cpu_s']))
            cheapest = min(rs, key=lambda r: r['cpu_s'])
            log(f'    {method:20s} best {b["attitude_error"]:9.2e} rad in {b["cpu_s"]:8.3g} s '
                f'({b["kind"]}={b["param"]:.3g}, nfev {b["nfev"]}); '
                f'cheapest {cheapest["cpu_s"]:.3g} s -> '
                f'{cheapest["attitude_error"]:.2e} rad; |L| drift {b["momentum_drift"]:.1e}, '
                f'T {b["energy_drift"]:.1e}'
                + (f'; {len(fails)} failed run(s)' if fails else ''))
