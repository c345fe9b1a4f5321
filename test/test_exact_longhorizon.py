"""exact (float64) against the 40-digit reference at t = 1e3 s and 1e6 s on every
torque-free scene: ≤ 1e-12 rad and ≤ 1e-9 rad (the issue's targets), and |Δm|/|m| alike.

The reference starts from the same float64 numbers, so the errors are exact.py's own. The
near-separatrix scenes (intermediate_axis, config/tennis_racket) were the misses (1.2e-9 and
5.5e-9 rad at 1e6 s, from Π(−N|k²) and the rates in float64); measured now ≤ 2e-12.
"""
import numpy as np
import pytest

from rigid_body_sim.bench.exact_horizon import HORIZONS, case, cases, measure
from rigid_body_sim.bench.reference40 import Reference40, attitude_error, vector_error
from rigid_body_sim.physics.exact import TorqueFreeSolution

pytestmark = pytest.mark.fast
NAMES = ['intermediate_axis', 'tumble', 'symmetric_top', 'config/tennis_racket',
         'config/symmetric_top', 'config/rigid_earth']


def test_every_torque_free_scene_is_covered():
    assert sorted(c.name for c in cases()) == sorted(NAMES)


@pytest.mark.parametrize('name', NAMES)
def test_exact_meets_the_long_horizon_targets(name):
    """Scalar path (the engine's: one body, one time)."""
    for row in measure(case(name)):
        assert row['attitude_error'] <= row['required'], row
        assert row['momentum_error'] <= row['required'], row


@pytest.mark.parametrize('name', NAMES)
def test_vectorised_path_too(name):
    """The vectorised path (several times at once) meets the same targets."""
    c = case(name)
    ref = Reference40(c.moments, c.q0, c.m0)
    ts = np.array([t for t, _ in HORIZONS])
    q, m = TorqueFreeSolution(c.moments, c.q0, c.m0).at(ts)
    g = float(np.linalg.norm(c.m0))
    for (t, required), qi, mi in zip(HORIZONS, q, m):
        q_ref, m_ref = ref.at(t)
        assert attitude_error(qi, q_ref) <= required, (t, attitude_error(qi, q_ref))
        assert vector_error(mi, m_ref) <= required * g
