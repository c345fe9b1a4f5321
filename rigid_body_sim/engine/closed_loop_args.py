"""The engine's side of the compiled closed loop (``closed_loop.closed_loop_run``): when
it applies, its arguments, and its results taken back.

:func:`advance` decides whether a stretch of events can run in the kernel (a method with
a compiled loop, only the law or only a held command acting, no re-anchored orbit), packs
the kernel's arguments from the engine (read, never written) and its :class:`State`, and
returns what the kernel did as a :class:`Stretch` for the engine to take.
"""
from typing import Optional

import numpy as np

from ..control_kernel import MODE_CODES
from ..physics import IntegrationError
from ..physics.integrators import dop853_dense, dop853_kernel
from . import sample_kernel, specs
from .closed_loop import (ADAPTIVE_FAILED, ATOL, CLIP, COEFFICIENT, CONTROL_NS, DOP853,
                          EXIT_RATE, FREE, FREE_TIME, GYROSCOPIC, H_MAX, INTERPOLATE,
                          LIMIT_NS, METHOD, MISSION_START, MODE, MODEL, N_OUT, N_REALS,
                          N_TICKS, NEED_ROOM, PERIOD_NS, RATE_LIMIT, ROW, RTOL, SAMPLE_NS,
                          SAMPLE_PERIOD_NS, T_NS, TORQUE_LIMIT, closed_loop_run)
from .config import NS
from .sources import NEVER
from .state import State, Stretch


def advance(engine, state: State, law, builder, until_ns: int, cap: int) -> Optional[Stretch]:
    """Every sample and control instant up to ``until_ns`` (before the run's end and any
    other source's event) in one compiled kernel, from ``state``, the samples written
    straight into ``builder`` (the engine's block, rows from ``builder.n`` up to ``cap``;
    the engine counts them in); ``law``: the in-process ControlLaw or None. Returns the
    :class:`Stretch` (new state, rows, steps, evaluations, error) for the engine to take,
    or None where it does not apply: it needs a method with a compiled loop and only the
    law (no held command) or only a held command acting; otherwise ``Engine.advance`` goes
    event by event. ``engine`` is read, never written."""
    c = engine.config
    integ = engine.integrator
    code = None if integ is None else integ.loop_code  # the method's own
    if engine.selection_pending or code is None or engine.orbit_anchored:
        return None  # (an SGP4 orbit is re-anchored at every interval: event by event)
    physical = min(engine.end_ns, engine.command.next_event())  # events of the physics
    if engine.magnetics is not None:  # a held dipole's expiry or a new one ends the stretch
        physical = min(physical, engine.magnetics.next_event())
    limit = min(physical, until_ns + 1)
    if law is not None:
        if engine.command.torque is not None or engine.command.expiry != NEVER:
            return None
        control_ns = law.next_t
        if not state.torque_seen and c.integrator == specs.AUTO:
            # auto chooses again at the first torque (Engine._update_torque), which the
            # event loop must see: the kernel runs the mission's free phase only, whose law
            # instants give no torque; the first that may is the event loop's
            limit = min(limit, law.first_instant_after_free(control_ns))
    else:
        control_ns = NEVER
    # the events at the current instant (t = 0's sample and law) are the event loop's
    first = min(control_ns, state.next_sample)
    if first >= limit or builder.n >= cap or first <= state.t_ns:
        return None
    spec = integ.loop_spec()
    if spec is None:
        return None
    adaptive = integ.loop_memory()
    memory, rtol, atol = (_NO_MEMORY, 0.0, 0.0) if adaptive is None else adaptive
    d = engine.dynamics.dissipation
    q, m = state.q.copy(), state.m.copy()
    out = np.zeros(N_OUT, dtype=np.int64)
    ticks = np.zeros(N_TICKS, dtype=np.int64)
    reals = np.zeros(N_REALS)
    if law is not None:
        settings, ctl, mission = law.settings, law.controller, law.mission
        cfg, model_body = ctl.config, ctl.config.body
        if mission.start is None:
            mission.start = law.next_t / NS
        tau = np.zeros(3) if law.torque is None else np.array(law.torque, float)
        tau_p = np.zeros(3)
        ticks[FREE] = law.free
        ticks[MODE], ticks[GYROSCOPIC] = MODE_CODES[ctl.mode], cfg.gyroscopic_compensation
        reals[RATE_LIMIT], reals[TORQUE_LIMIT], reals[CLIP] = \
            cfg.rate_limit, cfg.torque_limit, law.clip
        reals[MISSION_START], reals[FREE_TIME], reals[EXIT_RATE] = \
            mission.start, mission.free_time, mission.detumble_exit_rate
        law_arrays = (ctl.target, model_body.principal_axes, model_body.principal_moments,
                      cfg.kp_principal, cfg.kd_principal, cfg.rate_gain_principal,
                      model_body.inertia)
        period = settings.period_ns
    else:  # the held command (or nothing): constant over the whole stretch
        tau = np.zeros(3) if state.tau_body is None else np.array(state.tau_body, float)
        tau_p = np.zeros(3) if state.tau_p is None else np.array(state.tau_p, float)
        law_arrays, period = _NO_LAW, 1
    if law is not None and control_ns < limit:
        # the stretch's last law instant goes through the event loop, so that law.last
        # holds the law's latest evaluation (saturation, error angle) as without the
        # kernel; one Python evaluation per call, not per instant
        limit = control_ns + (limit - 1 - control_ns) // period * period
        if min(control_ns, state.next_sample) >= limit:
            return None
    ticks[T_NS], ticks[LIMIT_NS], ticks[CONTROL_NS], ticks[PERIOD_NS] = \
        state.t_ns, limit, control_ns, period
    ticks[SAMPLE_NS], ticks[SAMPLE_PERIOD_NS] = state.next_sample, c.sample_period_ns
    ticks[METHOD], ticks[MODEL], ticks[ROW] = code, integ.loop_model(), builder.n
    # samples between steps where the stretch ends at an event of the physics (with the law
    # it ends at a law instant), never at a caller's until_ns, which would split a step
    ticks[INTERPOLATE] = code != DOP853 and (law is not None or physical <= until_ns + 1) \
        and sample_kernel.interpolation_allowed(engine, state.m)
    reals[H_MAX], reals[COEFFICIENT] = engine.step_max, d.coefficient
    reals[RTOL], reals[ATOL] = rtol, atol
    body = engine.body
    h = closed_loop_run(
        (q, m, tau, tau_p), ticks, reals, (spec[0], spec[1], memory),
        (engine.dynamics.moments, body.principal_axes, body.principal_to_body,
         engine.dynamics.environment), law_arrays,
        builder.columns(cap), out)
    next_control, mode, free, steps, evals, failed, rows, t_end, next_sample, status, \
        failed_ns = out.tolist()  # Python ints, in one call (a lockstep exchange's CPU)
    error = None
    if failed == ADAPTIVE_FAILED:  # as DOP853._advance reports it, and starts afresh next
        integ.reset()
        error = IntegrationError(engine.method, h, failed_ns / NS,
                                 dop853_kernel.REASONS[status])
    elif failed >= 0:
        error = IntegrationError(engine.method, h, (next_control + (failed + 1) * h * NS) / NS,
                                 'state became non-finite (the method diverged)')
    elif failed == -2:
        error = IntegrationError(engine.method, engine.step_max, next_control / NS,
                                 f'state became non-finite at t = {next_control / NS:.9g} s')
    if error is not None:
        return Stretch(state, rows, steps, evals, error)
    if law is not None:
        law.next_t, law.free, law.last = next_control, bool(free), None
        if mode != MODE_CODES[ctl.mode]:
            ctl.set_mode(next(k for k, v in MODE_CODES.items() if v == mode))
        law.torque = tau if tau.any() else None
    # the record made directly: dataclasses.replace inspects the fields at every call
    return Stretch(State(q, m, t_end, next_sample, state.tau_body, state.tau_p,
                         state.torque_seen), rows, steps, evals, full=failed == NEED_ROOM)


def _frozen(a):
    a.setflags(write=False)
    return a


_NO_MEMORY = np.zeros(dop853_dense.MEMORY)  # what methods without one pass (never read)

# the law's arrays when no law runs (never read: its instant is NEVER), typed as the
# law's own (read-only model arrays), so that both share one compiled kernel
_NO_LAW = (np.array([0.0, 0.0, 0.0, 1.0]), _frozen(np.eye(3)), _frozen(np.ones(3)),
           _frozen(np.zeros(3)), _frozen(np.zeros(3)), _frozen(np.zeros(3)),
           _frozen(np.eye(3)))
