"""B-dot detumbling: the law's arithmetic, and |ω| decaying under it in closed loop within
the orbits its averaged dynamics predict (offline, compiled and plain)."""
import math
import os

import numpy as np
import pytest

from rigid_body_sim import bdot
from rigid_body_sim.engine import EngineConfig, SampleBlock
from rigid_body_sim.engine.config import ControlSettings
from rigid_body_sim.engine.core import Engine
from rigid_body_sim.physics import orbit
from rigid_body_sim.scene import load

pytestmark = pytest.mark.fast  # make check


def test_the_law_differences_consecutive_readings_and_clips_per_rod():
    law = bdot.Bdot(2.0e-5, [0.2, 0.2, 0.2])
    assert law.update(10.0, [2e-5, 0.0, 1e-5]) is None  # nothing to difference yet
    m = law.update(10.5, [2.2e-5, -1e-6, 1e-5])
    b = np.array([2.2e-5, -1e-6, 1e-5])
    rate = (b - [2e-5, 0.0, 1e-5]) / 0.5
    np.testing.assert_allclose(m, -2.0e-5 * rate / (b @ b), rtol=1e-12)
    assert law.saturated == 0
    assert law.update(10.5, b) is None  # a repeated instant: no difference
    big = law.update(11.0, b + [6e-6, 0.0, -1e-7])
    assert big[0] == -0.2 and 0.0 < big[2] < 0.2 and law.saturated == 1
    # dissipative: each rod opposes Ḃ's component, clipped or not
    assert np.all(big * np.array([6e-6, 0.0, -1e-7]) <= 0.0)


def test_the_avanzini_giulietti_gain():
    n = math.sqrt(orbit.MU / 6878137.0 ** 3)
    assert bdot.avanzini_giulietti_gain(n, math.pi / 2, 0.01) == pytest.approx(4 * n * 0.01)
    assert bdot.avanzini_giulietti_gain(n, 0.0, 0.01) == pytest.approx(2 * n * 0.01)
    gain = bdot.gain_from_parameters({'bdot.gain': 0.0, 'bdot.orbit_rate': n,
                                      'bdot.magnetic_inclination': 1.0}, 0.02)
    assert gain == pytest.approx(2 * n * (1 + math.sin(1.0)) * 0.02)
    with pytest.raises(ValueError, match='bdot.gain: mode bdot needs a gain'):
        ControlSettings.from_parameters({'mode': 'bdot', 'inertia': [0.03, 0.025, 0.01]})


def detumble(duration=None, **simulator):
    """The bdot_detumble scene's engine (its in-process B-dot), with overrides."""
    scene = load('bdot_detumble')
    p = dict(scene.simulator, **simulator)
    if duration is not None:
        p['duration'] = duration
    config = EngineConfig.from_parameters(p, scene.controller)
    return scene, Engine(config)


def predicted_orbits(scene) -> float:
    """Orbits from |ω0| to 0.5 °/s by the averaged closed loop (Avanzini & Giulietti 2012,
    §III): with Ḃ ≈ B × ω the torque is −k(ω − (b̂·ω)b̂), and over a tumble the field's
    direction in body axes averages to ⟨b̂b̂ᵀ⟩ = 1/3, so each principal rate decays as
    e^{−(2/3)(k/I_i)t}; the slowest, about the major axis, sets the time:
    ln(|ω0|/0.5°/s)/((2/3)k/I_max). Saturation (the rods' 0.2 A·m²) only slows the start."""
    c = scene.controller
    moments = np.array(scene.simulator['inertia'], float)
    k = bdot.avanzini_giulietti_gain(c['bdot.orbit_rate'], c['bdot.magnetic_inclination'],
                                     moments.min())
    rate = 2.0 / 3.0 * k / moments.max()
    w0 = np.linalg.norm(scene.simulator['initial_angular_velocity'])
    seconds = math.log(w0 / math.radians(0.5)) / rate
    return seconds * c['bdot.orbit_rate'] / (2 * math.pi)


@pytest.mark.slow
def test_bdot_detumbles_within_the_predicted_orbits():
    """From 10 °/s to below 0.5 °/s within the prediction (0.54 orbit; measured 0.58 with
    the scene's noise and saturation: within 1.5×, and not implausibly sooner), then held
    near the residual of about 2n that B-dot leaves (the field turns at ~2n)."""
    scene, engine = detumble()
    prediction = predicted_orbits(scene)
    assert 0.4 < prediction < 0.7
    block = SampleBlock.concatenate(list(engine.run()))
    n = scene.controller['bdot.orbit_rate']
    orbits = block.t * n / (2 * math.pi)
    rate = np.linalg.norm(block.angular_velocity, axis=1)
    below = np.nonzero(rate < math.radians(0.5))[0]
    assert len(below), f'never below 0.5 deg/s: last {math.degrees(rate[-1]):.3g} deg/s'
    crossed = orbits[below[0]]
    assert 0.5 * prediction < crossed < 1.5 * prediction, (crossed, prediction)
    after = rate[orbits > 1.5 * prediction]
    assert after.max() < math.radians(0.5) and 0.5 * n < np.median(after) < 4.0 * n
    law = engine.magnetics.law.law
    assert law.saturated > 0  # the rods' limit acted at the start
    # without the law (rods never commanded) the body keeps its momentum: a free tumble
    free = Engine(EngineConfig.from_parameters(dict(scene.simulator, duration=600.0)))
    end = SampleBlock.concatenate(list(free.run()))
    h = np.linalg.norm(end.angular_momentum, axis=1)
    assert abs(h[-1] / h[0] - 1.0) < 1e-9


_SCRIPT = '''
import json, sys
sys.path.insert(0, %r)
import numpy as np
import test_bdot as t
from rigid_body_sim.engine import SampleBlock
from rigid_body_sim.physics import jit
scene, engine = t.detumble(duration=120.0)
block = SampleBlock.concatenate(list(engine.run()))
print(json.dumps({"compiled": jit.COMPILED, "method": engine.method,
                  "w": block.angular_velocity[-1].tolist(),
                  "w0": block.angular_velocity[0].tolist()}))
'''


@pytest.mark.slow
def test_compiled_and_plain_bdot_loops_agree():
    """Two minutes of the closed loop, compiled and as plain Python: the same states to
    round-off, and the rate fell."""
    from jit_modes import run_both
    compiled, plain = run_both(_SCRIPT % os.path.dirname(os.path.abspath(__file__)))
    assert compiled['compiled'] is True and plain['compiled'] is False
    assert compiled['method'] == plain['method']
    np.testing.assert_allclose(plain['w'], compiled['w'], rtol=0, atol=1e-12)
    assert np.linalg.norm(compiled['w']) < 0.97 * np.linalg.norm(compiled['w0'])


def test_the_mission_hands_over_from_bdot_to_the_torque_law_below_the_exit_rate():
    """mission.detumble_exit_rate in bdot: once |ω| is below it the controller switches to
    slew (the torque law); the rods rest from then on."""
    scene = load('bdot_detumble')
    p = dict(scene.simulator, duration=300.0, initial_angular_velocity=[0.02, -0.01, 0.015])
    controller = dict(scene.controller, **{'mission.detumble_exit_rate': 0.022})
    engine = Engine(EngineConfig.from_parameters(p, controller))
    assert engine.magnetics.law is not None
    block = SampleBlock.concatenate(list(engine.run()))
    assert engine._law.controller.mode == 'slew'
    assert engine.magnetics.law.dipole is None and not engine.magnetics.dipole().any()
    assert np.abs(block.torque).max() > 0.0  # the torque law acted after the switch
