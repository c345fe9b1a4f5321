"""The generalisation suite's scenes: seeded draws across the space users run
(:mod:`.generated` runs and judges them).

Every scene is drawn from one ``numpy.random.Generator`` seeded with ``seed`` and its index,
so a scene is the same whatever the count and the order (scene i of seed s is reproducible
alone). A scene:

* kind: torque-free, double-bracket or viscous dissipation, or detumble control;
* principal moments log-uniform in 0.2–3 kg·m² (redrawn until I1 + I2 ≥ I3), initial
  ω of log-uniform norm 0.1–100 rad/s in a uniform direction, attitude uniform;
* rotation |ω|·T log-uniform in 10²–10⁵ rad (10²–10⁴ with ``quick``, to fit its minutes);
  50–2000 samples per run, the duration a non-integer number of sample periods;
* dissipation: its decay over the run (κT, κ the rate at which the momentum leaves the
  minor axis, double bracket; c·T/I_max, viscous) log-uniform in 0.05–20 (0.05–3);
  detumble: the rate decays as exp(−2ζω_n t) with 2ζω_n set so that the body turns about
  the drawn rotation, control at 10–100 Hz;
* budget: a decade from 1e-2 to 1e-10 rad.

The orbit family (:func:`draw_gravity_gradient`) puts the body in a Kepler or J2 orbit with
the gravity gradient on; the B-dot family draws in :mod:`.generated_bdot`.
"""
import math
from dataclasses import dataclass

import numpy as np

from ..param_spec import coerce_all
from ..scene import SceneFile

KINDS = ('free', 'double_bracket', 'viscous', 'detumble')
WEIGHTS = (0.2, 0.35, 0.25, 0.2)


@dataclass(frozen=True)
class Scene:
    """A generated scene: what was drawn, and the scene file the engine runs."""
    seed: int
    index: int
    kind: str
    moments: tuple
    omega: tuple       # rad/s, body frame
    attitude: tuple    # (x, y, z, w)
    rotation: float    # rad: |ω|·duration
    duration: float    # s
    publish_rate: float
    budget: float      # rad
    coefficient: float = 0.0
    control_rate: float = 0.0
    natural_frequency: float = 0.0
    orbit: tuple = ()   # ((key, value), …) of orbit.*: an orbit scene (gravity gradient on)
    frame: str = 'world'  # of attitude and omega (lvlh: relative to the orbit frame)
    extra: tuple = ()       # ((key, value), …) more simulator parameters (a family's own)
    controller: tuple = ()  # ((key, value), …) the controller's, where the family has one

    @property
    def name(self) -> str:
        tag = 'bdot' if self.kind == 'bdot' else 'gg' if self.orbit else ''
        return f'gen{self.seed}-{tag}{self.index}'

    @property
    def dissipative(self) -> bool:
        return self.kind in ('double_bracket', 'viscous')

    def describe(self) -> str:
        extra = (f', coefficient {self.coefficient:.3g}' if self.dissipative else
                 f', control {self.control_rate:.3g} Hz' if self.kind == 'detumble' else
                 f', B-dot at {self.control_rate:.3g} Hz{_orbit_words(self)}'
                 if self.kind == 'bdot' else
                 _orbit_words(self) if self.orbit else '')
        return (f'{self.name} {self.kind}: I = {", ".join(f"{i:.3g}" for i in self.moments)}, '
                f'|ω| = {np.linalg.norm(self.omega):.3g} rad/s, {self.rotation:.3g} rad over '
                f'{self.duration:.4g} s at {self.publish_rate:.3g} Hz, budget '
                f'{self.budget:.0e}{extra}')

    def parameters(self):
        """(simulator, controller) parameters as a params file would give them."""
        sim = {'inertia': list(self.moments), 'initial_attitude': list(self.attitude),
               'initial_angular_velocity': list(self.omega), 'integrator': 'auto',
               'accuracy': self.budget, 'publish_rate': self.publish_rate,
               'duration': self.duration, 'real_time_factor': 0.0,
               'step': 1.0 / self.publish_rate}
        if self.orbit:
            sim.update(dict(self.orbit), **{'environment.gravity_gradient': True,
                                            'initial_attitude_frame': self.frame})
        sim.update(dict(self.extra))
        if self.dissipative:
            sim.update({'dissipation.model': self.kind,
                        'dissipation.coefficient': self.coefficient})
        ctl = {}
        if self.kind == 'detumble':
            torque = 20.0 * self.natural_frequency * max(self.moments) * \
                float(np.linalg.norm(self.omega))
            sim['max_torque'] = torque
            ctl = {'mode': 'detumble', 'inertia': list(self.moments),
                   'control_rate': self.control_rate,
                   'natural_frequency': self.natural_frequency, 'damping_ratio': 1.0,
                   'max_torque': torque}
        ctl.update(dict(self.controller))
        return sim, ctl

    def scene_file(self) -> SceneFile:
        from ..engine import specs
        sim, ctl = self.parameters()
        if ctl:
            ctl = coerce_all(specs.CONTROLLER, ctl, 'generated controller')
        return SceneFile(self.name, self.describe(), f'<generated {self.name}>',
                         coerce_all(specs.SIMULATOR, sim, 'generated scene'), ctl)

    def write_params_file(self, path: str) -> str:
        """The scene as a params file ``rigid-body-sim run`` takes (what a user would
        write); floats in repr form, so the file gives the same scene bit for bit."""
        import yaml
        sim, ctl = self.parameters()
        doc = {'/**/attitude_simulator': {'ros__parameters': _nested(sim)}}
        if ctl:
            doc['/**/attitude_controller'] = {'ros__parameters': _nested(ctl)}
        with open(path, 'w', encoding='utf-8') as f:
            yaml.safe_dump(doc, f, sort_keys=False)
        return path


def _nested(flat):
    """'a.b': v → {'a': {'b': v}} (a params file's nesting)."""
    out = {}
    for key, value in flat.items():
        *parents, leaf = key.split('.')
        node = out
        for p in parents:
            node = node.setdefault(p, {})
        node[leaf] = value
    return out


def _log_uniform(rng, lo, hi):
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def draw(seed: int, index: int, quick: bool = False) -> Scene:
    """Scene ``index`` of ``seed`` (deterministic; independent of the other scenes)."""
    rng = np.random.default_rng([seed, index])
    kind = KINDS[int(rng.choice(len(KINDS), p=WEIGHTS))]
    while True:
        moments = sorted(_log_uniform(rng, 0.2, 3.0) for _ in range(3))
        if moments[0] + moments[1] >= moments[2]:
            break
    rng.shuffle(moments)
    spin = _log_uniform(rng, 0.1, 100.0)
    direction = rng.normal(size=3)
    omega = spin * direction / np.linalg.norm(direction)
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    turned = _log_uniform(rng, 1e2, 1e4 if quick else 1e5)
    samples = _log_uniform(rng, 50.0, 2000.0)
    duration = turned / spin
    # a period in whole µs, and a duration off the sample grid by a drawn fraction
    period = max(1e-6, round(duration / samples, 6))
    duration = (math.floor(duration / period) + rng.uniform(0.1, 0.9)) * period
    budget = 10.0 ** -int(rng.integers(2, 11))
    spread = 1.0 / min(moments) - 1.0 / max(moments)
    coefficient = control = wn = 0.0
    if kind == 'double_bracket':  # κ = α|L|²(1/I_min − 1/I_max)
        decay = _log_uniform(rng, 0.05, 20.0)
        norm2 = float(np.sum((np.array(moments) * omega) ** 2))
        coefficient = decay / (duration * norm2 * spread)
    elif kind == 'viscous':       # |L| falls at least as exp(−c t / I_max)
        coefficient = _log_uniform(rng, 0.05, 3.0) * max(moments) / duration
    elif kind == 'detumble':      # rate ∝ exp(−2ζω_n t): turns |ω|/(2ζω_n) in all
        wn = spin / (2.0 * turned)
        control = _log_uniform(rng, 10.0, 100.0)
    return Scene(seed, index, kind, tuple(moments), tuple(omega.tolist()),
                 (float(q[0]), float(q[1]), float(q[2]), float(q[3])),
                 spin * duration, duration, 1.0 / period, budget, coefficient, control, wn)


def scenes(seed: int, count: int, quick: bool = False):
    return [draw(seed, i, quick) for i in range(count)]


# ---------------------------------------------------------------------------- orbit scenes
GG_STREAM = 30     # the orbit family's scenes come from their own streams: [seed, 30, index]
GG_ORBITS = {True: (0.5, 3.0), False: (0.5, 10.0)}  # run length in orbits (log-uniform)
LOW_PERIGEE = 200e3   # m above the surface: the lowest perigee drawn
GEO = 42.164e6        # m: the largest semi-major axis drawn


def draw_gravity_gradient(seed: int, index: int, quick: bool = False) -> Scene:
    """Orbit scene ``index`` of ``seed``: the gravity gradient along a Kepler or J2 orbit.

    * orbit: a log-uniform in 400 km up to GEO's radius; circular or (half the scenes)
      e up to 0.7 with the perigee at least 200 km up; inclination uniform on the sphere,
      node, periapsis and true anomaly uniform;
    * the body: moments as the free family's; libration about LVLH (half: a turn of
      0.01–0.3 rad from it, a rate relative to it of 0.01–0.3 n) or a tumble in the inertial
      frame at n to 10³ n (|ω|·T at most 10⁴ rad with ``quick``, 10⁵ without);
    * 0.5–10 orbits (0.5–3 with ``quick``), 50–2000 samples, the duration off the sample
      grid; budget: a decade from 1e-2 to 1e-10 rad."""
    from ..physics.orbit import MU, RADIUS
    rng = np.random.default_rng([seed, GG_STREAM, index])
    while True:
        moments = sorted(_log_uniform(rng, 0.2, 3.0) for _ in range(3))
        if moments[0] + moments[1] >= moments[2]:
            break
    rng.shuffle(moments)
    a = _log_uniform(rng, RADIUS + 400e3, GEO)
    e = 0.0 if rng.uniform() < 0.5 else \
        float(rng.uniform(0.01, min(0.7, 1.0 - (RADIUS + LOW_PERIGEE) / a)))
    model = 'j2' if rng.uniform() < 0.5 else 'kepler'
    angles = [float(math.acos(rng.uniform(-1.0, 1.0)))] + \
        [float(x) for x in rng.uniform(0.0, 2.0 * math.pi, 3)]
    n = math.sqrt(MU / a ** 3)
    direction = rng.normal(size=3)
    direction /= np.linalg.norm(direction)
    orbits = _log_uniform(rng, *GG_ORBITS[quick])
    duration = orbits * 2.0 * math.pi / n
    if rng.uniform() < 0.5:   # libration about LVLH
        frame, angle = 'lvlh', _log_uniform(rng, 0.01, 0.3)
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        q = np.append(axis * math.sin(angle / 2.0), math.cos(angle / 2.0))
        omega = _log_uniform(rng, 0.01, 0.3) * n * direction
        spin = n + float(np.linalg.norm(omega))  # roughly: the orbit frame's rate and its own
    else:                     # a tumble in the inertial frame
        frame = 'world'
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        spin = min(_log_uniform(rng, n, 1e3 * n), (1e4 if quick else 1e5) / duration)
        omega = spin * direction
    samples = _log_uniform(rng, 50.0, 2000.0)
    period = max(1e-6, round(duration / samples, 6))
    duration = (math.floor(duration / period) + rng.uniform(0.1, 0.9)) * period
    budget = 10.0 ** -int(rng.integers(2, 11))
    orbit = (('orbit.model', model), ('orbit.semi_major_axis', a),
             ('orbit.eccentricity', e), ('orbit.inclination', angles[0]),
             ('orbit.raan', angles[1]), ('orbit.argument_of_periapsis', angles[2]),
             ('orbit.true_anomaly', angles[3]))
    return Scene(seed, index, 'gravity_gradient', tuple(moments), tuple(omega.tolist()),
                 (float(q[0]), float(q[1]), float(q[2]), float(q[3])), spin * duration,
                 duration, 1.0 / period, budget, orbit=orbit, frame=frame)


def _orbit_words(scene: Scene) -> str:
    o = dict(scene.orbit)
    return (f', {o["orbit.model"]} orbit a = {o["orbit.semi_major_axis"] / 1e3:.6g} km, '
            f'e = {o["orbit.eccentricity"]:.3g}, ω given in {scene.frame}')
