"""The generalisation suite's B-dot family: small spacecraft detumbled by magnetorquers.

Issue 30: the B-dot scenes join the generalisation suite, and ``auto`` meets its budget
there too. Each scene is ``config/bdot_detumble.yaml``'s kind of run with its values drawn
(its own stream, [seed, 31, index]):

* the body: principal moments log-uniform in 0.005–0.5 kg·m² (CubeSats to small
  satellites), redrawn until the triangle inequality holds;
* the orbit: circular or nearly (e < 0.01), 400–900 km up, Kepler or J2, inclination
  uniform on the sphere, node and anomaly uniform; the epoch a uniform instant of
  2020–2029;
* the field: the tilted dipole or IGRF-14 (half each); rods of 0.05–2 A·m² each;
* the magnetometer at the control rate (1, 2 or 5 Hz), 10–100 nT of noise, a bias up to
  300 nT per axis, seeded by the scene's index;
* the controller: B-dot with Avanzini–Giulietti's gain from the orbit's n and inclination;
* the start: a tumble of 1–20 °/s in a uniform direction, attitude uniform;
* 0.05–0.4 orbit (0.03–0.1 with ``quick``: the runs go through Python at each control
  instant), samples at the control rate, the duration off the sample grid; budget: a
  decade from 1e-2 to 1e-10 rad. The gravity gradient is off, as in the scene.
"""
import math

import numpy as np

from .generated_scenes import Scene, _log_uniform

STREAM = 31
ORBITS = {True: (0.03, 0.1), False: (0.05, 0.4)}
RATES = (1.0, 2.0, 5.0)  # Hz: the magnetometer's and the controller's


def draw(seed: int, index: int, quick: bool = False) -> Scene:
    """B-dot scene ``index`` of ``seed`` (deterministic; independent of the others)."""
    from ..physics.orbit import MU, RADIUS
    rng = np.random.default_rng([seed, STREAM, index])
    while True:
        moments = sorted(_log_uniform(rng, 0.005, 0.5) for _ in range(3))
        if moments[0] + moments[1] >= moments[2]:
            break
    rng.shuffle(moments)
    a = RADIUS + float(rng.uniform(400e3, 900e3))
    e = float(rng.uniform(0.0, 0.01))
    model = 'j2' if rng.uniform() < 0.5 else 'kepler'
    inclination = float(math.acos(rng.uniform(-1.0, 1.0)))
    raan, argp, anomaly = (float(x) for x in rng.uniform(0.0, 2.0 * math.pi, 3))
    n = math.sqrt(MU / a ** 3)
    year, day, second = int(rng.integers(2020, 2030)), int(rng.integers(1, 366)), \
        int(rng.integers(0, 86400))
    epoch = (np.datetime64(f'{year}-01-01T00:00:00') + np.timedelta64(day - 1, 'D')
             + np.timedelta64(second, 's'))
    field = 'igrf' if rng.uniform() < 0.5 else 'dipole'
    rod = _log_uniform(rng, 0.05, 2.0)
    rate = float(RATES[int(rng.integers(0, len(RATES)))])
    noise = _log_uniform(rng, 1e-8, 1e-7)
    bias = rng.uniform(-3e-7, 3e-7, 3)
    spin = math.radians(_log_uniform(rng, 1.0, 20.0))
    direction = rng.normal(size=3)
    omega = spin * direction / np.linalg.norm(direction)
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    period = 1.0 / rate
    duration = _log_uniform(rng, *ORBITS[quick]) * 2.0 * math.pi / n
    duration = (math.floor(duration / period) + rng.uniform(0.1, 0.9)) * period
    budget = 10.0 ** -int(rng.integers(2, 11))
    orbit = (('orbit.model', model), ('orbit.semi_major_axis', a),
             ('orbit.eccentricity', e), ('orbit.inclination', inclination),
             ('orbit.raan', raan), ('orbit.argument_of_periapsis', argp),
             ('orbit.true_anomaly', anomaly))
    extra = (('environment.gravity_gradient', False),
             ('epoch', f'{epoch}Z'), ('environment.magnetic_field', field),
             ('magnetorquer.max_dipole', [rod] * 3), ('magnetometer.enabled', True),
             ('magnetometer.rate', rate), ('magnetometer.noise', noise),
             ('magnetometer.bias', [float(b) for b in bias]), ('seed', index),
             ('command_timeout', 2.0 * period))
    # the magnetic inclination of the gain rule: the orbit's, folded into [0, π/2]
    xi = min(inclination, math.pi - inclination)
    controller = (('mode', 'bdot'), ('inertia', list(moments)), ('control_rate', rate),
                  ('bdot.orbit_rate', n), ('bdot.magnetic_inclination', xi),
                  ('bdot.max_dipole', [rod] * 3))
    return Scene(seed, index, 'bdot', tuple(moments), tuple(omega.tolist()),
                 (float(q[0]), float(q[1]), float(q[2]), float(q[3])), spin * duration,
                 duration, rate, budget, control_rate=rate, orbit=orbit, extra=extra,
                 controller=controller)
