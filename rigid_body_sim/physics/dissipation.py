"""The dissipation model of a scene, chosen by name, free of numba (a scene's checks build
it; the dynamics, which re-export it, apply it in the compiled loops)."""
from dataclasses import dataclass

import numpy as np

from .choices import DISSIPATION_MODELS


@dataclass(frozen=True)
class Dissipation:
    """A dissipation model chosen by name.

    * ``double_bracket`` — internal damping dm/dt ⊃ α m×(m×Ω), α in s/(kg·m²). Keeps |m|
      exactly, T falls monotonically (dT/dt = −α|m×Ω|²), spin goes to the major axis.
    * ``viscous`` — external torque τ = −c ω, c in N·m·s; both T and |m| decay.
    * ``none``.
    """
    model: str = 'none'
    coefficient: float = 0.0

    def __post_init__(self):
        if self.model not in DISSIPATION_MODELS:
            raise ValueError(f'unknown dissipation model {self.model!r}; '
                             f'choose one of {DISSIPATION_MODELS}')
        c = float(self.coefficient)
        if not np.isfinite(c):
            raise ValueError(f'dissipation coefficient is not finite: {self.coefficient}')
        if c < 0.0:
            raise ValueError(f'dissipation coefficient must be >= 0 (got {c}); '
                             'a negative value would pump energy in')
        object.__setattr__(self, 'coefficient', c)

    @property
    def active(self) -> bool:
        return self.model != 'none' and self.coefficient > 0.0
