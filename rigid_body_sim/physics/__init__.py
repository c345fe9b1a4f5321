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
from ..lazy_exports import lazy_exports

# The names below are imported on first use (module ``__getattr__``): a module that needs
# only ``rotation`` or ``body`` (the engine's specs and samples, a scene's checks) then does
# not load the integrators' kernels and numba, which --help and a refused input never run.
_HOME = {'RigidBody': 'body', 'Dissipation': 'dissipation', 'Dynamics': 'dynamics',
         'DISSIPATION_MODELS': 'choices', 'INTEGRATORS': 'integrators',
         'Integrator': 'integrators', 'IntegrationError': 'integration_error',
         'create': 'integrators', 'get_integrator': 'integrators', 'Propagator': 'propagator',
         'State': 'propagator', 'poinsot': 'propagator'}

__all__ = list(_HOME)


__getattr__, __dir__ = lazy_exports(__name__, globals(), _HOME)
