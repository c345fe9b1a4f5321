"""Each scene's figures show what the scene is for: they exist, every axis has a unit, and
the numbers they draw agree with the analytic laws to the physics tests' tolerances
(test_scenes.py: flip interval 5e-3, wobble period 1e-3, nutation law 0.1°)."""
import math
import os

import numpy as np
import pytest

from rigid_body_sim.offline import simulate
from rigid_body_sim.physics import analytic, orbit
from rigid_body_sim.plots import free_until, write_figures
from rigid_body_sim.scene import load

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# the source tree's scene files (an installed share/ may hold another checkout's)
CONFIG = os.path.join(REPO, 'config')
EXPECTED = {
    'tennis_racket': {'omega.png', 'invariants.png', 'poinsot.png', 'flips.png'},
    'symmetric_top': {'omega.png', 'invariants.png', 'poinsot.png', 'precession.png'},
    'rigid_earth': {'omega.png', 'invariants.png', 'poinsot.png', 'precession.png'},
    'explorer1': {'omega.png', 'invariants.png', 'poinsot.png', 'nutation.png'},
    'default': {'omega.png', 'invariants.png', 'poinsot.png', 'flips.png', 'control.png'},
    # controlled from t = 0: no free phase, so no Poinsot figure (it drew round-off noise)
    'slew': {'omega.png', 'invariants.png', 'control.png'},
    'detumble': {'omega.png', 'invariants.png', 'control.png'},
    # the environment's torque acts all along: no free phase (no Poinsot, no flips)
    'gravity_gradient': {'omega.png', 'invariants.png', 'libration.png'},
    # B-dot: |ω| against the averaged closed loop's decay, not the slew's control figure
    'bdot_detumble': {'omega.png', 'invariants.png', 'bdot.png'},
}


def scene(name):
    return load(os.path.join(CONFIG, f'{name}.yaml'))


def figures_of(name, tmp_path, only=None):
    sc = scene(name)
    r = simulate(sc, keep='plot')
    s = r.samples
    return sc, s, {os.path.basename(f.path): f for f in write_figures(
        s, r.body, str(tmp_path), name, free_until(s.t, s.torque), sc, only)}


@pytest.fixture(scope='module')
def figures(tmp_path_factory):
    """``figures_of(name)``, run and drawn once a scene for the module: each scene's figures
    were checked by two tests (units, then its law), which only read them."""
    made = {}

    def get(name):
        if name not in made:
            made[name] = figures_of(name, tmp_path_factory.mktemp(name))
        return made[name]
    return get


@pytest.mark.parametrize('name', sorted(EXPECTED))
def test_figures_exist_with_units_on_every_axis(name, figures):
    _, _, figs = figures(name)
    assert set(figs) == EXPECTED[name]
    for fname, fig in figs.items():
        assert os.path.getsize(fig.path) > 10_000, fname
        assert fig.axes, fname
        for xlabel, ylabel in fig.axes:
            for label in (xlabel, ylabel):
                if label:  # a colour bar has one label only
                    assert '[' in label and ']' in label, f'{fname}: {label!r} has no unit'
        assert any('t [' in x and 'sim time' in x for x, _ in fig.axes) \
            or fname == 'poinsot.png', fname
    # Explorer 1's 1 Hz samples cannot follow its 10 rev/s spin: points, not aliased lines
    assert figs['omega.png'].values['aliased'] == (name == 'explorer1')
    # conserved quantities are drawn as drift, never as the value on 14-digit ticks
    inv = figs['invariants.png']
    if name in ('tennis_racket', 'symmetric_top', 'rigid_earth'):
        assert [y for _, y in inv.axes] == ['T/T₀ − 1 [1]', '|L|/|L₀| − 1 [1]']
    if name == 'explorer1':
        assert [y for _, y in inv.axes] == ['T [J]', '|L|/|L₀| − 1 [1]']


def test_tennis_racket_figure_draws_the_elliptic_flip_interval(figures):
    _, _, figs = figures('tennis_racket')
    v = figs['flips.png'].values
    measured, predicted = v['flip_interval']
    assert v['flips'] >= 4
    assert measured == pytest.approx(predicted, rel=5e-3)


def test_symmetric_top_figure_draws_both_cone_rates(figures):
    sc, _, figs = figures('symmetric_top')
    v = figs['precession.png'].values
    inertia = np.asarray(sc.simulator['inertia'])
    w = np.asarray(sc.simulator['initial_angular_velocity'])
    body_rate = (inertia[2] - inertia[0]) * w[2] / inertia[0]  # written out, not the helper
    space_rate = np.linalg.norm(inertia * w) / inertia[0]
    assert v['body_cone_rate'][1] == pytest.approx(body_rate, rel=1e-12)
    assert v['space_cone_rate'][1] == pytest.approx(space_rate, rel=1e-12)
    for key in ('body_cone_rate', 'space_cone_rate'):
        assert v[key][0] == pytest.approx(v[key][1], rel=1e-3)


def test_rigid_earth_figure_marks_the_304_day_wobble(figures):
    _, _, figs = figures('rigid_earth')
    v = figs['precession.png'].values
    measured, predicted = (p / analytic.SIDEREAL_DAY for p in v['wobble_period'])
    assert predicted == pytest.approx(304.46, rel=1e-4)
    assert measured == pytest.approx(predicted, rel=1e-3)
    assert 'space_cone_rate' not in v  # one sample a day cannot show the daily space cone
    assert any('arcsec' in x for x, _ in figs['precession.png'].axes)


def test_explorer1_figure_follows_the_nutation_law(figures):
    sc, s, figs = figures('explorer1')
    v = figs['nutation.png'].values
    assert v['nutation_max_error_deg'][0] < 0.1
    i_s, i_t = sc.simulator['inertia'][:2]
    G = np.linalg.norm(s['angular_momentum'][0])
    c = sc.simulator['dissipation.coefficient'] * G ** 2 * (1 / i_s - 1 / i_t)
    assert v['nutation_rate'][1] == pytest.approx(c, rel=1e-12)
    T0, T1 = v['energy']
    assert T0 == pytest.approx(79.0, rel=0.01) and T1 == pytest.approx(15.8, rel=0.01)


def test_gravity_gradient_figure_draws_the_libration_frequencies(figures):
    """Pitch at n·√(3(I_x − I_z)/I_y) within 2e-3 (as test_scenes: the 0.05 rad amplitude
    shifts it), the fast roll–yaw root within 5e-3 and the slow one within 5 % (2.3 of its
    periods in the run, and the pitch couples into it at this amplitude)."""
    sc, _, figs = figures('gravity_gradient')
    v = figs['libration.png'].values
    n = math.sqrt(orbit.MU / sc.simulator['orbit.semi_major_axis'] ** 3)
    ix, iy, iz = sc.simulator['inertia']
    measured, predicted = v['pitch_frequency']
    assert predicted == pytest.approx(n * math.sqrt(3 * (ix - iz) / iy), rel=1e-12)
    assert predicted == pytest.approx(0.8660 * n, rel=1e-4)   # the notes' check value
    assert measured == pytest.approx(predicted, rel=2e-3)
    (low_m, high_m), (low, high) = v['roll_yaw_frequencies']
    assert (low / n, high / n) == pytest.approx((0.6818, 1.6937), abs=1e-4)
    assert high_m == pytest.approx(high, rel=5e-3) and low_m == pytest.approx(low, rel=5e-2)


def test_default_free_phase_shows_one_full_flip_then_the_predicted_control(figures):
    """free_time (default.yaml) is derived from the flip: after the first sign change t₁
    of ω_mid plus half the flip interval (ω_mid at its opposite extreme) and before the
    next flip back (t₁ + 2K/λ)."""
    sc, s, figs = figures('default')
    free_time = sc.controller['mission.free_time']
    moments = np.asarray(sc.simulator['inertia'])
    interval = analytic.flip_interval(moments, sc.simulator['initial_angular_velocity'])
    assert interval == pytest.approx(14.49, abs=0.01)
    w_mid = s['angular_velocity'][:, 1]
    t1 = s.t[np.argmax(np.sign(w_mid) != np.sign(w_mid[0]))]
    assert t1 + interval / 2 <= free_time <= t1 + interval
    assert figs['flips.png'].values['flips'] == 1
    v = figs['control.png'].values
    assert v['slew_max_error_deg'][0] < 1.0  # the eigen-axis law, within 1° over the slew
    measured, predicted = v['detumble_rate']
    assert measured == pytest.approx(predicted, rel=0.02)


@pytest.mark.parametrize('name', ['slew', 'detumble'])
def test_control_figures_follow_the_prediction(name, figures):
    _, _, figs = figures(name)
    v = figs['control.png'].values
    if name == 'slew':
        assert v['slew_max_error_deg'][0] < 1.0
    else:
        measured, predicted = v['detumble_rate']
        assert measured == pytest.approx(predicted, rel=0.02)


def test_a_slew_beginning_at_the_last_sample_draws_its_first_point():
    """A live run cut short at its second sample (the demo's simulator lost at t = 0.02 s)
    has its slew begin at the last sample: the eigen-axis law over no time span is its
    initial values (solve_ivp gave no solution and control.png raised IndexError)."""
    th, dth = analytic.eigenaxis_slew(1.2, 0.3, 1.0, 1.0, [0.0])
    assert th.tolist() == [1.2] and dth.tolist() == [0.3]


def test_bench_chart_never_plots_the_reference_against_itself(tmp_path):
    from types import SimpleNamespace

    from rigid_body_sim.bench import charts
    rows = [dict(scene='s', method=m, family='ours', status='ok', cpu_s=c, attitude_error=e)
            for m, c, e in (('exact', 1e-4, 1e-17), ('exact', 2e-4, 1e-17),
                            ('rk4', 1e-3, 1e-6), ('rk4', 1e-2, 1e-10),
                            ('dop853', 1e-3, 1e-8), ('dop853', 1e-1, 0.0))]
    assert charts.plotted_methods(rows, 's', 'exact') == ['rk4', 'dop853']
    assert charts.plotted_methods(rows, 's', 'dop853 rtol 1e-13') == ['exact', 'rk4', 'dop853']
    scene = SimpleNamespace(name='s', title='S', description='d')
    path = tmp_path / 'wp.png'
    charts.work_precision(rows, scene, str(path), reference_label='exact')
    assert path.stat().st_size > 10_000


def test_only_the_figures_asked_for_are_drawn(tmp_path):
    """``only`` (the tour's): the scene's figures of those names and no other file; a
    name the scene has no figure for draws nothing."""
    _, _, figs = figures_of('symmetric_top', tmp_path, only={'precession.png', 'flips.png'})
    assert set(figs) == {'precession.png'}
    assert sorted(os.listdir(tmp_path)) == ['precession.png']


def test_tour_writes_five_small_thumbnails_that_the_docs_show(tmp_path):
    """`rigid-body-sim tour` (in the test's process, cli_inprocess: what it writes, not its
    process) writes the five thumbnails the scenes page shows, each small."""
    from cli_inprocess import run_cli
    from rigid_body_sim.tour import MAX_BYTES, TOUR, thumbnail_name
    out = run_cli('tour', '--out', tmp_path)
    assert out.returncode == 0, out.stderr
    # the tour lives on the scenes page (its pictures relative to docs/)
    page = open(os.path.join(REPO, 'docs', 'scenes.md'), encoding='utf-8').read()
    assert len(TOUR) == 5
    for _, scene_name, figure in TOUR:
        name = thumbnail_name(scene_name, figure)
        assert 10_000 < (tmp_path / name).stat().st_size <= MAX_BYTES, name
        committed = os.path.join(REPO, 'docs', 'tour', name)
        assert os.path.getsize(committed) <= MAX_BYTES and f'(tour/{name})' in page
        assert f'rigid-body-sim run {scene_name}' in page


def test_bdot_figure_reaches_half_a_degree_per_second_near_the_prediction(figures):
    """The B-dot scene's figure: the time to 0.5 °/s against the averaged closed loop,
    written out here (Avanzini–Giulietti's k* = 2n(1 + sin ξ_m)I_min, the major axis's
    e^(−(2/3)(k/I_max)t)): 0.54 orbit predicted, within 1.5× measured (test_bdot's bound)."""
    sc, _, figs = figures('bdot_detumble')
    measured, predicted = figs['bdot.png'].values['orbits_to_half_degree']
    c, inertia = sc.controller, np.asarray(sc.simulator['inertia'], float)
    n, xi = c['bdot.orbit_rate'], c['bdot.magnetic_inclination']
    k = 2 * n * (1 + math.sin(xi)) * inertia.min()
    w0 = np.linalg.norm(sc.simulator['initial_angular_velocity'])
    expected = math.log(w0 / math.radians(0.5)) / (2 / 3 * k / inertia.max()) * n / (2 * math.pi)
    assert figs['bdot.png'].values['gain'] == pytest.approx(k, rel=1e-12)
    assert predicted == pytest.approx(expected, rel=1e-12)
    assert 0.5 * predicted < measured < 1.5 * predicted, (measured, predicted)
