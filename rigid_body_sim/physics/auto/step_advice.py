"""A fixed method's error predicted before its run, with ``auto``'s error model.

``auto`` picks a method and step that meet the scene's ``accuracy`` (:mod:`.selection`);
a method named by the user runs at the scene's ``step`` whatever it costs the physics.
Explorer 1 with ``rk4`` at 0.05 s: hλ ≈ 2.5i on the nutation mode, |R| ≈ 0.5 per step,
so the nutation is damped away numerically and the body never goes flat, without a word
(the stability check only looked for |R| > 1). This module predicts such a run's error
the way ``auto`` verifies its own choice, and the step that would meet the budget:

* torque-free (with or without dissipation): ``auto``'s pilot (:func:`.pilot.error`,
  step doubling at the states :func:`.pilot.levels` picks along the dissipation's path),
  plus the round-off model of :class:`.model.RunModel`;
* with torque (a control law, commands): the pilot cannot know the torque, so, as
  ``auto`` does, the a-priori bound k·(hΩ)^p·ΩT (``RunModel.prior_error``), for the
  methods ``auto`` has constants for;
* the explicit methods' stability functions (:func:`.stability.distortion`) say whether
  the error is artificial damping or growth, for the message.

Adaptive ``dop853`` (its error is set by rtol, not the step) and ``exact`` on a free body
(no stepping error) are not predicted.
"""
import math
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from . import pilot
from ..integrators import create, get_integrator
from .model import CANDIDATES, RunModel

FAR = 10.0                  # predicted error over the budget that earns a warning
OVER_RUN = 1.01             # a mode's amplitude off by this factor over the run is named
DRIFTING = ('euler', 'rk4')  # energy and |L| drift: phase error ∝ T² (pilot's ``drift``)
MAX_PILOT_STEPS = 2_000_000  # pilot steps spent predicting at most (compiled: well < 1 s)
ROUNDS = 12                  # pilots searching the step that meets the budget
DEFAULT_HORIZON = 600.0      # s: open-ended runs (as selection.DEFAULT_HORIZON)


@dataclass(frozen=True)
class Advice:
    """The prediction for ``method`` at ``step`` (s): attitude error (rad) over
    ``horizon`` (s) against ``accuracy`` (rad); ``basis`` 'pilot' or 'a priori';
    ``meets``: the largest step (s, dividing the event spacing) predicted to meet the
    budget, None if none was found; ``damping`` / ``growth``: the stability function's
    per-step factor on the most damped / amplified mode (1: none; explicit methods)."""
    method: str
    step: float
    predicted_error: float
    accuracy: float
    horizon: float
    basis: str
    meets: Optional[float] = None
    damping: float = 1.0
    damping_z: complex = 0j
    growth: float = 1.0

    @property
    def far(self) -> bool:
        """Whether the predicted error is FAR times the budget or more."""
        return not self.predicted_error <= FAR * self.accuracy

    def message(self) -> str:
        e = self.predicted_error
        err = 'diverges' if not math.isfinite(e) else f'{e:.2g} rad' if e <= math.pi else \
            f'{e:.2g} rad (the attitude is lost)'
        text = (f'{self.method} at h = {self.step:.3g} s: predicted attitude error {err} over '
                f'{self.horizon:g} s ({self.basis}, as auto predicts), the scene\'s accuracy '
                f'is {self.accuracy:g} rad')
        steps = self.horizon / self.step
        damped = math.exp(max(-700.0, steps * math.log(max(self.damping, 1e-300))))
        grown = math.exp(min(700.0, steps * math.log(self.growth)))
        if damped < 1.0 / OVER_RUN:
            text += (f'; it damps a mode the true motion keeps (|R(hλ)| = {self.damping:.2g} '
                     f'per step at hλ ≈ {_z(self.damping_z)}, ×{damped:.2g} over the run): '
                     'too damped')
        if grown > OVER_RUN:
            text += (f'; it amplifies a mode beyond the true motion ({self.growth - 1:.2g} '
                     f'per step, ×{grown:.3g} over the run): too amplified')
        if self.meets is not None:
            text += f'; a step of {self.meets:.3g} s would meet it'
        else:
            text += '; no step found that meets it: integrator auto picks one that does'
        return text


def _z(z: complex) -> str:
    if abs(z.real) < 1e-3 * abs(z):
        return f'{abs(z.imag):.2g}i'
    return f'{z.real:.2g}{z.imag:+.2g}i'


def run_step(step: float, spacing: float) -> float:
    """The step that runs: the engine splits each interval between events (``spacing``, s)
    into equal steps no longer than ``step``."""
    return spacing / max(1, math.ceil(spacing / step - 1e-9))


def advise(method: str, dynamics, q, m, step: float, *, accuracy: float, duration: float,
           spacing: float, torque: bool = False, torque_rate: float = 0.0) -> Optional[Advice]:
    """The predicted error of ``method`` at ``step`` (s) from the principal-frame state
    (q, m) over ``duration`` (s; 0: open-ended, DEFAULT_HORIZON) against ``accuracy``
    (rad); ``spacing``: the event spacing (sample and control period), s; ``torque``:
    torques will act (rate scale ``torque_rate``, 1/s). None where it is not predicted
    (adaptive, free exact, a body at rest, a method auto has no model of under torque)."""
    cls = get_integrator(method)
    m = np.asarray(m, float)
    if getattr(cls, 'adaptive', False) or not np.any(m):
        return None
    if method == 'exact' and not (torque or dynamics.dissipation.active):
        return None
    horizon = duration if duration > 0 else DEFAULT_HORIZON
    model = RunModel(dynamics, None, m, accuracy, horizon, spacing, torque_rate)
    h = run_step(step, spacing)
    candidate = next((c for c in CANDIDATES if c.name == method), None)
    if torque:
        if candidate is None or not math.isfinite(candidate.k):
            return None
        error = model.prior_error(candidate, h)
        meets = model.prior_step(candidate)
        return _with_stability(Advice(method, h, error, accuracy, horizon, 'a priori', meets),
                               dynamics, m)
    measure = _pilot(method, dynamics, np.asarray(q, float), m, model, candidate)
    error = measure(h)
    if error is None:
        return None
    meets = h if error <= accuracy else _search(measure, h, error, accuracy, model,
                                                cls.order_on(dynamics, model.G, h))
    return _with_stability(Advice(method, h, error, accuracy, horizon, 'pilot', meets),
                           dynamics, m)


def _pilot(method, dynamics, q, m, model, candidate) -> Callable[[float], Optional[float]]:
    """error(h): auto's pilot of ``method`` at h (round-off included), None past
    MAX_PILOT_STEPS in all."""
    integ = create(method, dynamics)
    levels = pilot.levels(dynamics, q, m, model.horizon, model.omega)
    cls = type(integ)
    budget = [MAX_PILOT_STEPS]

    def error(h):
        n = sum(3 * pilot.steps_for(lv, h) for lv in levels)
        if n > budget[0]:
            return None
        budget[0] -= n
        p = cls.order_on(dynamics, model.G, h)
        worst = 0.0
        for lv in levels:
            # under dissipation every method's energy drifts (auto's pilot likewise)
            work = pilot.error(integ, p, lv, h, model.horizon,
                               method in DRIFTING or dynamics.dissipation.active)
            try:
                while True:
                    next(work)
            except StopIteration as done:
                worst = max(worst, done.value[0])
        return worst + (model.roundoff(candidate, h) if candidate is not None else 0.0)
    return error


def _search(measure, h, error, accuracy, model, order) -> Optional[float]:
    """The largest step found (dividing the spacing) whose pilot meets the budget."""
    for _ in range(ROUNDS):
        shrink = 0.9 * (accuracy / error) ** (1.0 / max(order, 1)) \
            if math.isfinite(error) and error > 0 else 0.25
        h_new = model.snap(h * min(shrink, 0.9))
        if h_new >= h:
            h_new = model.max_step / (round(model.max_step / h) + 1)
        h = h_new
        error = measure(h)
        if error is None:
            return None
        if error <= accuracy:
            return h
    return None


def _with_stability(advice: Advice, dynamics, m) -> Advice:
    from ..integrators.stability import distortion
    damping, z, growth = distortion(advice.method, dynamics, m, advice.step)
    return Advice(advice.method, advice.step, advice.predicted_error, advice.accuracy,
                  advice.horizon, advice.basis, advice.meets, damping, z, growth)
