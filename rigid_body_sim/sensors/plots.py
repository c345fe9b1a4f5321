"""pointing.png for scenes that close the loop on sensors: the pointing error against time
per body axis, and its distribution over the last two thirds of the run against the
linearised prediction (``sensors.prediction``) — the noise parameters' expected spread."""
import os

import numpy as np

from ..physics import rotation
from .prediction import pointing_variance


def pointing_error(samples, target) -> np.ndarray:
    """2·vec(target* ⊗ q) per sample (body frame, rad; shortest sign)."""
    d = rotation.multiply(rotation.conjugate(np.asarray(target, float)), samples.attitude)
    return 2.0 * np.where(d[:, 3:4] < 0.0, -d, d)[:, :3]


def write_pointing_plot(samples, scene, out_dir) -> str:
    """Write ``pointing.png`` into ``out_dir``; returns its path."""
    from ..plots import _pyplot, _save
    plt = _pyplot()
    os.makedirs(out_dir, exist_ok=True)
    t = samples.t
    err = pointing_error(samples, scene.controller['target_attitude'])
    settle = t[-1] / 3.0
    try:
        sigma = np.sqrt(pointing_variance(scene.simulator, scene.controller,
                                          duration=t[-1], settle=settle))
    except ValueError:  # a scene outside the linear model: no prediction to show
        sigma = None
    fig, (ax, hist) = plt.subplots(1, 2, figsize=(12, 4.5),
                                   gridspec_kw={'width_ratios': [2, 1]})
    for i, name in enumerate('xyz'):
        ax.plot(t, err[:, i] * 1e3, lw=0.6, label=f'about {name}')
    ax.axvline(settle, color='0.5', lw=0.8, ls='--')
    ax.set(xlabel='t [s]', ylabel='pointing error [mrad] (body frame)',
           title=f'{scene.name}: pointing error (controller on sensors)')
    ax.legend(loc='upper right')
    ax.grid(alpha=0.3)
    steady = err[t >= settle] * 1e3
    span = max(np.abs(steady).max(), 1e-12)
    bins = np.linspace(-span, span, 61)
    x = np.linspace(-span, span, 400)
    for i, name in enumerate('xyz'):
        hist.hist(steady[:, i], bins=bins, density=True, histtype='step', color=f'C{i}',
                  label=f'{name}: RMS {np.sqrt(np.mean(steady[:, i] ** 2)):.3g} mrad')
        if sigma is not None:
            s = sigma[i] * 1e3
            hist.plot(x, np.exp(-0.5 * (x / s) ** 2) / (s * np.sqrt(2 * np.pi)), color=f'C{i}',
                      lw=0.8, ls=':', label=f'{name}: predicted σ {s:.3g} mrad')
    hist.set(xlabel='pointing error [mrad]', ylabel='density',
             title=f't ≥ {settle:.3g} s (seed {scene.simulator["seed"]})')
    hist.legend(fontsize=7)
    hist.grid(alpha=0.3)
    return _save(fig, out_dir, 'pointing.png', plt)
