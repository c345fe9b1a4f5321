"""The figure each scene exists for, with the analytic expectation drawn beside the run.

* flips.png — intermediate-axis tumble: ω along the middle axis flipping, the measured
  interval between flips against 2K(k)/λ (physics.analytic.flip_interval).
* precession.png — axisymmetric free body: the body cone (ω about the symmetry axis, in
  the body) and the space cone (the symmetry axis about L, in space) with the predicted
  rates; for a long run (the rigid Earth) the pole's path in the body, period marked.
* nutation.png — axisymmetric body with internal dissipation (Explorer 1): θ(t) against
  tan θ = tan θ0·e^{ct}, and the energy falling at constant |L|.
* control.png — controlled runs: error angle and rate against the critically damped
  prediction, |L| against the detumble's exponential decay, phases marked.
Each returns a plots.common.Figure whose ``values`` hold (measured, predicted) pairs.
"""
import numpy as np

from ..control import slew_begins
from ..physics import analytic, rotation
from .common import drift, phase_rate, pyplot, save, sign_changes


def flips(s, body, out_dir, title, unit, scale, free_end):
    """ω along the intermediate axis over the free phase, flips and 2K/λ marked."""
    plt = pyplot()
    t = np.asarray(s['t'])
    free = t < free_end
    w_p = body.to_principal(np.asarray(s['angular_velocity'])[free])
    t = t[free]
    moments = body.principal_moments
    mid = int(np.argsort(moments)[1])
    predicted = analytic.flip_interval(moments, w_p[0])
    crossings = sign_changes(t, w_p[:, mid])
    measured = float(np.mean(np.diff(crossings))) if len(crossings) >= 2 else np.nan
    fig, ax = plt.subplots(figsize=(9, 4.2))
    for i in range(3):
        ax.plot(t / scale, w_p[:, i], lw=1.6 if i == mid else 0.8,
                label=f'ω_{i + 1} (I = {moments[i]:.3g} kg·m²)' + (', middle' if i == mid else ''))
    for k, tc in enumerate(crossings):
        ax.axvline(tc / scale, color='k', lw=0.6, ls=':',
                   label='flip (ω_mid = 0)' if not k else None)
    if len(crossings):
        # the predicted flips: every 2K/λ from the first one seen
        pred = crossings[0] + predicted * np.arange(0, 1 + (t[-1] - crossings[0]) // predicted)
        ax.plot(pred / scale, np.zeros_like(pred), 'rv', ms=8,
                label=f'predicted flips, every 2K/λ = {predicted:.4g} s')
    ax.set(xlabel=f't [{unit}] (sim time)', ylabel='ω [rad/s] (principal frame)')
    seen = (f'measured interval {measured:.4g} s' if len(crossings) >= 2 else
            f'{len(crossings)} flip(s) in the free phase')
    ax.set_title(f'{title}: the tennis-racket flip — {seen}, 2K(k)/λ = {predicted:.4g} s',
                 fontsize=10)
    ax.legend(fontsize=7, loc='lower left')
    ax.grid(alpha=0.3)
    return save(fig, out_dir, 'flips.png', 'intermediate-axis flips against 2K(k)/λ', plt,
                {'flip_interval': (measured, predicted), 'flips': len(crossings)})


def precession(s, body, out_dir, title, unit, scale):
    """Body cone and space cone of a free axisymmetric body, with the predicted rates."""
    plt = pyplot()
    t = np.asarray(s['t'])
    moments = body.principal_moments
    ax_s = analytic.symmetry_axis(moments)
    a, b = (ax_s + 1) % 3, (ax_s + 2) % 3
    w_p = body.to_principal(np.asarray(s['angular_velocity']))
    body_pred, space_pred = analytic.precession_rates(moments, w_p[0])
    body_meas, _ = phase_rate(t, w_p[:, a], w_p[:, b])
    # the symmetry axis in space, about L̂ (fixed while torque-free)
    e_s = np.zeros(3)
    e_s[ax_s] = 1.0
    axis_in = rotation.rotate(s['attitude'], body.to_body(e_s))
    lhat = s['angular_momentum'][0] / np.linalg.norm(s['angular_momentum'][0])
    u1 = np.cross(lhat, [1.0, 0, 0] if abs(lhat[0]) < 0.9 else [0, 1.0, 0])
    u1 /= np.linalg.norm(u1)
    u2 = np.cross(lhat, u1)
    space_meas, _ = phase_rate(t, axis_in @ u1, axis_in @ u2)
    long_run = unit == 'sidereal days'
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.6))
    ax = axes[0]
    if long_run:  # the pole (ω's direction) in the body: arcseconds from the figure axis
        arcsec = np.degrees(1.0) * 3600
        x, y = (w_p[:, a] / w_p[:, ax_s] * arcsec, w_p[:, b] / w_p[:, ax_s] * arcsec)
        ax.plot(x, y, lw=0.8)
        ax.set(xlabel='pole x [arcsec] (body frame)', ylabel='pole y [arcsec] (body frame)')
        ax.set_title('the pole\'s path in the body (figure axis at the centre)', fontsize=9)
    else:
        ax.plot(w_p[:, a], w_p[:, b], lw=0.8, label='ω⊥ in the body (body cone)')
        ax.plot(axis_in @ u1 * np.linalg.norm(w_p[0]), axis_in @ u2 * np.linalg.norm(w_p[0]),
                lw=0.8, label='symmetry axis in space ⊥ L, × |ω| (space cone)')
        ax.set(xlabel='component 1 [rad/s]', ylabel='component 2 [rad/s]')
        ax.set_title('cones seen from their axes', fontsize=9)
        ax.legend(fontsize=7, loc='upper right')
    ax.plot([0], [0], 'k+')
    ax.set_aspect('equal', adjustable='datalim')
    ax.grid(alpha=0.3)
    ax = axes[1]
    turns = []
    period = 2 * np.pi / abs(body_pred)
    if long_run:  # the wobble itself: the pole's x against time, and the prediction
        arcsec = np.degrees(1.0) * 3600
        x = w_p[:, a] / w_p[:, ax_s] * arcsec
        r = np.hypot(x[0], (w_p[0, b] / w_p[0, ax_s]) * arcsec)
        phi0 = np.arctan2(w_p[0, b], w_p[0, a])
        ax.plot(t / scale, x, lw=2.5, alpha=0.5, label='pole x (simulated)')
        ax.plot(t / scale, r * np.cos(phi0 + np.sign(body_meas) * (t - t[0]) * abs(body_pred)),
                'k--', lw=0.8, label=f'predicted, period A/(C − A) = {period / scale:.2f} {unit}')
        for k in range(1, int((t[-1] - t[0]) / period) + 1):
            ax.axvline(k * period / scale, color='r', lw=0.8, ls=':')
        ax.set(xlabel=f't [{unit}] (sim time)', ylabel='pole x [arcsec] (body frame)')
        ax.set_title(f'the free (Euler) wobble: measured period '
                     f'{2 * np.pi / abs(body_meas) / scale:.2f} {unit}', fontsize=9)
    cones = [] if long_run else [
        ('body cone', body_meas, body_pred, w_p[:, a], w_p[:, b]),
        ('space cone', space_meas, space_pred, axis_in @ u1, axis_in @ u2)]
    for name, meas, pred, x, y in cones:
        rate, phase = phase_rate(t, x, y)
        if np.isnan(rate) or abs(pred) * np.min(np.diff(t)) > np.pi / 2:
            continue  # sampled too slowly to follow (the Earth's daily space cone)
        turns.append(name)
        ax.plot(t / scale, (phase - phase[0]) / (2 * np.pi), lw=2.5, alpha=0.5,
                label=f'{name}: measured {meas:.6g} rad/s')
        ax.plot(t / scale, pred * np.sign(meas) * (t - t[0]) / (2 * np.pi), 'k--', lw=0.8,
                label=f'{name}: predicted {pred:.6g} rad/s')
    if not long_run:
        ax.set(xlabel=f't [{unit}] (sim time)', ylabel='turns [rev]')
        ax.set_title('angle turned: |I_s − I_t|ω_s/I_t (body) and |L|/I_t (space)',
                     fontsize=9)
    ax.legend(fontsize=7, loc='best' if long_run else 'lower right')
    ax.grid(alpha=0.3)
    fig.suptitle(f'{title}: free precession')
    return save(fig, out_dir, 'precession.png', 'body and space cones with predicted rates',
                plt, {'body_cone_rate': (abs(body_meas), abs(body_pred)),
                      'wobble_period': (2 * np.pi / abs(body_meas), period),
                      **({'space_cone_rate': (abs(space_meas), space_pred)}
                         if 'space cone' in turns else {}),
                      **({'body_cone_rate': (abs(body_meas), abs(body_pred))}
                         if 'body cone' in turns or long_run else {})})


def nutation(s, body, out_dir, title, unit, scale, coefficient):
    """θ(t) against tan θ = tan θ0·e^{ct}; T falling at constant |L|."""
    plt = pyplot()
    t = np.asarray(s['t'])
    moments = body.principal_moments
    ax_s = analytic.symmetry_axis(moments)
    m = body.to_principal(np.asarray(s['angular_momentum_body']))
    G = np.linalg.norm(m, axis=1)
    theta = np.arccos(np.clip(np.abs(m[:, ax_s]) / G, 0.0, 1.0))
    c = analytic.nutation_rate(moments, coefficient, G[0])
    pred = analytic.nutation_angle(theta[0], c, t - t[0])
    fig, axes = plt.subplots(3, 1, figsize=(8, 7.5), sharex=True)
    axes[0].plot(t / scale, np.degrees(theta), lw=2.5, alpha=0.5, label='simulated')
    axes[0].plot(t / scale, np.degrees(pred), 'k--', lw=0.9,
                 label=f'tan θ = tan θ₀·e^(ct), c = {c:.4g} 1/s')
    axes[0].set_ylabel('nutation θ [°] (L from the spin axis)')
    axes[0].legend(fontsize=8)
    axes[1].plot(t / scale, s['kinetic_energy'], lw=0.9)
    axes[1].set_ylabel('T [J]')
    axes[2].plot(t / scale, drift(G), lw=0.9)
    axes[2].set_ylabel('|L|/|L₀| − 1 [1]')
    axes[2].text(0.01, 0.04, f'|L₀| = {G[0]:.9g} kg·m²/s: internal dissipation keeps it',
                 transform=axes[2].transAxes, fontsize=8, va='bottom',
                 bbox={'facecolor': 'white', 'alpha': 0.8, 'lw': 0})
    axes[2].set_xlabel(f't [{unit}] (sim time)')
    for ax in axes:
        ax.grid(alpha=0.3)
    axes[0].set_title(f'{title}: the major-axis rule — energy falls, |L| stays, the spin '
                      f'goes flat', fontsize=10)
    return save(fig, out_dir, 'nutation.png', 'nutation angle against tan θ = tan θ0·e^(ct)',
                plt, {'nutation_max_error_deg': (float(np.max(np.abs(np.degrees(theta - pred)))),
                                                 0.0),
                      'nutation_rate': (c, c), 'energy': (float(s['kinetic_energy'][0]),
                                                          float(s['kinetic_energy'][-1]))})


def control(s, out_dir, title, unit, scale, controller, free_end):
    """Error angle, rate and |L| against the critically damped / exponential predictions."""
    plt = pyplot()
    t = np.asarray(s['t'])
    target = np.asarray(controller['target_attitude'], float)
    angle = rotation.angle_between(s['attitude'], target)
    w = np.linalg.norm(s['angular_velocity'], axis=1)
    L = np.linalg.norm(s['angular_momentum'], axis=1)
    wn = float(np.mean(controller['natural_frequency']))
    zeta = float(np.mean(controller['damping_ratio']))
    active = t >= (free_end if np.isfinite(free_end) else t[0])
    slew_start = slew_begins(s, free_end, controller)
    values = {}
    fig, axes = plt.subplots(3, 1, figsize=(8.5, 8), sharex=True)
    axes[0].plot(t / scale, np.degrees(angle), lw=2.5, alpha=0.5, label='simulated')
    axes[1].semilogy(t / scale, np.maximum(w, 1e-12), lw=2.5, alpha=0.5, label='simulated')
    axes[2].semilogy(t / scale, np.maximum(L, 1e-15), lw=2.5, alpha=0.5, label='simulated')
    if np.isfinite(slew_start):
        k = int(np.searchsorted(t, slew_start))
        tau = t[k:] - t[k]
        rate0 = (angle[k + 1] - angle[k]) / (t[k + 1] - t[k]) if k + 1 < len(t) else 0.0
        lin, _ = analytic.critical_response(angle[k], rate0, wn, tau)
        th, dth = analytic.eigenaxis_slew(angle[k], rate0, wn, zeta, tau)
        axes[0].plot(t[k:] / scale, np.degrees(lin), ':', color='0.4', lw=0.9,
                     label='critically damped, linearised')
        axes[0].plot(t[k:] / scale, np.degrees(th), 'k--', lw=0.9,
                     label=f'eigen-axis law, ω_n = {wn:g} rad/s, ζ = {zeta:g}')
        axes[1].semilogy(t[k:] / scale, np.maximum(np.abs(dth), 1e-12), 'k--', lw=0.9,
                         label='|dθ/dt| predicted (slew)')
        settle = t[k] + 5.834 / wn
        axes[0].axvline(settle / scale, color='g', ls=':', lw=0.8)
        axes[0].text(settle / scale, np.degrees(angle[k]) * 0.9, ' 2 % settling (5.83/ω_n)',
                     color='g', fontsize=8)
        done = tau <= 4 * 5.834 / wn
        values['slew_max_error_deg'] = (float(np.max(np.abs(np.degrees(angle[k:] - th)[done]))),
                                        0.0)
    detumbling = active & (t < slew_start) & (controller['mode'] == 'detumble')
    if np.count_nonzero(detumbling) > 2:
        # |L| = |L₀|e^(−2ζω_n t) while the torque is not saturated: start where it is not
        tq = np.linalg.norm(s['torque'], axis=1)
        limit = controller.get('max_torque', np.inf)
        free_of_limit = detumbling & (tq < 0.999 * limit)
        k = int(np.argmax(free_of_limit)) if np.any(free_of_limit) else int(np.argmax(detumbling))
        end = int(np.searchsorted(t, slew_start))
        pred = L[k] * np.exp(-2 * zeta * wn * (t[k:end] - t[k]))
        axes[2].semilogy(t[k:end] / scale, pred, 'k--', lw=0.9,
                         label=f'|L₀|e^(−2ζω_n t), 2ζω_n = {2 * zeta * wn:g} 1/s')
        values['detumble_rate'] = (float(-np.polyfit(t[k:end], np.log(L[k:end]), 1)[0]),
                                   2 * zeta * wn)
    for ax in axes:
        if np.isfinite(free_end) and free_end > t[0]:
            ax.axvspan(t[0] / scale, free_end / scale, color='0.9', label=None)
        if np.isfinite(slew_start) and controller['mode'] != 'slew':
            ax.axvline(slew_start / scale, color='C1', lw=0.8, ls=':')
        ax.grid(alpha=0.3, which='both')
        ax.legend(fontsize=7, loc='upper right')
    phases = []
    if np.isfinite(free_end) and free_end > t[0]:
        phases.append(f'free (grey) until {free_end / scale:.3g} {unit}')
    if controller['mode'] == 'detumble':
        phases.append('detumble')
    if np.isfinite(slew_start):
        phases.append(f'slew from {slew_start / scale:.3g} {unit}')
    axes[0].set_ylabel('error angle [°]')
    axes[1].set_ylabel('|ω| [rad/s]')
    axes[2].set_ylabel('|L| [kg·m²/s]')
    axes[2].set_xlabel(f't [{unit}] (sim time)')
    axes[0].set_title(f'{title}: ' + ', '.join(phases), fontsize=10)
    return save(fig, out_dir, 'control.png',
                'error angle and rate against the critically damped prediction', plt, values)
