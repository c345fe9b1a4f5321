"""Basilisk on the generated scenes (bench/generated_basilisk.py): its hub integrates the
scene's own physics, the damping torque of a dissipative scene from the user's Python
module, and its sweep gives generated_peers a peer's rows."""
from dataclasses import replace

import numpy as np
import pytest

from rigid_body_sim.bench import generated, generated_basilisk as gb, generated_peers as gp
from rigid_body_sim.bench import oracle
from rigid_body_sim.physics import analytic, rotation

PERIOD = 0.1      # s: the samples' period (a whole number of µs, as generated scenes have)
DURATION = 10.04  # s: off the sample grid, as every generated scene's
TIMES = np.r_[np.arange(0.0, DURATION, PERIOD), DURATION]
Q0 = np.array([0.2, -0.1, 0.4, 0.8]) / np.linalg.norm([0.2, -0.1, 0.4, 0.8])


def _scene(kind, moments, omega, coefficient=0.0):
    return generated.Scene(seed=0, index=0, kind=kind, moments=tuple(moments),
                           omega=tuple(omega), attitude=tuple(Q0), rotation=0.0,
                           duration=DURATION, publish_rate=1.0 / PERIOD, budget=1e-6,
                           coefficient=coefficient)


def _axisymmetric_exact(moments, omega, t):
    """q(t) = exp(Ω t L̂_N) ⊗ q0 ⊗ exp(−λ t e_s): the space cone about L, the body cone
    about the symmetry axis (analytic.precession_rates)."""
    body_rate, space_rate = analytic.precession_rates(moments, omega)
    s = analytic.symmetry_axis(moments)
    m = np.asarray(moments) * np.asarray(omega)
    axis = rotation.rotate(Q0, m / np.linalg.norm(m))
    return np.array([rotation.multiply(rotation.multiply(rotation.exp(space_rate * x * axis),
                                                         Q0),
                                       rotation.axis_rotation(s, -body_rate * x))
                     for x in t])


def test_the_exact_axisymmetric_solution_is_the_free_motion():
    """The closed form the next test judges Basilisk by: the body-frame rate it implies
    (finite difference) matches Euler's equations' ω(t) (ω_⊥ turning at λ about e_s)."""
    moments, omega = (1.2, 1.2, 0.5), (0.3, -0.2, 1.0)
    dt = 1e-6
    q = _axisymmetric_exact(moments, omega, (2.0 - dt, 2.0 + dt))
    dq = (q[1] - q[0]) / (2 * dt)
    mid = _axisymmetric_exact(moments, omega, (2.0,))[0]
    w = 2.0 * rotation.multiply(rotation.conjugate(mid), dq)[:3]  # body rate
    lam = analytic.precession_rates(moments, omega)[0]
    c, s = np.cos(lam * 2.0), np.sin(lam * 2.0)
    expected = (omega[0] * c - omega[1] * s, omega[0] * s + omega[1] * c, omega[2])
    assert np.allclose(w, expected, atol=1e-8), (w, expected)


def test_rk4_at_a_small_step_is_the_exact_solution_and_drifts_at_a_large_one():
    """Torque-free axisymmetric body, read at the samples and the off-grid end: within
    1e-9 rad at 20 steps a sample (~0.005 rad a step); at one a sample (~0.1 rad) its
    error is far larger (RK4's h⁴: ~20⁴ times)."""
    moments, omega = (1.2, 1.2, 0.5), (0.3, -0.2, 1.0)
    scene = _scene('free', moments, omega)
    exact = _axisymmetric_exact(moments, omega, TIMES)
    _, fine = gb.run(scene, 20, 'rk4', TIMES)
    _, coarse = gb.run(scene, 1, 'rk4', TIMES)
    err_fine = float(np.max(rotation.angle_between(fine, exact)))
    err_coarse = float(np.max(rotation.angle_between(coarse, exact)))
    assert len(fine) == len(TIMES)
    assert err_fine < 1e-9, err_fine
    assert err_coarse > 1e3 * err_fine and err_coarse > 1e-7, (err_coarse, err_fine)
    _, rkf = gb.run(scene, 1e-10, 'rkf78', TIMES)
    assert float(np.max(rotation.angle_between(rkf, exact))) < 1e-9


def test_rk4_needs_its_steps_to_divide_the_sample_period():
    with pytest.raises(ValueError, match='not a divisor'):
        gb.run(_scene('free', (1, 2, 3), (0.1, 0.2, 0.3)), 3, 'rk4', TIMES)
    assert gb.steps_per_sample(100_000_000, 3) == 4
    assert gb.steps_per_sample(100_000_000, 0.2) == 1
    assert gb.steps_per_sample(1000 * 1_000_003, 1001) == 1_000_003  # a prime: no hang
    assert gb.steps_per_sample(1000, 1001) is None


def test_the_damping_module_decays_the_rate_as_the_closed_form():
    """Viscous damping on a spherical body: ω = ω0·exp(−c t / I) about a fixed axis, so
    the angle turned is |ω0| I/c (1 − exp(−c t / I)). With the user's module (the torque
    held over each 2 ms step: a first-order error, ~(c t)(c h)/2 of the decay) within
    1e-3 rad; without it (the same scene free) off by radians."""
    c, omega = 0.1, np.array([0.0, 0.6, 0.8])
    scene = _scene('viscous', (1.0, 1.0, 1.0), omega, coefficient=c)
    angle = np.linalg.norm(omega) / c * (1.0 - np.exp(-c * TIMES))
    axis = rotation.rotate(Q0, omega / np.linalg.norm(omega))
    exact = np.array([rotation.multiply(rotation.exp(a * axis), Q0) for a in angle])
    _, damped = gb.run(scene, 50, 'rk4', TIMES)
    err = float(np.max(rotation.angle_between(damped, exact)))
    assert err < 1e-3, err
    _, coarse = gb.run(scene, 5, 'rk4', TIMES)  # the held torque's error grows with h
    assert float(np.max(rotation.angle_between(coarse, exact))) > 5 * err
    _, free = gb.run(replace(scene, kind='free'), 50, 'rk4', TIMES)
    assert float(np.max(rotation.angle_between(free, exact))) > 1.0


def test_the_sweep_gives_generated_peers_a_peers_rows():
    """On a cheap generated scene: one row per Basilisk integrator, (name, step or relTol,
    CPU s, error); RK4's step divides the sample period and meets the budget, and
    generated_peers' row takes it (its step as peer_step)."""
    scene = min((s for s in (generated.draw(generated.SEED, i, True) for i in range(40))
                 if s.kind == 'free'), key=lambda s: s.rotation)
    scene = replace(scene, budget=1e-4)
    ref = oracle.reference(scene)
    times = oracle.timed(scene.scene_file())[0].samples['t']
    out = gb.runs(scene, ref, times, cap=5.0)
    assert [r[0] for r in out] == ['bsk_rk4', 'bsk_rkf78']
    assert all(len(r) == 4 and r[2] > 0 for r in out)
    name, h, cpu_s, err = out[0]
    assert h is not None and err + ref.error <= scene.budget
    period = times[1] - times[0]
    assert abs(period / h - round(period / h)) < 1e-9
    row = gp._row_of({'scene': scene.name}, [out[0]], auto_cpu=1e-3)
    assert row['status'] == 'ok' and row['peer'] == 'bsk_rk4' and row['peer_step'] == h
    missed = gb.sweep(replace(scene, budget=1e-16), 'rk4', ref, times, cap=0.05)
    assert missed[0] is None and missed[1] > 0 and missed[2] > 1e-16


def test_basilisk_is_imported_before_any_runs_cap():
    """A first import of Basilisk's modules inside a run's cap, stopped there, left the
    package half initialised: every later rung failed at once ("partially initialized
    module 'Basilisk'") and counted as a diverged run. In a fresh interpreter, every run of
    a sweep now starts with all of them loaded."""
    import subprocess
    import sys
    code = (
        'import sys\n'
        'from rigid_body_sim.bench import generated, generated_basilisk as gb\n'
        'from rigid_body_sim.bench import oracle\n'
        'import numpy as np\n'
        'names = ("Basilisk.simulation.svIntegrators", "Basilisk.architecture.sysModel",\n'
        '         "Basilisk.simulation.extForceTorque", "Basilisk.architecture.messaging")\n'
        'seen = []\n'
        'def run(*a):\n'
        '    seen.append(all(n in sys.modules for n in names))\n'
        '    raise RuntimeError("stop")\n'
        'gb.run = run\n'
        'scene = generated.draw(generated.SEED, 11, True)\n'
        'ref = oracle.Reference(np.zeros((3, 4)), 0.0, "none")\n'
        'assert "Basilisk" not in sys.modules\n'
        'gb.sweep(scene, "rkf78", ref, np.array([0.0, 1.0, 1.5]), cap=1.0)\n'
        'print(len(seen), all(seen))\n')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == [str(len(gb.RTOLS)), 'True'], out.stdout


def test_the_cap_stops_a_run_in_its_middle(monkeypatch):
    """ExecuteSimulation runs in C and holds the GIL: a whole run in one call (~1.2 CPU-s
    here: RKF78 at 1e-13 over 500 samples of 6 rad) was stopped only at its end. In calls
    of ~10 ms the interrupt lands in time: no run finishes (error inf) and the bound, the
    CPU spent, stays within a few chunks of the 0.05 s cap (< 0.5 s)."""
    monkeypatch.setattr(gb, 'RTOLS', (1e-13,))
    scene = generated.draw(generated.SEED, 11, True)  # free, |ω| ≈ 0.1 rad/s
    times = np.arange(500) * 60.0
    ref = oracle.Reference(np.tile([0.0, 0.0, 0.0, 1.0], (len(times), 1)), 0.0, 'identity')
    rtol, bound, err = gb.sweep(scene, 'rkf78', ref, times, cap=0.05)
    assert rtol is None and err == np.inf
    assert 0.05 <= bound < 0.5, bound


def test_a_sweep_runs_in_a_child_that_may_die_without_ending_the_bench():
    """isolated(): the child's result comes back; a child that aborts (as a Basilisk run
    did from C++, ending a whole peers run) gives None and its wait status, and the
    parent goes on."""
    import os
    from rigid_body_sim.bench import generated_basilisk as gb
    assert gb.isolated(lambda: (1e-6, 0.25, [1.0, 2.0])) == ((1e-6, 0.25, [1.0, 2.0]), 0)
    out, status = gb.isolated(os.abort)
    assert out is None and os.WIFSIGNALED(status) and os.WTERMSIG(status) == 6
    assert gb.isolated(lambda: 1 / 0)[0] is None  # a Python error too: no result
