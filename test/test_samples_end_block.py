"""An offline run that keeps every sample takes them as one block (Engine.reserve), the
run's end off the sample grid included: in a block of its own, that one sample made
offline.simulate copy every other to join the two (~15 ns a sample at 100 samples/s)."""
import numpy as np
import pytest

from rigid_body_sim.offline import block_size, engine_for, simulate
from rigid_body_sim.scene import load

pytestmark = pytest.mark.fast


def test_the_end_off_the_grid_is_in_the_interpolated_runs_one_block():
    """detumble (a law at 50 Hz, a fixed-step method, samples between its steps) for 2.355
    s at 100 samples/s, a sample (2.35 s) between the last law instant (2.34 s) and the
    end, so that the kernel runs to the end: 237 samples (0 to 2.35 s and the end) in one
    block, the last at the end, and they are simulate's samples."""
    scene = load('detumble', ['publish_rate=100.0'])
    engine = engine_for(scene, duration=2.355)
    assert engine.interpolate_samples
    engine.reserve(block_size(engine.config, limit=None))
    blocks = list(engine.run())
    assert [len(b) for b in blocks] == [237]
    assert blocks[0].t_ns[-1] == 2_355_000_000 and blocks[0].t_ns[-2] == 2_350_000_000
    result = simulate(scene, duration=2.355)
    np.testing.assert_array_equal(result.samples.t_ns, blocks[0].t_ns)
    np.testing.assert_array_equal(result.samples.q, blocks[0].q)
    np.testing.assert_array_equal(result.samples.m, blocks[0].m)
