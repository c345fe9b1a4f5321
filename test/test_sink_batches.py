"""offline.simulate hands its sinks (a bag) the blocks after the run, or SINK_BATCH rows at
a time in a longer one, and every block even when the run is interrupted."""
import numpy as np
import pytest

from rigid_body_sim import offline
from rigid_body_sim.engine import Engine
from rigid_body_sim.scene import load

pytestmark = pytest.mark.fast


class Sink:
    """Records each block it gets and whether the run had ended then."""

    def __init__(self, engine):
        self.engine, self.blocks, self.ended = engine, [], []

    def __call__(self, block):
        self.blocks.append(block)
        self.ended.append(self.engine.finished)


def _engine(duration, block=64):
    scene = load('tennis_racket')
    config = offline.engine_for(scene, duration=duration, integrator='rk4', step=0.01).config
    return scene, Engine(config, block_size=block)  # small blocks: several a run


def _every_t(scene):
    """The sample instants of the same run, kept whole (one block, no sink)."""
    return offline.simulate(scene, duration=5.0, integrator='rk4', step=0.01).samples.t


def test_a_short_run_s_sinks_get_every_block_in_order_after_it():
    scene, engine = _engine(5.0)
    sink = Sink(engine)
    offline.simulate(scene, engine=engine, sinks=[sink], keep='none')
    assert len(sink.blocks) > 1 and all(sink.ended)
    np.testing.assert_array_equal(np.concatenate([b.t for b in sink.blocks]), _every_t(scene))


def test_a_longer_run_s_sinks_get_batches_while_it_runs(monkeypatch):
    monkeypatch.setattr(offline, 'SINK_BATCH', 128)
    scene, engine = _engine(5.0)
    sink = Sink(engine)
    offline.simulate(scene, engine=engine, sinks=[sink], keep='none')
    assert not sink.ended[0] and sink.ended[-1]  # memory bounded: not all kept back
    np.testing.assert_array_equal(np.concatenate([b.t for b in sink.blocks]), _every_t(scene))


def test_an_interrupted_run_s_sinks_still_get_every_block_it_made():
    scene, engine = _engine(5.0)
    sink = Sink(engine)
    made = []
    run = engine.run

    def interrupted(until_ns=None):
        for block in run(until_ns):
            made.append(block)
            yield block
            if len(made) == 3:
                raise KeyboardInterrupt

    engine.run = interrupted
    with pytest.raises(KeyboardInterrupt):
        offline.simulate(scene, engine=engine, sinks=[sink], keep='none')
    assert sink.blocks == made and len(made) == 3
