"""What ``auto``'s selection (:mod:`.selection`) returns, and the choices it makes in closed
form, without a search: the free body's (``exact``), a symmetric body's split under
dissipation alone, and where no bound can promise anything (an exponential growth).

Kept apart from the search for the module's size. The reason's figures are formatted with
%, which gives format()'s text for these types (g, .2g, .3g: the same correctly rounded
conversion, checked equal on 10⁶ doubles) without a spec parsed per field: the floats'
formatting was a sixth of a short run's choosing (Explorer 1 over 1 s: ~6 of 38 µs, cold,
for five figures).
"""
import math
from typing import NamedTuple

import numpy as np

from . import pilot
from .model import is_symmetric

# what choosing costs, in the units of the run's cost model (RUN_COST, CANDIDATES), set
# from Explorer 1's median selection CPU against its median run CPU at 10–690 s (its
# Python runs between runs, with cold caches: 1.3–1.7× its cost in a tight loop)
PRIOR_BASE = 2e-5         # s: the a-priori pass before it asks a candidate (time scales)
PRIOR_EACH = 1e-5         # s: asking one candidate a priori (its step and cost)
SPLIT_K = 2.0             # × Δβ: exact's split error bound on a symmetric body (measured ≤ 1.0)
SPLIT_NOTE = f'symmetric body: E ≤ {SPLIT_K:g}·Δβ'
# the free body's reason by whether the body is symmetric: constants, not formatted per
# choice (a controlled run's first choice, before any command, is the free body's)
FREE_REASON = {symmetric: 'torque-free, no dissipation → exact solution (%s); no stepping '
               'error at any horizon' % shape for symmetric, shape in (
                   (True, 'symmetric body: closed-form free precession'),
                   (False, 'Jacobi elliptic functions + Carlson integrals'))}


class Selection(NamedTuple):
    """The chosen method and step (s), why, the predicted attitude error (rad) and run CPU
    (s), and what choosing cost: pilot steps and their predicted CPU (s), and the a-priori
    pass's predicted CPU (s). Immutable; a named tuple, not a frozen dataclass, whose ten
    fields set one by one cost a sixth of Explorer 1's whole selection."""
    name: str
    step: float
    reason: str
    predicted_error: float = 0.0
    predicted_cost: float = 0.0
    pilot_steps: int = 0
    pilot_cost: float = 0.0
    prior_cost: float = 0.0
    options: tuple = ()  # (name, value) pairs for the method: dop853's rtol and atol

    @property
    def planned_cost(self) -> float:
        """What choosing costs in the run's cost model (s): the a-priori pass and pilots."""
        return self.prior_cost + self.pilot_cost


def prior_cost(asked: int) -> float:
    """What the a-priori pass costs having asked ``asked`` candidates (s, the run's model)."""
    return PRIOR_BASE + PRIOR_EACH * asked


def checked(accuracy, max_step):
    """ValueError naming a budget or an event spacing that no choice can be made for."""
    if not (accuracy > 0 and math.isfinite(accuracy)):
        raise ValueError(f'accuracy must be a positive attitude error in rad, got {accuracy}')
    if not (max_step > 0 and math.isfinite(max_step)):
        raise ValueError(f'max_step must be positive, got {max_step}')


def free_choice(moments, m, accuracy: float, max_step: float) -> Selection:
    """The choice for a torque-free body without dissipation (``exact``), from the principal
    moments and m = I·ω alone: cheaper than building :func:`.selection.selecting`'s arguments."""
    checked(accuracy, max_step)
    if not any(m.tolist() if isinstance(m, np.ndarray) else m):  # numpy's any: 1.5 µs
        return Selection('exact', max_step, 'body at rest: exact', 0.0)
    return Selection('exact', max_step, FREE_REASON[is_symmetric(moments)], 0.0)


def symmetric_split(s, exact, why):
    """(best, asked): a method whose free flow is exact (``exact``: the usable ones,
    :func:`.kinds.split_exact`), at the event spacing, on a symmetric body under
    dissipation alone, if SPLIT_K·Δβ meets the budget (else None).

    There the damping commutes with the free flow in the body (both keep the symmetry
    axis), and the spin rate it sets evolves exactly across the split steps: what errs is
    the momentum the damping turns in inertial space, sampled at the steps. At a step that
    is a multiple of the precession period 2π·I_t/|L| every kick lands at the same phase
    and they add up; elsewhere they cancel. So the error is at most the whole turning,
    Δβ (:func:`.pilot.turning`), at any step: Explorer 1 at h = 1 s and 0.5 s (both
    multiples of its 0.5 s period) erred 0.93–1.0·Δβ over 30–690 s, at h = 0.37 s 2000×
    less. The earlier facts (no a-priori bound, 18 µs a step, hΩ ≤ 2) made it 30× dearer
    than it is and kept auto on dop853 at 2.8× its CPU there."""
    best, asked, err = None, 0, None
    for c in exact:
        asked += 1
        err = SPLIT_K * pilot.turning(s.dyn, s.m_floats, s.horizon, s.G,
                                      s.moment_floats) if err is None else err
        why.append('%s h=%.3g (%s = %.2g, the damping\'s turning, at any step)' % (
            c.name, s.max_step, SPLIT_NOTE, err))
        if err <= s.accuracy:
            best = (c, s.max_step, s.run_cost(c, s.max_step), err)
    return best, asked


def unknowable(s, c, accuracy, horizon, why):
    """The adaptive candidate c at its tightest rtol, where the motion makes the error grow
    exponentially (``why``: a periodic forcing at least as fast as the body's own rate,
    ``forced``; an unstable equilibrium, ``orbit_state``), beyond any a-priori bound or
    pilot: no promise (``predicted_error`` inf), the most accurate choice."""
    rtol, cost, err = s.tightest(c)
    reason = (f'{why}: its error can grow exponentially, so no a-priori bound or pilot can '
              f'promise {accuracy:g} rad over {horizon:g} s; the most accurate: {c.name} at '
              f'rtol {rtol:.0e} (E≤{err:.2g} were the growth not exponential: not a promise)')
    return Selection(c.name, s.max_step, reason, math.inf, cost, prior_cost=prior_cost(1),
                     options=options(c, {c.name: rtol}, s.G))


def options(c, tolerances, momentum):
    """The chosen method's options: an adaptive one's rtol, and an atol that many times
    smaller on the state (q of norm 1, m of norm |L|)."""
    if not c.adaptive:
        return ()
    rtol = tolerances[c.name]
    return (('rtol', rtol), ('atol', rtol * 1e-3 * min(1.0, momentum)))
