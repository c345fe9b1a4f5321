"""The engine's side of the compiled closed loop (``closed_loop.closed_loop_run``): when
it applies, its arguments, and its results taken back.

:func:`advance` decides whether a stretch of events can run in the kernel (a method with
a compiled loop, only the law or only a held command acting, no re-anchored orbit), packs
the kernel's arguments from the engine (read, never written) and its :class:`State` into
the engine's :class:`Packing` (kept from call to call), and returns what the kernel did
as a :class:`Stretch` for the engine to take.
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


class Packing:
    """``closed_loop_run``'s arguments for one engine, kept from call to call: packing them
    afresh cost ~2.3 of a call's ~15.5 CPU µs (a lockstep exchange is a call; the
    method's dissipation code was most of it). The integer, real and result arrays are
    allocated once and written at every call with what changes from call to call
    (instants, state, torques, the step, the law's mode and limits). The groups of arrays
    the kernel reads (the method's, the body's, the law's model) are packed again only
    when the objects they come from are others (a new integrator, dynamics or body,
    controller, gains or target: compared by identity, the objects held); they hold the
    arrays themselves, so a change made in place is seen."""

    def __init__(self):
        self.ticks = np.zeros(N_TICKS, dtype=np.int64)
        self.reals = np.zeros(N_REALS)
        # the results: a run's normal end writes them all; a failure, those it reports
        self.out = np.zeros(N_OUT, dtype=np.int64)
        self.tau = np.zeros(3)  # a held command's torque, body frame (the kernel reads it)
        self.tau_p = np.zeros(3)  # its principal-frame torque (the law's, written by it)
        self._method = self._body = self._law = (None, None)  # (what it came from, groups)

    def method(self, integ):
        """(spec = (weights, split_axes, memory), dissipation code, rtol, atol) of the
        integrator's compiled loop; None if it has none."""
        if self._method[0] is not integ:
            spec, packed = integ.loop_spec(), None
            if spec is not None:
                adaptive = integ.loop_memory()
                memory, rtol, atol = (_NO_MEMORY, 0.0, 0.0) if adaptive is None else adaptive
                packed = ((spec[0], spec[1], memory), integ.loop_model(), rtol, atol)
            self._method = (integ, packed)
        return self._method[1]

    def body(self, dynamics, body):
        """(moments, axes, principal → body, environment's array)."""
        key = self._body[0]
        if key is None or key[0] is not dynamics or key[1] is not body:
            self._body = ((dynamics, body), (dynamics.moments, body.principal_axes,
                                             body.principal_to_body, dynamics.environment))
        return self._body[1]

    def law(self, controller):
        """The controller's model: (target, axes, moments, kp, kd, kw, inertia)."""
        cfg, target, key = controller.config, controller.target, self._law[0]
        if key is None or key[0] is not controller or key[1] is not cfg \
                or key[2] is not target:
            model = cfg.body
            self._law = ((controller, cfg, target), (
                target, model.principal_axes, model.principal_moments, cfg.kp_principal,
                cfg.kd_principal, cfg.rate_gain_principal, model.inertia))
        return self._law[1]


def _copy(torque, into):
    """A held torque (None: none) into the kernel's array."""
    if torque is None:
        into.fill(0.0)
    else:
        into[:] = torque


def advance(engine, state: State, law, builder, until_ns: int, cap: int,
            packing: Packing) -> Optional[Stretch]:
    """Every sample and control instant up to ``until_ns`` (before the run's end and any
    other source's event) in one compiled kernel, from ``state``, the samples written
    straight into ``builder`` (the engine's block, rows from ``builder.n`` up to ``cap``;
    the engine counts them in); ``law``: the in-process ControlLaw or None. Returns the
    :class:`Stretch` (new state, rows, steps, evaluations, error) for the engine to take,
    or None where it does not apply: it needs a method with a compiled loop and only the
    law (no held command) or only a held command acting; otherwise ``Engine.advance`` goes
    event by event. ``engine`` is read, never written; ``packing``: the engine's
    :class:`Packing` of the kernel's arguments."""
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
    method = packing.method(integ)
    if method is None:
        return None
    spec, model, rtol, atol = method
    q, m = state.q.copy(), state.m.copy()
    ticks, reals, tau_p = packing.ticks, packing.reals, packing.tau_p
    if law is not None:
        settings, ctl, mission = law.settings, law.controller, law.mission
        cfg = ctl.config
        if mission.start is None:
            mission.start = law.next_t / NS
        # a new array: the law keeps it as its torque (below)
        tau = np.zeros(3) if law.torque is None else np.array(law.torque, float)
        ticks[FREE] = law.free
        ticks[MODE], ticks[GYROSCOPIC] = MODE_CODES[ctl.mode], cfg.gyroscopic_compensation
        reals[RATE_LIMIT], reals[TORQUE_LIMIT], reals[CLIP] = \
            cfg.rate_limit, cfg.torque_limit, law.clip
        reals[MISSION_START], reals[FREE_TIME], reals[EXIT_RATE] = \
            mission.start, mission.free_time, mission.detumble_exit_rate
        law_arrays = packing.law(ctl)
        period = settings.period_ns
    else:  # the held command (or nothing): constant over the whole stretch, only read
        tau = packing.tau
        _copy(state.tau_body, tau)
        _copy(state.tau_p, tau_p)
        ticks[FREE] = ticks[MODE] = ticks[GYROSCOPIC] = 0
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
    ticks[METHOD], ticks[MODEL], ticks[ROW] = code, model, builder.n
    # samples between steps where the stretch ends at an event of the physics (with the law
    # it ends at a law instant), never at a caller's until_ns, which would split a step
    ticks[INTERPOLATE] = code != DOP853 and (law is not None or physical <= until_ns + 1) \
        and sample_kernel.interpolation_allowed(engine, state.m)
    reals[H_MAX], reals[COEFFICIENT] = engine.step_max, engine.dynamics.dissipation.coefficient
    reals[RTOL], reals[ATOL] = rtol, atol
    out = packing.out
    body = packing.body(engine.dynamics, engine.body)
    h = closed_loop_run((q, m, tau, tau_p), ticks, reals, spec, body, body[3], law_arrays,
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
    # the record made directly, field by field
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
