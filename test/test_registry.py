"""Every method's facts live on its class, and the rest of the package reads them there:
``auto``'s candidates, the stability check, the closed loop's codes and the warm-up."""
import cmath
import pkgutil

import numpy as np
import pytest

from rigid_body_sim.physics import Dissipation, Dynamics, integrators
from rigid_body_sim.physics.auto import CANDIDATES
from rigid_body_sim.physics.integrators import INTEGRATORS, KINDS
from rigid_body_sim.physics.integrators.stability import STABILITY_FUNCTIONS

pytestmark = pytest.mark.fast  # make check


def test_auto_chooses_among_the_registered_methods_by_their_own_facts():
    stated = {name: cls for name, cls in INTEGRATORS.items() if cls.auto is not None}
    assert [c.name for c in CANDIDATES] == list(stated)
    for c in CANDIDATES:
        cls = stated[c.name]
        assert (c.cost, c.k, c.call, c.stages) == (cls.auto.cost, cls.auto.k, cls.auto.call,
                                                    cls.stages)


@pytest.mark.parametrize('name', list(INTEGRATORS))
def test_each_method_states_its_order_per_kind_of_dynamics(name):
    """``orders`` covers every kind; ``order_on`` (what auto asks) agrees with it on weak
    damping, where the tests measure the orders (test_integrators)."""
    cls = INTEGRATORS[name]
    assert set(cls.orders) == set(KINDS), name
    assert all(p is None or p >= 1 for p in cls.orders.values())
    for model in ('double_bracket', 'viscous'):
        dyn = Dynamics(np.array([1.0, 2.0, 3.0]), Dissipation(model, 1e-3))
        if cls.orders[model] is not None:
            assert cls.order_on(dyn, 1.0, 0.01) == cls.orders[model], (name, model)


def test_the_stability_check_uses_each_methods_own_stability_function():
    """R(z) of a method of order p matches e^z to O(z^(p+1)) (a wrong function would not)."""
    assert set(STABILITY_FUNCTIONS) == {n for n, c in INTEGRATORS.items()
                                        if c.amplification is not None} >= {'euler', 'rk4'}
    for name, R in STABILITY_FUNCTIONS.items():
        p = INTEGRATORS[name].orders['torque_free']
        z1, z2 = 0.02j, 0.01j
        ratio = abs(R(z1) - cmath.exp(z1)) / abs(R(z2) - cmath.exp(z2))
        assert abs(np.log2(ratio) - (p + 1)) < 0.1, (name, ratio)


def test_the_closed_loop_codes_are_the_methods_own():
    """The compiled closed loop dispatches 0 splitting, 1 RK4, 2 Euler, 3 dop853, 4 exact's
    split steps (its names for them); methods without a code (None) run event by event."""
    from rigid_body_sim.engine import closed_loop
    codes = {n: c.loop_code for n, c in INTEGRATORS.items() if c.loop_code is not None}
    assert codes == {'splitting2': 0, 'splitting4': 0, 'splitting6': 0,
                     'splitting2_lstable': 0, 'rk4': 1, 'euler': 2, 'dop853': 3, 'exact': 4}
    assert (closed_loop.SPLITTING, closed_loop.RK4, closed_loop.EULER, closed_loop.DOP853,
            closed_loop.EXACT) == (0, 1, 2, 3, 4)


def test_every_compiled_loop_module_is_warmed_through_a_registered_method():
    warmed = {m.__name__.rsplit('.', 1)[1] for c in INTEGRATORS.values()
              for m in c.kernel_modules}
    loops = {m.name for m in pkgutil.iter_modules(integrators.__path__)
             if m.name.endswith(('_kernel', '_dense'))}
    assert loops <= warmed
    for cls in INTEGRATORS.values():
        assert all(callable(m.warm) for m in cls.kernel_modules), cls.name


def test_the_closed_loop_and_the_splittings_share_one_inner_damping_rule():
    """Damping goes inside a composition's stages by one rule (splitting_kernel), which the
    classes and the engine's compiled closed loop both call: no copy of it, or of its limit,
    lives in the closed loop, and the compiled rule answers as the class does."""
    from rigid_body_sim.engine import closed_loop
    from rigid_body_sim.physics.integrators import splitting_kernel
    src = open(closed_loop.__file__).read()
    assert 'INNER_LIMIT' not in src and 'def _inner' not in src
    assert 'splitting_kernel.inner_dissipation' in src
    rng = np.random.default_rng(3)
    for model, coefficient in (('double_bracket', 0.4), ('viscous', 0.7)):
        dyn = Dynamics(np.array([1.0, 2.0, 3.0]), Dissipation(model, coefficient))
        for name in ('splitting2', 'splitting4', 'splitting6'):
            integ = INTEGRATORS[name](dyn)
            weights, _ = integ.loop_spec()
            seen = set()
            for h in np.geomspace(1e-3, 3.0, 40):
                m = rng.normal(size=3)
                ours = integ.inner_dissipation(m, h)
                seen.add(ours)
                assert ours == bool(splitting_kernel.inner_dissipation(
                    m, h, weights, dyn.moments, 1 if model == 'double_bracket' else 2,
                    coefficient)), (name, model, h)
            assert seen == ({False} if name == 'splitting2' else {True, False}), (name, model)


def test_the_gyrostat_is_a_registered_method_that_needs_actuators():
    """The method of scenes with wheels/CMGs is in the registry, warmed through it, and
    states that it needs actuators; the engine uses it by that fact and steps it as any
    other method (its integrator, its evaluations), and it refuses to run without them."""
    from rigid_body_sim.engine import Engine, EngineConfig
    from rigid_body_sim.physics.integrators import BODY_ONLY
    carried = [n for n, c in INTEGRATORS.items() if c.requires_actuators]
    assert carried == ['gyrostat_strang'] and 'gyrostat_strang' not in BODY_ONLY
    assert integrators.gyrostat_kernel in INTEGRATORS['gyrostat_strang'].kernel_modules
    with pytest.raises(ValueError, match='gyrostat_strang needs the scene.s actuators'):
        INTEGRATORS['gyrostat_strang'](Dynamics(np.array([1.0, 2.0, 3.0])))
    config = EngineConfig.from_parameters({
        'duration': 0.5, 'publish_rate': 10.0, 'integrator': 'rk4', 'step': 0.01,
        'actuators.wheels.axes': [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]})
    engine = Engine(config)
    for _ in engine.run():
        pass
    assert type(engine.integrator) is INTEGRATORS['gyrostat_strang']
    assert engine.method == 'gyrostat_strang' and engine.steps == 50
    assert engine.integrator.nfev == 50 and engine.total_evaluations == 50
