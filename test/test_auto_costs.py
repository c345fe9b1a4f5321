"""auto's per-step costs calibrated on the machine (physics/auto/calibration.py): the cache is
written, read and keyed; auto's cost model uses its ratios (clamped); without one it uses
the classes' constants and says so. No timing is asserted: calibrations are injected."""
import json
import os

import numpy as np
import pytest

from rigid_body_sim.physics import jit
from rigid_body_sim.physics.auto import CANDIDATES, calibration, select
from rigid_body_sim.physics.auto.model import RunModel
from rigid_body_sim.physics.body import RigidBody
from rigid_body_sim.physics.dynamics import Dissipation, Dynamics

pytestmark = pytest.mark.fast

MOMENTS = [0.04, 0.2, 0.2]
EXPLORER_I = np.diag(MOMENTS)
EXPLORER_W = [62.83, 1.1, 0.0]  # rad/s, body frame
Q_ID = [0.0, 0.0, 0.0, 1.0]
OWN = {c.name: c.cost for c in CANDIDATES}


def record(ratios=None, **changes):
    """A calibration record with every candidate at its class constant's ratio (a machine
    exactly like the one the constants were measured on), ``ratios`` overriding."""
    unit = OWN['splitting2'][0]
    rows = {n: {'free': c[0] / unit, 'double_bracket': c[1] / unit,
                'viscous': c[0] * calibration.VISCOUS_FACTOR / unit if n == 'splitting2'
                else c[1] / unit} for n, c in OWN.items() if n != 'exact'}
    for name, value in (ratios or {}).items():
        rows[name].update(value)
    rec = {'key': calibration.key(), 'cpu': 'Test CPU 9000', 'reference': 'splitting2',
           'ratios': rows}
    rec.update(changes)
    return rec


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """The cache at a temporary path, auto's env override off, nothing read yet; compiled
    mode (under NUMBA_DISABLE_JIT too: an injected calibration stands for a compiled one)."""
    path = tmp_path / 'numba_cache' / calibration.FILE_NAME
    monkeypatch.setattr(calibration, 'cache_path', lambda: str(path))
    monkeypatch.delenv(calibration.ENV, raising=False)
    monkeypatch.setattr(jit, 'COMPILED', True)
    calibration.current.cache_clear()
    yield path
    calibration.current.cache_clear()


def explorer_choice():
    """Explorer 1 damped, 1e-3 rad over 10 s (rk4 with the class constants; 4× dearer, it
    loses to dop853)."""
    return select(RigidBody.from_inertia(EXPLORER_I), Dissipation('double_bracket', 1e-3),
                  Q_ID, EXPLORER_W, torque=False, accuracy=1e-3, duration=10.0,
                  max_step=1.0, prior_only=True)


def test_calibration_times_every_compiled_candidate_and_round_trips(tmp_path):
    cache = tmp_path / calibration.FILE_NAME
    rec = calibration.calibrate(steps=200, repeats=1)
    if not jit.COMPILED:
        assert rec is None  # Python loops say nothing of the compiled cost
        return
    assert set(rec['ratios']) == set(OWN)  # exact too: its split steps are compiled
    assert all(set(r) == set(calibration.KINDS) and min(r.values()) > 0
               for r in rec['ratios'].values())
    assert rec['ratios']['splitting2']['free'] == 1.0 and rec['key'] == calibration.key()
    calibration.save(rec, str(cache))
    assert json.loads(cache.read_text()) == rec
    assert calibration.load(str(cache)) == (rec, '')


def test_the_calibration_keeps_the_closed_loops_event_cost_as_a_ratio(tmp_path):
    rec = calibration.calibrate(steps=200, repeats=1, events=lambda: 0.25)
    if rec is None:  # NUMBA_DISABLE_JIT: nothing compiled to time
        return
    assert rec['event_us'] == 0.25
    assert rec['event'] == pytest.approx(0.25 / rec['measured_us']['splitting2']['free'])


def test_an_uncommanded_run_costs_its_events_at_the_calibrated_closed_loop_figure(cache):
    """The event-by-event constant (15 µs and the method's call) was 100× the compiled
    closed loop's (0.08–0.2 µs measured): it drowned the per-step costs, and within its 10 %
    preference for a geometric method auto took splitting4 at 3× dop853's CPU on generated
    orbit scenes. Commanded runs (or an environment re-made per event) keep it."""
    from rigid_body_sim.physics.auto import model
    unit = OWN['splitting2'][0]
    calibration.save(record(event=0.5), str(cache))
    assert calibration.current().event == pytest.approx(0.5 * unit)
    rk4 = next(c for c in CANDIDATES if c.name == 'rk4')
    dyn = Dynamics(np.array(MOMENTS), Dissipation('viscous', 1e-3))
    m = np.array([2.5, 0.04, 0.0])
    free = RunModel(dyn, None, m, 1e-6, 100.0, 0.01, 0.0)
    held = RunModel(dyn, None, m, 1e-6, 100.0, 0.01, 0.0, commanded=True)
    assert free.per_event(rk4) == pytest.approx(0.5 * unit * 1e-6)
    assert held.per_event(rk4) == pytest.approx(model.EVENT_COST + rk4.call[1] * 1e-6)
    steps = free.events * 10
    assert free.run_cost(rk4, 0.001) == pytest.approx(
        model.RUN_COST + free.events * 0.5 * unit * 1e-6 + steps * free.step_cost(rk4, 0.001))
    unknown = RunModel(dyn, None, m, 1e-6, 100.0, 0.01, 0.0, costs=calibration.Costs())
    assert unknown.per_event(rk4) == held.per_event(rk4)  # not calibrated: the constant


def test_the_cache_sits_beside_numbas_cache_of_the_kernels():
    """In the directory where numba keeps the reference method's compiled loop (its index
    files), so that clearing numba's cache clears the calibration with it."""
    from rigid_body_sim.physics.integrators import create
    create('splitting2', Dynamics(np.array(MOMENTS))).run(Q_ID, [1.0, 0.0, 0.0], 0.1, 2)
    where = calibration.cache_dir()
    assert calibration.cache_path() == os.path.join(where, calibration.FILE_NAME)
    if jit.COMPILED:
        assert any(f.startswith('splitting_kernel.') and f.endswith('.nbi')
                   for f in os.listdir(where)), where


def test_a_changed_kernel_source_or_cpu_changes_the_key(tmp_path, monkeypatch):
    kernel = tmp_path / 'some_kernel.py'
    kernel.write_text('x = 1\n')
    monkeypatch.setattr(calibration, 'kernel_files', lambda: [str(kernel)])
    keys = []
    for change in (lambda: None, lambda: kernel.write_text('x = 2\n'),
                   lambda: monkeypatch.setattr(calibration, 'cpu_model', lambda: 'Other CPU')):
        change()
        calibration.key.cache_clear()
        keys.append(calibration.key())
    calibration.key.cache_clear()
    assert len(set(keys)) == 3


def test_the_key_covers_the_engines_compiled_loop_and_how_events_are_timed():
    """The calibration holds the cost of an event in the engine's compiled loop
    (engine/event_cost.py): a change to that loop or to its timing makes it stale."""
    import rigid_body_sim.engine.closed_loop as closed_loop
    import rigid_body_sim.engine.event_cost as event_cost
    files = calibration.kernel_files()
    for module in (closed_loop, event_cost):
        assert os.path.abspath(module.__file__) in files


def test_a_stale_cache_is_not_used_and_ensure_recalibrates(cache, monkeypatch):
    calibration.save(record(key='kernels of another day'), str(cache))
    assert calibration.load() == (None, 'calibration stale (kernels or CPU changed)')
    assert 'calibration stale' in calibration.current().source
    fresh = record(cpu='Fresh CPU')
    calls = []
    monkeypatch.setattr(calibration, 'calibrate', lambda **kw: calls.append(1) or fresh)
    assert calibration.ensure(log=lambda *_: None) == fresh and calls == [1]
    assert json.loads(cache.read_text()) == fresh
    assert calibration.ensure(log=lambda *_: None) == fresh and calls == [1]  # current: kept
    assert calibration.current().source == 'costs calibrated on Fresh CPU'


def test_auto_costs_a_run_with_the_calibrated_ratios(cache):
    """rk4 measured at half splitting2's free cost: the model's step cost is that ratio times
    splitting2's constant; splitting2's damping substep comes from its damped ratio."""
    unit = OWN['splitting2'][0]
    calibration.save(record({'rk4': {'free': 0.5, 'double_bracket': 0.55},
                             'splitting2': {'double_bracket': 2.0}}), str(cache))
    costs = calibration.current()
    assert costs.source == 'costs calibrated on Test CPU 9000'
    rk4 = next(c for c in CANDIDATES if c.name == 'rk4')
    free = RunModel(Dynamics(np.array([0.04, 0.2, 0.2])), None, np.array([2.5, 0.04, 0.0]),
                    1e-6, 10.0, 0.1, 1.0)
    assert free.step_cost(rk4, 0.01) == pytest.approx(0.5 * unit * 1e-6)
    assert costs.damp_substep == pytest.approx((2.0 - 1.0) * unit / 2)


def test_calibrated_costs_are_clamped_to_within_4x_of_the_class_constant(cache):
    """A calibration under load (one method preempted through all its repeats) moves a cost
    at most CLAMP from its class constant."""
    calibration.save(record({'rk4': {'free': 1000.0, 'double_bracket': 1e-6},
                             'splitting2': {'viscous': 50.0}}), str(cache))
    costs = calibration.current()
    rk4 = next(c for c in CANDIDATES if c.name == 'rk4')
    assert costs.cost(rk4) == pytest.approx((4 * OWN['rk4'][0], 0.25 * OWN['rk4'][1]))
    assert costs.viscous_factor == pytest.approx(4 * calibration.VISCOUS_FACTOR)


def test_auto_choice_follows_a_calibration_that_makes_its_method_dear(cache):
    """The method chosen with the class constants, measured 4× dearer than its constant on
    this machine, is no longer chosen; the reason names the calibration."""
    with_constants = explorer_choice()
    assert 'class-constant costs (not calibrated' in with_constants.reason
    unit = OWN['splitting2'][0]
    name = with_constants.name
    dear = {'free': 4 * OWN[name][0] / unit, 'double_bracket': 4 * OWN[name][1] / unit}
    if name == 'splitting2':  # the reference: every other method 4× cheaper instead
        calibration.save(record({n: {'free': c[0] / 4 / unit, 'double_bracket': c[1] / 4 / unit}
                                 for n, c in OWN.items() if n not in ('exact', name)}),
                         str(cache))
    else:
        calibration.save(record({name: dear}), str(cache))
    calibration.current.cache_clear()
    calibrated = explorer_choice()
    assert 'costs calibrated on Test CPU 9000' in calibrated.reason
    assert calibrated.name != name, (with_constants.reason, calibrated.reason)


def test_without_a_calibration_auto_says_it_uses_the_class_constants(cache, monkeypatch):
    costs = calibration.current()
    assert costs.per_step == {} and costs.damp_substep is None and 'not calibrated' in \
        costs.source
    assert 'class-constant costs (not calibrated' in explorer_choice().reason
    monkeypatch.setattr(jit, 'COMPILED', False)  # NUMBA_DISABLE_JIT: nothing to calibrate
    calibration.current.cache_clear()
    calibration.save(record(), str(cache))       # even with a cache: uncompiled runs differ
    assert calibration.current().source == 'class-constant costs (kernels not compiled)'
    assert calibration.calibrate(steps=10, repeats=1) is None
    monkeypatch.setenv(calibration.ENV, 'constants')
    calibration.current.cache_clear()
    assert 'RIGID_BODY_SIM_AUTO_COSTS=constants' in calibration.current().source



def test_the_setup_and_the_benchmarks_calibrate_with_the_cost_of_an_event(monkeypatch):
    """What `python -m rigid_body_sim.compiled` does (compiled.setup), and every benchmark
    that runs auto starts with: the kernels warm, then the calibration ensured with the
    engine's measured event cost (a stale one left auto on class constants: seed 20261125's
    gen-19 took rk4 at 1.9x the CPU of the dop853 it takes when calibrated)."""
    import inspect

    from rigid_body_sim import compiled
    from rigid_body_sim.bench import generated, generated_peers, sampling
    from rigid_body_sim.engine import event_cost
    calls = []
    monkeypatch.setattr(compiled, 'warm', lambda: calls.append('warm') or True)
    monkeypatch.setattr(compiled, '_warm_scenes_once', lambda: calls.append('scenes'))
    monkeypatch.setattr(calibration, 'ensure',
                        lambda log=print, events=None: calls.append(events))
    assert compiled.setup() is True
    assert calls == ['warm', 'scenes', event_cost.measure]
    for module in (generated, generated_peers, sampling):
        source = inspect.getsource(module)
        assert 'compiled.setup()' in source and 'compiled.warm()' not in source, module


@pytest.mark.parametrize('damping', [Dissipation(), Dissipation('double_bracket', 0.05),
                                     Dissipation('viscous', 0.02)],
                         ids=['free', 'double_bracket', 'viscous'])
@pytest.mark.parametrize('viscous_factor', [0.6, 1.3])
def test_the_least_step_cost_is_never_above_a_step_s_cost(damping, viscous_factor):
    """law_pilot.plans skips a candidate whose run at one step per event at this cost per
    step cannot beat the best: a bound above some step's cost would change a choice. Each
    branch of step_cost (the damping inside or outside a composition, substeps, a viscous
    factor below 1 from a calibration) at steps from the event spacing down, to the bit."""
    body_m = np.array([0.04, 0.2, 0.21])
    costs = calibration.Costs(viscous_factor=viscous_factor)
    for stiff in (1.0, 1e4):  # the substeps' count and the order inside depend on it
        dyn = Dynamics(body_m, damping if not damping.active else
                       Dissipation(damping.model, damping.coefficient * stiff))
        s = RunModel(dyn, None, body_m * np.array([50.0, 1.0, 0.5]), 1e-6, 10.0, 0.1, 0.0,
                     costs=costs)
        for c in CANDIDATES:
            least = s.least_step_cost(c)
            steps = [s.snap(0.1 / 1.7 ** k) for k in range(30)]
            assert all(least <= s.step_cost(c, h) for h in steps), (c.name, least)
            # tight: some step costs exactly that where the damping takes one branch
            if not damping.active:
                assert least == s.step_cost(c, 0.1)
