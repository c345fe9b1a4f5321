"""The attitude control law (:mod:`rigid_body_sim.control_law`) compiled by numba: the
offline engine's closed loop calls it from its own compiled loop (engine/closed_loop.py).
"""
from . import control_law
from .control_law import MODE_CODES  # noqa: F401 - the kernel's mode codes, re-exported
from .physics.jit import jit

control_torque = jit(control_law.control_torque)


def warm():
    """Compile (or load from the cache) the control kernel for both argument layouts."""
    import numpy as np
    eye = np.eye(3)
    ones = np.ones(3)
    for writeable in (True, False):
        args = [eye.copy(), ones.copy(), ones.copy(), ones.copy(), ones.copy(), eye.copy()]
        for a in args:
            a.setflags(write=writeable)
        axes, moments, kp, kd, kw, inertia = args
        for mode in (0, 1, 2):
            control_torque(mode, np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3),
                           np.array([0.0, 0.0, 0.0, 1.0]), axes, moments, kp, kd, kw, np.inf,
                           np.inf, True, inertia, np.empty(3), np.empty(3))
