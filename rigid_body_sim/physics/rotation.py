"""Quaternion helpers on batched numpy arrays, ROS order (x, y, z, w).

These few vectorised functions exist because the integrators call them every step on
(N, 4) batches, where building scipy Rotation objects would dominate the cost. The one
conversion a run needs at set-up, a rotation matrix to its quaternion (``from_matrix``),
is scipy's algorithm too, to the bit: importing ``scipy.spatial`` for it cost every node
and CLI process 0.3 CPU-s of its 1 s start-up (``test_rotation.py`` checks the bits).
"""
import math

import numpy as np


def multiply(p, q):
    """Hamilton product p ⊗ q (rotation q first, then p); shapes (..., 4)."""
    p = np.asarray(p, float)
    q = np.asarray(q, float)
    px, py, pz, pw = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    qx, qy, qz, qw = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out = np.empty(np.broadcast_shapes(p.shape, q.shape))
    out[..., 0] = pw * qx + px * qw + py * qz - pz * qy
    out[..., 1] = pw * qy - px * qz + py * qw + pz * qx
    out[..., 2] = pw * qz + px * qy - py * qx + pz * qw
    out[..., 3] = pw * qw - px * qx - py * qy - pz * qz
    return out


def cross(a, b):
    """a × b on (..., 3) arrays; np.cross costs ~10× more on single vectors."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a1 * b2 - a2 * b1
    out[..., 1] = a2 * b0 - a0 * b2
    out[..., 2] = a0 * b1 - a1 * b0
    return out


def conjugate(q):
    """Inverse of a unit quaternion."""
    q = np.array(q, float)
    q[..., :3] *= -1.0
    return q


def rotate(q, v):
    """Rotate vectors v (..., 3) by unit quaternions q (..., 4): q v q*."""
    q = np.asarray(q, float)
    v = np.asarray(v, float)
    u, w = q[..., :3], q[..., 3:4]
    t = 2.0 * cross(u, v)
    return v + w * t + cross(u, t)


def exp(rotvec):
    """Unit quaternion of the rotation by ``rotvec`` (axis × angle, rad), exact for any angle.

    sin(θ/2)/θ is evaluated with np.sinc so small angles lose no digits.
    """
    rotvec = np.asarray(rotvec, float)
    angle = np.linalg.norm(rotvec, axis=-1, keepdims=True)
    return np.concatenate((rotvec * (0.5 * np.sinc(angle / (2.0 * np.pi))), np.cos(0.5 * angle)),
                          axis=-1)


def axis_rotation(axis: int, angle):
    """Quaternions of rotations by ``angle`` (array, rad) about principal axis ``axis``
    (0, 1, 2)."""
    angle = np.asarray(angle, float)
    q = np.zeros(angle.shape + (4,))
    q[..., axis] = np.sin(0.5 * angle)
    q[..., 3] = np.cos(0.5 * angle)
    return q


def angle_between(q1, q2):
    """Rotation angle (rad, in [0, π]) taking attitude q1 to q2; sign-invariant (q ≡ −q)."""
    d = multiply(conjugate(q1), q2)
    return 2.0 * np.arctan2(np.linalg.norm(d[..., :3], axis=-1), np.abs(d[..., 3]))


def validated(q, name='quaternion'):
    """Return q normalised; ValueError if it is not finite or (near) zero.

    A norm off by more than 1e-6 is normalised silently only when it is clearly a unit
    quaternion written with few digits; zero, NaN or Inf can't be a rotation.
    """
    q = np.asarray(q, float)
    if q.shape == (4,):  # one quaternion in plain floats: numpy's per-call cost was most of it
        values = q.tolist()
        if all(map(math.isfinite, values)):
            norm = math.sqrt(sum(v * v for v in values))
            if 1e-6 <= norm < math.inf:  # else the general path says why
                return q / norm
    if q.shape[-1] != 4:
        raise ValueError(f'{name} must have 4 components (x, y, z, w), got shape {q.shape}')
    if not np.all(np.isfinite(q)):
        raise ValueError(f'{name} is not finite: {q.tolist()}')
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.any(norm < 1e-6):
        raise ValueError(f'{name} has zero norm; a rotation needs a unit quaternion (x, y, z, w)')
    return q / norm


def from_matrix(matrix):
    """The unit quaternion (x, y, z, w) of a 3×3 rotation matrix (columns: the rotated
    frame's axes), as ``scipy.spatial.transform.Rotation.from_matrix(m).as_quat()`` gives
    it, bit for bit: Shepperd's choice of the largest of the diagonal and the trace, and a
    matrix off orthogonality by more than 1e-12 first replaced by the nearest orthogonal
    one (SVD). ValueError for a determinant ≤ 0 (left-handed or singular)."""
    m = np.array(matrix, float)
    if m.shape != (3, 3):
        raise ValueError(f'a rotation matrix is 3x3, got shape {m.shape}')
    if not np.all(np.isfinite(m)) or np.linalg.det(m) <= 0:
        raise ValueError(f'not a rotation matrix (non-positive determinant or not finite): '
                         f'{m.tolist()}')
    if not np.allclose(m @ m.T, np.eye(3), rtol=1e-5, atol=1e-12):
        u, _, vt = np.linalg.svd(m)
        m = u @ vt
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    decision = (m[0, 0], m[1, 1], m[2, 2], trace)
    choice = max(range(4), key=decision.__getitem__)  # the first maximum, as argmax
    q = [0.0, 0.0, 0.0, 0.0]
    if choice != 3:
        i = choice
        j = (i + 1) % 3
        k = (j + 1) % 3
        q[i] = 1 - trace + 2 * m[i, i]
        q[j] = m[j, i] + m[i, j]
        q[k] = m[k, i] + m[i, k]
        q[3] = m[k, j] - m[j, k]
    else:
        q[0] = m[2, 1] - m[1, 2]
        q[1] = m[0, 2] - m[2, 0]
        q[2] = m[1, 0] - m[0, 1]
        q[3] = 1 + trace
    norm = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return np.array([x / norm for x in q])
