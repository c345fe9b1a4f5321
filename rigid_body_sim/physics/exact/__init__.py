"""The torque-free solution in closed form (Jacobi elliptic functions).

* :mod:`.solution` — :class:`TorqueFreeSolution`, its public face, and ``warm``.
* :mod:`.kernel` — its compiled evaluation (:mod:`.elliptic_kernel`, :mod:`.double_double`);
  :mod:`.build` and :mod:`.constants` its compiled set-up; :mod:`.grid_kernel` the same on
  an equally spaced grid of times (the engine's samples), by addition theorems.
* :mod:`.numpy_path` — the vectorised numpy path in long double (:mod:`.extended`), the
  tests' second opinion.
"""
from .build import MOMENT_RTOL, SEPARATRIX_RTOL, STEADY_RTOL
from .solution import TorqueFreeSolution, warm

__all__ = ['TorqueFreeSolution', 'warm', 'MOMENT_RTOL', 'SEPARATRIX_RTOL', 'STEADY_RTOL']
