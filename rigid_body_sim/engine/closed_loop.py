"""The closed loop compiled: the control law and the steps between its instants in one kernel.

Offline runs, the bench and campaigns run the control law in-process (``ControlLaw``).
Driven event by event from Python, every control instant costs ~10 µs of interpreter work
around a sub-microsecond law and a few sub-microsecond steps. This kernel runs the whole
stretch between two samples instead: at each control instant it evaluates the same law
(``control_kernel.control_torque``) with the same mission schedule and clip, then steps the
same compiled integrator loop (``physics.kernels``) to the next instant, with the step
split exactly as :meth:`Engine._integrate` splits it. The trajectory is the one the
event-by-event path computes (the tests compare both). :func:`advance` is the engine's
side: it decides when the kernel applies, packs its arguments and takes its results back.

Frames: q is principal → inertial and m the principal-frame momentum (what the
integrators advance); the law sees the body frame (attitude body → inertial, ω body), as
everywhere else. ``p2b`` is the principal → body rotation (x, y, z, w), ``axes`` its
matrix (v_body = axes @ v_principal).
"""
import math

import numpy as np

from .. import control_kernel
from ..control_kernel import MODE_CODES, control_torque
from ..physics import IntegrationError
from ..physics import kernels
from ..physics.kernels import depends_on, jit
from . import specs
from .config import NS
from .sources import NEVER

MODEL_CODES = kernels.MODEL_CODES
METHOD_CODES = {'splitting2': 0, 'splitting4': 0, 'splitting6': 0, 'rk4': 1, 'euler': 2}
INNER_LIMIT = 0.5  # = splitting.INNER_LIMIT: damping inside the compositions when weak


@jit
def _inner(m, h, weights, moments, model, coefficient):
    """Splitting2.inner_dissipation: damping inside the compositions when weak at h."""
    if model == 0 or len(weights) == 1:
        return False
    norm = math.sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2])
    i_min = min(moments[0], min(moments[1], moments[2]))
    i_max = max(moments[0], max(moments[1], moments[2]))
    if model == 1:
        stiffness = coefficient * norm ** 2 * (1.0 / i_min - 1.0 / i_max)
    else:
        stiffness = coefficient / i_min
    w_max = 0.0
    for w in weights:
        w_max = max(w_max, abs(w))
    return stiffness * h * w_max <= INNER_LIMIT


@jit
def closed_loop_run(q, m, t_ns, t_stop_ns, control_ns, period_ns, h_max, method, weights,
                    split_axes, moments, model, coefficient, axes, p2b, mode, target, law_axes,
                    law_moments, kp, kd, kw, rate_limit, torque_limit, gyroscopic, inertia, clip,
                    mission_start, free_time, exit_rate, tau_body, out):
    """Advance (q, m) in place from ``t_ns`` to ``t_stop_ns``, evaluating the law at every
    control instant ``control_ns + k·period_ns`` before ``t_stop_ns``. ``moments``,
    ``axes``, ``p2b``: the simulated body; ``law_*``, ``inertia``: the controller's model
    of it (its own ``inertia`` parameter), as :class:`control.AttitudeController` uses.

    ``tau_body`` (in/out): the held body-frame torque (zeros = none). ``out`` (int64, 6):
    [next control instant, mode, free (1/0), steps, evaluations, failed step or -1]; on a
    failure, ``out[0]`` is the start (ns) of the failing segment and the return value its
    step h. Returns the last step h (s)."""
    tau_p = np.zeros(3)
    tau_unsat = np.empty(3)
    scratch = np.empty((10, 4))  # the Runge–Kutta loops' stages, allocated once
    qb = np.empty(4)
    wb = np.empty(3)
    has_tau = False
    for i in range(3):
        has_tau = has_tau or tau_body[i] != 0.0
    for j in range(3):
        tau_p[j] = tau_body[0] * axes[0, j] + tau_body[1] * axes[1, j] + tau_body[2] * axes[2, j]
    free = out[2]
    steps = 0
    evals = 0
    h = 0.0
    t = t_ns
    while t < t_stop_ns:
        if t == control_ns:
            # the body-frame state the law sees (Engine.attitude / angular_velocity)
            cx, cy, cz, cw = -p2b[0], -p2b[1], -p2b[2], p2b[3]
            qb[0] = q[3] * cx + q[0] * cw + q[1] * cz - q[2] * cy
            qb[1] = q[3] * cy - q[0] * cz + q[1] * cw + q[2] * cx
            qb[2] = q[3] * cz + q[0] * cy - q[1] * cx + q[2] * cw
            qb[3] = q[3] * cw - q[0] * cx - q[1] * cy - q[2] * cz
            # as published (sources.published_attitude): what the controller node sees
            n = math.sqrt(qb[0] * qb[0] + qb[1] * qb[1] + qb[2] * qb[2] + qb[3] * qb[3])
            for i in range(4):
                qb[i] /= n
            for i in range(3):
                wb[i] = (axes[i, 0] * (m[0] / moments[0]) + axes[i, 1] * (m[1] / moments[1])
                         + axes[i, 2] * (m[2] / moments[2]))
            # Mission.update, then the law (ControlLaw.evaluate / on_event)
            if t / 1e9 - mission_start < free_time:
                free = 1
                for i in range(3):
                    tau_body[i] = 0.0
            else:
                free = 0
                if mode == 1 and exit_rate > 0.0 and \
                        math.sqrt(wb[0] * wb[0] + wb[1] * wb[1] + wb[2] * wb[2]) < exit_rate:
                    mode = 2
                control_torque(mode, qb, wb, target, law_axes, law_moments, kp, kd, kw,
                               rate_limit, torque_limit, gyroscopic, inertia, tau_body,
                               tau_unsat)
                for i in range(3):
                    tau_body[i] = min(max(tau_body[i], -clip), clip)
            has_tau = tau_body[0] != 0.0 or tau_body[1] != 0.0 or tau_body[2] != 0.0
            for j in range(3):
                tau_p[j] = (tau_body[0] * axes[0, j] + tau_body[1] * axes[1, j]
                            + tau_body[2] * axes[2, j])
            control_ns += period_ns
        seg_end = min(control_ns, t_stop_ns)
        span = seg_end - t
        # equal steps no longer than h_max, split as Engine._integrate splits them
        n = max(1, int(math.ceil(span / (h_max * 1e9) - 1e-9)))
        h = span / (n * 1e9)
        if method == 0:
            failed, e = kernels.splitting_run(q, m, h, n, weights, split_axes, moments, tau_p,
                                              has_tau, model, coefficient,
                                              _inner(m, h, weights, moments, model,
                                                     coefficient))
            evals += e
        elif method == 1:
            failed = kernels.rk4_steps(q, m, h, n, moments, tau_p, model, coefficient, scratch)
            evals += 4 * (n if failed < 0 else failed + 1)
        else:
            failed = kernels.euler_steps(q, m, h, n, moments, tau_p, model, coefficient,
                                         scratch)
            evals += n if failed < 0 else failed + 1
        if failed >= 0:
            out[0] = t
            out[3] = steps + failed + 1
            out[5] = failed
            return h
        steps += n
        t = seg_end
    out[0] = control_ns
    out[1] = mode
    out[2] = free
    out[3] = steps
    out[4] = evals
    out[5] = -1
    return h


# it calls the step loops and the law from their own files (see kernels.depends_on)
closed_loop_run = depends_on(closed_loop_run, kernels, control_kernel)


def advance(engine, until_ns: int) -> None:
    """The control law's instants up to the next sample (or the end) in one compiled
    kernel, when only the law acts (no held command) and the method has a compiled
    loop; otherwise nothing (``Engine.advance`` goes event by event)."""
    law, c = engine._law, engine.config
    stop = min(engine._next_sample, engine.end_ns)
    if (stop > until_ns or law.next_t >= stop or engine._selection is not None
            or engine.command.torque is not None or engine.command.expiry != NEVER
            or engine.method not in METHOD_CODES
            or not (engine._torque_seen or c.integrator != specs.AUTO)):
        return
    spec = engine._integ.loop_spec()
    if spec is None:
        return
    settings, ctl, mission = law.settings, law.controller, law.mission
    cfg, model_body = ctl.config, ctl.config.body
    if mission.start is None:
        mission.start = law.next_t / NS
    d = engine.dynamics.dissipation
    q, m = engine._q.copy(), engine._m.copy()
    tau = np.zeros(3) if law.torque is None else np.array(law.torque, float)
    out = np.zeros(6, dtype=np.int64)
    out[2] = law.free
    h = closed_loop_run(
        q, m, engine.t_ns, stop, law.next_t, settings.period_ns, engine.step_max,
        METHOD_CODES[engine.method], spec[0], spec[1], engine.dynamics.moments,
        MODEL_CODES[d.model] if d.active else 0, d.coefficient,
        engine.body.principal_axes, engine.body.principal_to_body, MODE_CODES[ctl.mode],
        ctl.target, model_body.principal_axes, model_body.principal_moments,
        cfg.kp_principal, cfg.kd_principal, cfg.rate_gain_principal, cfg.rate_limit,
        cfg.torque_limit, cfg.gyroscopic_compensation, model_body.inertia, law.clip,
        mission.start, mission.free_time, mission.detumble_exit_rate, tau, out)
    next_control, mode, free, steps, evals, failed = (int(v) for v in out)
    engine.steps += steps
    engine._integ.nfev += evals
    if failed >= 0:
        engine.fault = 'state became non-finite (the method diverged)'
        raise IntegrationError(engine.method, h, (next_control + (failed + 1) * h * NS) / NS,
                               engine.fault)
    engine._q, engine._m, engine.t_ns = q, m, stop
    law.next_t, law.free, law.last = next_control, bool(free), None
    if mode != MODE_CODES[ctl.mode]:
        ctl.set_mode(next(k for k, v in MODE_CODES.items() if v == mode))
    law.torque = tau if tau.any() else None
    engine._update_torque()
