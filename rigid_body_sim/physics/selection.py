"""Model selection for ``integrator: auto``: the cheapest method that meets the budget.

* Torque-free, no dissipation → ``exact``: no stepping error at any horizon (a symmetric
  body uses its closed-form free precession inside the same solver).
* Otherwise each candidate splitting (and, when dissipation is stiff at the pilot step,
  the A-stable implicit midpoint) is run
  on a short pilot horizon at h and h/2 (step doubling): Richardson's estimate of the
  attitude error, grown linearly to the scene's horizon (phase error accumulates in
  proportion to time), gives the largest step h* ≤ max_step with error ≤ accuracy for
  a method of order p: starting at max_step, h ← 0.9·h·(accuracy / E(h))^(1/p) until the
  prediction meets the budget (at most 3 rounds). The pilot also measures CPU
  seconds per step (this thread's CPU time, so a node running it in a worker thread
  is not charged for its own publishing), and the choice minimises cost per simulated second.
* Commanded torque is unknown in advance; the pilot uses the free (dissipative) motion,
  and the torque kick of every splitting is exact, so that error is what the step sets.
"""
import time
from dataclasses import dataclass

import numpy as np

from . import rotation
from .body import RigidBody
from .dynamics import Dissipation, Dynamics
from .integrators import IntegrationError, create

CANDIDATES = ('splitting2_lstable', 'splitting2', 'splitting4', 'splitting6', 'implicit_midpoint')
DEFAULT_HORIZON = 600.0  # s: the budget horizon for open-ended (duration 0) runs


@dataclass(frozen=True)
class Selection:
    """The chosen method, its step (s), why, and the predicted attitude error (rad)."""
    name: str
    step: float
    reason: str
    predicted_error: float = 0.0


def _is_symmetric(moments, rtol=1e-12):
    a, b, c = np.sort(moments)
    return abs(b - a) <= rtol * c or abs(c - b) <= rtol * c


YIELD_EVERY = 512  # pilot steps per chunk (< 1 ms compiled): a caller can interleave work


def _pilot(name, dyn, q, m, h, horizon):
    """Generator: attitude at ``horizon`` with step h and CPU seconds per step (its return
    value); None if the method fails. Runs the method's own loop (``Integrator.run``, the
    compiled kernel where there is one) in chunks of YIELD_EVERY steps, yielding between."""
    integ = create(name, dyn)
    n = max(1, int(round(horizon / h)))
    h = horizon / n
    spent = 0.0
    try:
        for k in range(0, n, YIELD_EVERY):
            t0 = time.thread_time()
            q, m = integ.run(q, m, h, min(YIELD_EVERY, n - k), None, k * h)
            spent += time.thread_time() - t0
            yield
    except IntegrationError:
        return None
    return q, spent / n


def _largest_step(name, dyn, q, m, accuracy, horizon, pilot, h_max):  # generator
    """(h, CPU s per step, predicted error) — the largest h ≤ h_max meeting ``accuracy``, or None.

    Starts at h_max and refines (≤ 3 rounds, 10 % margin) only while the error predicted
    for the horizon exceeds the budget: starting small would measure round-off, not the
    truncation error, and choose needlessly small steps.
    """
    probe = create(name, dyn)
    h = h_max
    for _ in range(3):
        order = probe.effective_order(m, h)
        coarse = yield from _pilot(name, dyn, q, m, h, pilot)
        fine = yield from _pilot(name, dyn, q, m, h / 2, pilot)
        if coarse is None or fine is None:
            return None
        err = rotation.angle_between(coarse[0], fine[0]) * 2 ** order / (2 ** order - 1)
        predicted = err * horizon / pilot
        if predicted <= accuracy:
            return h, coarse[1], float(predicted)
        h *= 0.9 * (accuracy / predicted) ** (1.0 / order)
    shrink = 0.9 * (accuracy / predicted) ** (1.0 / order)
    return h, coarse[1], float(predicted * shrink ** order)


def select(body: RigidBody, dissipation: Dissipation, attitude, angular_velocity, *, torque: bool,
           accuracy: float, duration: float, max_step: float) -> Selection:
    """Pick integrator and step for a scene (see module docstring and :func:`selecting`)."""
    work = selecting(body, dissipation, attitude, angular_velocity, torque=torque,
                     accuracy=accuracy, duration=duration, max_step=max_step)
    while True:
        try:
            next(work)
        except StopIteration as done:
            return done.value


def selecting(body: RigidBody, dissipation: Dissipation, attitude, angular_velocity, *,
              torque: bool, accuracy: float, duration: float, max_step: float):
    """Generator form of :func:`select`: yields often (every few ms of pilot work) so that a
    caller can interleave the selection with its own work; its return value is the Selection.

    Args:
        body, dissipation: the model.
        attitude, angular_velocity: initial state (body→inertial quaternion; ω body frame).
        torque: whether commanded torques will act.
        accuracy: attitude-error budget in rad over ``duration``.
        duration: horizon in s (0 = open-ended: budget per DEFAULT_HORIZON s).
        max_step: largest admissible step in s (command and output period).
    """
    if not (accuracy > 0 and np.isfinite(accuracy)):
        raise ValueError(f'accuracy must be a positive attitude error in rad, got {accuracy}')
    if not (max_step > 0 and np.isfinite(max_step)):
        raise ValueError(f'max_step must be positive, got {max_step}')
    moments = body.principal_moments
    if not torque and not dissipation.active:
        shape = 'symmetric body: closed-form free precession' if _is_symmetric(moments) else \
            'Jacobi elliptic functions + Carlson integrals'
        return Selection('exact', max_step, 'torque-free, no dissipation → exact solution '
                         f'({shape}); '
                         'no stepping error at any horizon', 0.0)

    dyn = Dynamics(moments, dissipation)
    q = body.attitude_to_principal(rotation.validated(attitude))
    m = moments * body.to_principal(angular_velocity)
    horizon = duration if duration > 0 else DEFAULT_HORIZON
    rate = np.max(np.abs(m / moments))
    if rate == 0.0:
        return Selection('splitting2', max_step, 'body at rest: any step is exact for the free '
                         'part; '
                         'splitting2 is the cheapest structure-preserving method', 0.0)
    period = 2 * np.pi / rate
    pilot = min(horizon, 2 * period)  # two rotation periods (or the whole run if shorter)
    stiffness = dyn.dissipation_stiffness(np.linalg.norm(m))
    why = []
    best = None
    for name in CANDIDATES:
        if name in ('implicit_midpoint', 'splitting2_lstable') and \
                stiffness * min(max_step, pilot / 8) < 1.0:
            continue  # A-stability only pays off when dissipation is stiff at the step we need
        if best is not None and best[1] >= max_step and name != 'implicit_midpoint':
            break  # a higher order cannot take a larger step and costs more per step
        found = yield from _largest_step(name, dyn, q, m, accuracy, horizon, pilot,
                                         min(max_step, pilot / 8))
        if found is None:
            why.append(f'{name}: failed in the pilot')
            continue
        h, cpu_per_step, predicted = found
        cost = cpu_per_step / h  # CPU s per simulated s
        why.append(f'{name}: h={h:.3g} s, {cost:.3g} CPU s per sim s')
        if best is None or cost < best[2]:
            best = (name, h, cost, predicted)
    if best is None:
        raise ValueError('no candidate integrator survived the pilot run: ' + '; '.join(why))
    name, h, _, predicted = best
    h = float(h)
    effects = [e for e, on in (('commanded torque', torque), (f'{dissipation.model} dissipation',
                                                                dissipation.active)) if on]
    stiff = f', dissipation stiffness h·λ = {h * stiffness:.2g}' if stiffness else ''
    reason = (f'{" + ".join(effects)} → cheapest method meeting {accuracy:g} rad over '
              f'{horizon:g} s '
              f'(step doubling on a {pilot:.3g} s pilot{stiff}): ' + '; '.join(why))
    return Selection(name, h, reason, float(predicted))
