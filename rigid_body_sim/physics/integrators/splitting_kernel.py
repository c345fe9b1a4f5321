"""The splittings' compiled loops (``splitting.py``'s classes, ``lstable.py``'s): one body
(``splitting_run``) and a range of a batch's bodies (``splitting_bodies``), in the
conventions of ``dynamics_kernel``.
"""
import math

import numpy as np

from .. import dynamics_kernel
from ..dynamics_kernel import _axis_flow, _dissipate, _finite
from ..environment import facets_kernel, magnetic_kernel
from ..jit import COMPILED, depends_on, jit
from ..orbit import kernel as orbit_kernel

INNER_LIMIT = 0.5  # |w|·h·λ up to which damping goes inside the compositions (weak damping)


@jit
def weak_damping(norm, h, w_max, moments, model, coefficient):
    """|w|·h·λ(|m|) ≤ INNER_LIMIT, λ the dissipation's stiffness at |m| = ``norm``
    (``Dynamics.dissipation_stiffness`` in the same operations; ``model`` ≠ 0): whether a
    composition with largest |weight| ``w_max`` runs the damping inside its stages at step
    h. The one rule of ``Splitting2`` and of the engine's compiled closed loop."""
    i_min = min(moments[0], min(moments[1], moments[2]))
    i_max = max(moments[0], max(moments[1], moments[2]))
    if model == 1:  # double bracket: α|L|²(1/I_min − 1/I_max)
        stiffness = coefficient * norm ** 2 * (1.0 / i_min - 1.0 / i_max)
    else:           # viscous: c/I_min
        stiffness = coefficient * (1.0 / i_min)
    return stiffness * h * w_max <= INNER_LIMIT


@jit
def weak_damping_bodies(norms, h, w_max, moments, model, coefficient, out):
    """:func:`weak_damping` for each of a batch's momentum norms, into ``out`` (bool)."""
    for i in range(len(norms)):
        out[i] = weak_damping(norms[i], h, w_max, moments, model, coefficient)


@jit
def inner_dissipation(m, h, weights, moments, model, coefficient):
    """Whether one body's damping goes inside the composition ``weights`` at step h
    (``Splitting2.inner_dissipation``): never without damping or for Strang itself."""
    if model == 0 or len(weights) == 1:
        return False
    w_max = 0.0
    for w in weights:
        w_max = max(w_max, abs(w))
    norm = math.sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2])
    return weak_damping(norm, h, w_max, moments, model, coefficient)


@jit
def splitting_run(q, m, h, n, weights, axes, moments, tau, has_tau, model, coefficient, inner,
                  t0, env):
    """n steps of D(h/2) · Π_w [K(wh/2) a(wh/2) b(wh/2) c(wh) b(wh/2) a(wh/2) K(wh/2)] · D(h/2).

    ``inner``: dissipation inside every stage instead, by a time-symmetric flow —
    Π_w [D K a b c b a K D](wh) — which keeps the composition's order (weak damping only:
    negative stages run it backwards).

    The environment's torque (``env``: gravity gradient, rods, SRP, drag) joins the kicks
    K: it depends on the attitude and the time, never on m, so its flow at fixed attitude
    is exactly a kick
    m ← m + (wh/2)·τ(q, t), evaluated at the kick's instant (Touma & Wisdom 1994). Time
    advances with the free flow (a b c b a), so in a stage starting at t the first kick
    is at t and the second at t + wh: the composition stays symmetric in the extended
    phase space and keeps its order. The first step starts at ``t0`` (s); ``env`` None
    (the free body) prunes the kicks from the compiled code.
    Returns (first non-finite step or -1, evaluations)."""
    a = axes[0]
    b = axes[1]
    c = axes[2]
    evals = 0
    # the environment's torque at a stage's end is the next stage's at its start (same q,
    # same t: only m moves between them), so it is evaluated once for both kicks, and the
    # orbit's frame once per call (orbit_kernel.frame): the same numbers, s + 1 torques a
    # step instead of 2s
    gx = gy = gz = bx = by = bz = fx = fy = fz = 0.0
    if env is not None:
        fr = orbit_kernel.frame(env, t0)
    for k in range(n):
        if not inner:
            evals += _dissipate(m, 0.5 * h, moments, model, coefficient, False)
        t = t0 + k * h
        for j in range(len(weights)):
            hw = weights[j] * h
            if inner:
                evals += _dissipate(m, 0.5 * hw, moments, model, coefficient, True)
            if has_tau:
                for i in range(3):
                    m[i] = m[i] + (0.5 * hw) * tau[i]
            # the kick at the stage's start; spelled out, not through
            # dynamics_kernel.kick_environment (the same terms, bit for bit): inlined here
            # twice, that made gravity_gradient's splitting4 15 % slower (129 -> 146-155 ms
            # for 1e5 steps, /tmp timing, A/B at load 0.8)
            if env is not None:
                if j == 0:
                    if env[orbit_kernel.ON] != 0.0:
                        ux, uy, uz, r = orbit_kernel.radial_framed(env, t, fr)
                        gx, gy, gz = orbit_kernel.gravity_gradient_at(q, ux, uy, uz, r, env,
                                                                      moments)
                    if env[orbit_kernel.MAG_MODEL] != 0.0:
                        bx, by, bz = magnetic_kernel.magnetorquer_torque(q, t, env)
                    if env[orbit_kernel.SRP_ON] != 0.0 or env[orbit_kernel.DRAG_ON] != 0.0:
                        fx, fy, fz = facets_kernel.facets_torque(q, t, env)
                if env[orbit_kernel.ON] != 0.0:
                    m[0] = m[0] + (0.5 * hw) * gx
                    m[1] = m[1] + (0.5 * hw) * gy
                    m[2] = m[2] + (0.5 * hw) * gz
                if env[orbit_kernel.MAG_MODEL] != 0.0:
                    m[0] = m[0] + (0.5 * hw) * bx
                    m[1] = m[1] + (0.5 * hw) * by
                    m[2] = m[2] + (0.5 * hw) * bz
                if env[orbit_kernel.SRP_ON] != 0.0 or env[orbit_kernel.DRAG_ON] != 0.0:
                    m[0] = m[0] + (0.5 * hw) * fx
                    m[1] = m[1] + (0.5 * hw) * fy
                    m[2] = m[2] + (0.5 * hw) * fz
            _axis_flow(q, m, a, 0.5 * hw, moments)
            _axis_flow(q, m, b, 0.5 * hw, moments)
            _axis_flow(q, m, c, hw, moments)
            _axis_flow(q, m, b, 0.5 * hw, moments)
            _axis_flow(q, m, a, 0.5 * hw, moments)
            t += hw
            if has_tau:
                for i in range(3):
                    m[i] = m[i] + (0.5 * hw) * tau[i]
            if env is not None:
                if env[orbit_kernel.ON] != 0.0:
                    ux, uy, uz, r = orbit_kernel.radial_framed(env, t, fr)
                    gx, gy, gz = orbit_kernel.gravity_gradient_at(q, ux, uy, uz, r, env,
                                                                  moments)
                    m[0] = m[0] + (0.5 * hw) * gx
                    m[1] = m[1] + (0.5 * hw) * gy
                    m[2] = m[2] + (0.5 * hw) * gz
                if env[orbit_kernel.MAG_MODEL] != 0.0:
                    bx, by, bz = magnetic_kernel.magnetorquer_torque(q, t, env)
                    m[0] = m[0] + (0.5 * hw) * bx
                    m[1] = m[1] + (0.5 * hw) * by
                    m[2] = m[2] + (0.5 * hw) * bz
                if env[orbit_kernel.SRP_ON] != 0.0 or env[orbit_kernel.DRAG_ON] != 0.0:
                    fx, fy, fz = facets_kernel.facets_torque(q, t, env)
                    m[0] = m[0] + (0.5 * hw) * fx
                    m[1] = m[1] + (0.5 * hw) * fy
                    m[2] = m[2] + (0.5 * hw) * fz
            if inner:
                evals += _dissipate(m, 0.5 * hw, moments, model, coefficient, True)
        if not inner:
            evals += _dissipate(m, 0.5 * h, moments, model, coefficient, False)
        evals += len(weights)
        if not _finite(q, m):
            return k, evals
    return -1, evals


@jit
def splitting_bodies(q, m, lo, hi, h, n, weights, axes, moments, tau, has_tau, model,
                     coefficient, inner):
    """splitting_run on bodies lo … hi−1 of q (N, 4), m (N, 3), in place: a batch's bodies
    with dissipation, or ones re-run unmerged (``splitting_batch_kernel``; here, not there, because
    numba's disk cache of a function tracks only its own file). tau (1, 3) shared or
    (N, 3); inner (1,) shared or (N,). Returns (first non-finite step or -1, a body that
    fails there, the largest evaluation count of one body). After a failure later bodies
    run only the steps before it: only an earlier failure can change the answer."""
    qs = np.empty(4)
    ms = np.empty(3)
    failed = -1
    failed_body = -1
    limit = n
    evals = 0
    for i in range(lo, hi):
        for j in range(4):
            qs[j] = q[i, j]
        for j in range(3):
            ms[j] = m[i, j]
        bad, used = splitting_run(qs, ms, h, limit, weights, axes, moments,
                                  tau[i % tau.shape[0]], has_tau, model, coefficient,
                                  inner[i % inner.shape[0]], 0.0, None)
        for j in range(4):
            q[i, j] = qs[j]
        for j in range(3):
            m[i, j] = ms[j]
        evals = max(evals, used)
        if bad >= 0:
            failed = bad
            failed_body = i
            limit = bad
    return failed, failed_body, evals


# they call the shared flows of another file (see jit.depends_on)
splitting_run = depends_on(splitting_run, dynamics_kernel, orbit_kernel, magnetic_kernel,
                           facets_kernel)
splitting_bodies = depends_on(splitting_bodies, dynamics_kernel, orbit_kernel,
                              magnetic_kernel, facets_kernel)


def warm():
    """Compile (or load from the cache) the splitting loop, damping outside and inside."""
    q = np.array([0.0, 0.0, 0.0, 1.0])
    m = np.array([0.1, 1.0, 0.2])
    for inner in (False, True):
        splitting_run(q, m, 1e-3, 1, np.array([1.0]), np.array([0, 2, 1]),
                      np.array([1.0, 2.0, 3.0]), np.zeros(3), False, 1, 0.1, inner, 0.0,
                      None)
    return COMPILED
