"""The extended-precision reference (rigid_body_sim.bench.extended) on torque-free bodies
with dissipation: against closed forms (viscous damping of a spherical body, the double
bracket's logistic on an axisymmetric one), against the engine's own run on a triaxial
body, its bound against a far finer run, and what it refuses."""
import math

import mpmath
import numpy as np
import pytest

from rigid_body_sim.bench import extended, generated, oracle
from rigid_body_sim.bench.generated_scenes import Scene
from rigid_body_sim.offline import simulate
from rigid_body_sim.physics import rotation

pytestmark = pytest.mark.fast

OMEGA = (2.0, -1.0, 3.0)  # rad/s, body frame: |ω| 3.74


def _scene(kind, moments, coefficient, duration=20.0, **kw):
    fields = dict(seed=0, index=0, kind=kind, moments=moments, omega=OMEGA,
                  attitude=(0.1, -0.2, 0.3, math.sqrt(0.86)),
                  rotation=float(np.linalg.norm(OMEGA)) * duration, duration=duration,
                  publish_rate=5.0, budget=1e-10, coefficient=coefficient)
    fields.update(kw)
    return Scene(**fields)


def _spin(q0, w, theta):
    """q0 ⊗ (rotation by theta about the unit w), in mpmath, as float64 (x, y, z, w)."""
    norm = mpmath.sqrt(sum(x * x for x in w))
    s, c = mpmath.sin(theta / 2), mpmath.cos(theta / 2)
    px, py, pz, pw = (mpmath.mpf(float(x)) for x in q0)
    qx, qy, qz, qw = w[0] / norm * s, w[1] / norm * s, w[2] / norm * s, c
    return [float(pw * qx + px * qw + py * qz - pz * qy),
            float(pw * qy - px * qz + py * qw + pz * qx),
            float(pw * qz + px * qy - py * qx + pz * qw),
            float(pw * qw - px * qx - py * qy - pz * qz)]


def test_viscous_damping_of_a_spherical_body_is_its_closed_form():
    """I = 0.7 kg·m² about every axis, c = 0.07 N·m·s: ω(t) = ω0 e^{−ct/I} about a fixed
    axis, the attitude turned by |ω0|(I/c)(1 − e^{−ct/I}) (32 rad over the run). From the
    reference's own float64 initial state, evaluated in 30 digits: its samples within its
    bound (which holds the samples' rounding to float64, 1e-15 rad), m within 1e-15 of |m|.
    A sign or a factor wrong in the damping would be off by radians."""
    problem = extended.Problem(_scene('viscous', (0.7, 0.7, 0.7), 0.07).scene_file())
    assert problem.model == extended.MODELS['viscous']
    q, m, _, _ = problem.run()
    _, bound, what, _ = extended.reference(_scene('viscous', (0.7, 0.7, 0.7),
                                                  0.07).scene_file())
    mpmath.mp.dps = 30
    inertia, c = mpmath.mpf(float(problem.moments[0])), mpmath.mpf(problem.coefficient)
    w0 = [mpmath.mpf(float(x)) / inertia for x in problem.m0]
    rate = sum(x * x for x in w0) ** 0.5
    want_q, want_m = [], []
    for t_ns in problem.t_ns:
        decay = mpmath.exp(-c * mpmath.mpf(int(t_ns)) / 10 ** 9 / inertia)
        want_q.append(_spin(problem.q0, w0, rate * inertia / c * (1 - decay)))
        want_m.append([float(mpmath.mpf(float(x)) * decay) for x in problem.m0])
    apart = float(np.max(rotation.angle_between(np.array(want_q), q)))
    assert apart <= bound and bound < 3e-15, (apart, what)
    assert np.max(np.abs(np.array(want_m) - m)) < 1e-15 * np.linalg.norm(problem.m0)
    assert 'viscous' in what


def test_the_double_bracket_on_an_axisymmetric_body_follows_its_logistic():
    """I = (0.6, 0.6, 1.0): the double bracket's axial momentum obeys du/dt = 2k u (1 − u),
    u = m₃²/|m|², k = α|m|²(1/I_t − 1/I₃), while |m| stays: u(t) = u₀e^{2kt}/(1 − u₀ +
    u₀e^{2kt}). Over 2kT = 4 (u from 0.83 to 0.996): m₃ within 1e-14 |m| of it, |m|
    within 1e-15, and the kinetic energy falls at every sample (a sign wrong would pump
    the momentum off the major axis)."""
    moments = (0.6, 0.6, 1.0)
    norm2 = sum((i * w) ** 2 for i, w in zip(moments, OMEGA))
    alpha = 0.1 / ((1 / 0.6 - 1 / 1.0) * norm2)   # k = 0.1 /s
    problem = extended.Problem(_scene('double_bracket', moments, alpha).scene_file())
    assert problem.model == extended.MODELS['double_bracket']
    _, m, _, _ = problem.run()
    axial = int(np.argmax(problem.moments))
    big, small = problem.moments[axial], np.min(problem.moments)
    mpmath.mp.dps = 30
    m0 = [mpmath.mpf(float(x)) for x in problem.m0]
    total = sum(x * x for x in m0)
    k = mpmath.mpf(problem.coefficient) * total * (1 / mpmath.mpf(float(small))
                                                   - 1 / mpmath.mpf(float(big)))
    u0 = m0[axial] ** 2 / total
    want = []
    for t_ns in problem.t_ns:
        g = mpmath.exp(2 * k * mpmath.mpf(int(t_ns)) / 10 ** 9)
        want.append(float(mpmath.sqrt(total * u0 * g / (1 - u0 + u0 * g))))
    norm = float(mpmath.sqrt(total))
    assert np.max(np.abs(np.abs(m[:, axial]) - want)) < 1e-14 * norm
    assert want[-1] ** 2 / norm ** 2 > 0.996  # the run reached the major axis
    assert np.max(np.abs(np.linalg.norm(m, axis=1) - norm)) < 1e-15 * norm
    energy = 0.5 * np.sum(m * m / problem.moments, axis=1)
    assert np.all(np.diff(energy) < 0)


def _triaxial(duration=20.0, decay=8.0):
    """A triaxial body under the double bracket: κT = decay (κ = α|m|²(1/I_min −
    1/I_max)), |ω| 3.74 rad/s, 75 rad turned over 20 s."""
    moments = (0.5, 0.8, 1.1)
    norm2 = sum((i * w) ** 2 for i, w in zip(moments, OMEGA))
    alpha = decay / (duration * norm2 * (1 / 0.5 - 1 / 1.1))
    return _scene('double_bracket', moments, alpha, duration=duration)


def test_the_double_bracket_on_a_triaxial_body_is_the_engine_s_dynamics():
    """Against the engine's own run (dop853 at rtol 1e-13, its samples at 5 Hz): the same
    attitudes within 1e-10 rad over 75 rad while the energy fell to within 1e-4 of the
    major axis' |m|²/(2 I_max) (a frame, a sign or a factor of the bracket wrong would be
    off by radians); |m| kept to 1e-14."""
    f = _triaxial().scene_file()
    attitude, bound, what, t_ns = extended.reference(f)
    run = simulate(f, integrator='dop853', integrator_options={'rtol': 1e-13, 'atol': 1e-16})
    assert np.array_equal(run.samples.t_ns, t_ns)
    apart = float(np.max(rotation.angle_between(run.samples['attitude'], attitude)))
    assert apart < 1e-10, (apart, what)
    assert bound < 1e-12, what
    problem = extended.Problem(f)
    _, m, _, _ = problem.run()
    norm = np.linalg.norm(problem.m0)
    assert np.max(np.abs(np.linalg.norm(m, axis=1) - norm)) < 1e-14 * norm
    energy = 0.5 * np.sum(m[-1] ** 2 / problem.moments)
    floor = norm ** 2 / (2 * np.max(problem.moments))
    assert 0 <= energy - floor < 1e-4 * floor, (energy, floor)


def test_its_bound_holds_against_a_far_finer_run_and_sees_a_coarse_one():
    """On the triaxial double bracket: the bound holds against a run with a fifth of the
    turn per step and a tolerance of 1e-28; a loose series (1e-9) is far outside it."""
    f = _triaxial().scene_file()
    problem = extended.Problem(f)
    attitude, bound, _, _ = extended.reference(f)
    fine = problem.attitude(*problem.run(turn=0.05, tol=1e-28)[:2])
    coarse = problem.attitude(*problem.run(turn=1.0, tol=1e-9)[:2])
    assert float(np.max(rotation.angle_between(fine, attitude))) <= bound
    assert float(np.max(rotation.angle_between(coarse, attitude))) > 100 * bound


def test_a_free_body_with_an_environment_torque_is_refused_by_name():
    """The gravity gradient (an orbit scene, no law): Unavailable, naming it."""
    scene = generated.draw_gravity_gradient(generated.SEED, 0)
    with pytest.raises(extended.Unavailable, match='torque-free body.*gravity gradient'):
        extended.Problem(scene.scene_file())


@pytest.mark.slow
def test_an_undecided_double_bracket_scene_is_decided_and_auto_meets_it():
    """Seed 20261125 scene 137 (double bracket, 1e-10 rad over 4.3e3 rad): undecided
    before (rk4 fine enough to check dop853's ladder would pass the cap). The Taylor
    reference's bound is ~3e-14 rad; auto (dop853) errs ~2e-11: met."""
    scene = generated.draw(generated.SEED, 137)
    ref = oracle.reference(scene)
    assert ref.error * oracle.JUDGE <= scene.budget and 'double bracket' in ref.what, ref.what
    result = simulate(scene.scene_file())
    err = generated.error(result, ref.attitude)
    assert ref.decide(err, scene.budget) == 'met', (err, ref.error, result.reason)


@pytest.mark.slow
def test_where_float64_cannot_reach_the_budget_auto_says_so_beforehand():
    """Seed 20261125 scene 99 (double bracket, 1e-10 rad over 1.6e4 rad): decided now, a
    miss (auto's dop853 at rtol 3e-15 errs ~2.3e-10), and float64's round-off is the floor:
    dop853 errs 1.05–3.6× the budget from rtol 1e-13 to 1e-15 (the judge's sweep tries
    the rest). auto said so beforehand: its predicted error is over the budget and its
    reason says no method can be shown to meet it (what the judge's INFEASIBLE needs)."""
    scene = generated.draw(generated.SEED, 99)
    ref = oracle.reference(scene)
    assert ref.error * oracle.JUDGE <= scene.budget, ref.what
    result = simulate(scene.scene_file())
    err = generated.error(result, ref.attitude)
    assert ref.decide(err, scene.budget) == 'missed', (err, ref.error)
    assert result.selection.predicted_error > scene.budget
    assert 'no method can be shown to meet 1e-10 rad' in result.reason
    for rtol in (1e-13, 1e-15):
        run = simulate(scene.scene_file(), integrator='dop853',
                       integrator_options={'rtol': rtol, 'atol': rtol * 1e-3})
        assert generated.error(run, ref.attitude) > scene.budget, rtol
