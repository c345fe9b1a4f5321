"""TorqueFreeSolution's one-body set-up (float arithmetic) against the batch path it
shortcuts, to the bit: the batch code, given a batch of one, is the construction every
one-body solution took before the shortcut."""
import numpy as np
import pytest

from rigid_body_sim.bench.generated_scenes import draw
from rigid_body_sim.physics.exact import TorqueFreeSolution

pytestmark = pytest.mark.fast  # make check

ARRAYS = ('moments', '_kind', '_e', '_ws', '_me', '_ie', '_it', '_G', '_order', '_q0', '_m0',
          '_rows')
BATCHED = ('kinetic_energy', 'angular_momentum_norm', 'omega_period', 'flip_interval')
Q = (0.1, 0.2, 0.3, 0.9)


def _bodies():
    """(moments, q0, m0): the first 100 generated scenes' bodies (seed 20261125, m = I·ω),
    and the closed forms and edges the generated ones never reach."""
    out = []
    for i in range(100):
        s = draw(20261125, i)
        out.append((s.moments, s.attitude, np.multiply(s.moments, s.omega)))
    sep = np.array([np.sqrt(0.3 ** 2 * (3 - 2) / 3 * 1 / (2 - 1)), 0.5, 0.3])  # Δ2 = 0
    out += [((2.0, 2.0, 2.0), Q, (0.3, -0.1, 0.2)),                  # spherical
            ((1.0, 1.0, 3.0), Q, (0.3, -0.1, 0.2)),                  # symmetric, oblate
            ((3.0, 1.0, 3.0), Q, (0.3, -0.1, 0.2)),                  # symmetric, prolate
            ((1.0, 2.0, 3.0), Q, (0.0, -1.0, 0.0)),                  # steady, middle axis
            ((1.0, 2.0, 3.0), Q, (-0.0, 0.0, -2.0)),                 # steady, signed zeros
            ((3.0, 1.0, 2.0), Q, (-0.0, -0.0, -0.0)),                # rest
            ((1.0, 2.0, 3.0), Q, sep), ((1.0, 2.0, 3.0), Q, -sep),   # separatrix
            ((2.0, 1.0, 2.0 / 3.0), Q, (np.cos(1.1), 0.0, np.sin(1.1))),  # case B, unsorted
            ([1.0, 2.0, 3.0], [0, 0, 0, 2], [0.1, 1.0, 0.2]),       # lists, q0 not unit
            (np.array([1.0, 2.0, 3.0]), Q, np.arange(6.0)[::2])]     # a strided m0
    return out


def test_one_body_set_up_is_the_batch_path_s_to_the_bit():
    # one test: pytest's per-case cost was most of it; at_numpy (its set-up reads the
    # attributes compared above, 1.5 ms a body) on every tenth generated body and the edges
    for i, (moments, q0, m0) in enumerate(_bodies()):
        _same(moments, q0, m0, numpy=i % 10 == 0 or i >= 100)


def _same(moments, q0, m0, numpy):
    one = TorqueFreeSolution(moments, q0, m0)
    batch = TorqueFreeSolution(moments, np.asarray(q0, float)[None], np.asarray(m0, float)[None])
    assert one.batch_shape == () and one.regime == batch.regime[0], (moments, m0)
    for name in ARRAYS:
        a, b = getattr(one, name), getattr(batch, name)
        assert (a.dtype, a.shape, a.tobytes()) == (b.dtype, b.shape, b.tobytes()), \
            (name, moments, m0)
    for name in BATCHED:
        a, b = getattr(one, name), getattr(batch, name)
        assert a.shape == () and a.tobytes() == b.tobytes(), name
    # read-only views, as before: the kernels see the argument types they were compiled for
    assert not one._q0.flags.writeable and not one._m0.flags.writeable
    t = np.array([0.0, 0.7, 123.4])
    for a, b in zip(one.at(t), batch.at(t[:, None])):
        assert a.tobytes() == b[:, 0].tobytes()
    for a, b in zip(one.at_numpy(t), batch.at_numpy(t[:, None])) if numpy else ():
        assert a.tobytes() == b[:, 0].tobytes()


def test_one_body_refuses_what_the_batch_path_refuses():
    for moments, m0, words in (((1.0, 0.0, 2.0), (1, 2, 3), 'moments must be 3 finite positive'),
                               ((1.0, np.nan, 2.0), (1, 2, 3), 'moments must be 3 finite'),
                               ((1.0, np.inf, 2.0), (1, 2, 3), 'moments must be 3 finite'),
                               ((1.0, 2.0, 3.0), (1, np.nan, 3), 'm0 must be finite'),
                               ((1.0, 2.0, 3.0), (1, 2), 'm0 must be finite with shape')):
        with pytest.raises(ValueError, match=words):
            TorqueFreeSolution(moments, Q, m0)
