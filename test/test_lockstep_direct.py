"""Lockstep's direct period (``engine.lockstep_direct``): one control period in one compiled
call gives what ``Engine.advance`` gives for it, bit for bit, or declines.

Two engines of one scene take the same commands at every instant; one advances the
general way, the other by ``DirectPeriod.step``. Their states, counters and the sample
values (what the node packs into messages) must be equal to the last bit at every
instant, for every fixed-step method, on bodies whose principal axes are and are not the
body axes, with damping and with an environment's torques (gravity gradient; an orbit's).
"""
import numpy as np
import pytest

from rigid_body_sim.engine import Engine, EngineConfig
from rigid_body_sim.engine.lockstep_direct import DirectPeriod
from rigid_body_sim.scene import load

TILTED = 'inertia=[2.0, 0.1, 0.0, 0.1, 3.0, 0.2, 0.0, 0.2, 4.0]'  # principal ≠ body axes


def _engines(scene, method, rate=100.0, overrides=()):
    p = dict(load(scene, list(overrides) + [
        f'integrator={method}', f'publish_rate={rate}', 'duration=30',
        'real_time_factor=0']).simulator)
    config = EngineConfig.from_parameters(p)
    return (Engine(config, blocking_selection=False),
            Engine(config, blocking_selection=False))


def _state(e):
    c = e.command
    return (e._q.tolist(), e._m.tolist(), e.t_ns, e._next_sample, e.steps,
            e.integrator.nfev, None if e.torque is None else e.torque.tolist(),
            None if e._tau_p is None else e._tau_p.tolist(), e.torque is c.torque,
            c.accepted, c.saturated, c.expiry, e._anchor is None)


@pytest.mark.parametrize('scene, method, overrides', [
    ('slew', 'splitting4', ()), ('slew', 'splitting4', (TILTED,)),
    ('slew', 'rk4', (TILTED,)), ('slew', 'euler', ()), ('slew', 'splitting2', ()),
    ('slew', 'splitting6', ()), ('slew', 'splitting2_lstable', ()), ('slew', 'exact', ()),
    ('explorer1', 'splitting4', ()), ('explorer1', 'exact', ()),
    ('gravity_gradient', 'rk4', ()), ('gravity_gradient', 'splitting4', ()),
    ('explorer1_orbit', 'splitting4', ())])
def test_a_direct_period_is_the_general_one_bit_for_bit(scene, method, overrides):
    general, direct = _engines(f'config/{scene}.yaml', method, overrides=overrides)
    period = 10_000_000
    general.advance(0)
    direct.advance(0)
    stepped = DirectPeriod(direct)
    rng = np.random.default_rng(7)
    used = 0
    for k in range(150):
        # every seventh command zero (no torque held: exact's free flow declines), every
        # fifth beyond max_torque on an axis (clipped, counted)
        command = tuple(rng.uniform(-0.01, 0.01, 3)) if k % 7 else (0.0, 0.0, 0.0)
        if k % 5 == 4:
            command = (command[0] * 1e4,) + command[1:]
        general.apply_command(command)
        direct.apply_command(tuple(float(v) for v in command))  # as sim_lockstep does
        assert _state(direct) == _state(general), k
        block = general.advance((k + 1) * period)
        assert len(block) == 1
        values = stepped.step((k + 1) * period)
        if values is None:
            values = direct.advance((k + 1) * period).values(0)
        else:
            used += 1
        assert values == block.values(0), k
        assert _state(direct) == _state(general), k
    # exact's torque-free flow (no damping: slew) is the closed form, evaluated from an
    # anchor: the general way's (the 22 zero commands); every other period is direct
    assert used == (128 if (scene, method) == ('slew', 'exact') else 150), used


def test_a_period_that_is_not_one_plain_stretch_is_declined():
    """dop853 (its step in progress is carried between calls), a sample that is not the
    next instant, the run's end (finished there), a command that expires within the
    period, an in-process law: None, the engine untouched."""
    general, _ = _engines('config/slew.yaml', 'dop853')
    general.advance(0)
    general.apply_command((0.01, 0.0, 0.0))
    before = _state(general)
    assert DirectPeriod(general).step(10_000_000) is None and _state(general) == before
    engine, _ = _engines('config/slew.yaml', 'splitting4')
    engine.advance(0)
    engine.apply_command((0.01, 0.0, 0.0))
    direct, before = DirectPeriod(engine), _state(engine)
    assert direct.step(20_000_000) is None  # the sample at 10 ms comes first
    assert direct.step(engine.end_ns) is None  # (and the end is the general way's)
    assert _state(engine) == before
    engine.command.expiry = 5_000_000
    before = _state(engine)
    assert direct.step(10_000_000) is None and _state(engine) == before
    engine.command.expiry = 10_000_000  # expiring at the instant: the general way too
    before = _state(engine)
    assert direct.step(10_000_000) is None and _state(engine) == before
    law = Engine(EngineConfig.from_parameters(
        {'integrator': 'splitting4', 'duration': 1.0, 'publish_rate': 100.0},
        {'mode': 'slew', 'target_attitude': [0.0, 0.0, 0.6, 0.8]}))
    law.advance(0)
    assert DirectPeriod(law).step(10_000_000) is None and law.t_ns == 0
