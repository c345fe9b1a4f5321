"""``integrator: auto``: its candidates, its pilot's states and growth law, what it costs."""
import math
import time

import numpy as np
import pytest

from rigid_body_sim.engine import Engine
from rigid_body_sim.offline import engine_for, simulate
from rigid_body_sim.physics import INTEGRATORS, Dissipation, Dynamics, RigidBody, create
from rigid_body_sim.physics.auto import CANDIDATES, pilot, select
from rigid_body_sim.scene import load

EXPLORER_I = np.array([0.04, 0.2, 0.2])
EXPLORER_W = np.array([62.83185307179586, 0.21934681498568484, 0.0])  # 10 rev/s, 1° nutation
EXPLORER_D = Dissipation('double_bracket', 1.0678e-05)
Q_ID = np.array([0.0, 0.0, 0.0, 1.0])


def _finish(gen):
    while True:
        try:
            next(gen)
        except StopIteration as done:
            return done.value


def test_every_candidate_is_a_registered_method_with_its_tested_order():
    """Each candidate is an integrator whose order the tests measure per kind of scene
    (test_integrators); auto uses ``effective_order``, e.g. exact's splitting is order 2."""
    names = [c.name for c in CANDIDATES]
    assert set(names) <= set(INTEGRATORS) and len(names) == len(set(names))
    assert {'splitting2', 'splitting4', 'splitting6', 'rk4', 'exact'} <= set(names)
    dyn = Dynamics(EXPLORER_I, EXPLORER_D)
    assert create('exact', dyn).effective_order(EXPLORER_I * EXPLORER_W, 0.01) == 2


def test_pilot_states_follow_the_exponential_path_of_the_nutation():
    """Double-bracket damping takes tan β (β from the minor axis) as exp(κt), κ the
    dissipation stiffness: over Explorer 1's orbit from 1° to ~90°, over 30 s barely."""
    dyn = Dynamics(EXPLORER_I, EXPLORER_D)
    m = EXPLORER_I * EXPLORER_W
    kappa = pilot.path_rate(dyn, float(np.linalg.norm(m)))
    assert kappa == pytest.approx(dyn.dissipation_stiffness(float(np.linalg.norm(m))))
    assert kappa == pytest.approx(1.349e-3, rel=1e-3)  # the scene file's calibration
    long = pilot.levels(dyn, Q_ID, m, 6900.0, 62.8, periods=True)
    betas = [lv.beta_deg for lv in long]
    assert betas[0] == pytest.approx(1.0) and 89.0 < betas[-1] < 90.0 and len(long) == 6
    u = np.log(np.tan(np.radians(betas)))
    assert np.allclose(np.diff(u), np.diff(u)[0])  # evenly spaced in ln tan β
    assert u[-1] - u[0] == pytest.approx(kappa * 6900.0, rel=0.05)
    # each pilot resolves its polhode: ≥ 4 turns and a nutation period (long near 90°)
    assert all(lv.horizon >= min(4 * 2 * math.pi / 62.8, 6900.0) for lv in long)
    assert long[-1].horizon > 10.0
    assert len(pilot.levels(dyn, Q_ID, m, 30.0, 62.8, periods=False)) == 1


def test_pilot_growth_law_linear_bounded_and_drift():
    """Explorer 1's initial state, pilot spanning ≥ 2 nutation periods: splitting2's phase
    error grows linearly (extrapolated ∝ T); exact's splitting with the weak damping errs a
    bounded offset that comes back every nutation period (far below linear); RK4's
    measured energy and |L| drift adds a term growing as T²."""
    dyn = Dynamics(EXPLORER_I, EXPLORER_D)
    m = EXPLORER_I * EXPLORER_W
    level = pilot.levels(dyn, Q_ID, m, 100.0, 62.8, periods=True)[0]
    span = pilot.steps_for(level, 0.0078125) * 0.0078125
    assert span >= 2 * level.period
    lin, g = _finish(pilot.error(create('splitting2', dyn), 2, level, 0.0078125, 100.0))
    one, _ = _finish(pilot.error(create('splitting2', dyn), 2, level, 0.0078125, span))
    assert 1.5 < g <= 2.5 and lin == pytest.approx(one * 100.0 / span, rel=0.3)
    bounded, _ = _finish(pilot.error(create('exact', dyn), 2, level, 0.0078125, 100.0))
    offset, _ = _finish(pilot.error(create('exact', dyn), 2, level, 0.0078125, span))
    assert bounded < 0.1 * offset * 100.0 / span
    # RK4: the measured energy and |L| drift adds a T² term on top of the fitted law
    rk4 = create('rk4', dyn)
    drift, _ = _finish(pilot.error(rk4, 4, level, 0.0078125, 100.0, drift=True))
    law, _ = _finish(pilot.error(rk4, 4, level, 0.0078125, 100.0))
    at_span, _ = _finish(pilot.error(rk4, 4, level, 0.0078125, span, drift=True))
    assert drift > law
    # the T² term: (drift − law) over 100 s against the same term over the pilot's span
    assert drift - law == pytest.approx((at_span - _finish(pilot.error(
        rk4, 4, level, 0.0078125, span))[0]) * (100.0 / span) ** 2, rel=1e-9)


def test_rk4_pilot_with_its_measured_drift_bounds_its_error_at_long_horizons():
    """RK4 on the standard body I = (2, 1, 2/3), m0 = (cos 1.1, 0, sin 1.1) (Hairer–Lubich–
    Wanner), against the exact solution: a 17 s pilot with the measured energy and |L|
    drift bounds the error over 100–5,000 s at hΩ = 0.03–0.15 (measured 3–40× above it);
    the fitted law alone falls short of it at 1,000 s and beyond (2.4–8× at 5,000 s)."""
    from rigid_body_sim.physics import rotation
    from rigid_body_sim.physics.exact import TorqueFreeSolution
    moments, m0 = np.array([2.0, 1.0, 2.0 / 3.0]), np.array([math.cos(1.1), 0.0, math.sin(1.1)])
    dyn, q0 = Dynamics(moments, Dissipation()), np.array([0.0, 0.0, 0.0, 1.0])
    level = pilot.levels(dyn, q0, m0, 1000.0, 1.5, periods=True)[0]
    exact = TorqueFreeSolution(moments, q0, m0)
    short = 0
    for h in (0.1, 0.05, 0.02):
        for horizon in (100.0, 1000.0, 5000.0):
            n = int(round(horizon / h))
            q, _ = create('rk4', dyn).run(q0, m0, h, n)
            true = float(rotation.angle_between(q, exact.at(n * h)[0]))
            bound, _ = _finish(pilot.error(create('rk4', dyn), 4, level, h, n * h, drift=True))
            law, _ = _finish(pilot.error(create('rk4', dyn), 4, level, h, n * h))
            assert true <= bound <= 50 * true, (h, horizon, true, bound)
            short += horizon >= 1000.0 and law < true
    assert short == 6  # without the drift term every long horizon is under-read


@pytest.mark.parametrize('name', ['slew', 'detumble', 'default'])
def test_controlled_scenes_choose_a_priori_at_the_control_period(name):
    """Commanded torque: no pilot (it cannot know the commands); a fixed-step method at the
    control period or half of it, not the scene's 2 ms step; choosing costs well under a
    ms. (It was a splitting while every control instant was costed at a Python round trip;
    with the compiled loop's cost rk4, the cheapest fixed choice the selection bench
    finds on these three, costs least.)"""
    scene = load(name)

    def run():
        engine = engine_for(scene, duration=scene.simulator['duration'])
        engine.advance(engine.end_ns)  # the law's first torque triggers the choice
        while not engine.finished:
            engine.advance(engine.end_ns)
        return engine
    # the same choice three times: the least CPU is its cost (a full garbage collection,
    # 40 ms of a worker's heap at times, may land in one choice's bracket)
    runs = [run() for _ in range(3)]
    assert len({(e.selected.name, e.selected.step) for e in runs}) == 1
    engine = min(runs, key=lambda e: e.selection_cpu)
    sel = engine.selected
    period = 1.0 / scene.controller['control_rate']
    assert sel is not None and sel.pilot_steps == 0
    assert sel.name in ('rk4', 'splitting4', 'splitting6'), sel.reason
    assert period / 2 <= sel.step <= period and 'a priori' in sel.reason
    assert sel.predicted_error <= scene.simulator['accuracy']
    assert engine.selection_cpu < 0.01


class _Ticks:
    """A process clock that advances one second per reading: CPU counted in a bracket is
    the number of brackets, whatever the machine does."""

    def __init__(self):
        self.now = 0.0

    def process_time(self):
        self.now += 1.0
        return self.now

    def __getattr__(self, name):
        return getattr(time, name)


@pytest.mark.parametrize('name, brackets', [('tennis_racket', 1), ('explorer1', 1)])
def test_all_of_auto_s_choosing_counts_as_selection_cpu(monkeypatch, name, brackets):
    """The free body's choice and the building of the selection's arguments count in
    selection_cpu (the share the selection bench reports): they ran outside it, 30-40 µs
    of default's 1.3 ms run. One bracket for the free body's choice, and one for a
    dissipative body's (building the arguments, then the pilot's ``work`` to its end: the
    clock read once at each end). A fixed method counts none."""
    from rigid_body_sim.engine import method_choice
    monkeypatch.setattr(method_choice, 'time', _Ticks())
    scene = load(name)
    assert engine_for(scene, duration=1.0).selection_cpu == brackets
    assert engine_for(scene, duration=1.0, integrator='rk4', step=0.01).selection_cpu == 0


@pytest.mark.parametrize('name, duration', [('explorer1', 690.0), ('slew', 15.0)])
def test_a_choice_made_at_once_reads_the_engine_s_state_and_leaves_it(name, duration):
    """A blocking selection (and one under torque) is handed the engine's own momentum and
    attitude, not copies (a numpy call each, cold, on a short run's choosing): its pilots
    run on copies (``Integrator.run``: new arrays), so the state is the configured one,
    to the bit, after Explorer 1's pilot (192 steps) and slew's choice at a command."""
    scene = load(name)
    engine = engine_for(scene, duration=duration)
    if name == 'slew':  # a first command: the choice under torque
        m0, q0 = engine._m.copy(), engine._q.copy()
        engine.apply_command(np.array([0.01, -0.02, 0.005]))
        assert engine.selected is not None
    else:
        assert engine.selected.pilot_steps > 0
        body, c = engine.body, engine.config
        m0 = body.principal_moments * body.to_principal(c.angular_velocity)
        q0 = body.attitude_to_principal(c.attitude)
    assert engine._aligned and engine._m.tolist() == m0.tolist()
    assert engine._q.tolist() == q0.tolist()


def test_live_engine_runs_the_a_priori_choice_while_the_pilot_is_pending():
    """The node's engine (non-blocking) steps with the a-priori choice meanwhile (a bound, so
    it meets the budget), then switches when ``work`` has fed the pilot to its end."""
    config = engine_for(load('explorer1'), duration=600.0).config
    engine = Engine(config, blocking_selection=False)
    assert engine.selection_pending and 'provisional a-priori' in engine.reason
    provisional = engine.method, engine.step_max
    assert provisional[1] < 1.0 / 62.8  # hΩ ≤ 1, not the 1 s sample period
    slices = 0
    while engine.work(deadline=time.monotonic() + 1e-4):  # slices as the node feeds them
        slices += 1
    assert slices > 3 and not engine.selection_pending and engine.selected.pilot_steps > 0
    assert engine.step_max >= provisional[1] and engine.selection_cpu > 0.0


def test_selection_costs_little_at_a_budget_below_double_precision():
    """1e-9 rad over 100 s of a 10 rev/s spin is 1.6e-13 of the angle turned: the pilot took
    57–113 CPU s for a ~1 s run. Now it is planned within 10 % of the run it selects for
    (the CPU measured is the bench's to report: a timed assertion here failed once when
    the suite's first run loaded the kernels), and the a-priori bound says which budgets
    its round-off floor puts out of reach."""
    result = simulate(load('explorer1'), duration=100.0, accuracy=1e-9)
    assert result.selection.planned_cost <= 0.1 * result.selection.predicted_cost
    body = RigidBody.from_inertia(EXPLORER_I)
    sel = select(body, EXPLORER_D, Q_ID, EXPLORER_W, torque=False, accuracy=1e-13,
                 duration=100.0, max_step=1.0, prior_only=True)
    assert 'none meets the budget' in sel.reason and sel.predicted_error > 1e-13


@pytest.mark.parametrize('duration', [1.0, 10.0, 30.0, 100.0, 690.0])
def test_the_whole_selection_is_planned_within_a_tenth_of_the_run(duration):
    """Explorer 1 from 1 s to 690 s: the a-priori pass and every pilot round, in the run's
    cost model, fit in 10 % of the predicted run (a round that would not fit does not start,
    and up to 100 s exact's bound on a symmetric body meets the budget a priori at the
    sample period, which nothing can beat; at 690 s pilots run; over 1 s even asking a
    second candidate a priori would pass 10 %). The CPU measured is the bench's to report."""
    from rigid_body_sim.physics.auto import answers
    sel = simulate(load('explorer1'), duration=duration).selection
    assert sel.planned_cost <= 0.1 * sel.predicted_cost, sel.reason
    assert (sel.pilot_steps > 0) == (duration > 100.0), sel.reason
    if duration == 1.0:  # 0.32 ms, all but 6 µs of it fixed: one question, no preference
        assert 'not asked' in sel.reason and sel.prior_cost == answers.PRIOR_BASE + \
            answers.PRIOR_EACH, sel.reason


def test_candidate_cost_bench_measures_every_compiled_candidate():
    """``tools.candidate_costs`` times every candidate but ``exact`` (the calibration times
    it on a triaxial body), free and damped, beside the table's cost; its ratios are the
    bench's to judge, not a test's."""
    from rigid_body_sim.tools import candidate_costs
    rows = candidate_costs.run(steps=1000, log=lambda *_: None)
    assert {r['method'] for r in rows} == {c.name for c in CANDIDATES} - {'exact'}
    assert len(rows) == 2 * (len(CANDIDATES) - 1)
    assert all(r['measured_us'] > 0 and r['table_us'] > 0 for r in rows)


STIFF_SCENE = """/**:
  ros__parameters:
    scene: {{name: stiff_dissipation, description: stiff double-bracket damping}}
    inertia: [1.0, 2.0, 3.0]
/**/attitude_simulator:
  ros__parameters:
    initial_attitude: [0.0, 0.0, 0.0, 1.0]
    initial_angular_velocity: {w}
    dissipation: {{model: double_bracket, coefficient: 1000.0}}
    integrator: auto
    accuracy: 1.0e-9
    publish_rate: 10.0
    duration: 5.0
"""


def test_pilot_on_a_run_short_against_its_polhode_period_costs_less_than_the_run(tmp_path):
    """The stiff bench scene (|L| = 1 started 1e-3 off the major axis, stiffness 667 /s) over
    5 s at 1e-9 rad: its polhode period is ~19 s, and pilots resolving it ran over the
    whole 5 s, predicted at 5.8× the run they chose (measured 21 ms for a 2.4 ms run). A
    pilot's horizon is now at most 2 % of the run's (at least four rotations): the choice
    still meets the budget (against DOP853 at rtol 1e-13) and the predicted pilot is less
    than the predicted run."""
    w = np.array([1e-3, 1e-3, 1.0]) / np.linalg.norm([1e-3, 1e-3, 1.0]) / (1.0, 2.0, 3.0)
    path = tmp_path / 'stiff.yaml'
    path.write_text(STIFF_SCENE.format(w=[float(x) for x in w]))
    scene = load(str(path))
    ref = simulate(scene, integrator='dop853',
                   integrator_options={'rtol': 1e-13, 'atol': 1e-16}).samples['attitude']
    result = simulate(scene)
    from rigid_body_sim.physics import rotation
    err = float(np.max(rotation.angle_between(result.samples['attitude'], ref)))
    assert err <= 1e-9, (result.integrator, result.step, err)
    sel = result.selection
    assert sel.pilot_steps > 0 and sel.pilot_cost < sel.predicted_cost, sel.reason
    # a priori only splitting6 at h = 2e-5 s bounds 1e-9 (a 0.48 s run): the pilot may then
    # spend 10 % of that run, as its rounds could each save ten times their cost; it found
    # a run far cheaper, so it costs more than 10 % of the run it chose (measured 2.2 ms
    # for a 6 ms run), and at most 10 % of the run it saved
    prior = select(RigidBody.from_inertia(np.diag([1.0, 2.0, 3.0])),
                   Dissipation('double_bracket', 1000.0), Q_ID, w, torque=False,
                   accuracy=1e-9, duration=5.0, max_step=0.1, prior_only=True)
    assert 'could save 10× its pilot' in sel.reason
    assert sel.planned_cost <= 0.1 * prior.predicted_cost
    assert sel.predicted_cost < 0.1 * prior.predicted_cost


def test_an_in_process_law_s_instants_cost_what_the_compiled_loop_pays():
    """Slew over 15 s (the selection bench's horizon): the cheapest fixed choice meeting its
    1e-6 rad is rk4 at the control period; auto took splitting4 (1.5× its CPU) because it
    costed every control instant at a Python round trip (17.5 µs), 40× what the compiled
    closed loop pays (model.LAW_EVENT), so the methods' step costs did not count, and a
    geometric method within 10 % won. The law's instants now cost what that loop pays, and
    the choice still meets the budget (against dop853 at rtol 1e-12)."""
    scene = load('slew')
    result = simulate(scene, duration=15.0)
    assert result.integrator == 'rk4', result.reason
    ref = simulate(scene, duration=15.0, integrator='dop853',
                   integrator_options={'rtol': 1e-12, 'atol': 1e-15})
    from rigid_body_sim.physics import rotation
    err = float(np.max(rotation.angle_between(result.samples['attitude'],
                                              ref.samples['attitude'])))
    assert err <= scene.simulator['accuracy'], (err, result.reason)


def test_the_law_s_rate_scale_in_floats_is_numpy_s_to_the_bit():
    """ControlSettings.bandwidth (auto's torque rate scale under the law) computes in plain
    floats (numpy's reductions on 3-vectors were ~9 µs of a ~110 µs selection): the same
    correctly rounded divisions and square roots, so the same value to the bit, on the
    controlled scenes and on generated bodies whose gains are set from kp/kd or
    natural_frequency per axis."""
    from rigid_body_sim.bench import generated_scenes
    settings = [engine_for(load(name), duration=1.0).config.control
                for name in ('default', 'slew', 'detumble')]
    for i in range(80):
        config = engine_for(generated_scenes.draw(20261125, i).scene_file(),
                            duration=1.0).config
        if config.control is not None and config.control.mode != 'bdot':
            settings.append(config.control)
    assert len(settings) > 10
    for cs in settings:
        cfg, i = cs.config, cs.config.body.principal_moments
        numpy_s = float(max(np.max(np.sqrt(cfg.kp_principal / i)), np.max(cfg.kd_principal / i),
                            np.max(cfg.rate_gain_principal / i)))
        assert cs.bandwidth() == numpy_s


def test_a_choice_without_a_pilot_is_made_without_a_generator_and_equals_its_form():
    """``choosing`` returns the Selection itself where no pilot runs (Explorer 1 over 1 s:
    exact's split bound a priori), so the engine makes no generator for it; where pilots
    run (690 s) the generator, which ``selecting`` feeds to the same Selection."""
    from rigid_body_sim.physics.auto.selection import Selection, choosing, selecting
    engine = engine_for(load('explorer1'), duration=1.0)
    c = engine.config
    args = (c.body, c.dissipation, c.attitude, c.angular_velocity)
    for duration, piloted in ((1.0, False), (690.0, True)):
        kw = dict(torque=False, accuracy=c.accuracy, duration=duration, max_step=1.0)
        work = choosing(*args, **kw)
        assert isinstance(work, Selection) != piloted
        if piloted:
            assert select(*args, **kw).pilot_steps > 0
        else:
            gen = selecting(*args, **kw)
            with pytest.raises(StopIteration) as done:
                next(gen)
            assert done.value.value == work and work.name == 'exact'


@pytest.mark.parametrize('blocking', [True, False])
def test_a_failed_selection_runs_splitting2_and_says_why(monkeypatch, blocking):
    """A selection that raises (here made to) leaves the engine on splitting2 at the scene's
    step, its reason naming the failure: made at once (``choosing``) as fed (``selecting``)."""
    from rigid_body_sim.engine import method_choice

    def raising(*args, **kw):
        raise ValueError('no budget here')

    def failing(*args, **kw):  # a generator, as selecting is: raises when fed
        raise ValueError('no budget here')
        yield

    monkeypatch.setattr(method_choice, 'choosing', raising)
    monkeypatch.setattr(method_choice, 'selecting', failing)
    config = engine_for(load('explorer1'), duration=690.0).config
    engine = Engine(config, blocking_selection=blocking)
    while engine.work():
        pass
    assert engine.method == 'splitting2' and not engine.selection_pending
    assert 'selection failed (no budget here)' in engine.reason
