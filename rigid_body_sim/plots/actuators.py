"""actuators.png: reaction wheels and CMGs of a scene that has them (engine.actuators)."""
import numpy as np

from .common import pyplot, save


def write_actuator_plot(samples, actuators, out_dir, title):
    """actuators.png: wheel speeds (rad/s, relative to the body) against their limits,
    gimbal angles and the singularity measure det(AAᵀ), and the actuators' momentum |h_A|
    against its envelope (Σ J_i·max_speed_i for wheels, Σ h0_j for CMGs). ``actuators``:
    the engine's ActuatorConfig; samples.actuators holds Actuators.row per sample."""
    plt = pyplot()
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
    return save(fig, out_dir, 'actuators.png', 'momentum-exchange actuators: wheel speeds, '
                'gimbal angles and det(AAᵀ), |h_A| against its envelope', plt).path
