"""Cost per step of one body, and of an offline run end to end (no bag, no plots).

Per step: ``splitting2``'s compiled loop, torque-free and with double-bracket damping,
against MuJoCo's Euler stepping the same free body in its C loop (``mj_step`` with
``nstep``), in the same run, so the ratio holds whatever the machine. End to end:
``offline.simulate`` on a built-in scene with nothing kept (what ``rigid-body-sim run
--no-bag --no-plots`` does): CPU per sample for a torque-free scene evaluated by
``exact``, and CPU per physics step for a dissipative one.

    python -m rigid_body_sim.bench.perstep [--quick] [--update DIR]
"""
import importlib.util

import numpy as np

from ..physics import Dissipation, Dynamics, create
from .common import best_of, cpu

FIELDS = ('what', 'method', 'count', 'cpu_s', 'us_per_unit', 'unit')
MOMENTS = (1.0, 2.0, 3.0)
Q0, M0 = np.array([0.1, -0.2, 0.3, 0.9]) / np.linalg.norm([0.1, -0.2, 0.3, 0.9]), \
    np.array([0.3, 0.6, 2.7])


def _ours(model, n):
    d = Dissipation(model, 0.1) if model != 'none' else Dissipation()
    integ = create('splitting2', Dynamics(np.array(MOMENTS), d))
    integ.run(Q0, M0, 1e-3, 10)  # compiled (or loaded) before timing
    return best_of(lambda: integ.run(Q0, M0, 1e-3, n))


def _mujoco_euler(n):
    import mujoco
    i = MOMENTS
    xml = ('<mujoco><option timestep="0.001" gravity="0 0 0" integrator="Euler"/>'
           f'<worldbody><body><freejoint/><inertial pos="0 0 0" mass="1" '
           f'diaginertia="{i[0]!r} {i[1]!r} {i[2]!r}"/></body></worldbody></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)

    def run():
        data.qpos[3:7] = (Q0[3], Q0[0], Q0[1], Q0[2])
        data.qvel[3:6] = M0 / np.array(i)
        mujoco.mj_step(model, data, nstep=n)
    return best_of(run)


def _offline(scene_name, duration, **overrides):
    from ..offline import simulate
    from ..scene import load
    scene = load(scene_name)
    simulate(scene, duration=duration / 100, keep='none', **overrides)  # kernels loaded
    t0 = cpu()
    result = simulate(scene, duration=duration, keep='none', **overrides)
    return cpu() - t0, result


def run(quick, log=print):
    """Rows per measurement, and a dict of the figures the targets read."""
    n = 20_000 if quick else 200_000
    rows, fig = [], {}

    def row(what, method, count, spent, unit):
        us = spent / count * 1e6
        rows.append({'what': what, 'method': method, 'count': count, 'cpu_s': spent,
                     'us_per_unit': us, 'unit': unit})
        log(f'  {what:34s} {method:14s} {us:8.3f} µs per {unit} ({count} in {spent:.3g} s)')
        return us

    fig['free'] = row('one body, torque-free', 'splitting2', n, _ours('none', n), 'step')
    fig['damped'] = row('one body, double-bracket damping', 'splitting2', n,
                        _ours('double_bracket', n), 'step')
    if importlib.util.find_spec('mujoco') is not None:
        fig['mujoco_euler'] = row('one body, torque-free', 'mujoco_euler', n, _mujoco_euler(n),
                                  'step')
    else:
        log('  mujoco not installed: no per-step peer (pip install --no-deps -r '
            'requirements-peers.txt)')

    duration = 100.0 if quick else 1000.0  # tennis_racket: 100 samples/s, exact
    spent, result = _offline('tennis_racket', duration, integrator='exact')
    fig['offline_exact'] = row('offline run, torque-free', 'exact', result.sample_count, spent,
                               'sample')
    duration = 20.0 if quick else 200.0  # explorer1 at its scene step, splitting2
    spent, result = _offline('explorer1', duration, integrator='splitting2')
    fig['offline_dissipative'] = row('offline run, dissipative (explorer1)', 'splitting2',
                                     result.steps, spent, 'step')
    return rows, fig


def targets_from(fig, quick=False):
    """The issue's per-step and end-to-end targets as rows (see targets.simple). ``quick``:
    the dissipative offline run is 20 s, where the run's fixed costs dominate its cost per
    step: that target is not measurable there and says so (n/a), not MISS."""
    from . import targets
    out = []
    if quick:
        out.append(targets.simple(
            'offline run µs per physics step (explorer1, no bag)', fig['offline_dissipative'],
            2.0, None, 'not measured in --quick: a 20 s run\'s fixed costs dominate; the full '
            'bench runs 200 s'))
    for key, limit, label in (('free', 0.5, 'splitting2 µs per step, torque-free'),
                              ('damped', 1.0, 'splitting2 µs per step, double-bracket damping'),
                              ('offline_exact', 10.0, 'offline run µs per sample (torque-free, '
                                                      'exact, no bag)'),
                              ('offline_dissipative', 2.0, 'offline run µs per physics step '
                                                           '(explorer1, no bag)')):
        if quick and key == 'offline_dissipative':
            continue
        out.append(targets.simple(label, fig[key], limit, fig[key] <= limit, 'at most'))
    if 'mujoco_euler' in fig:
        for key, kind in (('free', 'torque-free'), ('damped', 'damped')):
            ratio = fig['mujoco_euler'] / fig[key]
            out.append(targets.simple(
                f'MuJoCo Euler step / splitting2 step ({kind})', ratio, 4.0, ratio >= 4.0,
                f'MuJoCo Euler (C loop, torque-free) {fig["mujoco_euler"]:.3g} µs per step'))
    else:
        out.append(targets.simple('MuJoCo Euler step / splitting2 step', float('nan'), 4.0, None,
                                  'mujoco not installed'))
    return out


def update(folder, log=print):
    """Re-run this section (full) into a full run's ``folder``
    (:func:`.common.replace_section`): perstep.csv and this section's target rows."""
    from .common import replace_section
    rows, fig = run(False, log)
    return replace_section(folder, 'perstep.csv', FIELDS, rows, targets_from(fig),
                           ('splitting2 µs per step', 'offline run µs per', 'MuJoCo Euler step'))


if __name__ == '__main__':
    from .common import section_main
    section_main(__doc__, lambda quick: targets_from(run(quick)[1], quick), update)
