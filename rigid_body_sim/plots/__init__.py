"""PNG figures of a run, chosen by what the scene is for (from the samples' sim-time stamps).

Every run: omega.png, invariants.png, and poinsot.png if it has a free phase (plots.free).
Then the scene's own story
(plots.story), with the analytic expectation beside the simulation:
* a free asymmetric tumble that flips: flips.png (2K/λ);
* a free axisymmetric body: precession.png (body and space cones; the Earth's wobble);
* an axisymmetric body with double-bracket dissipation: nutation.png (tan θ ∝ e^{ct});
* a controlled run: control.png (critically damped slew, exponential detumble);
* the gravity gradient in a circular orbit, started relative to LVLH: libration.png
  (plots.orbit: pitch and roll–yaw at their small-libration frequencies);
* a B-dot detumble (controller mode bdot): bdot.png (plots.orbit: |ω| against the
  averaged closed loop's decay) in place of control.png.
A scene whose environment exerts a torque (orbit terms) has no free phase.
"""
import numpy as np

from ..physics import analytic
from . import free, orbit, story
from .actuators import write_actuator_plot
from .common import Figure, time_unit

__all__ = ['Figure', 'free_until', 'write_actuator_plot', 'write_figures', 'write_plots']


def free_until(t, torque):
    """Time of the first nonzero torque sample (inf when the run is torque-free)."""
    applied = np.nonzero(np.any(np.asarray(torque) != 0.0, axis=1))[0]
    return float(t[applied[0]]) if applied.size else np.inf


def write_figures(samples, body, out_dir, title, free_end=np.inf, scene=None, only=None):
    """Write the run's figures into ``out_dir``; returns their :class:`Figure` records.

    samples: t (N,) sim time s, attitude (N, 4) body→inertial, angular_velocity (N, 3) body
    frame, angular_momentum (N, 3) inertial, kinetic_energy (N,); optionally
    angular_momentum_body (N, 3) and torque (N, 3), body frame. Poinsot's picture holds
    only without torque: it shows the samples before ``free_end`` (s), and is not drawn
    when there are none. ``scene`` (a scene.SceneFile) says what the run is for: its
    dissipation and its controller. ``only`` (a set of file names): draw just those of the
    run's figures (the tour's thumbnails need one or two of a scene's four or five).
    """
    def wanted(name):
        return only is None or name in only

    s = {k: np.asarray(samples[k]) for k in ('t', 'attitude', 'angular_velocity',
                                              'angular_momentum', 'kinetic_energy')}
    w = s['angular_velocity']
    s['angular_momentum_body'] = _field(samples, 'angular_momentum_body', w @ body.inertia)
    s['torque'] = _field(samples, 'torque', np.zeros_like(w))
    unit, scale = time_unit(s['t'])
    figures = [draw(s, out_dir, title, unit, scale)
               for name, draw in (('omega.png', free.omega), ('invariants.png', free.invariants))
               if wanted(name)]
    sim = scene.simulator if scene is not None else {}
    environment = _environment(sim)
    torque_free_end = free_end
    if environment is not None and environment.terms:
        free_end = min(free_end, float(s['t'][0]))  # the environment's torque acts all along
    figure = free.poinsot(s, body, out_dir, title, unit, scale, free_end) \
        if wanted('poinsot.png') else None
    figures += [figure] if figure is not None else []  # None: no free phase (or not wanted)
    dissipative = sim.get('dissipation.model', 'none') != 'none'
    symmetric = analytic.symmetry_axis(body.principal_moments) is not None
    n_free = int(np.count_nonzero(s['t'] < free_end))
    if n_free >= 3 and not dissipative:
        w0 = body.to_principal(w[0])
        if symmetric:
            if wanted('precession.png'):
                figures.append(story.precession(s, body, out_dir, title, unit, scale))
        elif np.isfinite(analytic.flip_interval(body.principal_moments, w0)) \
                and wanted('flips.png'):
            figures.append(story.flips(s, body, out_dir, title, unit, scale, free_end))
    if dissipative and symmetric and sim.get('dissipation.model') == 'double_bracket' \
            and not np.isfinite(torque_free_end) and wanted('nutation.png'):
        figures.append(story.nutation(s, body, out_dir, title, unit, scale,
                                      sim['dissipation.coefficient']))
    if scene is not None and scene.controlled and scene.controller.get('mode') == 'bdot':
        if wanted('bdot.png'):
            figures.append(orbit.bdot_detumble(s, body.principal_moments, scene.controller,
                                               out_dir, title, unit, scale))
    elif scene is not None and scene.controlled and wanted('control.png'):
        ctl = dict(scene.controller)
        ctl.setdefault('max_torque', sim.get('max_torque', np.inf))
        figures.append(story.control(s, out_dir, title, unit, scale, ctl, free_end))
    if environment is not None and environment.gravity_gradient \
            and sim.get('orbit.eccentricity') == 0.0 and sim.get('orbit.model') == 'kepler' \
            and sim.get('initial_attitude_frame') == 'lvlh' and len(s['t']) >= 20 \
            and wanted('libration.png'):
        figures.append(orbit.libration(s, environment.orbit, np.diag(body.inertia), out_dir,
                                       title, unit, scale))
    return figures


def _environment(sim):
    """The scene's orbit settings (engine.environment_specs), None without an orbit."""
    if sim.get('orbit.model', 'none') == 'none':
        return None
    from ..engine.environment_specs import environment_from_parameters
    return environment_from_parameters(sim)


def write_plots(samples, body, out_dir, title, free_end=np.inf, scene=None, only=None):
    """:func:`write_figures`, returning the paths only."""
    return [f.path for f in write_figures(samples, body, out_dir, title, free_end, scene, only)]


def _field(samples, key, default):
    try:
        return np.asarray(samples[key])
    except (KeyError, AttributeError):
        return default
