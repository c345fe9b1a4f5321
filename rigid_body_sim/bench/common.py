"""Timing, error metrics and references shared by the benchmark sections."""
import time

import numpy as np

from ..physics import IntegrationError, create, rotation

REF_RTOL = 1e-13
EPS = np.finfo(float).eps


def cpu():
    """Process CPU time (s): robust to other load on the machine, counts Python overhead."""
    return time.process_time()


def invariants(moments, m):
    m = np.asarray(m, float)
    return 0.5 * float(np.sum(m * m / moments)), float(np.linalg.norm(m))


def metrics(scene, q, m, q_ref, m_ref):
    """Attitude error (rad), ω error (rad/s), relative T and |L| error against the reference."""
    moments = np.asarray(scene.moments, float)
    t, g = invariants(moments, m)
    t_ref, g_ref = invariants(moments, m_ref)
    return {'attitude_error': float(rotation.angle_between(np.asarray(q, float), q_ref)),
            'omega_error': float(np.linalg.norm((np.asarray(m) - m_ref) / moments)),
            'energy_drift': abs(t - t_ref) / t_ref,
            'momentum_drift': abs(g - g_ref) / g_ref}


def simulate(scene, integrator, h=None):
    """Run ``integrator`` over the scene: fixed steps h, or (h None) one adaptive call per
    output interval (the whole horizon, or each control period for the slew)."""
    q, m = scene.q0_array, scene.m0
    moments = np.asarray(scene.moments, float)
    if scene.slew is not None:
        period = scene.slew.period
        intervals = int(round(scene.t_end / period))
        n = 1 if h is None else int(round(period / h))
        hh = period if h is None else h
        t = 0.0
        for _ in range(intervals):
            tau = scene.slew.torque(moments, q, m)
            for _ in range(n):
                q, m = integrator.step(q, m, hh, torque=tau, t=t)
                t += hh
        return q, m
    if h is None:
        return integrator.step(q, m, scene.t_end)
    n = int(round(scene.t_end / h))
    t = 0.0
    for _ in range(n):
        q, m = integrator.step(q, m, h, t=t)
        t += h
    return q, m


def timed(run, repeat_below=0.05, repeats=3):
    """(min CPU seconds, result of the last run); short runs are repeated, the minimum kept."""
    best, out = np.inf, None
    for i in range(repeats):
        t0 = cpu()
        out = run()
        best = min(best, cpu() - t0)
        if best > repeat_below:
            break
    return best, out


def reference(scene):
    """(q_ref, m_ref, label, own-error estimate in rad).

    Torque-free: the exact solution (its error is cross-checked against dop853 at rtol
    1e-13). Otherwise dop853 at rtol 1e-13; its own error is estimated by the distance to
    the rtol 1e-12 solution (an upper estimate: that is the error of the looser run).
    """
    dyn = scene.dynamics
    fine = simulate(scene, create('dop853', dyn, rtol=REF_RTOL, atol=REF_RTOL * 1e-2))
    if scene.torque_free:
        from ..physics.exact import TorqueFreeSolution
        q, m = TorqueFreeSolution(dyn.moments, scene.q0_array, scene.m0).at(scene.t_end)
        check = float(rotation.angle_between(fine[0], q))
        return q, m, 'exact', check
    looser = simulate(scene, create('dop853', dyn, rtol=10 * REF_RTOL, atol=REF_RTOL * 1e-1))
    return fine[0], fine[1], 'dop853 rtol 1e-13', float(rotation.angle_between(fine[0], looser[0]))


__all__ = ['cpu', 'metrics', 'simulate', 'timed', 'reference', 'invariants', 'IntegrationError', 'EPS']
