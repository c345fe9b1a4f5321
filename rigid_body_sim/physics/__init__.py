"""Rigid-body rotation physics, free of ROS: numpy, scipy and numba.

* :mod:`.body` — inertia validation, principal moments and axes.
* :mod:`.dynamics` — Euler's equations, torques and dissipation (principal frame);
  :mod:`.dynamics_kernel` its compiled twin, shared by every method's loop.
* :mod:`.integrators` — the registry of methods with one interface; each method's module
  sits beside its compiled loop (``splitting.py`` with ``splitting_kernel.py``, …).
* :mod:`.exact` — the torque-free solution in closed form (Jacobi elliptic functions).
* :mod:`.auto` — ``integrator: auto``: selection, its model and pilot.
* :mod:`.jit` — numba's settings for every kernel.
* :mod:`.propagator` — propagation in the user's body frame.
"""
from .body import RigidBody
from .dynamics import DISSIPATION_MODELS, Dissipation, Dynamics
from .integrators import INTEGRATORS, IntegrationError, Integrator, create, get_integrator
from .propagator import Propagator, State, poinsot

__all__ = ['RigidBody', 'Dissipation', 'Dynamics', 'DISSIPATION_MODELS', 'INTEGRATORS',
           'Integrator', 'IntegrationError', 'create', 'get_integrator', 'Propagator', 'State',
           'poinsot']
