"""Seeded scenes across the space users run, each with an oracle: the generalisation suite.

``python -m rigid_body_sim.bench.generated [--quick] [--seed N] [--count N]``

Every scene is drawn from one ``numpy.random.Generator`` seeded with ``seed`` and its index,
so a scene is the same whatever the count and the order (scene i of seed s is reproducible
alone). A scene:

* kind: torque-free, double-bracket or viscous dissipation, or detumble control;
* principal moments log-uniform in 0.2–3 kg·m² (redrawn until I1 + I2 ≥ I3), initial
  ω of log-uniform norm 0.1–100 rad/s in a uniform direction, attitude uniform;
* rotation |ω|·T log-uniform in 10²–10⁵ rad (10²–10⁴ with ``quick``, to fit its minutes);
  50–2000 samples per run, the duration a non-integer number of sample periods;
* dissipation: its decay over the run (κT, κ the rate at which the momentum leaves the
  minor axis, double bracket; c·T/I_max, viscous) log-uniform in 0.05–20 (0.05–3);
  detumble: the rate decays as exp(−2ζω_n t) with 2ζω_n set so that the body turns about
  the drawn rotation, control at 10–100 Hz;
* budget: a decade from 1e-2 to 1e-10 rad.

The oracle is the cheapest fixed choice of the registry meeting the budget, found by a
sweep (:func:`oracle`): every stepping method at steps dividing the event spacing, refined
from the measured error, and ``dop853`` over its rtol, errors against a reference at the
samples (the exact solution torque-free; else ``dop853`` at rtol 1e-13, whose own error is
estimated against rtol 1e-12 — a scene whose budget is under four times that estimate
cannot be judged and says so).
"""
import math
from dataclasses import dataclass

import numpy as np

from ..offline import simulate
from ..param_spec import coerce_all
from ..physics import IntegrationError, rotation
from ..scene import SceneFile

KINDS = ('free', 'double_bracket', 'viscous', 'detumble')
WEIGHTS = (0.2, 0.35, 0.25, 0.2)
STEPPERS = ('splitting2', 'splitting4', 'splitting6', 'rk4', 'implicit_midpoint',
            'splitting2_lstable', 'exact')
ORDERS = {'splitting2': 2, 'splitting4': 4, 'splitting6': 6, 'rk4': 4, 'implicit_midpoint': 2,
          'splitting2_lstable': 2, 'exact': 2}
REF_RTOL, CHECK_RTOL = 1e-13, 1e-12
JUDGE = 4.0  # a budget under this many times the reference's own error cannot be judged


@dataclass(frozen=True)
class Scene:
    """A generated scene: what was drawn, and the scene file the engine runs."""
    seed: int
    index: int
    kind: str
    moments: tuple
    omega: tuple       # rad/s, body frame
    attitude: tuple    # (x, y, z, w)
    rotation: float    # rad: |ω|·duration
    duration: float    # s
    publish_rate: float
    budget: float      # rad
    coefficient: float = 0.0
    control_rate: float = 0.0
    natural_frequency: float = 0.0

    @property
    def name(self) -> str:
        return f'gen{self.seed}-{self.index}'

    @property
    def dissipative(self) -> bool:
        return self.kind in ('double_bracket', 'viscous')

    def describe(self) -> str:
        extra = (f', coefficient {self.coefficient:.3g}' if self.dissipative else
                 f', control {self.control_rate:.3g} Hz' if self.kind == 'detumble' else '')
        return (f'{self.name} {self.kind}: I = {", ".join(f"{i:.3g}" for i in self.moments)}, '
                f'|ω| = {np.linalg.norm(self.omega):.3g} rad/s, {self.rotation:.3g} rad over '
                f'{self.duration:.4g} s at {self.publish_rate:.3g} Hz, budget '
                f'{self.budget:.0e}{extra}')

    def scene_file(self) -> SceneFile:
        from ..engine import specs
        sim = {'inertia': list(self.moments), 'initial_attitude': list(self.attitude),
               'initial_angular_velocity': list(self.omega), 'integrator': 'auto',
               'accuracy': self.budget, 'publish_rate': self.publish_rate,
               'duration': self.duration, 'real_time_factor': 0.0,
               'step': 1.0 / self.publish_rate}
        if self.dissipative:
            sim.update({'dissipation.model': self.kind,
                        'dissipation.coefficient': self.coefficient})
        ctl = {}
        if self.kind == 'detumble':
            torque = 20.0 * self.natural_frequency * max(self.moments) * \
                float(np.linalg.norm(self.omega))
            sim['max_torque'] = torque
            ctl = coerce_all(specs.CONTROLLER, {
                'mode': 'detumble', 'inertia': list(self.moments),
                'control_rate': self.control_rate, 'natural_frequency': self.natural_frequency,
                'damping_ratio': 1.0, 'max_torque': torque}, 'generated controller')
        return SceneFile(self.name, self.describe(), f'<generated {self.name}>',
                         coerce_all(specs.SIMULATOR, sim, 'generated scene'), ctl)


def _log_uniform(rng, lo, hi):
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def draw(seed: int, index: int, quick: bool = False) -> Scene:
    """Scene ``index`` of ``seed`` (deterministic; independent of the other scenes)."""
    rng = np.random.default_rng([seed, index])
    kind = KINDS[int(rng.choice(len(KINDS), p=WEIGHTS))]
    while True:
        moments = sorted(_log_uniform(rng, 0.2, 3.0) for _ in range(3))
        if moments[0] + moments[1] >= moments[2]:
            break
    rng.shuffle(moments)
    spin = _log_uniform(rng, 0.1, 100.0)
    direction = rng.normal(size=3)
    omega = spin * direction / np.linalg.norm(direction)
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    turned = _log_uniform(rng, 1e2, 1e4 if quick else 1e5)
    samples = _log_uniform(rng, 50.0, 2000.0)
    duration = turned / spin
    # a period in whole µs, and a duration off the sample grid by a drawn fraction
    period = max(1e-6, round(duration / samples, 6))
    duration = (math.floor(duration / period) + rng.uniform(0.1, 0.9)) * period
    budget = 10.0 ** -int(rng.integers(2, 11))
    spread = 1.0 / min(moments) - 1.0 / max(moments)
    coefficient = control = wn = 0.0
    if kind == 'double_bracket':  # κ = α|L|²(1/I_min − 1/I_max)
        decay = _log_uniform(rng, 0.05, 20.0)
        norm2 = float(np.sum((np.array(moments) * omega) ** 2))
        coefficient = decay / (duration * norm2 * spread)
    elif kind == 'viscous':       # |L| falls at least as exp(−c t / I_max)
        coefficient = _log_uniform(rng, 0.05, 3.0) * max(moments) / duration
    elif kind == 'detumble':      # rate ∝ exp(−2ζω_n t): turns |ω|/(2ζω_n) in all
        wn = spin / (2.0 * turned)
        control = _log_uniform(rng, 10.0, 100.0)
    return Scene(seed, index, kind, tuple(moments), tuple(omega.tolist()),
                 (float(q[0]), float(q[1]), float(q[2]), float(q[3])),
                 spin * duration, duration, 1.0 / period, budget, coefficient, control, wn)


def scenes(seed: int, count: int, quick: bool = False):
    return [draw(seed, i, quick) for i in range(count)]


# ---------------------------------------------------------------------------- measuring
def timed(scene_file, repeat=3, **kw):
    """(result, CPU s of the run, selection included): the least of up to ``repeat`` runs
    while they take < 0.3 s in all (the machine is shared: the least is the least noisy)."""
    best, total, result = math.inf, 0.0, None
    for _ in range(repeat):
        result = simulate(scene_file, **kw)
        cpu = result.cpu_seconds + result.selection_cpu_seconds
        best, total = min(best, cpu), total + cpu
        if total > 0.3:
            break
    return result, best


def error(result, ref) -> float:
    a = result.samples['attitude']
    if len(a) != len(ref):
        return math.inf
    return float(np.max(rotation.angle_between(a, ref)))


def reference(scene: Scene):
    """(attitude samples, own error estimate rad, what it is)."""
    f = scene.scene_file()
    if scene.kind == 'free':
        return simulate(f, integrator='exact').samples['attitude'], 0.0, 'exact'
    fine = simulate(f, integrator='dop853', integrator_options={'rtol': REF_RTOL, 'atol': 1e-16})
    coarse = simulate(f, integrator='dop853',
                      integrator_options={'rtol': CHECK_RTOL, 'atol': 1e-15})
    ref = fine.samples['attitude']
    # the rtol 1e-12 run's error, a bound on the 1e-13 run's (which errs ~10^(7/8)... less)
    return ref, error(coarse, ref), f'dop853 rtol {REF_RTOL:g}'


def _spacing(f: SceneFile) -> float:
    spacing = 1.0 / f.simulator['publish_rate']
    if f.controlled:
        spacing = min(spacing, 1.0 / f.controller['control_rate'])
    return spacing


def _snap(spacing, h):
    return spacing / max(1, math.ceil(spacing / h - 1e-9))


def _try(f, ref, budget, **kw):
    """(error, CPU s, result) of one fixed choice; a diverging one errs inf."""
    try:
        result, cpu = timed(f, **kw)
        return error(result, ref), cpu, result
    except (IntegrationError, FloatingPointError, ValueError) as exc:
        return math.inf, math.nan, str(exc)


def oracle(scene: Scene, ref, cap: float, log=None):
    """The cheapest (method, parameter, CPU s, error) meeting the scene's budget among the
    registry's fixed choices, or None; ``cap``: CPU s above which a run is not tried
    (the sweep's own bound: nothing dearer can be cheapest). Steps: from hΩ ≈ 1 (or the
    event spacing), each next step from the last error by its order (0.8 of the budget),
    at most 4× smaller at a time; then one step 1.25× larger to tighten the bound."""
    f = scene.scene_file()
    budget, spacing = scene.budget, _spacing(f)
    omega = float(np.linalg.norm(scene.omega))
    best = None
    tried = []

    def consider(name, param, err, cpu):
        nonlocal best
        tried.append((name, param, err, cpu))
        if err <= budget and (best is None or cpu < best[2]):
            best = (name, param, cpu, err)

    def limit():
        return cap if best is None else min(cap, best[2])

    # dop853 first: it often wins, and its cost bounds every other sweep
    rtol = min(1e-3, max(1e-13, budget * 1e-2))
    last = None
    while rtol >= 1e-13:
        err, cpu, _ = _try(f, ref, budget, integrator='dop853',
                           integrator_options={'rtol': rtol, 'atol': rtol * 1e-3})
        consider('dop853', rtol, err, cpu)
        if err <= budget:
            if last is None:  # met at once: try looser
                looser = rtol * 10
                if looser <= 1e-3:
                    e2, c2, _ = _try(f, ref, budget, integrator='dop853',
                                     integrator_options={'rtol': looser, 'atol': looser * 1e-3})
                    consider('dop853', looser, e2, c2)
            break
        last = err
        rtol /= 10
    for name in STEPPERS:
        if name == 'splitting2_lstable' and scene.kind != 'double_bracket':
            continue
        if name == 'exact' and scene.kind == 'free':
            err, cpu, _ = _try(f, ref, budget, integrator='exact')
            consider('exact', spacing, err, cpu)
            continue
        p = ORDERS[name]
        h = _snap(spacing, 1.0 / max(omega, 1e-9))
        met = None
        for _ in range(6):
            steps = scene.duration / h
            per_step = 1e-7 if name != 'exact' else 1.5e-5
            if steps * per_step > limit():  # even at the cheapest per step: too dear
                break
            err, cpu, _ = _try(f, ref, budget, integrator=name, step=h)
            consider(name, h, err, cpu)
            if not (cpu <= limit() * 4 or err <= budget):
                break
            if err <= budget:
                met = h
                break
            shrink = (0.8 * budget / err) ** (1.0 / p) if math.isfinite(err) else 0.25
            h = _snap(spacing, h * max(0.25, min(0.9, shrink)))
        if met is not None and met < spacing:
            h = _snap(spacing, met * 1.25)
            if h > met:
                err, cpu, _ = _try(f, ref, budget, integrator=name, step=h)
                consider(name, h, err, cpu)
    if log:
        log('    sweep: ' + ', '.join(f'{n} {p:.3g}: {e:.2g} ({c:.3g} s)'
                                      for n, p, e, c in tried))
    return best, tried


# ---------------------------------------------------------------------------- the suite
FIELDS = ('scene', 'kind', 'budget', 'rotation', 'duration', 'publish_rate', 'status',
          'auto_method', 'auto_step', 'auto_cpu_s', 'auto_error', 'error_ratio',
          'oracle_method', 'oracle_param', 'oracle_cpu_s', 'oracle_error', 'cpu_ratio',
          'reference_error', 'reason')
SEED = 20261125
COUNTS = {True: 20, False: 200}


def judge(scene: Scene, log=None, cap: float = 30.0) -> dict:
    """One row: auto against the oracle on ``scene``. A method that diverges is a row with
    its reason, never an exception."""
    f = scene.scene_file()
    row = {'scene': scene.name, 'kind': scene.kind, 'budget': scene.budget,
           'rotation': scene.rotation, 'duration': scene.duration,
           'publish_rate': scene.publish_rate}
    try:
        ref, ref_err, _ = reference(scene)
    except IntegrationError as exc:
        row.update(status='no reference', reason=str(exc))
        return row
    row['reference_error'] = ref_err
    auto_err, auto_cpu, auto = _try(f, ref, scene.budget)
    if isinstance(auto, str):
        row.update(status='auto failed', reason=auto)
        return row
    row.update(auto_method=auto.integrator, auto_step=auto.step, auto_cpu_s=auto_cpu,
               auto_error=auto_err, error_ratio=auto_err / scene.budget, reason=auto.reason)
    best, _ = oracle(scene, ref, cap=max(cap, 20 * auto_cpu), log=log)
    if ref_err * JUDGE > scene.budget:
        row['status'] = 'unjudged: budget under the reference\'s resolution'
    elif best is None:
        row['status'] = 'no fixed choice meets the budget'
    else:
        row['status'] = 'ok' if auto_err <= scene.budget else 'auto missed'
    if best is not None:
        row.update(oracle_method=best[0], oracle_param=best[1], oracle_cpu_s=best[2],
                   oracle_error=best[3], cpu_ratio=auto_cpu / best[2])
    return row


def summary(rows) -> dict:
    """Worst error/budget, median and worst CPU ratio to the oracle over the judged rows, and
    their spread (10th/50th/90th percentiles)."""
    judged = [r for r in rows if r.get('status') in ('ok', 'auto missed')]
    ratios = np.array([r['cpu_ratio'] for r in judged]) if judged else np.array([math.nan])
    errors = np.array([r['error_ratio'] for r in judged]) if judged else np.array([math.nan])
    return {'scenes': len(rows), 'judged': len(judged),
            'missed': sum(r.get('status') == 'auto missed' for r in rows),
            'failed': sum(r.get('status') in ('auto failed', 'no reference') for r in rows),
            'worst_error_ratio': float(np.max(errors)),
            'error_ratio_p50': float(np.median(errors)),
            'cpu_ratio_p10': float(np.percentile(ratios, 10)),
            'cpu_ratio_median': float(np.median(ratios)),
            'cpu_ratio_p90': float(np.percentile(ratios, 90)),
            'cpu_ratio_worst': float(np.max(ratios))}


def run(quick, log=print, seed=SEED, count=None):
    """(rows, target rows, summary) of the generalisation suite."""
    from . import targets
    from .. import compiled
    compiled.warm()  # kernels loaded before any clock starts (else the first run pays)
    count = COUNTS[quick] if count is None else count
    rows = []
    for scene in scenes(seed, count, quick):
        log(f'  {scene.describe()}')
        row = judge(scene, log=None)
        rows.append(row)
        log(f'    {row["status"]}: auto → {row.get("auto_method", "-")} '
            f'error/budget {row.get("error_ratio", math.nan):.2g}, '
            f'{row.get("auto_cpu_s", math.nan):.3g} s; oracle {row.get("oracle_method", "-")} '
            f'{row.get("oracle_param", math.nan):.3g} {row.get("oracle_cpu_s", math.nan):.3g} s;'
            f' ratio {row.get("cpu_ratio", math.nan):.2f}')
    s = summary(rows)
    where = f'seed {seed}, {s["judged"]} of {s["scenes"]} scenes judged'
    spread = (f'{where}; CPU ratio p10 {s["cpu_ratio_p10"]:.2f}, p50 '
              f'{s["cpu_ratio_median"]:.2f}, p90 {s["cpu_ratio_p90"]:.2f}, worst '
              f'{s["cpu_ratio_worst"]:.2f}; {s["failed"]} failed')
    ok = s['judged'] > 0
    t_rows = [
        targets.simple('generated: auto worst attitude error / budget', s['worst_error_ratio'],
                       1.0, s['worst_error_ratio'] <= 1.0 if ok else None,
                       f'{where}; {s["missed"]} missed; median {s["error_ratio_p50"]:.2g}'),
        targets.simple('generated: auto CPU / oracle, median', s['cpu_ratio_median'], 1.5,
                       s['cpu_ratio_median'] <= 1.5 if ok else None, spread),
        targets.simple('generated: auto CPU / oracle, worst scene', s['cpu_ratio_worst'], 3.0,
                       s['cpu_ratio_worst'] <= 3.0 if ok else None, spread)]
    return rows, t_rows, s


def main(argv=None):
    import argparse
    import csv
    import json
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true', help=f'{COUNTS[True]} scenes, '
                        'rotations up to 1e4 rad')
    parser.add_argument('--seed', type=int, default=SEED, help=f'default {SEED}')
    parser.add_argument('--count', type=int, default=None, help='scenes (default 20 / 200)')
    parser.add_argument('--only', type=int, default=None, help='just scene INDEX of the seed')
    parser.add_argument('--csv', default='', help='write the rows here')
    args = parser.parse_args(argv)
    if args.only is not None:
        from .. import compiled
        compiled.warm()
        scene = draw(args.seed, args.only, args.quick)
        print(scene.describe())
        row = judge(scene, log=print)
        print(json.dumps(row, indent=1, default=str))
        return 0
    rows, t_rows, s = run(args.quick, seed=args.seed, count=args.count)
    for r in t_rows:
        print(f'{r["verdict"]:5s} {r["target"]}: {r["measured"]:.3g} (required '
              f'{r["required"]:g}) {r["note"]}')
    if args.csv:
        with open(args.csv, 'w', newline='') as fh:
            w = csv.DictWriter(fh, fieldnames=FIELDS, extrasaction='ignore')
            w.writeheader()
            w.writerows(rows)
    print(json.dumps(s))
    return 0


if __name__ == '__main__':
    import sys
    sys.exit(main())
