"""The generalisation suite's measuring: each scene judged against its oracle (:func:`judge`),
the families run (:func:`run`), their summary and target rows, and the rows put into a
full run's files (:func:`merge`, :func:`update`). The scenes are drawn in
:mod:`.generated_scenes`; the reference and the oracle sweep live in :mod:`.oracle`; the
command line is :mod:`.generated`.
"""
import math
import os
import time

import numpy as np

from . import oracle as oracle_mod
from .common import GENERATED_COUNTS
from .generated_scenes import Scene, draw, draw_gravity_gradient

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
                  f'bound) around the budget' if math.isfinite(ref.error) else
        f'undecided: no trusted reference ({ref.what})')
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


def run(quick, log=print, seed=SEED, count=None, families=tuple(FAMILIES), kind=None):
    """(rows, target rows, summary of the free-body family) of the generalisation suite:
    ``families`` (FAMILIES' names), ``count`` scenes of the body family or of the one
    family run (default: each family's own count); ``kind``: only the scenes of that kind
    (the others drawn, not judged). Target rows per family (TARGET_NAMES)."""
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
            if kind is not None and scene.kind != kind:
                continue
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


def family_targets(family, s, seed, name=None, said='') -> list:
    """The three target rows of a family's summary ``s`` (error, median and worst CPU);
    ``name`` in place of the family's, ``said`` first in each note."""
    from . import targets
    name = name or TARGET_NAMES[family]
    where = (said + f'seed {seed}, {s["judged"]} of {s["scenes"]} scenes judged'
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
    from . import generated_bdot  # the B-dot family's drawing (imported when drawn)
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


HELD_OUT_CSV = 'generated_held_out.csv'


def update_kind(folder, rows, seed, kind, held_out=False):
    """Put a ``--kind`` run of the body family (its ``rows``) into a full run's ``folder``.

    * not held out: its rows in place of that kind's in generated.csv (the other kinds'
      kept), the body family's target rows summed again over them all;
    * ``held_out``: a seed nothing was fitted on, reported apart: its rows into
      HELD_OUT_CSV (that seed's rows of the kind replaced) and their own target rows,
      named and noted as held out.

    Returns the summary's path."""
    from . import report
    from .common import write_csv
    mine = {r['scene'] for r in rows}
    stamp = time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())
    if held_out:
        old = [r for r in _read(folder, HELD_OUT_CSV)
               if not (r.get('kind') == kind and r['scene'].startswith(f'gen{seed}-'))]
        write_csv(os.path.join(folder, HELD_OUT_CSV), FIELDS, old + list(rows))
        t_rows = family_targets('body', summary(rows), seed, name=f'generated {kind}, '
                                f'held-out seed {seed}', said=f'HELD OUT (no fitting or '
                                f'tuning on this seed), its {kind} scenes only, written {stamp}; ')
    else:
        old = _read(folder, 'generated.csv')
        kept = [r for r in old if r['scene'] not in mine and not (
            _family_of(r) == 'body' and r.get('kind') == kind)]
        by_name = {r['scene']: r for r in rows}
        merged = [by_name.get(r['scene'], r) for r in old if r['scene'] in by_name
                  or r in kept] + [r for r in rows if r['scene'] not in
                                   {o['scene'] for o in old}]
        write_csv(os.path.join(folder, 'generated.csv'), FIELDS, merged)
        t_rows = family_targets('body', summary([r for r in merged
                                                 if _family_of(r) == 'body']), seed,
                                said=f'its {kind} rows re-run {stamp} (--kind {kind}), the '
                                     'other kinds\' rows kept from the previous run (and '
                                     'its reference); ')
    report.replace_targets(folder, tuple(r['target'] for r in t_rows), t_rows,
                           command=f'python -m rigid_body_sim.bench.generated --seed {seed} '
                                   f'--kind {kind} --update {{out}}'
                                   + (' --held-out' if held_out else ''), after='generated')
    return report.write(folder)


def _read(folder, name):
    path = os.path.join(folder, name)
    return read_rows(path) if os.path.exists(path) else []
