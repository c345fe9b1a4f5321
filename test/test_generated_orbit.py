"""The generalisation suite's orbit family (bench.generated.draw_gravity_gradient): seeded,
in its ranges, valid scenes with the gravity gradient on; a family run alone replaces only
its own rows and targets in a full run's files."""
import csv
import math

import pytest

from rigid_body_sim.bench import generated
from rigid_body_sim.offline import simulate
from rigid_body_sim.physics.orbit import MU, RADIUS

SEED = 1


def test_the_orbit_family_is_seeded_apart_and_stays_in_its_ranges():
    draw = generated.draw_gravity_gradient
    assert draw(SEED, 3, True) == draw(SEED, 3, True)
    assert draw(SEED, 3, True) != draw(SEED + 1, 3, True)
    assert draw(SEED, 3).name == f'gen{SEED}-gg3' != generated.draw(SEED, 3).name
    drawn = [draw(SEED, i) for i in range(40)]
    frames, circular = set(), 0
    for s in drawn:
        o = dict(s.orbit)
        a, e = o['orbit.semi_major_axis'], o['orbit.eccentricity']
        assert RADIUS + 400e3 <= a <= generated.GEO and 0.0 <= e <= 0.7
        assert a * (1.0 - e) >= RADIUS + generated.LOW_PERIGEE
        assert o['orbit.model'] in ('kepler', 'j2') and s.kind == 'gravity_gradient'
        orbits = s.duration * math.sqrt(MU / a ** 3) / (2 * math.pi)
        assert 0.5 * 0.99 <= orbits <= 10.0 * 1.01
        assert s.budget in {10.0 ** -k for k in range(2, 11)}
        frames.add(s.frame)
        circular += e == 0.0
        p = s.scene_file().simulator
        assert p['environment.gravity_gradient'] and p['initial_attitude_frame'] == s.frame
    assert frames == {'world', 'lvlh'} and 0 < circular < len(drawn)


def test_an_orbit_scene_runs_with_the_gradient_named():
    scene = generated.draw_gravity_gradient(SEED, 0, True)
    result = simulate(scene.scene_file(), keep='none')
    assert 'gravity gradient' in result.reason


def test_a_family_run_alone_replaces_only_its_rows(tmp_path, monkeypatch):
    body = {f: '' for f in generated.FIELDS}
    body.update(scene='gen1-0', kind='free', status='ok')
    old_gg = dict(body, scene='gen1-gg0', kind='gravity_gradient')
    with open(tmp_path / 'generated.csv', 'w', newline='') as f:
        w = csv.DictWriter(f, fieldnames=generated.FIELDS)
        w.writeheader()
        w.writerows([body, old_gg])
    s = generated.summary([])
    t_rows = generated.family_targets('gravity_gradient', s, SEED)
    new = dict(old_gg, scene='gen1-gg1')
    generated.merge(str(tmp_path), 'gravity_gradient', [new], t_rows, SEED)
    with open(tmp_path / 'generated.csv', newline='') as f:
        scenes = [r['scene'] for r in csv.DictReader(f)]
    assert scenes == ['gen1-0', 'gen1-gg1']
    with open(tmp_path / 'targets.csv', newline='') as f:
        names = [r['target'] for r in csv.DictReader(f)]
    assert names == [r['target'] for r in t_rows]
    assert all(n.startswith('generated, gravity gradient:') for n in names)
    text = (tmp_path / 'targets.md').read_text()
    assert '--family gravity_gradient' in text and (tmp_path / 'summary.md').exists()


def test_a_family_without_judged_rows_is_not_judged():
    s = generated.summary([])
    rows = generated.family_targets('gravity_gradient', s, SEED)
    assert [r['verdict'] for r in rows] == ['n/a'] * 3


@pytest.mark.parametrize('index', [24, 27, 29])
def test_auto_meets_its_budget_on_eccentric_librations(index):
    """The bench's seed, orbit scenes 24, 27, 29: librations about LVLH on orbits of
    e = 0.23, 0.54, 0.69, where the gradient's rate at perigee exceeds the body's own. auto
    took rk4 within its a-priori bound and erred 85, 3.1e4 and 66× the budget: the forced
    libration is chaotic there (dop853 at rtol 1e-9 erred 3 rad on scene 27), beyond any
    bound growing as T or T². auto now says it cannot know (no predicted error) and takes
    dop853 at its tightest rtol. Scene 27's truth is past float64 here: rk4 from h = 2.6 s
    down to 0.02 s stays 1e-4 to 2e-3 rad from dop853's ladder (round-off grown by the
    chaos), so no independent reference confirms it (the judge says undecided only after
    its whole 40 s cap: its ladder's own tests, test_generated, cover that): there the test
    checks what auto says."""
    scene = generated.draw_gravity_gradient(generated.SEED, index)
    result = simulate(scene.scene_file())
    assert 'possibly chaotic' in result.reason and \
        math.isinf(result.selection.predicted_error)
    if index == 27:
        return
    ref, ref_error, _ = generated.reference(scene)
    assert ref_error * generated.JUDGE <= scene.budget
    assert generated.error(result, ref) <= scene.budget - ref_error, result.reason


def test_auto_promises_nothing_near_an_unstable_lvlh_equilibrium():
    """Seed 7's orbit scene 21: a circular orbit, 0.027 rad from LVLH with I_x < I_z (pitch
    unstable, roll–yaw too). auto took dop853 at the rtol of its bound and erred 4.6× the
    1e-6 budget: the body leaves the equilibrium exponentially, and so does the error. auto
    now tests the equilibrium's stability, promises nothing and takes the most accurate."""
    scene = generated.draw_gravity_gradient(7, 21)
    ref, ref_error, _ = generated.reference(scene)
    assert ref_error * generated.JUDGE <= scene.budget
    result = simulate(scene.scene_file())
    assert 'unstable in pitch' in result.reason and \
        math.isinf(result.selection.predicted_error), result.reason
    assert generated.error(result, ref) <= scene.budget - ref_error, result.reason


def test_a_fast_tumble_on_an_eccentric_orbit_keeps_the_a_priori_choice():
    """Scene 14 of the bench's seed (e = 0.55, a tumble 56× faster than the gradient's
    rate): the spin averages the forcing, auto's bound holds (it met 1e-4 by 10×), so the
    forced-libration rule must not take it."""
    scene = generated.draw_gravity_gradient(generated.SEED, 14)
    result = simulate(scene.scene_file(), duration=scene.duration / 50)
    assert 'possibly chaotic' not in result.reason and 'a priori' in result.reason


def test_update_from_a_body_only_run_keeps_the_orbit_family(tmp_path):
    """``--update DIR`` with the body family alone rewrote generated.csv with its rows only:
    the orbit family's rows were dropped (their targets stayed, judging nothing shown).
    Each family's rows and targets now change only with a run of that family."""
    body = {f: '' for f in generated.FIELDS}
    body.update(scene='gen1-0', kind='free', status='ok', cpu_ratio=1.2, error_ratio=0.5)
    gg = dict(body, scene='gen1-gg0', kind='gravity_gradient')
    empty = generated.summary([])
    for family, row in (('body', body), ('gravity_gradient', gg)):
        generated.merge(str(tmp_path), family, [row],
                        generated.family_targets(family, empty, SEED), SEED)

    def scenes():
        with open(tmp_path / 'generated.csv', newline='') as f:
            return [r['scene'] for r in csv.DictReader(f)]

    def notes():
        with open(tmp_path / 'targets.csv', newline='') as f:
            return {r['target']: r['note'] for r in csv.DictReader(f)}
    before = notes()
    generated.update(str(tmp_path), [dict(body, scene='gen1-1')], SEED + 1)
    assert sorted(scenes()) == ['gen1-1', 'gen1-gg0']
    after = notes()
    assert set(after) == set(before)
    for target, note in after.items():
        moved = target.startswith('generated:')
        assert (f'seed {SEED + 1}' in note) == moved, (target, note)
    generated.update(str(tmp_path), [dict(gg, scene='gen1-gg1')], SEED + 2)
    assert sorted(scenes()) == ['gen1-1', 'gen1-gg1']
    assert all((f'seed {SEED + 2}' in note) == t.startswith('generated, gravity gradient:')
               for t, note in notes().items())
