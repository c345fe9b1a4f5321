"""The ``exact`` method's compiled loop with torque or dissipation (``exact_flow.py``).

Each step is the symmetric splitting D(h/2) K(h/2) Φ(h) K(h/2) D(h/2): the damping's
sub-flow D (``dynamics_kernel._dissipate``, as the splittings take it), the held torque's
kick K, and the exact torque-free flow Φ built afresh from the step's state
(``exact.build.flow``, a one-shot closed form). ``Exact._step`` takes the same sub-flows
one step at a time from Python (~20 µs a step); this loop runs n of them in one call, so
the engine's compiled closed loop can step ``exact`` between samples without a Python
round trip (``engine/closed_loop.py``).
"""
import math

import numpy as np

from .. import dynamics_kernel
from ..dynamics_kernel import _dissipate, _finite
from ..exact import build as exact_build, constants, double_double, elliptic_kernel
from ..exact import kernel as exact_kernel
from ..jit import COMPILED, depends_on, jit


@jit
def exact_steps(q, m, h, n, moments, tau, has_tau, model, coefficient, q_out, m_out):
    """n split steps of h from (q, m), in place; q_out (4,), m_out (3,): scratch for the
    flow's output. q is normalised before each flow (as ``Exact._flow``). Returns (first
    non-finite step or -1, evaluations: one per flow plus the damping's sub-flows)."""
    evals = 0
    for k in range(n):
        evals += _dissipate(m, 0.5 * h, moments, model, coefficient, False)
        if has_tau:
            for i in range(3):
                m[i] = m[i] + (0.5 * h) * tau[i]
        norm = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
        if not (math.isfinite(norm) and norm > 0.0 and _finite(q, m)):
            return k, evals
        for i in range(4):
            q[i] = q[i] / norm
        exact_build.flow(moments, q, m, h, q_out, m_out)
        for i in range(4):
            q[i] = q_out[i]
        for i in range(3):
            m[i] = m_out[i]
        evals += 1
        if has_tau:
            for i in range(3):
                m[i] = m[i] + (0.5 * h) * tau[i]
        evals += _dissipate(m, 0.5 * h, moments, model, coefficient, False)
        if not _finite(q, m):
            return k, evals
    return -1, evals


# it calls the closed form and the damping of other files (see jit.depends_on)
exact_steps = depends_on(exact_steps, dynamics_kernel, exact_build, exact_kernel, constants,
                         double_double, elliptic_kernel)


def warm():
    """Compile (or load from the cache) the loop, damped and with torque: with the
    integrator's own moments and with the engine's read-only model arrays (its compiled
    sample loop passes those: a second signature, which an offline run of explorer1 at
    50 s otherwise loaded inside its clock, 11 ms of a 0.3 ms run)."""
    moments = np.array([1.0, 2.0, 3.0])
    frozen = moments.copy()
    frozen.setflags(write=False)
    for inertia in (moments, frozen):
        q = np.array([0.0, 0.0, 0.0, 1.0])
        m = np.array([0.1, 1.0, 0.2])
        exact_steps(q, m, 1e-3, 1, inertia, np.zeros(3), False, 1, 0.1, np.empty(4),
                    np.empty(3))
    return COMPILED
