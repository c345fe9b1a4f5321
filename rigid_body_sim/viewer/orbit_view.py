"""What the viewer draws of a spacecraft's orbit, from the physics' own functions (no ROS, no
Foxglove): the Earth, the orbit's path, the LVLH frame, the Sun's direction and the Earth's
magnetic field at the spacecraft.

The orbit is drawn in an inset beside the body (frame ``orbit_view``, axes parallel to
``world``, centred on the Earth), scaled so that the orbit's apoapsis is ``size`` from the
Earth's centre: the Earth (radius 6378137 m) and a 7,000 km orbit cannot share a scale with
a 1 m body. At the body itself, the LVLH axes, the Sun's direction and the field's direction
are drawn as arrows of fixed length: directions, in ``world``.

The path is the osculating two-body conic through the orbit's state (r, v) at the sample,
over one period: the orbit itself for ``kepler``, the instantaneous conic for ``j2`` and
``sgp4`` (whose drift over one period is a fraction of a degree).
"""
from datetime import datetime, timedelta, timezone
import math

import numpy as np

from ..physics.environment import earth, magnetic_field, sunlight
from ..physics.orbit import MU, frames

PATH_POINTS = 180          # segments of the drawn conic
# the epoch of a scene that gives none (the orbit alone needs none; the Sun and the field
# do): J2000, said in the log and on the docs page
DEFAULT_EPOCH = datetime(2000, 1, 1, 12, 0, 0, tzinfo=timezone.utc)
FIELD_MODELS = magnetic_field.MODELS
DIPOLE_REFRESH_S = 3600.0  # sim time over which the dipole's moment is kept (see field)


def conic_path(r, v, mu: float = MU, points: int = PATH_POINTS) -> np.ndarray:
    """Positions (points + 1, 3; m, inertial) of the two-body conic through (r, v) over one
    period, starting at r and closing on it. ValueError for a state on no closed orbit."""
    # here, not at the top: the orbit's kernel loads numba (~0.35 CPU-s), and a viewer of a
    # scene without an orbit never draws one
    from ..physics.orbit import kernel, osculating_elements
    env = osculating_elements(r, v, mu, 0.0)
    period = 2.0 * math.pi / env[kernel.M_RATE]
    out = np.zeros(6)
    path = np.empty((points + 1, 3))
    for k in range(points + 1):
        kernel.state_at(env, period * k / points, out)
        path[k] = out[:3]
    return path


class OrbitFrame:
    """The orbit's drawing at one sample (its stamp, ns): the inset's scale and the vectors
    in ``world``."""

    def __init__(self, r, v, sun=None, field=None, size: float = 1.0, stamp_ns: int = 0):
        self.stamp_ns = int(stamp_ns)
        self.r, self.v = np.asarray(r, float), np.asarray(v, float)
        self.path = conic_path(self.r, self.v)
        radii = np.linalg.norm(self.path, axis=1)
        self.scale = size / float(radii.max())          # display m per m
        self.earth_radius = sunlight.EARTH_RADIUS * self.scale
        self.lvlh = frames.lvlh_axes(self.r, self.v)    # columns: LVLH x, y, z in world
        self.sun = sun          # unit Earth → Sun, world (None: unknown sim time)
        self.field = field      # T, world (None: unknown sim time)


class Environment:
    """The Sun and the field along the orbit: ``epoch`` (datetime, None: DEFAULT_EPOCH) and
    the field model (``dipole`` or ``igrf``). ValueError naming the model or the epoch."""

    def __init__(self, epoch=None, field_model: str = 'dipole'):
        if field_model not in FIELD_MODELS:
            raise ValueError(f'magnetic field model {field_model!r} is not one of '
                             f'{FIELD_MODELS}')
        self.epoch = epoch or DEFAULT_EPOCH
        self.field_model = field_model
        self._moment = None  # (sim time, the dipole's moment then, A·m², ECEF)
        magnetic_field.check_epoch(self.epoch)

    def sun(self, t: float) -> np.ndarray:
        """Unit Earth → Sun vector (world) at sim time ``t`` (s)."""
        return np.asarray(sunlight.sun_direction(self.epoch, t), float)

    def field(self, r, t: float) -> np.ndarray:
        """The field (T, world) at inertial position ``r`` (m) at sim time ``t`` (s).

        The dipole as ``magnetic_field.field`` computes it, with its moment (IGRF's degree 1,
        32 ms to read from the model's file) kept for DIPOLE_REFRESH_S of sim time: the
        moment turns by ~1e-3 rad a year, ~1e-7 rad in that time. IGRF in full (70 ms a
        call): the node draws it at most once a wall second."""
        r = np.asarray(r, float)
        if self.field_model != 'dipole':
            return np.asarray(magnetic_field.field(self.field_model, r, self.epoch, t), float)
        if self._moment is None or abs(t - self._moment[0]) > DIPOLE_REFRESH_S:
            self._moment = (t, magnetic_field.dipole_moment(
                self.epoch + timedelta(seconds=float(t))))
        angle = earth.gmst(self.epoch, t)
        b = magnetic_field.dipole_field(earth.eci_to_ecef(r, angle), self._moment[1])
        return np.asarray(earth.ecef_to_eci(b, angle), float)

    def frame(self, r, v, t, size: float = 1.0, stamp_ns: int = 0) -> OrbitFrame:
        """The drawing at a sample; ``t`` None (not yet known): no Sun, no field."""
        if t is None:
            return OrbitFrame(r, v, size=size, stamp_ns=stamp_ns)
        return OrbitFrame(r, v, self.sun(t), self.field(r, t), size=size, stamp_ns=stamp_ns)


class SimTime:
    """Sim time (s) of a state stamp (ns), from one (stamp, sim time) pair the simulator
    states in its diagnostics and the slope between them: stamps are sim time with
    ``publish_clock``, else the run's start plus sim time / ``real_time_factor`` (1 when 0),
    so the map is linear (``nodes/simulator.py``)."""

    def __init__(self):
        self.anchor = None   # (stamp ns, sim time s, sim seconds per stamp second)

    def set(self, stamp_ns: int, sim_time: float, real_time_factor: float,
            publish_clock: bool):
        slope = 1.0 if publish_clock or real_time_factor <= 0.0 else real_time_factor
        self.anchor = (int(stamp_ns), float(sim_time), slope)

    def __call__(self, stamp_ns: int):
        if self.anchor is None:
            return None
        stamp0, t0, slope = self.anchor
        return t0 + (int(stamp_ns) - stamp0) * 1e-9 * slope

