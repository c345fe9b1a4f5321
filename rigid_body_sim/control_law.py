"""The attitude control law as plain float code: the kernel numba compiles
(:mod:`rigid_body_sim.control_kernel`) and, interpreted, the controller node's law.

Same law as documented in :mod:`rigid_body_sim.control` (which calls this): error
quaternion q_e = target* ⊗ q with q_e.w ≥ 0; detumble τ = −K_ω ω; slew
τ = −k_d ⊙ (ω − ω_cmd) [+ ω × Iω], ω_cmd = −sat(k_p/k_d ⊙ e); then the torque vector is
scaled to |τ| ≤ max_torque. Gains are per principal axis; ``axes`` holds the principal
axes as columns in the body frame (v_principal = v_body @ axes).

This module imports neither numpy nor numba. The controller node evaluates one command
per control period, interpreted: bit for bit the compiled kernel's torques, ~35 µs a
command through ``AttitudeController.compute`` (0.2 % of a core at 50 Hz) against ~6 µs
compiled; loading numba and the compiled kernel cost each controller start 0.8 CPU-s.
"""
import math

MODE_CODES = {'off': 0, 'detumble': 1, 'slew': 2, 'bdot': 0}  # bdot: no torque (the rods)


def control_torque(mode, q, w, target, axes, moments, kp, kd, kw, rate_limit, torque_limit,
                   gyroscopic, inertia, tau, unsaturated):
    """Body-frame torque into ``tau`` (and before saturation into ``unsaturated``) for
    attitude q (x, y, z, w, body → inertial) and body rate w. Returns (saturated,
    rate_limited, error angle in rad, |ω|)."""
    tx, ty, tz, tw = -target[0], -target[1], -target[2], target[3]
    ex = tw * q[0] + tx * q[3] + ty * q[2] - tz * q[1]
    ey = tw * q[1] - tx * q[2] + ty * q[3] + tz * q[0]
    ez = tw * q[2] + tx * q[1] - ty * q[0] + tz * q[3]
    ew = tw * q[3] - tx * q[0] - ty * q[1] - tz * q[2]
    angle = 2.0 * math.atan2(math.sqrt(ex * ex + ey * ey + ez * ez), abs(ew))
    if ew < 0.0:
        ex, ey, ez = -ex, -ey, -ez
    rate_norm = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    rate_limited = False
    # principal-frame rates, error and torque as scalars (no allocation per call)
    w0 = w[0] * axes[0, 0] + w[1] * axes[1, 0] + w[2] * axes[2, 0]
    w1 = w[0] * axes[0, 1] + w[1] * axes[1, 1] + w[2] * axes[2, 1]
    w2 = w[0] * axes[0, 2] + w[1] * axes[1, 2] + w[2] * axes[2, 2]
    p0 = p1 = p2 = 0.0
    if mode == 1:
        p0, p1, p2 = -kw[0] * w0, -kw[1] * w1, -kw[2] * w2
    elif mode == 2:
        wc0 = -(kp[0] / kd[0]) * (ex * axes[0, 0] + ey * axes[1, 0] + ez * axes[2, 0])
        wc1 = -(kp[1] / kd[1]) * (ex * axes[0, 1] + ey * axes[1, 1] + ez * axes[2, 1])
        wc2 = -(kp[2] / kd[2]) * (ex * axes[0, 2] + ey * axes[1, 2] + ez * axes[2, 2])
        n = math.sqrt(wc0 * wc0 + wc1 * wc1 + wc2 * wc2)
        if n > 0.0:
            limit = rate_limit
            if torque_limit < math.inf:  # the rate the torque bound can brake (README)
                d0 = moments[0] * kp[0] / kd[0] * wc0 / n
                d1 = moments[1] * kp[1] / kd[1] * wc1 / n
                d2 = moments[2] * kp[2] / kd[2] * wc2 / n
                limit = min(rate_limit, torque_limit / math.sqrt(d0 * d0 + d1 * d1 + d2 * d2))
            if n > limit:
                wc0 *= limit / n
                wc1 *= limit / n
                wc2 *= limit / n
                rate_limited = True
        p0, p1, p2 = -kd[0] * (w0 - wc0), -kd[1] * (w1 - wc1), -kd[2] * (w2 - wc2)
    for i in range(3):
        tau[i] = p0 * axes[i, 0] + p1 * axes[i, 1] + p2 * axes[i, 2]
    if mode == 2 and gyroscopic:
        iw0 = inertia[0, 0] * w[0] + inertia[0, 1] * w[1] + inertia[0, 2] * w[2]
        iw1 = inertia[1, 0] * w[0] + inertia[1, 1] * w[1] + inertia[1, 2] * w[2]
        iw2 = inertia[2, 0] * w[0] + inertia[2, 1] * w[1] + inertia[2, 2] * w[2]
        tau[0] += w[1] * iw2 - w[2] * iw1
        tau[1] += w[2] * iw0 - w[0] * iw2
        tau[2] += w[0] * iw1 - w[1] * iw0
    for i in range(3):
        unsaturated[i] = tau[i]
    norm = math.sqrt(tau[0] * tau[0] + tau[1] * tau[1] + tau[2] * tau[2])
    saturated = norm > torque_limit
    if saturated:
        for i in range(3):
            tau[i] *= torque_limit / norm
    return saturated, rate_limited, angle, rate_norm

