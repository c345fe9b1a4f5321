"""The rigid body: inertia tensor, its validation, principal moments and axes."""
from dataclasses import dataclass

import numpy as np

from . import rotation


@dataclass(frozen=True, eq=False)
class RigidBody:
    """Mass properties of a rigid body.

    Attributes:
        inertia: (3, 3) inertia tensor about the centre of mass, body frame, kg·m².
        principal_moments: (3,) principal moments, kg·m², in the order of the columns of
            ``principal_axes``. Moments given as a diagonal keep the user's order.
        principal_axes: (3, 3) proper rotation matrix whose columns are the principal axes
            expressed in the body frame (v_body = principal_axes @ v_principal).
        principal_to_body: quaternion (x, y, z, w) of that rotation.
    """
    inertia: np.ndarray
    principal_moments: np.ndarray
    principal_axes: np.ndarray
    principal_to_body: np.ndarray

    @classmethod
    def from_inertia(cls, inertia) -> 'RigidBody':
        """Build from 3 principal moments, 9 values (row-major) or a 3×3 tensor.

        Raises ValueError naming the problem: wrong size, not finite, not symmetric, not
        positive definite, or moments violating the triangle inequalities.
        """
        values = np.asarray(inertia, dtype=float)
        if values.size == 3:
            tensor = np.diag(values.ravel())
        elif values.size == 9:
            tensor = values.reshape(3, 3)
        else:
            raise ValueError('inertia needs 3 principal moments or 9 tensor values, '
                             f'got {values.size}')
        if not np.all(np.isfinite(tensor)):
            raise ValueError(f'inertia is not finite: {tensor.tolist()}')
        scale = np.max(np.abs(tensor))
        if scale == 0.0:
            raise ValueError('inertia is zero: not positive definite')
        # exactly symmetric (3 moments, most 9-value tensors) needs no tolerance: allclose
        # costs ~20 µs of a short run's build
        if not (np.array_equal(tensor, tensor.T)
                or np.allclose(tensor, tensor.T, rtol=0.0, atol=1e-9 * scale)):
            raise ValueError(f'inertia tensor is not symmetric: {tensor.tolist()}')
        tensor = 0.5 * (tensor + tensor.T)
        off_diagonal = tensor - np.diag(np.diag(tensor))
        diagonal = not off_diagonal.any()
        if diagonal:
            moments, axes = np.diag(tensor).copy(), np.eye(3)
        else:
            moments, axes = np.linalg.eigh(tensor)
            if np.linalg.det(axes) < 0:  # make the principal frame right-handed
                axes[:, 2] *= -1.0
        if np.any(moments <= 0.0):
            raise ValueError('inertia is not positive definite: '
                             f'principal moments {moments.tolist()}')
        for i in range(3):
            a, b, c = moments[i], moments[(i + 1) % 3], moments[(i + 2) % 3]
            if a + b < c * (1.0 - 1e-12):
                raise ValueError(
                    f'principal moments {moments.tolist()} violate the triangle inequality '
                    f'({a:g} + {b:g} < {c:g}): no real mass distribution has them')
        # (x, y, z, w), as scipy's to the bit; the identity's is (0, 0, 0, 1) exactly, as
        # from_matrix gives it (its checks cost ~30 µs of a short run's build)
        quat = np.array([0.0, 0.0, 0.0, 1.0]) if diagonal else rotation.from_matrix(axes)
        for arr in (tensor, moments, axes, quat):
            arr.setflags(write=False)
        return cls(tensor, moments, axes, quat)

    def to_principal(self, v_body):
        """Vectors (..., 3) from the body frame to the principal frame."""
        return np.asarray(v_body, float) @ self.principal_axes

    def to_body(self, v_principal):
        """Vectors (..., 3) from the principal frame to the body frame."""
        return np.asarray(v_principal, float) @ self.principal_axes.T

    def attitude_to_principal(self, q_body):
        """Attitude body→inertial to principal→inertial (quaternions (..., 4), x y z w)."""
        return rotation.multiply(q_body, self.principal_to_body)

    def attitude_to_body(self, q_principal):
        """Attitude principal→inertial to body→inertial."""
        return rotation.multiply(q_principal, rotation.conjugate(self.principal_to_body))
