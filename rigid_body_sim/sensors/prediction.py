"""The pointing error a sensor scene should show: the linearised closed loop's covariance.

For a pointing hold (``slew`` mode about a fixed target, diagonal inertia, small angles
and rates) each body axis is a linear, periodically time-varying system. Per gyro instant,
as the engine runs it (gyro at the control rate, star tracker every ``star_every`` gyro
instants):

    truth under the held torque     θ ← θ + hω + h²u/(2I),  ω ← ω + hu/I
    Gauss–Markov bias               b ← φ b + w_gm
    gyro reading                    g = ω + b + n            (n: ARW, variance N²/h)
    estimator propagation           θ̂ ← θ̂ + h (g_prev − b̂)
    star-tracker fix (every M)      δ = θ + v − θ̂,  θ̂ ← θ̂ + 2ω_e T δ,  b̂ ← b̂ − ω_e² T δ
    the law                         u = −(k_p/2) θ̂ − k_d (g − b̂)

The covariance is propagated exactly, P ← A P Aᵀ + B Q Bᵀ, from the stationary bias, and
averaged over whole star-tracker periods once the loop has settled. A turn-on bias and
outages only move the mean, which decays. Rate random walk is left out (the bias is not
stationary then; the error still is, but this model does not carry it).

``python -m rigid_body_sim.tools.pointing SCENE`` prints it for a scene.
"""
import math

import numpy as np

from .gauss_markov import gauss_markov_sigma


def pointing_variance(sim, ctl, h=None, star_every=None, duration=300.0, settle=100.0):
    """Per-body-axis variance (rad²) of the pointing error, from the simulator's (``sim``)
    and the controller's (``ctl``) coerced parameters. ValueError if the scene is not of
    the form the model covers (gyro at the control rate, star rate dividing it)."""
    inertia = np.asarray(sim['inertia'], float)
    if inertia.size == 9:
        m = inertia.reshape(3, 3)
        if np.any(m != np.diag(np.diag(m))):
            raise ValueError('the linear model needs a diagonal inertia')
        inertia = np.diag(m)
    h = 1.0 / sim['sensors.gyro.rate'] if h is None else h
    if abs(h * ctl['control_rate'] - 1.0) > 1e-9:
        raise ValueError('the linear model needs sensors.gyro.rate == control_rate')
    if star_every is None:
        star_every = round(sim['sensors.gyro.rate'] / sim['sensors.star_tracker.rate'])
    wn = np.broadcast_to(np.asarray(ctl['natural_frequency'], float), (3,))
    zeta = np.broadcast_to(np.asarray(ctl['damping_ratio'], float), (3,))
    we, big_t = ctl['estimator.bandwidth'], star_every * h
    sigma_gm = gauss_markov_sigma(sim['sensors.gyro.bias_instability'])
    phi = math.exp(-h / sim['sensors.gyro.bias_correlation_time'])
    arw = sim['sensors.gyro.angle_random_walk']
    noise = list(sim['sensors.star_tracker.noise'])
    noise = noise * 3 if len(noise) == 1 else noise
    out = []
    for axis in range(3):
        i_ax = inertia[axis]
        kp, kd = 2.0 * i_ax * wn[axis] ** 2, 2.0 * zeta[axis] * wn[axis] * i_ax

        def step(x, e, star):
            th, om, th_hat, b_hat, b, g, u = x
            n, w_gm, v = e
            th1 = th + h * om + h * h / (2.0 * i_ax) * u
            om1 = om + h / i_ax * u
            b1 = phi * b + w_gm
            g1 = om1 + b1 + n
            th_hat1 = th_hat + h * (g - b_hat)
            b_hat1 = b_hat
            if star:
                d = th1 + v - th_hat1
                th_hat1 += 2.0 * we * big_t * d
                b_hat1 = b_hat - we * we * big_t * d
            return np.array([th1, om1, th_hat1, b_hat1, b1, g1,
                             -0.5 * kp * th_hat1 - kd * (g1 - b_hat1)])

        maps = {}
        for star in (False, True):  # the step is linear: its matrices from unit vectors
            a = np.column_stack([step(col, np.zeros(3), star) for col in np.eye(7)])
            b = np.column_stack([step(np.zeros(7), col, star) for col in np.eye(3)])
            maps[star] = (a, b)
        q = np.diag([arw ** 2 / h, sigma_gm ** 2 * (1.0 - phi ** 2), noise[axis] ** 2])
        cov = np.zeros((7, 7))
        cov[4, 4] = sigma_gm ** 2
        total, count = 0.0, 0
        for k in range(1, int(round(duration / h)) + 1):
            a, b = maps[k % star_every == 0]
            cov = a @ cov @ a.T + b @ q @ b.T
            if k * h > settle + 1e-9:
                total, count = total + cov[0, 0], count + 1
        out.append(total / count)
    return np.array(out)
