"""The figure of a body in orbit, with the analytic expectation drawn beside the run.

* libration.png — gravity-gradient libration about the orbit frame (circular orbit): roll,
  pitch and yaw from LVLH against the small-amplitude laws (pitch at n·√(3(I_x − I_z)/I_y),
  roll–yaw at the roots of the quartic: ``physics.analytic.libration_frequencies``). The
  dashed curves are sinusoids at the predicted frequencies (amplitudes and phases fitted);
  the measured frequencies are fitted freely, starting from the predicted ones.
* bdot.png — a B-dot detumble: |ω| against the averaged closed loop's decay
  (``bdot.averaged_decay_rate``, the major axis's e^{−(2/3)(k/I_max)t}) down to the residual
  of about 2n that B-dot leaves (the field turns at ~2n in the orbit frame).
"""
import math

import numpy as np

from .. import bdot
from ..physics import analytic
from ..physics.orbit import frames
from .common import pyplot, save


def lvlh_angles(t, attitude, orbit):
    """(N, 3) rotation vectors of the body from LVLH (roll, pitch, yaw about LVLH x, y, z)."""
    # scipy's optimize and spatial here, not at the top: every run that writes figures
    # imports this module, and only orbit scenes draw these (0.3 CPU-s a run)
    from scipy.spatial.transform import Rotation
    if len(t) == 0:
        return np.empty((0, 3))
    # the samples at once: a Rotation and LVLH axes a sample cost ~75 µs each (issue 32)
    r, v = (np.array(x) for x in zip(*(orbit.state(float(tk)) for tk in t)))
    rel = np.swapaxes(frames.lvlh_axes(r, v), -1, -2) @ Rotation.from_quat(
        np.asarray(attitude)).as_matrix()
    return Rotation.from_matrix(rel).as_rotvec()


def _basis(t, frequencies):
    return np.column_stack([f(w * t) for w in frequencies for f in (np.cos, np.sin)])


def sinusoids(t, signals, frequencies):
    """Least-squares sum of sinusoids at fixed ``frequencies`` (rad/s) through ``signals``
    (N, k) and the fitted curves (N, k)."""
    basis = _basis(t, frequencies)
    coef, *_ = np.linalg.lstsq(basis, signals, rcond=None)
    return basis @ coef


def fitted_frequencies(t, signals, guesses):
    """The frequencies (rad/s) of a sum of sinusoids shared by the columns of ``signals``,
    by least squares from ``guesses``."""
    def residual(w):
        return (sinusoids(t, signals, w) - signals).ravel()
    from scipy.optimize import least_squares  # orbit scenes only (lvlh_angles: why)
    scale = max(guesses)
    fit = least_squares(residual, guesses, x_scale=scale, xtol=1e-14, ftol=1e-14, gtol=1e-14)
    return [float(w) for w in fit.x]


def libration(s, orbit, moments, out_dir, title, unit, scale):
    """Roll, pitch and yaw from LVLH against the small-libration laws."""
    plt = pyplot()
    t = np.asarray(s['t'], float)
    angles = lvlh_angles(t, s['attitude'], orbit)
    pitch_w, (low, high) = analytic.libration_frequencies(moments, orbit.mean_motion)
    (pitch_m,) = fitted_frequencies(t, angles[:, 1:2], [pitch_w])
    low_m, high_m = fitted_frequencies(t, angles[:, [0, 2]], [low, high])
    fig, axes = plt.subplots(2, 1, figsize=(8, 6.5), sharex=True)
    n = orbit.mean_motion
    axes[0].plot(t / scale, np.degrees(angles[:, 1]), lw=2.5, alpha=0.5, label='pitch')
    axes[0].plot(t / scale, np.degrees(sinusoids(t, angles[:, 1:2], [pitch_w])[:, 0]), 'k--',
                 lw=0.9, label=f'n·√(3(I_x − I_z)/I_y) = {pitch_w / n:.4f} n '
                               f'(measured {pitch_m / n:.4f} n)')
    axes[0].set_ylabel('pitch [°] (about the orbit normal)')
    predicted = sinusoids(t, angles[:, [0, 2]], [low, high])
    for i, name in ((0, 'roll'), (2, 'yaw')):
        axes[1].plot(t / scale, np.degrees(angles[:, i]), lw=2.5, alpha=0.5, label=name)
    axes[1].plot(t / scale, np.degrees(predicted), 'k--', lw=0.9)
    axes[1].plot([], [], 'k--', lw=0.9,
                 label=f'quartic roots {low / n:.4f} n, {high / n:.4f} n '
                       f'(measured {low_m / n:.4f} n, {high_m / n:.4f} n)')
    axes[1].set_ylabel('roll, yaw [°] (about along-track, nadir)')
    axes[1].set_xlabel(f't [{unit}] (sim time)')
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    axes[0].set_title(f'{title}: gravity-gradient libration about LVLH, n = '
                      f'{n:.4g} rad/s (period {2 * math.pi / n / 60:.1f} min)', fontsize=10)
    return save(fig, out_dir, 'libration.png', 'roll, pitch and yaw from the orbit frame '
                'against the small-libration frequencies', plt,
                {'pitch_frequency': (pitch_m, pitch_w),
                 'roll_yaw_frequencies': ((low_m, high_m), (low, high))})


HALF_DEGREE = math.radians(0.5)  # rad/s: a detumbled spacecraft, as the B-dot scene asks


def bdot_detumble(s, moments, controller, out_dir, title, unit, scale):
    """|ω| of a B-dot run against the averaged closed loop's exponential decay; the
    values: the time to 0.5 °/s in orbits (measured, predicted) and the gain."""
    plt = pyplot()
    t = np.asarray(s['t'], float)
    w = np.linalg.norm(np.asarray(s['angular_velocity'], float), axis=1)
    n = float(controller['bdot.orbit_rate'])
    gain = bdot.gain_from_parameters(controller, float(np.min(moments)))
    rate = bdot.averaged_decay_rate(gain, moments)
    period = 2.0 * math.pi / n if n > 0.0 else math.nan
    predicted = bdot.predicted_time(w[0], HALF_DEGREE, gain, moments) if w[0] > HALF_DEGREE \
        else 0.0
    below = np.nonzero(w < HALF_DEGREE)[0]
    measured = t[below[0]] - t[0] if len(below) else math.nan
    fig, ax = plt.subplots(1, 1, figsize=(8, 4.8))
    ax.semilogy(t / scale, np.degrees(w), lw=2.5, alpha=0.5, label='simulated |ω|')
    floor = 2.0 * n
    envelope = np.maximum(w[0] * np.exp(-rate * (t - t[0])), floor)
    ax.semilogy(t / scale, np.degrees(envelope), 'k--', lw=0.9,
                label=f'averaged closed loop: e^(−(2/3)(k/I_max)t), k = {gain:.3g} kg·m²/s')
    if n > 0.0:
        ax.axhline(math.degrees(floor), color='0.5', ls=':', lw=0.8,
                   label='2n: the residual B-dot leaves')
    ax.axhline(0.5, color='g', ls=':', lw=0.8)
    if predicted > 0.0:
        ax.axvline((t[0] + predicted) / scale, color='g', ls='--', lw=0.8,
                   label=f'0.5 °/s predicted at {predicted / period:.3g} orbit'
                   + (f' (reached at {measured / period:.3g})' if measured == measured else ''))
    ax.set_xlabel(f't [{unit}] (sim time)')
    ax.set_ylabel('|ω| [°/s]')
    ax.grid(alpha=0.3, which='both')
    ax.legend(fontsize=8)
    ax.set_title(f'{title}: B-dot detumble (orbit {period / 60:.1f} min)', fontsize=10)
    return save(fig, out_dir, 'bdot.png', '|ω| under B-dot against the averaged closed '
                'loop\'s decay', plt,
                {'orbits_to_half_degree': (measured / period, predicted / period),
                 'gain': gain})
