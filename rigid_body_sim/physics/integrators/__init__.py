"""The integrator registry: every method by name, all with the interface of ``Integrator``.

Adding a method: write its module (a subclass of Integrator that states its facts: orders,
stages, stability function, closed-loop code, auto's costs, its compiled loops' modules),
beside its compiled loop (``<method>_kernel.py``), and add it to ``_METHODS``. ``auto``,
the warm-up, the stability check and the engine's closed loop read the facts from here.
Its name goes in ``physics/choices.py`` too (parsing and --help read it there, without numba).
"""
from dataclasses import replace

from ..choices import BODY_ONLY, CARRY_ACTUATORS, INTEGRATOR_NAMES
from .base import KINDS, PRESERVES, Candidate, IntegrationError, Integrator
from .explicit import Euler, RK4
from .exact_flow import Exact
from .implicit import ImplicitMidpoint
from .dop853 import DOP853
from .gyrostat import GyrostatStrang
from .lstable import Splitting2LStable
from .splitting import Splitting2, Splitting4, Splitting6

# auto asks its candidates in this order where their costs tie
_METHODS = (Splitting2, Splitting4, Splitting6, RK4, ImplicitMidpoint, Splitting2LStable, Exact,
            DOP853, Euler, GyrostatStrang)

INTEGRATORS = {cls.name: cls for cls in _METHODS}

# auto's candidates: every registered method that states its facts (``Integrator.auto``),
# in the registry's order (auto breaks ties of cost in it)
AUTO_CANDIDATES = tuple(replace(cls.auto, name=cls.name, stages=cls.stages,
                                environment=cls.environment,
                                environment_evals=cls.environment_evaluations)
                        for cls in _METHODS if cls.auto is not None)

# The names live in ..choices, which parsing and --help import without numba; a method
# added here and not there (or the other way round) stops every import of the registry.
if (tuple(INTEGRATORS) != INTEGRATOR_NAMES or CARRY_ACTUATORS != tuple(
        name for name, cls in INTEGRATORS.items() if cls.requires_actuators)):
    raise ImportError('physics/choices.py names other integrators than the registry: '
                      f'{INTEGRATOR_NAMES} (carrying {CARRY_ACTUATORS}) there, '
                      f'{tuple(INTEGRATORS)} here')


def get_integrator(name: str):
    """The integrator class registered under ``name``; ValueError listing the choices."""
    try:
        return INTEGRATORS[name]
    except KeyError:
        raise ValueError(f'unknown integrator {name!r}; '
                         f'registered: {", ".join(INTEGRATORS)}') from None


def create(name: str, dynamics, **options) -> Integrator:
    """An instance of integrator ``name`` for ``dynamics``."""
    return get_integrator(name)(dynamics, **options)


__all__ = ['AUTO_CANDIDATES', 'BODY_ONLY', 'INTEGRATORS', 'Candidate', 'Integrator',
           'IntegrationError', 'KINDS', 'PRESERVES', 'create', 'get_integrator']
