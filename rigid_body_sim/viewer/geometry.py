"""Poinsot's construction and the body's display box: pure geometry, free of ROS and Foxglove.

Frames: the *principal* frame has the principal axes of inertia as its axes; the *body*
frame is ``base_link``; the *inertial* frame is ``world``. Quaternions are (x, y, z, w).

Poinsot's construction (torque-free motion): the angular velocity ω lies on the energy
ellipsoid ω·Iω = 2T, fixed in the body (semi-axes √(2T/I_i) along the principal axes), and
on the invariable plane ω·L̂ = 2T/|L|, fixed in space and perpendicular to L. The plane is
tangent to the ellipsoid at ω (the ellipsoid's normal at ω is Iω = L), so the ellipsoid
rolls without slipping on it. The contact point traces the polhode on the ellipsoid (in the
body) and the herpolhode on the plane (in space).
"""
import numpy as np


def box_edges(moments, mass: float = 1.0):
    """Edge lengths (a, b, c) in m of the uniform box of ``mass`` kg with principal moments
    ``moments`` (kg·m²), edge i along principal axis i.

    A uniform box has I_1 = m(b² + c²)/12 and cyclic, so a² = 6(I_2 + I_3 − I_1)/m. A thin
    plate (I_3 = I_1 + I_2) gives c = 0. ValueError when the moments violate the triangle
    inequalities (no box, and no body, has them)."""
    i = np.asarray(moments, float)
    sq = 6.0 * (i.sum() - 2.0 * i) / mass
    tol = 1e-12 * 6.0 * i.sum() / mass
    if np.any(sq < -tol):
        raise ValueError(f'principal moments {i.tolist()} violate the triangle inequality')
    return np.sqrt(np.maximum(sq, 0.0))


def box_inertia(edges, mass: float = 1.0):
    """Principal moments (kg·m²) of the uniform box with ``edges`` (m): the inverse of
    :func:`box_edges`."""
    e2 = np.asarray(edges, float) ** 2
    return mass * (e2.sum() - e2) / 12.0


def display_box(moments, size: float = 1.0):
    """Edges of the uniform box with the body's principal moments, scaled so that the longest
    edge is ``size`` m (the box's mass is chosen for display; the edge ratios carry the
    moments). Returns (edges, mass): ``box_inertia(edges, mass)`` equals ``moments``."""
    unit = box_edges(moments, 1.0)
    k = size / unit.max()
    # edges scale as 1/√m: m = 1/k² gives edges unit·k
    return unit * k, 1.0 / k ** 2


def ellipsoid_semi_axes(moments, kinetic_energy: float):
    """Semi-axes (rad/s) of the energy ellipsoid ω·Iω = 2T along the principal axes."""
    return np.sqrt(2.0 * kinetic_energy / np.asarray(moments, float))


def invariable_plane(angular_momentum, kinetic_energy: float):
    """(unit normal L̂, distance 2T/|L| from the fixed point) of the invariable plane, in the
    frame ``angular_momentum`` is given in (world). Distance in rad/s."""
    L = np.asarray(angular_momentum, float)
    norm = float(np.linalg.norm(L))
    if norm == 0.0:
        raise ValueError('|L| = 0: the body is at rest, there is no invariable plane')
    return L / norm, 2.0 * kinetic_energy / norm


def polhode_point(omega_principal):
    """The contact point of the energy ellipsoid with the invariable plane, in the principal
    frame: ω itself (rad/s). Named for what it is in the construction."""
    return np.asarray(omega_principal, float).copy()


def _shortest_rotation(a, b):
    """Quaternion (x, y, z, w) of the shortest rotation taking unit ``a`` to unit ``b``.

    q ∝ (a × b, 1 + a·b), with 1 + a·b computed as |a + b|²/2, which keeps its relative
    accuracy when b is nearly −a (where 1 + a·b itself cancels)."""
    s = a + b
    q = np.array((*np.cross(a, b), 0.5 * float(s @ s)))
    n = np.linalg.norm(q)
    if n == 0.0:  # exactly opposite: half a turn about any axis perpendicular to a
        axis = np.cross(a, (1.0, 0.0, 0.0) if abs(a[0]) < 0.9 else (0.0, 1.0, 0.0))
        return np.append(axis / np.linalg.norm(axis), 0.0)
    return q / n


def plane_rotation(normal):
    """Quaternion (x, y, z, w) of the shortest rotation taking +z to ``normal`` (unit): the
    orientation of a plane drawn in its own xy-plane."""
    return _shortest_rotation(np.array((0.0, 0.0, 1.0)), np.asarray(normal, float))


def arrow_rotation(direction):
    """Quaternion (x, y, z, w) of the shortest rotation taking +x to ``direction`` (any
    length; identity for zero): Foxglove's arrows point along their pose's +x."""
    d = np.asarray(direction, float)
    n = float(np.linalg.norm(d))
    if n == 0.0:
        return np.array((0.0, 0.0, 0.0, 1.0))
    return _shortest_rotation(np.array((1.0, 0.0, 0.0)), d / n)


def rotate_vector(q, v):
    """``v`` rotated by the unit quaternion ``q`` (x, y, z, w), for one vector in plain floats:
    v + 2w(u × v) + 2u × (u × v), u = (x, y, z). ``physics.rotation.rotate`` does the same on
    arrays; for a single vector per sample its numpy overhead is most of the viewer's cost."""
    x, y, z, w = (float(c) for c in q)
    vx, vy, vz = (float(c) for c in v)
    tx, ty, tz = 2.0 * (y * vz - z * vy), 2.0 * (z * vx - x * vz), 2.0 * (x * vy - y * vx)
    return np.array((vx + w * tx + y * tz - z * ty, vy + w * ty + z * tx - x * tz,
                     vz + w * tz + x * ty - y * tx))


class Trace:
    """A bounded polyline: the last ``capacity`` points (m) kept, a new point appended only
    when it is at least ``min_step`` from the last one (a slow trace does not fill the buffer
    with duplicates)."""

    def __init__(self, capacity: int, min_step: float):
        self.capacity = int(capacity)
        self.min_step = float(min_step)
        self.points = np.empty((self.capacity, 3))
        self.count = 0  # points held, ≤ capacity
        self.head = 0   # where the next point goes

    def clear(self):
        self.count = self.head = 0

    def add(self, point) -> bool:
        """Append ``point``; returns whether it was kept."""
        p = np.asarray(point, float)
        if self.count:
            last = self.points[(self.head - 1) % self.capacity]
            if np.linalg.norm(p - last) < self.min_step:
                return False
        self.points[self.head] = p
        self.head = (self.head + 1) % self.capacity
        self.count = min(self.count + 1, self.capacity)
        return True

    def ordered(self):
        """The points held, oldest first, shape (count, 3)."""
        if self.count < self.capacity:
            return self.points[:self.count]
        return np.roll(self.points, -self.head, axis=0)
