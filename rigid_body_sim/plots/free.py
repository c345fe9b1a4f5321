"""The figures every run gets: ω(t), T and |L| (as drift while they are conserved), and
Poinsot's construction for the free (torque-free) part of the run.

Poinsot: the energy ellipsoid ω·Iω = 2T (principal frame) rolls without slipping on the
invariable plane ω·L̂ = 2T/|L| fixed in space. The polhode is ω's path on the ellipsoid
(body frame); the herpolhode is ω's path on the plane (inertial frame). With internal
dissipation T falls at constant |L|: the ellipsoid shrinks and the plane moves towards
the origin, so the path is drawn coloured by time on the ellipsoids of a few energies.
"""
import numpy as np

from ..physics import rotation
from .common import drift, pyplot, save

CONSERVED_RTOL = 1e-6  # a quantity that moves less than this is plotted as its drift


def omega(s, out_dir, title, unit, scale):
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(8, 4))
    w = np.asarray(s['angular_velocity'])
    norm = np.linalg.norm(w, axis=1)
    # samples further apart than the components turn (Explorer 1 at 1 Hz spins at 10 rev/s):
    # lines between them would draw aliasing, so dots, with |ω| as the envelope
    # (judged between torque-free samples: a controller may change ω fast on purpose)
    step = np.linalg.norm(np.diff(w, axis=0), axis=1) if len(w) > 2 else np.zeros(0)
    free = np.all(np.asarray(s['torque'])[:-1] == 0.0, axis=1) if len(w) > 2 else step > 0
    aliased = bool(np.any(free & (step > 0.5 * np.maximum(norm[1:], 1e-300))))
    for i, name in enumerate('xyz'):
        if aliased:
            ax.plot(s['t'] / scale, w[:, i], '.', ms=1.5, label=f'ω_{name}')
        else:
            ax.plot(s['t'] / scale, w[:, i], lw=0.8, label=f'ω_{name}')
    ax.plot(s['t'] / scale, norm, 'k', lw=0.8, label='|ω|')
    note = ' (samples slower than the spin: components shown as points)' if aliased else ''
    ax.set(xlabel=f't [{unit}] (sim time)', ylabel='ω [rad/s] (body frame)')
    ax.set_title(f'{title}: angular velocity{note}', fontsize=10)
    ax.legend(loc='upper right')
    ax.grid(alpha=0.3)
    return save(fig, out_dir, 'omega.png', 'ω components (body frame) against sim time', plt,
                {'aliased': aliased})


def invariants(s, out_dir, title, unit, scale):
    """T and |L| against time: the value where it changes, the drift where it is conserved."""
    plt = pyplot()
    fig, axes = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    T = np.asarray(s['kinetic_energy'])
    L = np.linalg.norm(s['angular_momentum'], axis=1)
    ts = s['t'] / scale
    values = {}
    for ax, y, name, u, rel in ((axes[0], T, 'T', 'J', 'T/T₀'),
                                (axes[1], L, '|L|', 'kg·m²/s', '|L|/|L₀|')):
        d = drift(y)
        if np.max(np.abs(d)) < CONSERVED_RTOL:
            ax.plot(ts, d, lw=0.9)
            ax.set_ylabel(f'{rel} − 1 [1]')
            ax.text(0.01, 0.04, f'{name}₀ = {y[0]:.9g} {u}, conserved', transform=ax.transAxes,
                    fontsize=8, va='bottom', bbox={'facecolor': 'white', 'alpha': 0.8, 'lw': 0})
        else:
            ax.plot(ts, y, lw=0.9)
            ax.set_ylabel(f'{name} [{u}]')
        values[f'{name}_drift'] = float(np.max(np.abs(d)))
        ax.grid(alpha=0.3)
    axes[0].set_title(f'{title}: kinetic energy and angular momentum')
    axes[1].set_xlabel(f't [{unit}] (sim time)')
    return save(fig, out_dir, 'invariants.png',
                'T and |L| against sim time (drift relative to t = 0 while conserved)', plt,
                values)


def poinsot(s, body, out_dir, title, unit, scale, free_end):
    """Poinsot's figure of the free phase (t < ``free_end``), or None when the run has
    none: under torque from the start the construction does not hold, and its ellipsoid
    of the energy at t = 0 (0 for a body at rest) drew round-off noise."""
    t = np.asarray(s['t'])
    free = t < free_end
    if np.count_nonzero(free) < 2:
        return None
    plt = pyplot()
    note = '' if np.all(free) else f' — free phase, t < {free_end / scale:.4g} {unit}'
    t = t[free]
    w_b = np.asarray(s['angular_velocity'])[free]
    q = np.asarray(s['attitude'])[free]
    L = np.asarray(s['angular_momentum'])[free]
    T = np.asarray(s['kinetic_energy'])[free]
    moments = body.principal_moments
    w_p = body.to_principal(w_b)
    moving = np.max(np.abs(drift(T))) >= CONSERVED_RTOL if T[0] > 0 else False
    fig = plt.figure(figsize=(11, 5))
    ax3 = fig.add_subplot(1, 2, 1, projection='3d')
    u, v = np.mgrid[0:2 * np.pi:40j, 0:np.pi:20j]
    # the ellipsoids drawn: the one energy, or a few snapshots of a falling energy
    snaps = np.unique(np.linspace(0, len(t) - 1, 4 if moving else 1).astype(int))
    cmap = plt.get_cmap('viridis')
    tn = (t - t[0]) / max(t[-1] - t[0], 1e-300)
    for k in snaps:
        radii = np.sqrt(2 * max(T[k], 1e-300) / moments)
        colour = cmap(tn[k]) if moving else '0.75'
        ax3.plot_wireframe(radii[0] * np.cos(u) * np.sin(v), radii[1] * np.sin(u) * np.sin(v),
                           radii[2] * np.cos(v), color=colour, lw=0.3, alpha=0.6)
    big = np.sqrt(2 * max(T[snaps[0]], 1e-300) / moments)
    ax3.set_box_aspect(big / big.max())
    if moving:
        ax3.scatter(w_p[:, 0], w_p[:, 1], w_p[:, 2], c=tn, cmap=cmap, s=2)
        ax3.set_title(f'polhode on the ellipsoids of T = {T[snaps[0]]:.3g} … '
                      f'{T[snaps[-1]]:.3g} J\n(colour = time, as the energy falls)', fontsize=9)
    else:
        ax3.plot(w_p[:, 0], w_p[:, 1], w_p[:, 2], color='C3', lw=1.2)
        ax3.set_title(f'polhode on the energy ellipsoid ω·Iω = 2T, T = {T[0]:.4g} J',
                      fontsize=9)
    ax3.set(xlabel='ω₁ [rad/s]', ylabel='ω₂ [rad/s]', zlabel='ω₃ [rad/s]')

    ax2 = fig.add_subplot(1, 2, 2)
    # the invariable plane's normal (fixed); a body at rest has none: any plane will do
    n = L[0] / np.linalg.norm(L[0]) if np.linalg.norm(L[0]) > 0 else np.array([0, 0, 1.0])
    e1 = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    w_in = rotation.rotate(q, w_b)
    height = w_in @ n  # = 2T/|L|: the plane's distance from the fixed point
    if moving:
        sc = ax2.scatter(w_in @ e1, w_in @ e2, c=(t - t[0]) / scale, cmap=cmap, s=2)
        fig.colorbar(sc, ax=ax2, label=f't [{unit}]')
        where = f'2T/|L| falls {height[0]:.3g} → {height[-1]:.3g} rad/s'
    else:
        ax2.plot(w_in @ e1, w_in @ e2, color='C0', lw=0.8)
        where = f'at 2T/|L| = {height[0]:.4g} rad/s'
    ax2.plot([0], [0], 'k+')
    ax2.set_aspect('equal', adjustable='datalim')
    ax2.set(xlabel='ω·e₁ [rad/s] (inertial)', ylabel='ω·e₂ [rad/s] (inertial)')
    ax2.set_title(f'herpolhode on the invariable plane ⊥ L ({where})', fontsize=9)
    ax2.grid(alpha=0.3)
    fig.suptitle(f'{title}: Poinsot\'s construction{note}')
    return save(fig, out_dir, 'poinsot.png',
                'Poinsot: polhode on the energy ellipsoid, herpolhode on the invariable plane',
                plt, {'plane_height': (float(height[0]), float(2 * T[0] / np.linalg.norm(L[0])))})
