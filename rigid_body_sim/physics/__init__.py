"""Rigid-body rotation physics, free of ROS: numpy and scipy only.

* :mod:`.body` — inertia validation, principal moments and axes.
* :mod:`.dynamics` — Euler's equations, torques and dissipation (principal frame).
* :mod:`.integrators` — the registry of methods with one interface.
* :mod:`.exact` — the torque-free solution in closed form (Jacobi elliptic functions);
  :mod:`.exact_kernel` its compiled evaluation (:mod:`.elliptic_kernel`,
  :mod:`.double_double`), :mod:`.exact_build` and :mod:`.exact_constants` its compiled
  set-up, :mod:`.exact_numpy` the vectorised numpy path (long double, :mod:`.extended`).
* :mod:`.propagator` — propagation in the user's body frame.
"""
from .body import RigidBody
from .dynamics import DISSIPATION_MODELS, Dissipation, Dynamics
from .integrators import INTEGRATORS, IntegrationError, Integrator, create, get_integrator
from .propagator import Propagator, State, poinsot

__all__ = ['RigidBody', 'Dissipation', 'Dynamics', 'DISSIPATION_MODELS', 'INTEGRATORS',
           'Integrator', 'IntegrationError', 'create', 'get_integrator', 'Propagator', 'State',
           'poinsot']
