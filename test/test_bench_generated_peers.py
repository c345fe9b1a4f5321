"""scipy on the generated scenes (bench/generated_peers.py): the peer integrates the scene's
own physics, so a ratio compares the same thing."""
from dataclasses import replace

import numpy as np
import pytest

from rigid_body_sim.bench import generated, generated_peers as gp, oracle
from rigid_body_sim.physics import rotation

pytestmark = pytest.mark.fast


def _first(kind, quick=True):
    """The scene of ``kind`` that turns the least among the first 40 (the cheapest)."""
    return min((s for s in (generated.draw(generated.SEED, i, quick) for i in range(40))
                if s.kind == kind), key=lambda s: s.rotation)


@pytest.mark.parametrize('kind', ['free', 'double_bracket', 'viscous'])
def test_the_peer_at_a_tight_tolerance_is_the_reference(kind):
    """At rtol 1e-12 scipy's DOP853 lands on the reference at every sample; a peer with
    the dissipation left out (the model mis-mapped) is off by far more."""
    scene = _first(kind)
    ref = oracle.reference(scene)
    result, _ = oracle.timed(scene.scene_file())
    times = result.samples['t']
    assert times[-1] == pytest.approx(scene.duration, abs=1e-9)
    assert len(times) == len(ref.attitude)
    _, q = gp.peer_run(scene, 'DOP853', 1e-12, times)
    err = float(np.max(rotation.angle_between(q, ref.attitude)))
    assert err < 1e-6, err
    if kind != 'free':
        _, q_free = gp.peer_run(replace(scene, kind='free'), 'DOP853', 1e-12, times)
        assert float(np.max(rotation.angle_between(q_free, ref.attitude))) > 100 * err


def test_a_peer_that_cannot_meet_the_budget_is_a_lower_bound():
    """With no rtol fine enough (a budget under the ladder's reach) the sweep returns no
    rtol and the CPU of its last run, which the row reports as a lower bound."""
    scene = _first('viscous')
    ref = oracle.reference(scene)
    times = oracle.timed(scene.scene_file())[0].samples['t']
    scene = replace(scene, budget=1e-16)  # past any scene's range: the sweep's own check
    rtol, c, err = gp.peer_sweep(scene, 'RK45', ref, times, cap=0.05)
    assert rtol is None and c > 0 and err > scene.budget
