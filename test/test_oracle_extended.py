"""The extended-precision reference under a detumble law (rigid_body_sim.bench.extended):
it models the engine's closed loop, its bound holds, and the judge decides with it the
held-out scenes float64's references left undecided."""
import math

import numpy as np
import pytest

from rigid_body_sim.bench import extended, generated, oracle
from rigid_body_sim.bench.generated_scenes import Scene
from rigid_body_sim.offline import simulate
from rigid_body_sim.physics import rotation

pytestmark = pytest.mark.fast


def _detumble(duration=20.0, wn=0.05, **kw):
    """A small detumble scene: |ω| 3.7 rad/s, 74 rad turned, the law at 50 Hz, the rate
    falling e² over the run."""
    omega = (2.0, -1.0, 3.0)
    fields = dict(seed=0, index=0, kind='detumble', moments=(0.5, 0.8, 1.1), omega=omega,
                  attitude=(0.1, -0.2, 0.3, math.sqrt(0.86)),
                  rotation=float(np.linalg.norm(omega)) * duration, duration=duration,
                  publish_rate=5.0, budget=1e-9, control_rate=50.0, natural_frequency=wn)
    fields.update(kw)
    return Scene(**fields)


def test_it_models_the_engine_s_closed_loop_law_and_all():
    """Against the engine's own closed loop (dop853 at rtol 1e-13, its law at 50 Hz, 1000
    instants): the same samples within 1e-10 rad, over 74 rad turned while the law took
    the rate down e²-fold (a sign, a frame or a hold wrong would be off by radians)."""
    scene = _detumble()
    f = scene.scene_file()
    attitude, bound, what, t_ns = extended.reference(f)
    run = simulate(f, integrator='dop853', integrator_options={'rtol': 1e-13, 'atol': 1e-16})
    assert np.array_equal(run.samples.t_ns, t_ns)
    w = np.linalg.norm(run.samples['angular_velocity'], axis=1)
    assert w[-1] < 0.2 * w[0], (w[0], w[-1])  # the law acts
    apart = float(np.max(rotation.angle_between(run.samples['attitude'], attitude)))
    assert apart < 1e-10, (apart, what)
    assert bound < 1e-12, what
    assert 'Taylor' in what and 'long double' in what


def test_its_bound_holds_against_a_far_finer_run_and_sees_a_coarse_one():
    """The bound (its distance to a finer run, plus float64's rounding × 2⁻¹¹ × 4) holds
    against a run with a fifth of the turn per step and a tolerance of 1e-28; a run with
    a loose series (tolerance 1e-9) is far outside it."""
    problem = extended.Problem(_detumble().scene_file())
    attitude, bound, _, _ = extended.reference(_detumble().scene_file())
    fine = problem.attitude(*problem.run(turn=0.05, tol=1e-28)[:2])
    coarse = problem.attitude(*problem.run(turn=1.0, tol=1e-9)[:2])
    assert float(np.max(rotation.angle_between(fine, attitude))) <= bound
    assert float(np.max(rotation.angle_between(coarse, attitude))) > 100 * bound


def test_what_it_does_not_model_it_refuses_by_name():
    """A slew, a mission schedule, dissipation: Unavailable, saying what it models."""
    for scene in (_detumble(controller=(('mode', 'slew'),)),
                  _detumble(controller=(('mission.detumble_exit_rate', 0.1),)),
                  _detumble(extra=(('dissipation.model', 'viscous'),
                                   ('dissipation.coefficient', 0.01)))):
        with pytest.raises(extended.Unavailable, match='detumble law alone'):
            extended.Problem(scene.scene_file())


def test_without_a_c_compiler_it_says_so_and_the_judge_falls_back(monkeypatch, tmp_path):
    monkeypatch.setenv('XDG_CACHE_HOME', str(tmp_path))
    monkeypatch.setattr(extended, '_LIBS', {})
    monkeypatch.setattr(extended.shutil, 'which', lambda name: None)
    with pytest.raises(extended.Unavailable, match='C compiler'):
        extended._library('long double')
    seen = []
    monkeypatch.setattr(oracle, '_float64_reference', lambda *a: seen.append(a) or
                        oracle.Reference(np.zeros((1, 4)), math.inf, 'undecided: x'))
    ref = oracle.reference(_detumble())
    assert seen and 'no extended reference' in ref.what and 'C compiler' in ref.what


@pytest.mark.slow
def test_the_held_out_scene_46_is_decided_and_auto_meets_it():
    """Seed 20261127 scene 46 (detumble, 1e-8 rad over 4.4e4 rad): undecided before (rk4
    fine enough to check dop853's ladder would pass the cap). The Taylor reference's bound
    is ~1e-12 rad; auto (dop853 weighed against rk4) errs ~3e-10: met."""
    scene = generated.draw(20261127, 46)
    ref = oracle.reference(scene)
    assert ref.error * oracle.JUDGE <= scene.budget, ref.what
    result = simulate(scene.scene_file())
    err = generated.error(result, ref.attitude)
    assert ref.decide(err, scene.budget) == 'met', (err, ref.error, result.reason)
