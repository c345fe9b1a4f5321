"""What every figure shares: the Agg backend, time axes in readable units, saving, and the
record of what each figure shows (axis labels and the numbers it plots) for the tests."""
import os
from dataclasses import dataclass, field

import numpy as np

from ..physics.analytic import SIDEREAL_DAY


@dataclass
class Figure:
    """A written figure: its file, the (xlabel, ylabel) of each axes, and the measured and
    predicted quantities it draws (e.g. {'flip_interval': (measured, predicted)})."""
    path: str
    caption: str
    axes: list = field(default_factory=list)
    values: dict = field(default_factory=dict)


def pyplot():
    import matplotlib
    matplotlib.use('Agg')  # files only; no display needed
    import matplotlib.pyplot as plt
    return plt


def time_unit(t):
    """(unit, scale): seconds, minutes, hours or sidereal days, by the run's length."""
    span = float(t[-1] - t[0]) if len(t) else 0.0
    if span >= 5 * SIDEREAL_DAY:
        return 'sidereal days', SIDEREAL_DAY
    if span >= 3 * 3600:
        return 'h', 3600.0
    if span >= 600:
        return 'min', 60.0
    return 's', 1.0


def drift(values):
    """Values relative to the first, minus one: a conserved quantity plotted as its drift
    (a constant plotted as itself shows only round-off on 14-digit tick labels)."""
    v = np.asarray(values, float)
    return v / v[0] - 1.0 if v.size and v[0] != 0 else np.zeros_like(v)


def sign_changes(t, y):
    """Times where ``y`` changes sign, by linear interpolation between samples."""
    t, y = np.asarray(t, float), np.asarray(y, float)
    idx = np.nonzero(np.sign(y[1:]) * np.sign(y[:-1]) < 0)[0]
    return t[idx] - y[idx] * (t[idx + 1] - t[idx]) / (y[idx + 1] - y[idx])


def phase_rate(t, x, y):
    """Slope (rad/s) of the unwrapped angle of (x, y) against t, by least squares; nan if it
    cannot be resolved (fewer than 3 samples, or more than π/2 per sample: aliased)."""
    phase = np.unwrap(np.arctan2(y, x))
    if len(t) < 3 or np.max(np.abs(np.diff(phase))) > np.pi / 2:
        return np.nan, phase
    return float(np.polyfit(t, phase, 1)[0]), phase


def save(fig, out_dir, name, caption, plt, values=None):
    """Write ``fig`` as out_dir/name; returns its :class:`Figure` record."""
    os.makedirs(out_dir, exist_ok=True)
    path = os.path.join(out_dir, name)
    axes = [(ax.get_xlabel(), ax.get_ylabel()) for ax in fig.axes
            if ax.get_xlabel() or ax.get_ylabel()]
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return Figure(path, caption, axes, dict(values or {}))
