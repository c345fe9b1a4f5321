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

The oracle is the cheapest fixed choice of the registry proven to meet the budget, found by
a sweep of bounded CPU, and the reference carries a bound on its own error (the exact
solution checked against the 40-digit closed form torque-free; else ``dop853`` down a
ladder of rtol): see :mod:`.oracle`. A row is judged when the bound decides it.
"""
import math
import os
from dataclasses import dataclass

import numpy as np

from . import oracle as oracle_mod
from .common import GENERATED_COUNTS
from ..param_spec import coerce_all
from ..scene import SceneFile

KINDS = ('free', 'double_bracket', 'viscous', 'detumble')
WEIGHTS = (0.2, 0.35, 0.25, 0.2)


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
    orbit: tuple = ()   # ((key, value), …) of orbit.*: an orbit scene (gravity gradient on)
    frame: str = 'world'  # of attitude and omega (lvlh: relative to the orbit frame)
    extra: tuple = ()       # ((key, value), …) more simulator parameters (a family's own)
    controller: tuple = ()  # ((key, value), …) the controller's, where the family has one

    @property
    def name(self) -> str:
        tag = 'bdot' if self.kind == 'bdot' else 'gg' if self.orbit else ''
        return f'gen{self.seed}-{tag}{self.index}'

    @property
    def dissipative(self) -> bool:
        return self.kind in ('double_bracket', 'viscous')

    def describe(self) -> str:
        extra = (f', coefficient {self.coefficient:.3g}' if self.dissipative else
                 f', control {self.control_rate:.3g} Hz' if self.kind == 'detumble' else
                 f', B-dot at {self.control_rate:.3g} Hz{_orbit_words(self)}'
                 if self.kind == 'bdot' else
                 _orbit_words(self) if self.orbit else '')
        return (f'{self.name} {self.kind}: I = {", ".join(f"{i:.3g}" for i in self.moments)}, '
                f'|ω| = {np.linalg.norm(self.omega):.3g} rad/s, {self.rotation:.3g} rad over '
                f'{self.duration:.4g} s at {self.publish_rate:.3g} Hz, budget '
                f'{self.budget:.0e}{extra}')

    def parameters(self):
        """(simulator, controller) parameters as a params file would give them."""
        sim = {'inertia': list(self.moments), 'initial_attitude': list(self.attitude),
               'initial_angular_velocity': list(self.omega), 'integrator': 'auto',
               'accuracy': self.budget, 'publish_rate': self.publish_rate,
               'duration': self.duration, 'real_time_factor': 0.0,
               'step': 1.0 / self.publish_rate}
        if self.orbit:
            sim.update(dict(self.orbit), **{'environment.gravity_gradient': True,
                                            'initial_attitude_frame': self.frame})
        sim.update(dict(self.extra))
        if self.dissipative:
            sim.update({'dissipation.model': self.kind,
                        'dissipation.coefficient': self.coefficient})
        ctl = {}
        if self.kind == 'detumble':
            torque = 20.0 * self.natural_frequency * max(self.moments) * \
                float(np.linalg.norm(self.omega))
            sim['max_torque'] = torque
            ctl = {'mode': 'detumble', 'inertia': list(self.moments),
                   'control_rate': self.control_rate,
                   'natural_frequency': self.natural_frequency, 'damping_ratio': 1.0,
                   'max_torque': torque}
        ctl.update(dict(self.controller))
        return sim, ctl

    def scene_file(self) -> SceneFile:
        from ..engine import specs
        sim, ctl = self.parameters()
        if ctl:
            ctl = coerce_all(specs.CONTROLLER, ctl, 'generated controller')
        return SceneFile(self.name, self.describe(), f'<generated {self.name}>',
                         coerce_all(specs.SIMULATOR, sim, 'generated scene'), ctl)

    def write_params_file(self, path: str) -> str:
        """The scene as a params file ``rigid-body-sim run`` takes (what a user would
        write); floats in repr form, so the file gives the same scene bit for bit."""
        import yaml
        sim, ctl = self.parameters()
        doc = {'/**/attitude_simulator': {'ros__parameters': _nested(sim)}}
        if ctl:
            doc['/**/attitude_controller'] = {'ros__parameters': _nested(ctl)}
        with open(path, 'w', encoding='utf-8') as f:
            yaml.safe_dump(doc, f, sort_keys=False)
        return path


def _nested(flat):
    """'a.b': v → {'a': {'b': v}} (a params file's nesting)."""
    out = {}
    for key, value in flat.items():
        *parents, leaf = key.split('.')
        node = out
        for p in parents:
            node = node.setdefault(p, {})
        node[leaf] = value
    return out


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


# ---------------------------------------------------------------------------- orbit scenes
GG_STREAM = 30     # the orbit family's scenes come from their own streams: [seed, 30, index]
GG_ORBITS = {True: (0.5, 3.0), False: (0.5, 10.0)}  # run length in orbits (log-uniform)
LOW_PERIGEE = 200e3   # m above the surface: the lowest perigee drawn
GEO = 42.164e6        # m: the largest semi-major axis drawn


def draw_gravity_gradient(seed: int, index: int, quick: bool = False) -> Scene:
    """Orbit scene ``index`` of ``seed``: the gravity gradient along a Kepler or J2 orbit.

    * orbit: a log-uniform in 400 km up to GEO's radius; circular or (half the scenes)
      e up to 0.7 with the perigee at least 200 km up; inclination uniform on the sphere,
      node, periapsis and true anomaly uniform;
    * the body: moments as the free family's; libration about LVLH (half: a turn of
      0.01–0.3 rad from it, a rate relative to it of 0.01–0.3 n) or a tumble in the inertial
      frame at n to 10³ n (|ω|·T at most 10⁴ rad with ``quick``, 10⁵ without);
    * 0.5–10 orbits (0.5–3 with ``quick``), 50–2000 samples, the duration off the sample
      grid; budget: a decade from 1e-2 to 1e-10 rad."""
    from ..physics.orbit import MU, RADIUS
    rng = np.random.default_rng([seed, GG_STREAM, index])
    while True:
        moments = sorted(_log_uniform(rng, 0.2, 3.0) for _ in range(3))
        if moments[0] + moments[1] >= moments[2]:
            break
    rng.shuffle(moments)
    a = _log_uniform(rng, RADIUS + 400e3, GEO)
    e = 0.0 if rng.uniform() < 0.5 else \
        float(rng.uniform(0.01, min(0.7, 1.0 - (RADIUS + LOW_PERIGEE) / a)))
    model = 'j2' if rng.uniform() < 0.5 else 'kepler'
    angles = [float(math.acos(rng.uniform(-1.0, 1.0)))] + \
        [float(x) for x in rng.uniform(0.0, 2.0 * math.pi, 3)]
    n = math.sqrt(MU / a ** 3)
    direction = rng.normal(size=3)
    direction /= np.linalg.norm(direction)
    orbits = _log_uniform(rng, *GG_ORBITS[quick])
    duration = orbits * 2.0 * math.pi / n
    if rng.uniform() < 0.5:   # libration about LVLH
        frame, angle = 'lvlh', _log_uniform(rng, 0.01, 0.3)
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        q = np.append(axis * math.sin(angle / 2.0), math.cos(angle / 2.0))
        omega = _log_uniform(rng, 0.01, 0.3) * n * direction
        spin = n + float(np.linalg.norm(omega))  # roughly: the orbit frame's rate and its own
    else:                     # a tumble in the inertial frame
        frame = 'world'
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        spin = min(_log_uniform(rng, n, 1e3 * n), (1e4 if quick else 1e5) / duration)
        omega = spin * direction
    samples = _log_uniform(rng, 50.0, 2000.0)
    period = max(1e-6, round(duration / samples, 6))
    duration = (math.floor(duration / period) + rng.uniform(0.1, 0.9)) * period
    budget = 10.0 ** -int(rng.integers(2, 11))
    orbit = (('orbit.model', model), ('orbit.semi_major_axis', a),
             ('orbit.eccentricity', e), ('orbit.inclination', angles[0]),
             ('orbit.raan', angles[1]), ('orbit.argument_of_periapsis', angles[2]),
             ('orbit.true_anomaly', angles[3]))
    return Scene(seed, index, 'gravity_gradient', tuple(moments), tuple(omega.tolist()),
                 (float(q[0]), float(q[1]), float(q[2]), float(q[3])), spin * duration,
                 duration, 1.0 / period, budget, orbit=orbit, frame=frame)


def _orbit_words(scene: Scene) -> str:
    o = dict(scene.orbit)
    return (f', {o["orbit.model"]} orbit a = {o["orbit.semi_major_axis"] / 1e3:.6g} km, '
            f'e = {o["orbit.eccentricity"]:.3g}, ω given in {scene.frame}')




# ---------------------------------------------------------------------------- measuring
# the reference and the oracle live in .oracle; these names are the suite's (and tests')
timed, error, JUDGE = oracle_mod.timed, oracle_mod.error, oracle_mod.JUDGE
_spacing, _snap, oracle = oracle_mod._spacing, oracle_mod._snap, oracle_mod.oracle


def reference(scene: Scene):
    """(attitude samples, bound on its own error rad, what it is): see :mod:`.oracle`."""
    ref = oracle_mod.reference(scene)
    return ref.attitude, ref.error, ref.what


def _try(f, ref, budget, **kw):
    """(error, CPU s, result) of one fixed choice; a diverging one errs inf."""
    return oracle_mod.try_run(f, ref, **kw)


# ---------------------------------------------------------------------------- the suite
FIELDS = ('scene', 'kind', 'budget', 'rotation', 'duration', 'publish_rate', 'status',
          'auto_method', 'auto_step', 'auto_cpu_s', 'auto_error', 'error_ratio',
          'auto_predicted_error',
          'oracle_method', 'oracle_param', 'oracle_cpu_s', 'oracle_error', 'cpu_ratio',
          'reference', 'reference_error', 'reason', 'note')
SEED = 20261125
COUNTS = GENERATED_COUNTS
# The families of the suite: (draw(seed, index, quick), scenes (quick, full)); a family's
# scenes are named and seeded apart (gen<seed>-<index>, gen<seed>-gg<index>)
FAMILIES = {
    'body': (draw, COUNTS),
    'gravity_gradient': (draw_gravity_gradient, {True: 4, False: 30}),
    'bdot': (lambda seed, index, quick: _bdot().draw(seed, index, quick), {True: 1, False: 20}),
}
JUDGED = ('ok', 'auto missed')
# a budget no fixed choice of the registry was found to meet, which auto said it cannot
# meet: counted apart, not as a miss of auto's (its error is reported beside)
INFEASIBLE = 'infeasible'


def judge(scene: Scene, log=None, cap: float = oracle_mod.SWEEP_CAP[True]) -> dict:
    """One row: auto against the oracle on ``scene``. A method that diverges is a row with
    its reason, never an exception; the sweep's CPU is bounded by ``cap`` (at most 4×
    more where auto itself is dear: the oracle must be able to beat it)."""
    f = scene.scene_file()
    row = {'scene': scene.name, 'kind': scene.kind, 'budget': scene.budget,
           'rotation': scene.rotation, 'duration': scene.duration,
           'publish_rate': scene.publish_rate}
    try:
        ref = oracle_mod.reference(scene)
    except oracle_mod.FAILURES as exc:
        row.update(status='no reference', reason=f'{type(exc).__name__}: {exc}')
        return row
    row.update(reference=ref.what, reference_error=ref.error)
    auto_err, auto_cpu, auto = _try(f, ref.attitude, scene.budget)
    if isinstance(auto, str):
        row.update(status='auto failed', reason=auto)
        return row
    predicted = auto.selection.predicted_error if auto.selection is not None else math.nan
    row.update(auto_method=auto.integrator, auto_step=auto.step, auto_cpu_s=auto_cpu,
               auto_error=auto_err, error_ratio=auto_err / scene.budget, reason=auto.reason,
               auto_predicted_error=predicted)
    if math.isfinite(ref.error):
        best, _, note = oracle(scene, ref, cap=min(max(cap, 20 * auto_cpu), 4 * cap), log=log)
    else:  # nothing can be proven against it: no sweep
        best, note = None, 'no sweep: the reference is unbounded'
    decided = ref.decide(auto_err, scene.budget)
    row['status'] = {'met': 'ok', 'missed': 'auto missed'}.get(
        decided, f'undecided: error {auto_err:.2g} ± {ref.error:.2g} rad (the reference\'s '
                  f'bound) around the budget')
    if best is None:
        note = '; '.join(x for x in ('no fixed choice proven to meet the budget', note) if x)
        row['status'] = classify(row['status'], predicted, scene.budget)
    else:
        row.update(oracle_method=best[0], oracle_param=best[1], oracle_cpu_s=best[2],
                   oracle_error=best[3], cpu_ratio=auto_cpu / best[2])
    row['note'] = note
    return row


def classify(status: str, predicted: float, budget: float) -> str:
    """A miss becomes INFEASIBLE where no fixed choice of the registry was proven to meet
    the budget (the caller's sweep found none) and auto said beforehand that it cannot
    (its predicted error, ``Selection.predicted_error``, over the budget). A miss where
    a fixed choice met it, or that auto did not foresee, stays a miss."""
    if status == 'auto missed' and predicted > budget:
        return INFEASIBLE
    return status


def summary(rows) -> dict:
    """Worst error/budget, median and worst CPU ratio to the oracle over the judged rows, and
    their spread (10th/50th/90th percentiles)."""
    judged = [r for r in rows if r.get('status') in JUDGED]
    # a CPU ratio counts where auto met its budget (a miss may be cheaper than the oracle)
    ratios = [r['cpu_ratio'] for r in judged if r.get('cpu_ratio') is not None
              and r['status'] == 'ok']
    ratios = np.array(ratios) if ratios else np.array([math.nan])
    errors = np.array([r['error_ratio'] for r in judged]) if judged else np.array([math.nan])
    return {'scenes': len(rows), 'judged': len(judged), 'with_oracle': int(np.sum(
            np.isfinite(ratios))), 'undecided': sum(r.get('status', '').startswith(
                'undecided') for r in rows),
            'missed': sum(r.get('status') == 'auto missed' for r in rows),
            'infeasible': sum(r.get('status') == INFEASIBLE for r in rows),
            'failed': sum(r.get('status') in ('auto failed', 'no reference') for r in rows),
            'worst_error_ratio': float(np.max(errors)),
            'error_ratio_p50': float(np.median(errors)),
            'cpu_ratio_p10': float(np.percentile(ratios, 10)),
            'cpu_ratio_median': float(np.median(ratios)),
            'cpu_ratio_p90': float(np.percentile(ratios, 90)),
            'cpu_ratio_worst': float(np.max(ratios))}


def run(quick, log=print, seed=SEED, count=None, families=tuple(FAMILIES)):
    """(rows, target rows, summary of the free-body family) of the generalisation suite:
    ``families`` (FAMILIES' names), ``count`` scenes of the body family or of the one
    family run (default: each family's own count). Target rows per family (TARGET_NAMES)."""
    from .. import compiled
    compiled.setup()  # kernels loaded before any clock starts (else the first run pays)
    rows, t_rows, first = [], [], None
    for family in families:
        draw_scene, counts = FAMILIES[family]
        alone = family == 'body' or len(families) == 1  # count is the body family's
        n = count if count is not None and alone else counts[quick]
        mine = []
        for i in range(n):
            scene = draw_scene(seed, i, quick)
            log(f'  {scene.describe()}')
            row = judge(scene, log=None, cap=oracle_mod.SWEEP_CAP[quick])
            mine.append(row)
            log(f'    {row["status"]}: auto → {row.get("auto_method", "-")} '
                f'error/budget {row.get("error_ratio", math.nan):.2g}, '
                f'{row.get("auto_cpu_s", math.nan):.3g} s; oracle '
                f'{row.get("oracle_method", "-")} {row.get("oracle_param", math.nan):.3g} '
                f'{row.get("oracle_cpu_s", math.nan):.3g} s; ratio '
                f'{row.get("cpu_ratio", math.nan):.2f}'
                + (f'; {row["note"]}' if row.get('note') else ''))
        s = summary(mine)
        first = s if first is None else first
        rows += mine
        t_rows += family_targets(family, s, seed)
    return rows, t_rows, first


TARGET_NAMES = {'body': 'generated', 'gravity_gradient': 'generated, gravity gradient',
                'bdot': 'generated, B-dot'}


def targets_for(rows, seed=SEED):
    """(target rows, summary) of the body family's rows (``run``'s, or read back from its
    CSV: ``update``); rows of other families are left out."""
    s = summary([r for r in rows if _family_of(r) == 'body'])
    return family_targets('body', s, seed), s


def family_targets(family, s, seed) -> list:
    """The three target rows of a family's summary ``s`` (error, median and worst CPU)."""
    from . import targets
    name = TARGET_NAMES[family]
    where = (f'seed {seed}, {s["judged"]} of {s["scenes"]} scenes judged'
             + (f', {s["undecided"]} undecided' if s['undecided'] else ''))
    spread = (f'{where}; {s["with_oracle"]} with an oracle; CPU ratio p10 '
              f'{s["cpu_ratio_p10"]:.2f}, p50 '
              f'{s["cpu_ratio_median"]:.2f}, p90 {s["cpu_ratio_p90"]:.2f}, worst '
              f'{s["cpu_ratio_worst"]:.2f}; {s["failed"]} failed')
    ok = s['judged'] > 0
    return [
        targets.simple(f'{name}: auto worst attitude error / budget', s['worst_error_ratio'],
                       1.0, s['worst_error_ratio'] <= 1.0 if ok else None,
                       f'{where}; {s["missed"]} missed; median {s["error_ratio_p50"]:.2g}; '
                       f'{s["infeasible"]} infeasible (no fixed choice met the budget and '
                       'auto said it cannot), not judged'),
        targets.simple(f'{name}: auto CPU / oracle, median', s['cpu_ratio_median'], 1.5,
                       s['cpu_ratio_median'] <= 1.5 if ok else None, spread),
        targets.simple(f'{name}: auto CPU / oracle, worst scene', s['cpu_ratio_worst'], 3.0,
                       s['cpu_ratio_worst'] <= 3.0 if ok else None, spread)]


def merge(out, family, rows, t_rows, seed=SEED):
    """A family run alone into a full run's files in ``out``: its rows in place of that
    family's in generated.csv, its target rows in targets.csv / targets.md, summary.md
    rendered again (``report``); the other families' rows as they were."""
    from . import report
    from .common import write_csv
    path = os.path.join(out, 'generated.csv')
    kept = report._rows(out, 'generated.csv') or []
    kept = [r for r in kept if _family_of(r) != family]
    write_csv(path, FIELDS, kept + list(rows))
    report.replace_targets(out, tuple(r['target'] for r in t_rows), t_rows,
                           command=f'python -m rigid_body_sim.bench.generated --family '
                                   f'{family} --seed {seed} --out {out}',
                           after='generated')
    return report.write(out)


def _family_of(row) -> str:
    kind = row.get('kind')
    return kind if kind in ('gravity_gradient', 'bdot') else 'body'


def _bdot():
    from . import generated_bdot  # the B-dot family's drawing (it imports this module)
    return generated_bdot


def read_rows(path):
    """The rows of a CSV this suite wrote, numbers as floats (empty cells left out)."""
    import csv
    out = []
    with open(path, newline='', encoding='utf-8') as f:
        for row in csv.DictReader(f):
            r = {}
            for k, v in row.items():
                if v == '':
                    continue
                try:
                    r[k] = v if k in ('scene', 'kind', 'status', 'auto_method',
                                      'oracle_method', 'reference', 'reason', 'note') \
                        else float(v)
                except ValueError:
                    r[k] = v
            out.append(r)
    return out


def update(folder, rows, seed=SEED):
    """Put a run of the suite (its ``rows``) into a full run's ``folder``: generated.csv,
    where the rows of a family the run did not hold stay as they were (a body-only run
    dropped the orbit family's), and each run family's target rows
    (:func:`.common.replace_section`)."""
    from . import report
    from .common import replace_section
    present = [f for f in FAMILIES if any(_family_of(r) == f for r in rows)]
    kept = [r for r in report._rows(folder, 'generated.csv') or []
            if _family_of(r) not in present]
    merged, out = kept + list(rows), None
    for family in present:
        s = summary([r for r in rows if _family_of(r) == family])
        out = replace_section(folder, 'generated.csv', FIELDS, merged,
                              family_targets(family, s, seed), (f'{TARGET_NAMES[family]}:',))
    return out


def main(argv=None):
    import argparse
    import json
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true', help=f'{COUNTS[True]} scenes, '
                        'rotations up to 1e4 rad')
    parser.add_argument('--seed', type=int, default=SEED, help=f'default {SEED}')
    parser.add_argument('--count', type=int, default=None, help='scenes of the body family, '
                        'or of --family (default: FAMILIES\' counts)')
    parser.add_argument('--family', choices=tuple(FAMILIES), default=None,
                        help='this family only (default: all)')
    parser.add_argument('--only', type=int, default=None, help='just scene INDEX of the seed '
                        '(of --family, default body)')
    parser.add_argument('--csv', default='', help='write the rows here')
    parser.add_argument('--out', default='', metavar='DIR', help='with --family: its rows '
                        'and targets into a full run\'s files in DIR (others kept)')
    parser.add_argument('--update', metavar='DIR', default='',
                        help='put the rows (or those of --from-csv) into a full run\'s DIR '
                             '(e.g. docs/bench): generated.csv, its targets, the summary')
    parser.add_argument('--from-csv', default='', help='with --update: rows a run wrote')
    args = parser.parse_args(argv)
    if args.only is not None:
        from .. import compiled
        compiled.setup()
        scene = FAMILIES[args.family or 'body'][0](args.seed, args.only, args.quick)
        print(scene.describe())
        row = judge(scene, log=print)
        print(json.dumps(row, indent=1, default=str))
        return 0
    if args.out and not args.family:
        parser.error('--out needs --family (a whole run: rigid-body-sim bench)')
    if args.update and args.from_csv:
        print(update(args.update, read_rows(args.from_csv), args.seed))
        return 0
    families = (args.family,) if args.family else tuple(FAMILIES)
    rows, t_rows, s = run(args.quick, seed=args.seed, count=args.count, families=families)
    for r in t_rows:
        print(f'{r["verdict"]:5s} {r["target"]}: {r["measured"]:.3g} (required '
              f'{r["required"]:g}) {r["note"]}')
    if args.csv:
        from .common import write_csv
        write_csv(args.csv, FIELDS, rows)
    if args.out:
        print(merge(args.out, args.family, rows, t_rows, args.seed))
    print(json.dumps(s))
    if args.update:
        print(update(args.update, rows, args.seed))
    return 0


if __name__ == '__main__':
    import sys
    sys.exit(main())
