"""Lockstep's direct period: one control period of a lockstep exchange in one compiled call.

As fast as possible in lockstep, the simulator's exchange is: apply the held instant's
command, step to the next control instant, publish that instant's state, hold. Through
:meth:`Engine.advance` the step alone cost ~22 µs of CPU (100 Hz, slew, splitting4;
``tools.lockstep_parts``), of which the physics is ~3: the rest was Python deciding, packing
and taking back what the general closed loop (``closed_loop_args``) needs for any stretch
of events (a law, dop853's memory, a block of samples), and the compiled call's own
argument handling (~2.6 µs for its 24 arrays). Here a period that is one plain stretch
(a fixed-step method, only the held command acting, the next instant a sample and no
other event before it) runs in :func:`period_kernel` with nine arguments: the same steps
as the closed loop's (``sample_kernel.fixed_steps``, the interval split as
``Engine._integrate`` splits it), and the instant's 17 sample values
(``SampleBlock.values``, the formulas of ``samples._row_values``) written beside the
constants, so that the node packs the messages from them directly. apply_command and
the period, hot: ~7 µs (the kernel ~4 of it, 5 splitting4 steps). The state and the
values are the general path's bit for bit (test_lockstep_direct); anything else
(dop853, a law, sensors, actuators, magnetorquers, an orbit re-anchored per interval,
exact's torque-free closed form, the run's end, a command's expiry, ``auto`` choosing, a
fault) goes the general way.
"""
import math

import numpy as np

from ..physics import dynamics_kernel
from ..physics.environment import facets_kernel, magnetic_kernel
from ..physics.integrators import exact_flow_kernel, explicit_kernel, splitting_kernel
from ..physics.jit import depends_on, jit
from ..physics.orbit import kernel as orbit_kernel
from . import sample_kernel
from .sample_kernel import DOP853, SPLITTING, fixed_steps, split

# period_kernel's real array ``f``: the step, the damping coefficient, the body's
# constants for the sample's values (principal → body rotation, principal moments, axes
# row by row), the values written (SampleBlock.values order), the dynamics' moments, then
# the method's weights (``ticks[WEIGHTS]`` of them)
H_MAX, COEFFICIENT, P2B, MOMENTS, AXES, VALUES, DYNAMICS, WEIGHTS_AT = \
    0, 1, 2, 6, 9, 18, 35, 38
# its integer array ``ticks``: from, to (ns), the method's loop and damping codes, the
# number of its weights and its split axes; then what it reports: the steps and
# evaluations done, the failing step (-1: none; -2: the state at the instant is not
# finite)
T_NS, UNTIL_NS, METHOD, MODEL, WEIGHTS, SPLIT_AXES, STEPS, EVALS, FAILED, N_TICKS = \
    0, 1, 2, 3, 4, 5, 8, 9, 10, 11


@jit
def period_kernel(f, ticks, env, q_in, m_in, tau, tau_p, q, m):
    """Advance (q_in, m_in) from ``ticks[T_NS]`` to ``ticks[UNTIL_NS]`` under the held
    torque ``tau`` (body frame; ``tau_p`` principal) into (q, m), as
    ``closed_loop.closed_loop_run`` steps one interval between events without a law, then
    write the sample's values into ``f[VALUES:]``. The method's and the body's constants
    are in ``f`` and ``ticks`` (one array each where the closed loop takes 24: their
    handling per call is most of a small kernel's); ``env`` is the dynamics' environment
    array (None: none). Returns the last step h."""
    weights = f[WEIGHTS_AT:WEIGHTS_AT + ticks[WEIGHTS]]
    split_axes = ticks[SPLIT_AXES:SPLIT_AXES + 3]
    moments = f[DYNAMICS:DYNAMICS + 3]
    for i in range(4):
        q[i] = q_in[i]
    for i in range(3):
        m[i] = m_in[i]
    has_tau = tau[0] != 0.0 or tau[1] != 0.0 or tau[2] != 0.0
    t = ticks[T_NS]
    span = ticks[UNTIL_NS] - t
    method = ticks[METHOD]
    model = ticks[MODEL]
    coefficient = f[COEFFICIENT]
    n, h = split(span, f[H_MAX])
    t0 = t / 1e9
    scratch = np.empty((10, 4))
    q_flow = np.empty(4)
    m_flow = np.empty(3)
    inner = method == SPLITTING and splitting_kernel.inner_dissipation(
        m, h, weights, moments, model, coefficient)
    failed, e = fixed_steps(method, q, m, h, n, weights, split_axes, moments, tau_p, has_tau,
                            model, coefficient, inner, scratch, q_flow, m_flow, t0, env)
    ticks[STEPS] = n
    ticks[EVALS] = e
    ticks[FAILED] = failed
    if failed >= 0:
        return h
    finite = True
    for i in range(4):
        finite = finite and math.isfinite(q[i])
    for i in range(3):
        finite = finite and math.isfinite(m[i])
    if not finite:
        ticks[FAILED] = -2
        return h
    # samples._row_values, operation for operation (a = q ⊗ conj(p): body attitude; ω, L
    # inertial, L body, the kinetic energy, the held body torque)
    qx, qy, qz, qw = q[0], q[1], q[2], q[3]
    cx, cy, cz, cw = -f[P2B], -f[P2B + 1], -f[P2B + 2], f[P2B + 3]
    ax = qw * cx + qx * cw + qy * cz - qz * cy
    ay = qw * cy - qx * cz + qy * cw + qz * cx
    az = qw * cz + qx * cy - qy * cx + qz * cw
    aw = qw * cw - qx * cx - qy * cy - qz * cz
    norm = math.sqrt(ax * ax + ay * ay + az * az + aw * aw)
    ix, iy, iz = f[MOMENTS], f[MOMENTS + 1], f[MOMENTS + 2]
    m0, m1, m2 = m[0], m[1], m[2]
    w0, w1, w2 = m0 / ix, m1 / iy, m2 / iz
    r00, r01, r02 = f[AXES], f[AXES + 1], f[AXES + 2]
    r10, r11, r12 = f[AXES + 3], f[AXES + 4], f[AXES + 5]
    r20, r21, r22 = f[AXES + 6], f[AXES + 7], f[AXES + 8]
    tx, ty, tz = 2 * (qy * m2 - qz * m1), 2 * (qz * m0 - qx * m2), 2 * (qx * m1 - qy * m0)
    v = f[VALUES:]
    v[0], v[1], v[2], v[3] = ax / norm, ay / norm, az / norm, aw / norm
    v[4] = r00 * w0 + r01 * w1 + r02 * w2
    v[5] = r10 * w0 + r11 * w1 + r12 * w2
    v[6] = r20 * w0 + r21 * w1 + r22 * w2
    v[7] = m0 + qw * tx + (qy * tz - qz * ty)
    v[8] = m1 + qw * ty + (qz * tx - qx * tz)
    v[9] = m2 + qw * tz + (qx * ty - qy * tx)
    v[10] = r00 * m0 + r01 * m1 + r02 * m2
    v[11] = r10 * m0 + r11 * m1 + r12 * m2
    v[12] = r20 * m0 + r21 * m1 + r22 * m2
    v[13] = 0.5 * (m0 * m0 / ix + m1 * m1 / iy + m2 * m2 / iz)
    v[14], v[15], v[16] = tau[0], tau[1], tau[2]
    return h


# it inlines the step loops from their own files (see jit.depends_on)
period_kernel = depends_on(period_kernel, sample_kernel, splitting_kernel, explicit_kernel,
                           exact_flow_kernel, dynamics_kernel, orbit_kernel, magnetic_kernel,
                           facets_kernel)


class DirectPeriod:
    """The direct period of one engine (see the module docstring): :meth:`step`."""

    def __init__(self, engine):
        self.engine = engine
        self.f = np.zeros(WEIGHTS_AT)  # and the weights (_pack)
        self.ticks = np.zeros(N_TICKS, dtype=np.int64)
        self._zero = np.zeros(3)  # a torque held as None
        self._key = (None, None, None, None)  # what the packed constants came from
        self._able = False  # whether its periods can be direct at all (_pack)
        self._free = False  # exact without damping or environment: free without torque
        self._end = 0
        self._written = None

    def _pack(self, e):
        """What a period needs of the engine that changes only with its integrator,
        configuration, dynamics or body (their identities, checked at every period):
        whether its periods can be direct at all, the method's and the body's
        constants."""
        integ = e._integ
        self._key, self._able = (integ, e.config, e.dynamics, e.body), False
        self._written = None  # (step, coefficient) in f (step: written when they change)
        code = None if integ is None else integ.loop_code
        spec = None if code is None else integ.loop_spec()
        if spec is None or code == DOP853 or e._law is not None or e._sensors is not None \
                or e.magnetics is not None or e.actuators is not None or \
                not e.compiled_loop or e.interpolate_samples or e.orbit_anchored:
            return
        weights, split_axes = spec[0], spec[1]
        body = e.body
        self.f = f = np.zeros(WEIGHTS_AT + len(weights))
        f[P2B:P2B + 4] = body.principal_to_body
        f[MOMENTS:MOMENTS + 3] = body.principal_moments
        f[AXES:AXES + 9] = np.asarray(body.principal_axes).ravel()
        f[DYNAMICS:DYNAMICS + 3] = e.dynamics.moments
        f[WEIGHTS_AT:] = weights
        ticks = self.ticks
        ticks[METHOD], ticks[MODEL], ticks[WEIGHTS] = code, integ.loop_model(), len(weights)
        ticks[SPLIT_AXES:SPLIT_AXES + 3] = split_axes
        self._able = True
        self._free = e.method == 'exact' and not e.dynamics.dissipation.active and \
            not e.dynamics.environment_active  # Stepping._free_exact but the torque
        self._end = e.end_ns

    def prepared(self) -> bool:
        """Whether the engine's periods can be direct now (its method, its body, no
        selection pending, not finished, no fault), ``f``'s constants written for them;
        what ``step`` checks beside the period's own conditions (``nodes/rcl_loop.py``
        checks those per period)."""
        e = self.engine
        key = self._key
        if e._integ is not key[0] or e.config is not key[1] or e.dynamics is not key[2] \
                or e.body is not key[3]:
            self._pack(e)
        if not self._able or e._selection is not None or e.finished or e.fault:
            return False
        # each numpy call of a period counts: one that follows a wake-up costs several
        # times its cost in a loop (tools.lockstep_parts), so what rarely changes is
        # written only when it does, and the counts are read in one call
        written = (e.step_max, e.dynamics.dissipation.coefficient)
        if written != self._written:
            self.f[H_MAX], self.f[COEFFICIENT] = self._written = written
        return True

    def step(self, until_ns: int):
        """The sample values (a list of 17 floats, ``SampleBlock.values``) at ``until_ns``,
        the engine advanced there as ``advance(until_ns)`` would advance it; None (the
        engine untouched) where the period is not one plain stretch, or the method failed
        (the general path then meets the failure and reports it)."""
        e = self.engine
        tau_p = e._tau_p
        if not self.prepared() or until_ns != e._next_sample or until_ns <= e.t_ns or \
                until_ns >= self._end or e.command.expiry <= until_ns or \
                (tau_p is None and self._free):
            return None
        tau = e._tau_body
        zero = self._zero
        f, ticks = self.f, self.ticks
        ticks[T_NS], ticks[UNTIL_NS] = e.t_ns, until_ns
        q, m = np.empty(4), np.empty(3)
        period_kernel(f, ticks, e.dynamics.environment, e._q, e._m,
                      zero if tau is None else tau, zero if tau_p is None else tau_p, q, m)
        counts = ticks.tolist()
        if counts[FAILED] != -1:
            return None
        steps, evaluations = counts[STEPS], counts[EVALS]
        e._q, e._m, e.t_ns = q, m, until_ns
        e._next_sample = until_ns + e.config.sample_period_ns
        e.steps += steps
        e._integ.nfev += evaluations
        return f[VALUES:DYNAMICS].tolist()


def warm_engine(engine) -> bool:
    """Load the kernel with the argument types ``engine``'s periods will pass (a live
    lockstep node, before its t = 0): a fresh engine of its configuration, with a small
    held command, one direct period. True if it ran one."""
    from .core import Engine
    c = engine.config
    copy = Engine(c, blocking_selection=False)
    while copy.selection_pending and not copy.fault:
        copy.work()
    copy.advance(copy.t_ns)  # the instant's own events (t = 0's sample)
    copy.apply_command((1e-3 * c.max_torque,) * 3 if c.max_torque else (1e-6,) * 3)
    return DirectPeriod(copy).step(copy._next_sample) is not None


def warm() -> bool:
    """Load (or compile) the kernel for a body without an environment (setup)."""
    from .config import EngineConfig
    from .core import Engine
    return warm_engine(Engine(EngineConfig.from_parameters(
        {'integrator': 'splitting4', 'duration': 1.0, 'publish_rate': 10.0})))
