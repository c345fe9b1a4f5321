"""A term that is off costs nothing (bench.term_off): the free body's loops are compiled
without the environment's term, and the search that says so can see it where it is."""
import numpy as np
import pytest

from rigid_body_sim.bench import term_off
from rigid_body_sim.physics import jit
from rigid_body_sim.physics.orbit import kernel as orbit_kernel

pytestmark = pytest.mark.fast


@jit.jit
def _always_pays(q, t0, env):
    """A loop that evaluates the term whatever env is (what the free body must not do)."""
    moments = np.ones(3)
    x = 0.0
    if env is not None:
        x = orbit_kernel.gravity_gradient_torque(q, t0, env, moments)[0]
    return x + orbit_kernel.eccentric_anomaly(t0, 0.1)


# slow: compiles each free-body loop twice (with and without the term), 5 CPU-s, once per
# version of the sources: the answer the bench keeps for them (the last test checks the
# keeping), which `make test`'s bench run (test_bench) searches for too (issue 32)
@pytest.mark.slow
def test_the_free_bodys_loops_name_none_of_the_term():
    found = term_off.inspect_code_kept()
    assert set(found) == {'splitting_run', 'rk4_run', 'rk4_steps', 'euler_run', 'euler_steps'}
    for name, (off, on) in found.items():
        assert off == (), name
        assert 'gravity_gradient' in on and 'eccentric_anomaly' in on, name


@pytest.mark.slow  # compiles a kernel of its own (0.5 CPU-s): make test
def test_a_loop_that_pays_for_the_term_when_it_is_off_is_caught():
    found = term_off.inspect_code([('always', _always_pays,
                                    (np.array([0.0, 0.0, 0.0, 1.0]), 1.0))])
    off, on = found['always']
    assert 'eccentric_anomaly' in off and 'gravity_gradient' in on


def test_the_bench_keeps_the_search_for_the_sources_it_read(tmp_path, monkeypatch):
    """The bench's section searches once per version of the sources (and numba): its answer
    is kept beside the kernels' cache (issue 32: ~8 CPU-s a bench run), read back while the
    sources are the same, searched again once they change."""
    from rigid_body_sim import compiled
    from rigid_body_sim.physics.auto import calibration
    monkeypatch.setattr(calibration, 'cache_dir', lambda: str(tmp_path))
    sources = ['one']
    monkeypatch.setattr(compiled, 'sources_digest', lambda: sources[0])
    searches = []

    def search():
        searches.append(sources[0])
        return {'rk4_run': ((), ('gravity_gradient', 'eccentric_anomaly'))}
    monkeypatch.setattr(term_off, 'inspect_code', search)
    answer = {'rk4_run': ((), ('gravity_gradient', 'eccentric_anomaly'))}
    assert term_off.inspect_code_kept() == answer and searches == ['one']
    assert term_off.inspect_code_kept() == answer and searches == ['one']  # kept
    sources[0] = 'two'
    assert term_off.inspect_code_kept() == answer and searches == ['one', 'two']
