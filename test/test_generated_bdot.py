"""The generalisation suite's B-dot family (bench/generated_bdot.py): scenes a user could
write, drawn reproducibly, whose runs detumble through the rods."""
import math

import numpy as np
import pytest

from rigid_body_sim.bench import generated, generated_bdot
from rigid_body_sim.offline import simulate
from rigid_body_sim.scene import load

pytestmark = pytest.mark.fast


def test_scenes_are_reproducible_and_apart_from_the_other_families():
    a, b = (generated_bdot.draw(7, 3, True) for _ in range(2))
    assert a == b and a.kind == 'bdot' and a.name == 'gen7-bdot3'
    assert generated_bdot.draw(7, 4, True) != a
    assert generated.draw_gravity_gradient(7, 3, True).name != a.name
    sim, ctl = a.parameters()
    assert ctl['mode'] == 'bdot' and sim['magnetometer.enabled'] is True
    assert not sim['environment.gravity_gradient']
    assert a.duration * a.publish_rate % 1.0 != 0.0  # off the sample grid


def test_a_drawn_scene_as_a_params_file_runs_and_the_rods_slow_the_tumble(tmp_path):
    """Written as a params file (what a user would run) and run to its end: the rods act
    from the start, and the rate falls (B-dot takes kinetic energy out)."""
    scene = min((generated_bdot.draw(generated.SEED, i, True) for i in range(6)),
                key=lambda s: s.duration)
    f = load(scene.write_params_file(str(tmp_path / 'bdot.yaml')))
    result = simulate(f, integrator='rk4', step=0.1)
    t = result.samples['t']
    assert t[-1] == pytest.approx(scene.duration, abs=1e-9)
    energy = result.samples['kinetic_energy']
    assert energy[-1] < energy[0] * (1.0 - 1e-6)
    assert np.all(np.diff(energy) <= 1e-9 * energy[0])  # dissipative, up to round-off
    assert not math.isnan(energy[-1])
