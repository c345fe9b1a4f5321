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


# "near": the generated orbit family starts its librations 0.01–0.3 rad from LVLH at
# 0.01–0.3 n relative to it; beyond these the motion is no small libration of one
# equilibrium and the test says nothing
NEAR_ANGLE = 0.5   # rad from the equilibrium attitude
NEAR_RATE = 0.5    # × the orbit rate n, relative to the orbit frame
MARGIN = 1e-9      # relative: an inequality closer than this is marginal (unknown)
AXES = 'xyz'
PERMUTATIONS = tuple(itertools.permutations(range(3)))


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


def _cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def _dot(a, b) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _axes(q):
    """The columns of the rotation matrix of q = (x, y, z, w): the principal axes in the
    inertial frame."""
    x, y, z, w = q
    return ([1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w)],
            [2 * (x * y - z * w), 1 - 2 * (x * x + z * z), 2 * (y * z + x * w)],
            [2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y)])


def nearest(moments, principal_attitude, angular_velocity, r, v) -> Optional[Equilibrium]:
    """The LVLH equilibrium the body starts near, None if it is near none (NEAR_ANGLE,
    NEAR_RATE). ``principal_attitude``: principal frame → inertial (x, y, z, w);
    ``angular_velocity``: rad/s in principal axes; r, v: the orbit's state (m, m/s) in the
    inertial frame at that instant. In plain floats: asked once per selection, where
    numpy's per-call cost on 3-vectors was most of a short run's selection (the generated
    gravity-gradient scenes: ~40 % of it)."""
    moments = [float(x) for x in np.asarray(moments, float).tolist()]
    r, v = np.asarray(r, float).tolist(), np.asarray(v, float).tolist()
    q = np.asarray(principal_attitude, float).tolist()
    norm = math.sqrt(sum(c * c for c in q))
    q = [c / norm for c in q]
    h = _cross(r, v)
    r2, h_norm = _dot(r, r), math.sqrt(_dot(h, h))
    if r2 <= 0.0 or h_norm <= 0.0:
        return None
    z = [-c / math.sqrt(r2) for c in r]                  # LVLH axes in the inertial frame
    y = [-c / h_norm for c in h]
    lvlh = (_cross(y, z), y, z)
    principal = _axes(q)                                 # principal axes, inertial frame
    m = [[_dot(lvlh[i], principal[j]) for j in range(3)] for i in range(3)]
    a = [[abs(c) for c in row] for row in m]
    perm = max(PERMUTATIONS, key=lambda p: a[0][p[0]] + a[1][p[1]] + a[2][p[2]])
    # the signed permutation nearest m, a proper rotation (det +1): flip the weakest axis
    signs = [math.copysign(1.0, m[i][perm[i]]) for i in range(3)]
    inversions = sum(perm[i] > perm[j] for i in range(3) for j in range(i + 1, 3))
    if (-1.0) ** inversions * signs[0] * signs[1] * signs[2] < 0:
        weakest = min(range(3), key=lambda i: abs(m[i][perm[i]]))
        signs[weakest] = -signs[weakest]
    trace = sum(signs[i] * m[i][perm[i]] for i in range(3))
    angle = math.acos(min(1.0, max(-1.0, (trace - 1.0) / 2.0)))
    rate_vector = [c / r2 for c in h]                    # LVLH's rate, inertial frame
    n = math.sqrt(_dot(rate_vector, rate_vector))
    w = np.asarray(angular_velocity, float).tolist()
    relative = [w[j] - _dot(principal[j], rate_vector) for j in range(3)]
    rate = math.sqrt(_dot(relative, relative)) / n
    if angle > NEAR_ANGLE or rate > NEAR_RATE:
        return None
    ix, iy, iz = (moments[perm[i]] for i in range(3))
    return Equilibrium((ix, iy, iz), angle, rate, *stability(ix, iy, iz))
