"""The orbit frame (LVLH) from the orbit's state: x along the velocity (for e = 0), z to
nadir (−r̂), y = z × x = −orbit normal. Frames per REP-103 (right-handed); quaternions
(x, y, z, w).
"""
import numpy as np

from ..rotation import from_matrix


def lvlh_axes(r, v) -> np.ndarray:
    """The LVLH axes as the columns of a matrix (LVLH → inertial) at position r, velocity v;
    r and v (N, 3) give the (N, 3, 3) matrices of N states."""
    r, v = np.asarray(r, float), np.asarray(v, float)
    # one state's norm as before (a dot product): along an axis numpy sums the squares
    # in another order, a last-bit change that moved auto's atol on two orbit scenes
    norm = np.linalg.norm if r.ndim == 1 else \
        (lambda a: np.linalg.norm(a, axis=-1, keepdims=True))
    z = -r / norm(r)
    h = np.cross(r, v)
    y = -h / norm(h)
    x = np.cross(y, z)
    return np.stack((x, y, z), axis=-1)


def lvlh_attitude(r, v) -> np.ndarray:
    """Quaternion (x, y, z, w) of the rotation LVLH → inertial (the orbit frame's pose)."""
    return from_matrix(lvlh_axes(r, v))


def lvlh_rate(r, v) -> np.ndarray:
    """The LVLH frame's angular velocity, inertial frame, rad/s: (r × v)/r² (exact for the
    circular orbit; the argument of latitude's rate in general)."""
    r, v = np.asarray(r, float), np.asarray(v, float)
    return np.cross(r, v) / float(r @ r)
