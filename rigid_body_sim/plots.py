"""PNG plots of a run: ω(t), T and |L| against time, and Poinsot's construction.

Poinsot: the energy ellipsoid ω·Iω = 2T (principal frame) rolls without slipping on the
invariable plane ω·L̂ = 2T/|L| fixed in space. The polhode is ω's path on the ellipsoid
(body frame); the herpolhode is ω's path on the plane (inertial frame).
"""
import os

import numpy as np


def _pyplot():
    import matplotlib
    matplotlib.use('Agg')  # files only; no display needed
    import matplotlib.pyplot as plt
    return plt


def free_until(t, torque):
    """Time of the first nonzero torque sample (inf when the run is torque-free)."""
    applied = np.nonzero(np.any(np.asarray(torque) != 0.0, axis=1))[0]
    return float(t[applied[0]]) if applied.size else np.inf


def write_plots(samples, body, out_dir, title, free_end=np.inf):
    """Write omega.png, invariants.png and poinsot.png into ``out_dir``; returns their paths.

    samples: dict of arrays — t (N,), attitude (N, 4) body→inertial, angular_velocity (N, 3)
    body frame, angular_momentum (N, 3) inertial, kinetic_energy (N,). Poinsot's picture
    holds only without torque: it shows the samples before ``free_end`` (s).
    """
    plt = _pyplot()
    from .physics import rotation
    os.makedirs(out_dir, exist_ok=True)
    t = np.asarray(samples['t'])
    w = np.asarray(samples['angular_velocity'])
    L = np.asarray(samples['angular_momentum'])
    T = np.asarray(samples['kinetic_energy'])
    q = np.asarray(samples['attitude'])
    unit, scale = ('s', 1.0) if t[-1] < 2e5 else ('sidereal days', 86164.0905)
    ts = t / scale
    paths = []

    fig, ax = plt.subplots(figsize=(8, 4))
    for i, name in enumerate('xyz'):
        ax.plot(ts, w[:, i], lw=0.8, label=f'ω_{name}')
    ax.set(xlabel=f't [{unit}]', ylabel='ω [rad/s] (body frame)',
           title=f'{title}: angular velocity')
    ax.legend(loc='upper right')
    ax.grid(alpha=0.3)
    paths.append(_save(fig, out_dir, 'omega.png', plt))

    fig, axes = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    Ln = np.linalg.norm(L, axis=1)
    for ax, y, label in ((axes[0], T, 'T [J]'), (axes[1], Ln, '|L| [kg·m²/s]')):
        ax.plot(ts, y, lw=0.9)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.ticklabel_format(useOffset=False, axis='y')
    axes[0].set_title(f'{title}: kinetic energy and angular momentum')
    axes[1].set_xlabel(f't [{unit}]')
    paths.append(_save(fig, out_dir, 'invariants.png', plt))

    fig = plt.figure(figsize=(11, 5))
    ax3 = fig.add_subplot(1, 2, 1, projection='3d')
    moments = body.principal_moments
    free = t < free_end
    phase = '' if np.all(free) else f' — free phase, t < {free_end / scale:.4g} {unit}'
    if np.count_nonzero(free) >= 2:  # torque from the start: show the whole run, labelled
        t, w, L, T, q = t[free], w[free], L[free], T[free], q[free]
        Ln = np.linalg.norm(L, axis=1)
    else:
        phase = ' — torque applied throughout: not a free (Poinsot) motion'
    w_p = body.to_principal(w)
    k0 = int(np.argmax(T > 0)) if np.any(T > 0) else 0  # a body at rest has no ellipsoid yet
    radii = np.sqrt(2 * max(T[k0], 1e-300) / moments)
    u, v = np.mgrid[0:2 * np.pi:40j, 0:np.pi:20j]
    ax3.plot_wireframe(radii[0] * np.cos(u) * np.sin(v), radii[1] * np.sin(u) * np.sin(v),
                       radii[2] * np.cos(v), color='0.8', lw=0.4)
    ax3.plot(w_p[:, 0], w_p[:, 1], w_p[:, 2], color='C3', lw=1.2, label='polhode')
    ax3.set(xlabel='ω₁', ylabel='ω₂', zlabel='ω₃',
            title=f'polhode on the energy ellipsoid (t = {t[k0]:.3g} {unit})')
    ax3.set_box_aspect(radii / radii.max())
    ax3.legend(loc='upper left')

    ax2 = fig.add_subplot(1, 2, 2)
    # invariable plane normal (fixed while torque-free)
    n = L[k0] / max(np.linalg.norm(L[k0]), 1e-300)
    e1 = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    w_in = rotation.rotate(q, w)
    ax2.plot(w_in @ e1, w_in @ e2, color='C0', lw=0.8)
    ax2.plot([0], [0], 'k+')
    ax2.set_aspect('equal', adjustable='datalim')
    ax2.set(xlabel='ω·e₁ [rad/s]', ylabel='ω·e₂ [rad/s]',
            title=f'herpolhode on the invariable plane '
                  f'(at 2T/|L| = {2 * T[k0] / max(Ln[k0], 1e-300):.4g})')
    ax2.grid(alpha=0.3)
    fig.suptitle(f'{title}: Poinsot\'s construction{phase}')
    paths.append(_save(fig, out_dir, 'poinsot.png', plt))
    return paths


def write_actuator_plot(samples, actuators, out_dir, title):
    """actuators.png: wheel speeds (rad/s, relative to the body) against their limits,
    gimbal angles and the singularity measure det(AAᵀ), and the actuators' momentum |h_A|
    against its envelope (Σ J_i·max_speed_i for wheels, Σ h0_j for CMGs). ``actuators``:
    the engine's ActuatorConfig; samples.actuators holds Actuators.row per sample."""
    plt = _pyplot()
    os.makedirs(out_dir, exist_ok=True)
    t, a = np.asarray(samples['t']), np.asarray(samples.actuators)
    n, k = actuators.wheels, actuators.cmgs
    rows = [r for r in ('wheels' if n else None, 'gimbals' if k else None, 'momentum') if r]
    fig, axes = plt.subplots(len(rows), 1, figsize=(8, 2.6 * len(rows)), sharex=True)
    axes = np.atleast_1d(axes)
    for ax, what in zip(axes, rows):
        if what == 'wheels':
            for i, name in enumerate(actuators.wheel_names):
                ax.plot(t, a[:, i], lw=0.9, label=name)
            for sign in (1, -1):
                ax.axhline(sign * actuators.max_speed.max(), color='k', ls='--', lw=0.6)
            ax.set_ylabel('wheel speed [rad/s]')
        elif what == 'gimbals':
            for j, name in enumerate(actuators.cmg_names):
                ax.plot(t, a[:, 2 * n + j], lw=0.9, label=name)
            ax.set_ylabel('gimbal angle [rad]')
            twin = ax.twinx()
            twin.plot(t, a[:, -2], color='k', lw=0.8, ls=':', label='det(AAᵀ)')
            twin.set_ylabel('det(AAᵀ)')
            twin.legend(loc='lower right', fontsize='small')
        else:
            ax.plot(t, a[:, -1], lw=0.9, label='|h_A|')
            cap = float(np.sum(actuators.inertia * actuators.max_speed)) + \
                float(np.sum(actuators.momentum))
            ax.axhline(cap, color='k', ls='--', lw=0.6, label='envelope bound')
            ax.set_ylabel('|h_A| [N·m·s]')
        ax.legend(loc='upper right', fontsize='small')
        ax.grid(alpha=0.3)
    axes[0].set_title(f'{title}: momentum-exchange actuators')
    axes[-1].set_xlabel('t [s]')
    return _save(fig, out_dir, 'actuators.png', plt)


def _save(fig, out_dir, name, plt):
    path = os.path.join(out_dir, name)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
