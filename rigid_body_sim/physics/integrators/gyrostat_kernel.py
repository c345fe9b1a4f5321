"""Compiled gyrostat step loop: a rigid body carrying reaction wheels and single-gimbal CMGs.

State (principal frame of the body, as in ``dynamics_kernel``): q (4,) principal → inertial,
m (3,) the body's own momentum I·ω, hw (N,) the wheels' absolute axial momenta
(h_i = J_i (a_i·ω + Ω_i), Hughes' form: the body inertia I excludes the wheels' spin-axis
inertia) and delta (K,) the CMG gimbal angles. The total momentum is

    H = I ω + Σ h_i a_i + Σ h0_j s_j(δ_j),     s_j(δ) = cos δ s0_j + sin δ (g_j × s0_j),

and in the body frame Ḣ = H × ω + τ_ext. The motors exchange momentum inside the body
(ḣ_i = u_i, δ̇_j = rate_j) without changing H.

Step (Strang, order 2): half a kick of the actuators (wheel momenta and gimbal angles move,
H does not), the body's flow with the actuator momentum h_A frozen, half a kick. The body's
flow is split as in ``splitting_kernel.splitting_run`` into exact rotations about the principal
axes: the Hamiltonian Σ_k (H_k − h_A,k)²/(2 I_k) has per-axis flows that rotate H (by −φ)
and q (by +φ) about axis k at the constant rate (H_k − h_A,k)/I_k. Every sub-flow is a
rotation, so |H| and the inertial H = R(q) H are kept to round-off, with or without
motor torque (the kicks are internal).

Commands are held over the whole step: wheel torques u (N·m) and gimbal rates (rad/s),
either given (forward commands) or allocated at the start of each step from a desired
body torque (wheels: u = −P τ with P the pseudo-inverse of the axis matrix; CMGs: the
singularity-robust inverse of the torque Jacobian at the current gimbal angles).
"""
import math

import numpy as np

from .. import dynamics_kernel
from ..dynamics_kernel import _finite, _rotate_half, environment_torque_full
from ..jit import depends_on, inline, jit
from ..environment import facets_kernel, magnetic_kernel
from ..orbit import kernel as orbit_kernel

# status slots (counters of steps on which a limit acted, and the last values)
ST_WHEEL_TORQUE_SAT, ST_WHEEL_SPEED_SAT, ST_GIMBAL_RATE_SAT, ST_GIMBAL_ANGLE_SAT = 0, 1, 2, 3
ST_SINGULARITY = 4   # det(A Aᵀ) of the unit-column CMG Jacobian at the last allocation
ST_SIZE = 5
RESYNC = 64  # steps between fresh cos/sin of the gimbal angles (round-off of the sum rule)


@inline
def cmg_spin(g, s0, delta, out):
    """Spin directions s_j(δ_j) = cos δ s0 + sin δ (g × s0), rows of ``out`` (K, 3)."""
    for j in range(g.shape[0]):
        c = math.cos(delta[j])
        s = math.sin(delta[j])
        gx, gy, gz = g[j, 0], g[j, 1], g[j, 2]
        ax, ay, az = s0[j, 0], s0[j, 1], s0[j, 2]
        out[j, 0] = c * ax + s * (gy * az - gz * ay)
        out[j, 1] = c * ay + s * (gz * ax - gx * az)
        out[j, 2] = c * az + s * (gx * ay - gy * ax)


@inline
def cmg_jacobian(g, s0, delta, out):
    """Unit torque directions t_j = g_j × s_j(δ_j) = ∂s_j/∂δ_j, rows of ``out`` (K, 3)."""
    for j in range(g.shape[0]):
        c = math.cos(delta[j])
        s = math.sin(delta[j])
        gx, gy, gz = g[j, 0], g[j, 1], g[j, 2]
        ax, ay, az = s0[j, 0], s0[j, 1], s0[j, 2]
        # d/dδ (cos δ s0 + sin δ g×s0) = −sin δ s0 + cos δ g×s0
        out[j, 0] = -s * ax + c * (gy * az - gz * ay)
        out[j, 1] = -s * ay + c * (gz * ax - gx * az)
        out[j, 2] = -s * az + c * (gx * ay - gy * ax)


@inline
def _solve3(a, b, x):
    """x = a⁻¹ b for a symmetric positive-definite 3×3 ``a`` (Cramer); returns det(a)."""
    c00 = a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1]
    c01 = a[1, 2] * a[2, 0] - a[1, 0] * a[2, 2]
    c02 = a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]
    det = a[0, 0] * c00 + a[0, 1] * c01 + a[0, 2] * c02
    c10 = a[0, 2] * a[2, 1] - a[0, 1] * a[2, 2]
    c11 = a[0, 0] * a[2, 2] - a[0, 2] * a[2, 0]
    c12 = a[0, 1] * a[2, 0] - a[0, 0] * a[2, 1]
    c20 = a[0, 1] * a[1, 2] - a[0, 2] * a[1, 1]
    c21 = a[0, 2] * a[1, 0] - a[0, 0] * a[1, 2]
    c22 = a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
    x[0] = (c00 * b[0] + c10 * b[1] + c20 * b[2]) / det
    x[1] = (c01 * b[0] + c11 * b[1] + c21 * b[2]) / det
    x[2] = (c02 * b[0] + c12 * b[1] + c22 * b[2]) / det
    return det


@inline
def sr_rates(t, h0, tau, lam0, mu, rates, work):
    """Gimbal rates giving body torque ``tau`` (principal frame): τ = −Σ h0_j t_j δ̇_j, by
    the singularity-robust inverse δ̇ = −Bᵀ (B Bᵀ + λ 1)⁻¹ τ, B = [h0_j t_j],
    λ = λ0 h̄0² exp(−μ m), m = det(A Aᵀ) of the unit columns A = [t_j]. Returns m.
    ``work`` (4, 3) scratch."""
    k = t.shape[0]
    aat = work[:3]
    hbar2 = 0.0
    for j in range(k):
        hbar2 += h0[j] * h0[j]
    hbar2 /= k
    for r in range(3):
        for c in range(3):
            s = 0.0
            for j in range(k):
                s += t[j, r] * t[j, c]
            aat[r, c] = s
    measure = aat[0, 0] * (aat[1, 1] * aat[2, 2] - aat[1, 2] * aat[2, 1]) \
        - aat[0, 1] * (aat[1, 0] * aat[2, 2] - aat[1, 2] * aat[2, 0]) \
        + aat[0, 2] * (aat[1, 0] * aat[2, 1] - aat[1, 1] * aat[2, 0])
    lam = lam0 * hbar2 * math.exp(-mu * measure)
    for r in range(3):  # B Bᵀ + λ 1
        for c in range(3):
            s = 0.0
            for j in range(k):
                s += h0[j] * h0[j] * t[j, r] * t[j, c]
            aat[r, c] = s + (lam if r == c else 0.0)
    y = work[3]
    _solve3(aat, tau, y)
    for j in range(k):
        rates[j] = -h0[j] * (t[j, 0] * y[0] + t[j, 1] * y[1] + t[j, 2] * y[2])
    return measure


@inline
def actuator_momentum(hw, delta, wa, g, s0, h0, spin, out):
    """h_A = Σ h_i a_i + Σ h0_j s_j(δ_j) (principal frame) into ``out``; ``spin`` (K, 3)."""
    out[0] = 0.0
    out[1] = 0.0
    out[2] = 0.0
    for i in range(hw.shape[0]):
        for r in range(3):
            out[r] += hw[i] * wa[i, r]
    if delta.shape[0] > 0:
        cmg_spin(g, s0, delta, spin)
        for j in range(delta.shape[0]):
            for r in range(3):
                out[r] += h0[j] * spin[j, r]


@jit
def gyrostat_run(q, m, hw, delta, h, n, moments, split_axes, tau_ext, has_ext,
                 wa, inertia_w, max_torque, max_speed, friction, u_cmd,
                 g, s0, h0, max_rate, angle_limit, rate_cmd,
                 allocate, tau_des, wheel_pinv, lam0, mu, u_out, rate_out, status,
                 t0, env, inertia_full):
    """n Strang steps of size h (see the module docstring), in place on q, m, hw, delta.

    ``env``: the orbit's element array (``orbit.kernel``) or None; its gravity gradient on
    the whole mass distribution ``inertia_full`` (3, 3, principal frame: the body and the
    wheels' rotors) joins the external kicks, evaluated at each kick's instant (the
    step's start, t0 + step·h, and its end, with the attitude then).

    ``allocate``: commands from ``tau_des`` (principal frame, N·m) each step — CMGs if
    there are any, else wheels — instead of ``u_cmd`` / ``rate_cmd``. Gimbal rates are
    scaled together to respect every ``max_rate`` (direction kept). ``u_out``,
    ``rate_out``: the commands of the last step; ``status`` (ST_SIZE,): counters (of
    half-step kicks on which a limit acted) and the singularity measure. Returns the
    first non-finite step or -1.

    The kick and the actuator momentum are written out here rather than called: a call
    that takes a dozen arrays costs a reference-count round trip per array, several times
    the body's whole step."""
    nw = hw.shape[0]
    k = delta.shape[0]
    a = split_axes[0]
    b = split_axes[1]
    c = split_axes[2]
    tdir = np.empty((max(k, 1), 3))
    cd = np.empty(max(k, 1))  # cos, sin of the gimbal angles, carried by the angle-sum
    sd = np.empty(max(k, 1))  # rule across kicks and recomputed every RESYNC steps
    ce = np.empty(max(k, 1))  # cos, sin of this step's half-step gimbal increment
    se = np.empty(max(k, 1))
    gxs = np.empty((max(k, 1), 3))  # g × s0
    for j in range(k):
        gxs[j, 0] = g[j, 1] * s0[j, 2] - g[j, 2] * s0[j, 1]
        gxs[j, 1] = g[j, 2] * s0[j, 0] - g[j, 0] * s0[j, 2]
        gxs[j, 2] = g[j, 0] * s0[j, 1] - g[j, 1] * s0[j, 0]
    hA = np.zeros(3)
    H = np.empty(3)
    half = 0.5 * h
    for step in range(n):
        if step % RESYNC == 0:
            for j in range(k):
                cd[j] = math.cos(delta[j])
                sd[j] = math.sin(delta[j])
        # commands held over the step
        for i in range(nw):
            u_out[i] = u_cmd[i]
        for j in range(k):
            rate_out[j] = rate_cmd[j]
        if allocate:
            if k > 0:
                # sr_rates written out on scalars (symmetric 3×3 sums in one pass)
                p00 = p01 = p02 = p11 = p12 = p22 = 0.0  # A Aᵀ, unit columns
                b00 = b01 = b02 = b11 = b12 = b22 = 0.0  # B Bᵀ, columns h0_j t_j
                hbar2 = 0.0
                for j in range(k):  # t_j = ∂s_j/∂δ_j = −sin δ s0 + cos δ (g × s0)
                    t0 = cd[j] * gxs[j, 0] - sd[j] * s0[j, 0]
                    t1 = cd[j] * gxs[j, 1] - sd[j] * s0[j, 1]
                    t2 = cd[j] * gxs[j, 2] - sd[j] * s0[j, 2]
                    tdir[j, 0] = t0
                    tdir[j, 1] = t1
                    tdir[j, 2] = t2
                    w = h0[j] * h0[j]
                    hbar2 += w
                    p00 += t0 * t0
                    p01 += t0 * t1
                    p02 += t0 * t2
                    p11 += t1 * t1
                    p12 += t1 * t2
                    p22 += t2 * t2
                    b00 += w * t0 * t0
                    b01 += w * t0 * t1
                    b02 += w * t0 * t2
                    b11 += w * t1 * t1
                    b12 += w * t1 * t2
                    b22 += w * t2 * t2
                measure = (p00 * (p11 * p22 - p12 * p12) - p01 * (p01 * p22 - p12 * p02)
                           + p02 * (p01 * p12 - p11 * p02))
                lam = lam0 * (hbar2 / k) * math.exp(-mu * measure)
                b00 += lam
                b11 += lam
                b22 += lam
                c00 = b11 * b22 - b12 * b12
                c01 = b12 * b02 - b01 * b22
                c02 = b01 * b12 - b11 * b02
                c11 = b00 * b22 - b02 * b02
                c12 = b01 * b02 - b00 * b12
                c22 = b00 * b11 - b01 * b01
                det = b00 * c00 + b01 * c01 + b02 * c02
                y0 = (c00 * tau_des[0] + c01 * tau_des[1] + c02 * tau_des[2]) / det
                y1 = (c01 * tau_des[0] + c11 * tau_des[1] + c12 * tau_des[2]) / det
                y2 = (c02 * tau_des[0] + c12 * tau_des[1] + c22 * tau_des[2]) / det
                for j in range(k):
                    rate_out[j] = -h0[j] * (tdir[j, 0] * y0 + tdir[j, 1] * y1 + tdir[j, 2] * y2)
                status[ST_SINGULARITY] = measure
            else:
                for i in range(nw):
                    u_out[i] = -(wheel_pinv[i, 0] * tau_des[0] + wheel_pinv[i, 1] * tau_des[1]
                                 + wheel_pinv[i, 2] * tau_des[2])
        if k > 0:
            worst = 0.0
            for j in range(k):
                worst = max(worst, abs(rate_out[j]) / max_rate[j])
            if worst > 1.0:
                status[ST_GIMBAL_RATE_SAT] += 1
                for j in range(k):
                    rate_out[j] /= worst
        for j in range(k):
            ce[j], se[j] = _cos_sin(half * rate_out[j])
        if step == 0:
            _momentum(hw, wa, s0, gxs, h0, hA, cd, sd)
        for r in range(3):
            H[r] = m[r] + hA[r]
        # kick(h/2) · body flow(h) · kick(h/2), the second mirroring the first
        for phase in range(2):
            if phase == 1 and has_ext:
                for r in range(3):
                    H[r] += half * tau_ext[r]
                    m[r] = H[r] - hA[r]
            if phase == 1 and env is not None:
                gx, gy, gz = environment_torque_full(q, t0 + (step + 1) * h, env,
                                                     inertia_full)
                H[0] += half * gx
                H[1] += half * gy
                H[2] += half * gz
                for r in range(3):
                    m[r] = H[r] - hA[r]
            if nw > 0:  # wheels: motor (torque and speed limits) minus friction
                o0 = m[0] / moments[0]
                o1 = m[1] / moments[1]
                o2 = m[2] / moments[2]
                for i in range(nw):
                    rel = hw[i] / inertia_w[i] - (wa[i, 0] * o0 + wa[i, 1] * o1 + wa[i, 2] * o2)
                    ui = u_out[i]
                    if ui > max_torque[i]:
                        ui = max_torque[i]
                        status[ST_WHEEL_TORQUE_SAT] += 1
                    elif ui < -max_torque[i]:
                        ui = -max_torque[i]
                        status[ST_WHEEL_TORQUE_SAT] += 1
                    if (rel >= max_speed[i] and ui > 0.0) or (rel <= -max_speed[i] and ui < 0.0):
                        ui = 0.0  # the motor cannot drive the wheel past its speed limit
                        status[ST_WHEEL_SPEED_SAT] += 1
                    hw[i] += half * (ui - friction[i] * rel)
            for j in range(k):  # gimbals: by their rates, stopped at the angle limit
                d = delta[j] + half * rate_out[j]
                lim = angle_limit[j]
                if lim > 0.0 and (d > lim or d < -lim):
                    d = lim if d > 0.0 else -lim
                    status[ST_GIMBAL_ANGLE_SAT] += 1
                    cd[j] = math.cos(d)
                    sd[j] = math.sin(d)
                else:
                    cj = cd[j] * ce[j] - sd[j] * se[j]
                    sd[j] = sd[j] * ce[j] + cd[j] * se[j]
                    cd[j] = cj
                delta[j] = d
            if phase == 0 and has_ext:
                for r in range(3):
                    H[r] += half * tau_ext[r]
            if phase == 0 and env is not None:
                gx, gy, gz = environment_torque_full(q, t0 + step * h, env, inertia_full)
                H[0] += half * gx
                H[1] += half * gy
                H[2] += half * gz
            _momentum(hw, wa, s0, gxs, h0, hA, cd, sd)
            if phase == 0:
                # body flow with h_A frozen (body-fixed): exact rotations of H about the axes
                _flow(q, H, hA, a, half, moments)
                _flow(q, H, hA, b, half, moments)
                _flow(q, H, hA, c, h, moments)
                _flow(q, H, hA, b, half, moments)
                _flow(q, H, hA, a, half, moments)
            for r in range(3):
                m[r] = H[r] - hA[r]
        if not _finite(q, m):
            return step
    return -1


@inline
def _cos_sin(x):
    """(cos x, sin x); for the small increments of a step (|x| < 0.01) by their Taylor
    series to round-off (next terms below 1e-22), cheaper than the library calls."""
    if abs(x) >= 0.01:
        return math.cos(x), math.sin(x)
    x2 = x * x
    return (1.0 - x2 * (0.5 - x2 * (1.0 / 24.0 - x2 * (1.0 / 720.0 - x2 / 40320.0))),
            x * (1.0 - x2 * (1.0 / 6.0 - x2 * (1.0 / 120.0 - x2 / 5040.0))))


@inline
def _momentum(hw, wa, s0, gxs, h0, out, cd, sd):
    """actuator_momentum from g × s0 and cos δ, sin δ (``cd``, ``sd``) precomputed."""
    out[0] = 0.0
    out[1] = 0.0
    out[2] = 0.0
    for i in range(hw.shape[0]):
        for r in range(3):
            out[r] += hw[i] * wa[i, r]
    for j in range(h0.shape[0]):
        cs = cd[j] * h0[j]
        sn = sd[j] * h0[j]
        for r in range(3):
            out[r] += cs * s0[j, r] + sn * gxs[j, r]


@inline
def _flow(q, H, hA, axis, t, moments):
    """Exact flow of (H_axis − h_A,axis)²/(2 I_axis) for time t: H turns by −φ about the
    axis, q by +φ, φ = t (H_axis − h_A,axis)/I_axis (constant: H_axis does not change)."""
    _rotate_half(q, H, axis, 0.5 * (t * (H[axis] - hA[axis]) / moments[axis]))


# numba's disk cache checks only this file; gyrostat_run embeds dynamics_kernel's _finite and
# _rotate_half
depends_on(gyrostat_run, dynamics_kernel, orbit_kernel, magnetic_kernel, facets_kernel)


def warm():
    """Compile (or load from the cache) this module's kernels on representative arguments."""
    q = np.array([0.0, 0.0, 0.0, 1.0])
    m = np.array([0.1, 1.0, 0.2])
    moments = np.array([1.0, 2.0, 3.0])
    wa = np.eye(3)
    g = np.array([[1.0, 0.0, 0.0]])
    s0 = np.array([[0.0, 1.0, 0.0]])
    gyrostat_run(q, m, np.zeros(3), np.zeros(1), 1e-3, 1, moments, np.array([0, 2, 1]),
                 np.zeros(3), False, wa, np.ones(3), np.ones(3), np.ones(3), np.zeros(3),
                 np.zeros(3), g, s0, np.ones(1), np.ones(1), np.zeros(1), np.zeros(1),
                 True, np.zeros(3), np.zeros((3, 3)), 0.01, 10.0, np.zeros(3), np.zeros(1),
                 np.zeros(ST_SIZE), 0.0, None, np.eye(3))
