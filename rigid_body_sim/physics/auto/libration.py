"""The gravity gradient's equilibrium a body starts near, and whether it is stable: for
``integrator: auto`` (:mod:`.selection`), whose error model (growth as T or T²) holds for
a libration about a stable equilibrium and fails about an unstable one.

In a circular orbit a body at rest in the orbit frame (LVLH: x along the velocity, y
against the orbit normal, z to nadir) with its principal axes along LVLH's is an
equilibrium: 24 of them, one per assignment of the principal axes (and signs) to x, y, z.
With I_x, I_y, I_z the moments about the axes along x, y, z (Hughes, *Spacecraft Attitude
Dynamics*, ch. 9; Wie, *Space Vehicle Dynamics and Control*, §6.3):

* pitch (about y) is stable if I_x > I_z;
* roll–yaw, with k_R = (I_y − I_z)/I_x and k_Y = (I_y − I_x)/I_z, if k_R·k_Y > 0 and
  1 + 3k_R + k_R·k_Y > 4·√(k_R·k_Y) (then both roots of ω⁴ − (1 + 3k_R + k_R k_Y)n²ω²
  + 4k_R k_Y n⁴ are real and positive: the Lagrange and DeBra–Delp regions).

About an unstable one the motion leaves the equilibrium exponentially, and so does any
error: seed 7's orbit scenes 21 and 28 (circular, 0.02–0.03 rad from LVLH, pitch
unstable) erred 4.6× and 700× the budget with dop853 and rk4 within their a-priori bounds.
A marginal equilibrium (an equality above, a symmetric body) is treated as unstable:
nothing is known of it.
"""
import itertools
import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from .. import rotation
from ..orbit import frames

# "near": the generated orbit family starts its librations 0.01–0.3 rad from LVLH at
# 0.01–0.3 n relative to it; beyond these the motion is no small libration of one
# equilibrium and the test says nothing
NEAR_ANGLE = 0.5   # rad from the equilibrium attitude
NEAR_RATE = 0.5    # × the orbit rate n, relative to the orbit frame
MARGIN = 1e-9      # relative: an inequality closer than this is marginal (unknown)
AXES = 'xyz'


@dataclass(frozen=True)
class Equilibrium:
    """The LVLH equilibrium a body starts near: its moments along x, y, z (kg·m²), how far
    the body is from it (rad, and its rate relative to LVLH as a multiple of n) and
    whether it is stable (pitch and roll–yaw), with why not."""
    moments: tuple
    angle: float
    rate: float
    pitch_stable: bool
    roll_yaw_stable: bool

    @property
    def stable(self) -> bool:
        return self.pitch_stable and self.roll_yaw_stable

    def describe(self) -> str:
        ix, iy, iz = self.moments
        what = [w for w, ok in (('pitch (I_x ≤ I_z)', self.pitch_stable),
                                ('roll–yaw (outside the Lagrange and DeBra–Delp regions)',
                                 self.roll_yaw_stable)) if not ok]
        return (f'{self.angle:.2g} rad and {self.rate:.2g} n from an LVLH equilibrium with '
                f'I_x, I_y, I_z = {ix:.3g}, {iy:.3g}, {iz:.3g} kg·m²'
                + (f', unstable in {" and ".join(what)}' if what else ', stable'))


def stability(ix: float, iy: float, iz: float):
    """(pitch stable, roll–yaw stable) of the equilibrium with moments I_x, I_y, I_z about
    LVLH's x, y, z (module docstring); marginal cases (within MARGIN) are not stable."""
    ix, iy, iz = float(ix), float(iy), float(iz)
    scale = max(ix, iy, iz)
    pitch = ix - iz > MARGIN * scale
    k_r, k_y = (iy - iz) / ix, (iy - ix) / iz
    product = k_r * k_y
    roll_yaw = product > MARGIN and 1.0 + 3.0 * k_r + product - 4.0 * math.sqrt(product) \
        > MARGIN
    return pitch, roll_yaw


def nearest(moments, principal_attitude, angular_velocity, r, v) -> Optional[Equilibrium]:
    """The LVLH equilibrium the body starts near, None if it is near none (NEAR_ANGLE,
    NEAR_RATE). ``principal_attitude``: principal frame → inertial (x, y, z, w);
    ``angular_velocity``: rad/s in principal axes; r, v: the orbit's state (m, m/s) in the
    inertial frame at that instant."""
    moments = np.asarray(moments, float)
    lvlh = frames.lvlh_axes(r, v)                       # LVLH → inertial (columns)
    principal = rotation.rotate(principal_attitude, np.eye(3)).T  # principal → inertial
    m = lvlh.T @ principal      # m[i, j]: cosine of LVLH axis i and principal axis j
    perm = max(itertools.permutations(range(3)),
               key=lambda p: sum(abs(m[i, p[i]]) for i in range(3)))
    # the signed permutation nearest m, a proper rotation (det +1): flip the weakest axis
    signs = np.array([math.copysign(1.0, m[i, perm[i]]) for i in range(3)])
    e = np.zeros((3, 3))
    e[range(3), perm] = signs
    if np.linalg.det(e) < 0:
        weakest = min(range(3), key=lambda i: abs(m[i, perm[i]]))
        e[weakest, perm[weakest]] *= -1.0
    cos_angle = min(1.0, max(-1.0, (float(np.trace(e.T @ m)) - 1.0) / 2.0))
    angle = math.acos(cos_angle)
    n = float(np.linalg.norm(frames.lvlh_rate(r, v)))
    if n <= 0.0:
        return None
    relative = np.asarray(angular_velocity, float) - principal.T @ frames.lvlh_rate(r, v)
    rate = float(np.linalg.norm(relative)) / n
    if angle > NEAR_ANGLE or rate > NEAR_RATE:
        return None
    ix, iy, iz = (float(moments[perm[i]]) for i in range(3))
    return Equilibrium((ix, iy, iz), angle, rate, *stability(ix, iy, iz))
