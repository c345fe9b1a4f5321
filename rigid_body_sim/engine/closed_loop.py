"""The loop compiled: samples, the control law and the steps between them in one kernel.

Offline runs, the bench and campaigns run the control law in-process (``ControlLaw``).
Driven event by event from Python, every control instant and every sample costs ~10-20 µs
of interpreter work around a sub-microsecond law and a few sub-microsecond steps: at 100
samples/s that was 10-30x the physics. This kernel runs every event up to the next one it
cannot handle (the end, a command's expiry, a full block) instead: at each control
instant it evaluates the same law (``control_kernel.control_torque``) with the same mission
schedule and clip; at each sample instant it writes the state into the engine's
preallocated block (``BlockBuilder``); between them it steps the same compiled integrator
loop (``physics.integrators``), with the step split exactly as :meth:`Engine._integrate`
splits it. The samples are the event-by-event path's (test_samples compares them bit for
bit). :func:`advance` is the engine's side: it decides when the kernel applies, packs its
arguments and takes its results back.

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
from ..physics import dynamics_kernel
from ..physics.integrators import explicit_kernel, splitting_kernel
from ..physics.jit import depends_on, jit
from . import specs
from .config import NS
from .sources import NEVER

NEVER_NS = NEVER  # numba reads module globals as compile-time constants

MODEL_CODES = dynamics_kernel.MODEL_CODES


@jit
def closed_loop_run(q, m, t_ns, limit_ns, control_ns, period_ns, sample_ns, sample_period_ns,
                    h_max, method, weights, split_axes, moments, model, coefficient, axes, p2b,
                    mode, target, law_axes, law_moments, kp, kd, kw, rate_limit, torque_limit,
                    gyroscopic, inertia, clip, mission_start, free_time, exit_rate, tau_body,
                    tau_p, t_out, q_out, m_out, tau_out, row, out):
    """Advance (q, m) in place from ``t_ns`` through every event instant before
    ``limit_ns``: the law at each control instant ``control_ns + k·period_ns`` (``NEVER``:
    no law; ``tau_p`` is then the held principal-frame torque), and a sample at each
    instant ``sample_ns + k·sample_period_ns``, written to rows ``row, row + 1, …`` of
    ``t_out``, ``q_out``, ``m_out``, ``tau_out`` (body-frame torque) until they are full.
    Every event at ``t_ns`` has been processed by the caller; the state ends at the last
    event processed (a law instant and a sample at one instant: the law first, as the
    engine's event loop does). ``moments``, ``axes``, ``p2b``: the simulated body;
    ``law_*``, ``inertia``: the controller's model of it (its own ``inertia`` parameter),
    as :class:`control.AttitudeController` uses.

    ``tau_body`` (in/out): the held body-frame torque (zeros = none). ``out`` (int64, 9):
    [next control instant, mode, free (1/0), steps, evaluations, failed step or -1, rows
    written, time reached (ns), next sample instant]; on a failure, ``out[0]`` is the start
    (ns) of the failing segment and the return value its step h. Returns the last step h."""
    tau_unsat = np.empty(3)
    scratch = np.empty((10, 4))  # the Runge–Kutta loops' stages, allocated once
    qb = np.empty(4)
    wb = np.empty(3)
    law = control_ns < NEVER_NS
    has_tau = False
    for i in range(3):
        has_tau = has_tau or tau_body[i] != 0.0
    if law:
        for j in range(3):
            tau_p[j] = (tau_body[0] * axes[0, j] + tau_body[1] * axes[1, j]
                        + tau_body[2] * axes[2, j])
    free = out[2]
    steps = 0
    evals = 0
    h = 0.0
    t = t_ns
    rows = 0
    capacity = len(t_out)
    while row + rows < capacity:
        seg_end = min(control_ns, sample_ns)
        if seg_end >= limit_ns:
            break
        span = seg_end - t
        # equal steps no longer than h_max, split as Engine._integrate splits them
        n = max(1, int(math.ceil(span / (h_max * 1e9) - 1e-9)))
        h = span / (n * 1e9)
        if method == 0:
            failed, e = splitting_kernel.splitting_run(
                q, m, h, n, weights, split_axes, moments, tau_p, has_tau, model, coefficient,
                splitting_kernel.inner_dissipation(m, h, weights, moments, model,
                                                   coefficient))
            evals += e
        elif method == 1:
            failed = explicit_kernel.rk4_steps(q, m, h, n, moments, tau_p, model, coefficient,
                                               scratch)
            evals += 4 * (n if failed < 0 else failed + 1)
        else:
            failed = explicit_kernel.euler_steps(q, m, h, n, moments, tau_p, model, coefficient,
                                                 scratch)
            evals += n if failed < 0 else failed + 1
        if failed >= 0:
            out[0] = t
            out[3] = steps + failed + 1
            out[4] = evals
            out[5] = failed
            out[6] = rows
            return h
        steps += n
        t = seg_end
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
        if t == sample_ns:
            finite = True
            for i in range(4):
                finite = finite and math.isfinite(q[i])
            for i in range(3):
                finite = finite and math.isfinite(m[i])
            if not finite:  # the loops check every step; this is the sample's own check
                out[0] = t
                out[3] = steps
                out[4] = evals
                out[5] = -2
                out[6] = rows
                return h
            r = row + rows
            t_out[r] = t
            for i in range(4):
                q_out[r, i] = q[i]
            for i in range(3):
                m_out[r, i] = m[i]
                tau_out[r, i] = tau_body[i]
            rows += 1
            sample_ns += sample_period_ns
    out[0] = control_ns
    out[1] = mode
    out[2] = free
    out[3] = steps
    out[4] = evals
    out[5] = -1
    out[6] = rows
    out[7] = t
    out[8] = sample_ns
    return h


# it calls the step loops and the law from their own files (see jit.depends_on)
closed_loop_run = depends_on(closed_loop_run, splitting_kernel, explicit_kernel,
                             dynamics_kernel, control_kernel)


def advance(engine, until_ns: int, cap: int) -> int:
    """Every sample and control instant up to ``until_ns`` (before the run's end and any
    other source's event) in one compiled kernel, the samples written straight into the
    engine's block builder (at most up to ``cap`` rows); returns the rows written. It
    applies when the method has a compiled loop and only the law (no held command) or
    only a held command acts; otherwise it returns 0 and ``Engine.advance`` goes event
    by event."""
    c, law = engine.config, engine._law
    code = None if engine._integ is None else engine._integ.loop_code  # the method's own
    if engine._selection is not None or code is None:
        return 0
    b = engine._builder
    limit = min(engine.end_ns, engine.command.next_event(), until_ns + 1)
    if law is not None:
        if (engine.command.torque is not None or engine.command.expiry != NEVER
                or not (engine._torque_seen or c.integrator != specs.AUTO)):
            return 0
        control_ns = law.next_t
    else:
        control_ns = NEVER
    # the events at the current instant (t = 0's sample and law) are the event loop's
    if min(control_ns, engine._next_sample) >= limit or b.n >= cap or \
            min(control_ns, engine._next_sample) <= engine.t_ns:
        return 0
    spec = engine._integ.loop_spec()
    if spec is None:
        return 0
    d = engine.dynamics.dissipation
    q, m = engine._q.copy(), engine._m.copy()
    out = np.zeros(9, dtype=np.int64)
    if law is not None:
        settings, ctl, mission = law.settings, law.controller, law.mission
        cfg, model_body = ctl.config, ctl.config.body
        if mission.start is None:
            mission.start = law.next_t / NS
        tau = np.zeros(3) if law.torque is None else np.array(law.torque, float)
        tau_p = np.zeros(3)
        out[2] = law.free
        law_args = (MODE_CODES[ctl.mode], ctl.target, model_body.principal_axes,
                    model_body.principal_moments, cfg.kp_principal, cfg.kd_principal,
                    cfg.rate_gain_principal, cfg.rate_limit, cfg.torque_limit,
                    cfg.gyroscopic_compensation, model_body.inertia, law.clip, mission.start,
                    mission.free_time, mission.detumble_exit_rate)
        period = settings.period_ns
    else:  # the held command (or nothing): constant over the whole stretch
        tau = np.zeros(3) if engine._tau_body is None else np.array(engine._tau_body, float)
        tau_p = np.zeros(3) if engine._tau_p is None else np.array(engine._tau_p, float)
        law_args, period = _NO_LAW, 1
    if law is not None and control_ns < limit:
        # the stretch's last law instant goes through the event loop, so that law.last
        # holds the law's latest evaluation (saturation, error angle) as without the
        # kernel; one Python evaluation per call, not per instant
        limit = control_ns + (limit - 1 - control_ns) // period * period
        if min(control_ns, engine._next_sample) >= limit:
            return 0
    h = closed_loop_run(
        q, m, engine.t_ns, limit, control_ns, period, engine._next_sample,
        c.sample_period_ns, engine.step_max, code, spec[0], spec[1],
        engine.dynamics.moments, MODEL_CODES[d.model] if d.active else 0, d.coefficient,
        engine.body.principal_axes, engine.body.principal_to_body, *law_args, tau, tau_p,
        b._t[:cap], b._q[:cap], b._m[:cap], b._tau[:cap], b.n, out)
    next_control, mode, free, steps, evals, failed, rows, t_end, next_sample = \
        (int(v) for v in out)
    engine.steps += steps
    engine._integ.nfev += evals
    b.n += rows
    if failed >= 0:
        engine.fault = 'state became non-finite (the method diverged)'
        raise IntegrationError(engine.method, h, (next_control + (failed + 1) * h * NS) / NS,
                               engine.fault)
    if failed == -2:
        engine.fault = f'state became non-finite at t = {next_control / NS:.9g} s'
        raise IntegrationError(engine.method, engine.step_max, next_control / NS,
                               engine.fault)
    engine._q, engine._m, engine.t_ns, engine._next_sample = q, m, t_end, next_sample
    if law is not None:
        law.next_t, law.free, law.last = next_control, bool(free), None
        if mode != MODE_CODES[ctl.mode]:
            ctl.set_mode(next(k for k, v in MODE_CODES.items() if v == mode))
        law.torque = tau if tau.any() else None
        engine._update_torque()
    return rows


def _frozen(a):
    a.setflags(write=False)
    return a


# the law's arguments when no law runs (never read: its instant is NEVER), typed as the
# law's own (read-only model arrays), so that both share one compiled kernel
_NO_LAW = (0, np.array([0.0, 0.0, 0.0, 1.0]), _frozen(np.eye(3)), _frozen(np.ones(3)),
           _frozen(np.zeros(3)), _frozen(np.zeros(3)), _frozen(np.zeros(3)), 0.0, 0.0, False,
           _frozen(np.eye(3)), 0.0, 0.0, 0.0, 0.0)
