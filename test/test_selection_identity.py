"""``auto`` chooses as it did before its fixed cost was cut (issue 29's selection share).

test/data/selection_choices.json.gz holds what the engine chose (method, step, reason, the
whole Selection) and the provisional a-priori choice a non-blocking engine (the live node)
takes first, on the named scenes at their own and three shorter horizons and on 300 body,
30 orbit and 30 B-dot scenes of ``bench.generated`` (seed 20261125), written by this file
(``python test/test_selection_identity.py --write``) from main at cf57fee, before the
a-priori pass was made cheaper. A change of the choice, of a step, of a predicted figure
or of a word of a reason fails here; one meant to change a choice rewrites the file in its
own commit and says why. The costs are the classes' constants (conftest), so the choices
do not depend on the machine; the pilots' measured errors are bit-identical runs of the
compiled kernels.

test/data/selection_law_choices.json.gz holds the choice a controlled scene makes at its
first command, under the law (:mod:`rigid_body_sim.physics.auto.law_pilot`), which the
record above, taken before any command, does not reach: the named controlled scenes at the
same horizons and the 61 detumble scenes of those 300, written from main at 1a0bc3f
(``--write-law``) before refine's planning was made cheaper. Where dop853 is taken by
weighing, its predicted cost is the pilot's measured CPU, so it is left out.
"""
import gzip
import json
import os
import sys

import pytest

from rigid_body_sim.bench import generated_bdot, generated_scenes
from rigid_body_sim.engine import Engine, EngineConfig
from rigid_body_sim.offline import effective_parameters, engine_for, simulate
from rigid_body_sim.scene import SceneError, load

pytestmark = pytest.mark.fast

DATA = os.path.join(os.path.dirname(__file__), 'data', 'selection_choices.json.gz')
LAW_DATA = os.path.join(os.path.dirname(__file__), 'data', 'selection_law_choices.json.gz')
CONTROLLED = ('default', 'slew', 'detumble')
SEED = 20261125
NAMED = ('default', 'slew', 'detumble', 'tennis_racket', 'symmetric_top', 'explorer1',
         'rigid_earth', 'gravity_gradient', 'explorer1_orbit', 'bdot_detumble')
HORIZONS = (None, 1.0, 10.0, 100.0)  # None: the scene's own duration


def _scenes():
    """(key, scene file maker, duration) of every recorded case."""
    for name in NAMED:
        for d in HORIZONS:
            yield f'{name}@{d}', lambda name=name: load(name), d
    for i in range(300):
        yield f'body{i}', lambda i=i: generated_scenes.draw(SEED, i).scene_file(), None
    for i in range(30):
        yield f'gg{i}', lambda i=i: generated_scenes.draw_gravity_gradient(
            SEED, i, quick=True).scene_file(), None
        yield f'bdot{i}', lambda i=i: generated_bdot.draw(SEED, i, quick=True).scene_file(), \
            None


def _selection(s):
    return None if s is None else [s.name, s.step, s.reason, s.predicted_error,
                                   s.predicted_cost, s.pilot_steps, s.pilot_cost,
                                   s.prior_cost, [list(o) for o in s.options]]


def _provisional(scene, duration):
    """The a-priori choice a non-blocking engine takes before its pilot runs."""
    p = effective_parameters(scene, duration)
    config = EngineConfig.from_parameters(p, scene.controller if scene.controlled else None)
    engine = Engine(config, blocking_selection=False, interpolate_samples=True)
    return [engine.method, engine.step_max, engine.reason]


def choices(scene, duration) -> dict:
    """What auto chooses for ``scene`` over ``duration`` (None: its own), as JSON values."""
    try:
        engine = engine_for(scene, duration=duration)
    except (SceneError, ValueError) as exc:
        return dict(error=str(exc))
    return dict(method=engine.method, step=engine.step_max, reason=engine.reason,
                selection=_selection(engine.selected),
                provisional=_provisional(scene, duration))


def _law_scenes():
    """(key, scene file maker, duration) of every recorded choice under the law."""
    for name in CONTROLLED:
        for d in HORIZONS:
            yield f'{name}@{d}', lambda name=name: load(name), d
    for i in range(300):
        drawn = generated_scenes.draw(SEED, i)
        if drawn.kind == 'detumble':
            yield f'body{i}', drawn.scene_file, None


def law_choices(scene, duration) -> dict:
    """What auto chooses for ``scene`` over ``duration`` at its first command (the law's,
    in the compiled closed loop), as JSON values."""
    try:
        engine = engine_for(scene, duration=duration)
    except (SceneError, ValueError) as exc:
        return dict(error=str(exc))
    until = engine.t_ns + 1
    while engine.selected is None and until < engine.end_ns:  # default: free for 17 s
        simulate(scene, engine=engine, until_ns=until)
        until = engine.t_ns + 10**9
    selection = _selection(engine.selected)
    if selection is not None and 'dop853 errs less: taken' in selection[2]:
        selection[4] = None  # the pilot's measured CPU
    return dict(method=engine.method, step=engine.step_max, reason=engine.reason,
                selection=selection)


def _recorded(path=DATA):
    with gzip.open(path, 'rt', encoding='utf-8') as f:
        return json.load(f)


def _assert_unchanged(recorded, cases, chosen):
    """Each case's choice now (``chosen(scene, duration)``) is the one recorded."""
    differ = []
    for key, make, duration in cases:
        now = chosen(make(), duration)
        if now != recorded[key]:
            differ.append(f'{key}: now {now}\n  was {recorded[key]}')
    assert not differ, f'{len(differ)} of {len(cases)} choices changed:\n' + \
        '\n'.join(differ[:5])


@pytest.mark.slow
def test_choices_and_reasons_are_those_recorded_before_the_cut():
    recorded = _recorded()
    cases = list(_scenes())
    assert sorted(recorded) == sorted(key for key, _, _ in cases)
    # the record spans what auto does: every kind of choice, piloted and a priori
    methods = {v['method'] for v in recorded.values() if 'method' in v}
    assert {'exact', 'dop853', 'rk4', 'splitting4', 'splitting6'} <= methods
    assert sum(1 for v in recorded.values() if (v.get('selection') or [0] * 6)[5] > 0) > 100
    _assert_unchanged(recorded, cases, choices)


@pytest.mark.slow
def test_choices_under_the_law_are_those_recorded_before_the_cut():
    recorded = _recorded(LAW_DATA)
    cases = list(_law_scenes())
    assert sorted(recorded) == sorted(key for key, _, _ in cases)
    # the record reaches the law's pilot: piloted choices, weighed ones and a priori ones
    reasons = [v['reason'] for v in recorded.values() if 'reason' in v]
    assert sum('pilot under the law: none' not in r for r in reasons) > 10
    assert sum('dop853 errs less: taken' in r for r in reasons) > 3
    assert all('pilot under the law' in recorded[f'{n}@None']['reason'] for n in CONTROLLED)
    _assert_unchanged(recorded, cases, law_choices)


if __name__ == '__main__' and sys.argv[1:] == ['--write-law']:
    os.environ.setdefault('RIGID_BODY_SIM_AUTO_COSTS', 'constants')
    with gzip.open(LAW_DATA, 'wt', encoding='utf-8') as out:
        json.dump({key: law_choices(make(), d) for key, make, d in _law_scenes()}, out,
                  indent=0)
elif __name__ == '__main__' and sys.argv[1:] == ['--write']:
    os.environ.setdefault('RIGID_BODY_SIM_AUTO_COSTS', 'constants')
    with gzip.open(DATA, 'wt', encoding='utf-8') as out:
        json.dump({key: choices(make(), d) for key, make, d in _scenes()}, out, indent=0)
