"""The integrator registry: every method by name, all with the interface of ``Integrator``.

Adding a method: write its module (a subclass of Integrator) and add it to ``_METHODS``.
"""
from .base import PRESERVES, IntegrationError, Integrator
from .explicit import Euler, RK4
from .exact_flow import Exact
from .implicit import ImplicitMidpoint
from .dop853 import DOP853
from .lstable import Splitting2LStable
from .splitting import Splitting2, Splitting4, Splitting6

_METHODS = (Euler, RK4, DOP853, ImplicitMidpoint, Splitting2, Splitting4, Splitting6, Exact,
            Splitting2LStable)

INTEGRATORS = {cls.name: cls for cls in _METHODS}


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


__all__ = ['INTEGRATORS', 'Integrator', 'IntegrationError', 'PRESERVES', 'create',
           'get_integrator']
