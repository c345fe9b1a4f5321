"""Explicit methods against their linear stability, checked before a run (not after).

An explicit Runge–Kutta step multiplies each mode with eigenvalue λ of the linearised
dynamics by its stability function R(hλ) (Euler: 1 + z; RK4: 1 + z + z²/2 + z³/6 +
z⁴/24), where the exact flow multiplies it by e^{hλ}. Spurious growth per step is
|R(hλ)| for a mode that does not grow (Re λ ≤ 0; damping one more slowly than the truth
is an accuracy matter, not instability) and |R(hλ)| / e^{h Re λ} for a physically
growing one (the intermediate axis: R(hλ) ≤ e^{hλ} there, no numerical instability).
On the imaginary axis (rotation: the body-frame precession of m, and ±i|ω|/2 of the
attitude quaternion) it exceeds 1 for Euler at any h (√(1 + (h|λ|)²)) and for RK4
beyond h|λ| = 2√2; on the negative real axis (dissipation), beyond 2 (Euler) and 2.785
(RK4).

The eigenvalues come from the momentum equation's Jacobian (with dissipation) at states
along the torque-free motion through the initial state, one rotation period of ω.
Other methods (the splittings, implicit midpoint, exact, dop853) have no such limit.
"""
import math
from typing import Optional, Tuple

import numpy as np

from . import INTEGRATORS

# each method's own stability function (``Integrator.amplification``), where it has one
STABILITY_FUNCTIONS = {name: cls.amplification for name, cls in INTEGRATORS.items()
                       if cls.amplification is not None}
WARN_GROWTH = 1.01   # spurious growth over the run that earns a warning
REFUSE_PER_STEP = 2.0  # spurious growth per step: far outside the stability region
SAMPLES = 32


def _eigenvalues(dynamics, m) -> np.ndarray:
    """Eigenvalues (1/s) of d(ṁ)/dm at m (central differences) and ±i|ω|/2 of q."""
    h = 1e-7 * max(1.0, float(np.linalg.norm(m)))
    jac = np.empty((3, 3))
    for j in range(3):
        e = np.zeros(3)
        e[j] = h
        jac[:, j] = (dynamics.momentum_rate(m + e) - dynamics.momentum_rate(m - e)) / (2 * h)
    half_rate = 0.5 * float(np.linalg.norm(m / dynamics.moments))
    return np.concatenate((np.linalg.eigvals(jac), [1j * half_rate]))


def _states(dynamics, m0) -> np.ndarray:
    """Momenta along the torque-free motion through m0 over one ω period."""
    from ..exact import TorqueFreeSolution
    try:
        solution = TorqueFreeSolution(dynamics.moments, np.array([0.0, 0.0, 0.0, 1.0]), m0)
        period = float(np.ravel(solution.omega_period)[0])
        if not (math.isfinite(period) and period > 0):
            return np.asarray(m0, float)[None, :]
        _, m = solution.at(np.linspace(0.0, period, SAMPLES, endpoint=False))
        return np.asarray(m, float).reshape(-1, 3)
    except (ValueError, ArithmeticError):
        return np.asarray(m0, float)[None, :]


def spurious_growth(method: str, dynamics, m0, h: float) -> np.ndarray:
    """Per sampled state: the largest growth per step that the true motion does not have:
    |R(hλ)| for a mode that does not grow (Re λ ≤ 0; a decaying mode damped more slowly
    than the truth is an accuracy matter, not instability), |R(hλ)| / e^{h Re λ} for a
    physically growing one."""
    R = STABILITY_FUNCTIONS[method]
    out = []
    for m in _states(dynamics, np.asarray(m0, float)):
        z = h * _eigenvalues(dynamics, m)
        growth = np.abs(R(z)) / np.exp(np.clip(z.real, 0.0, 700.0))
        out.append(float(np.max(growth)))
    return np.array(out)


def largest_stable_step(method: str, dynamics, m0, h: float) -> float:
    """The largest step ≤ h without spurious growth per step (bisection); 0 for none."""
    if np.max(spurious_growth(method, dynamics, m0, h)) <= 1.0 + 1e-12:
        return h
    lo, hi = 0.0, h
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if np.max(spurious_growth(method, dynamics, m0, mid)) <= 1.0 + 1e-12:
            lo = mid
        else:
            hi = mid
    return lo


def check_step(method: str, dynamics, momentum, h: float,
               duration: float) -> Tuple[str, Optional[str]]:
    """('ok' | 'warn' | 'refuse', message) for ``method`` at step ``h`` (s) over
    ``duration`` (s) from body momentum ``momentum`` (principal frame, kg·m²/s)."""
    if method not in STABILITY_FUNCTIONS or not np.any(momentum):
        return 'ok', None
    growth = spurious_growth(method, dynamics, momentum, h)
    steps = max(1.0, duration / h) if duration > 0 else 1.0
    over_run = math.exp(min(700.0, steps * float(np.mean(np.log(growth)))))
    if over_run <= WARN_GROWTH:
        return 'ok', None
    limit = largest_stable_step(method, dynamics, momentum, h)
    where = (f'the largest stable step here is {limit:.3g} s' if limit > 1e-3 * h else
             f'{method} is unstable for free rotation at any step')
    text = (f'{method} at h = {h:.3g} s amplifies errors beyond the true motion by up to '
            f'{(np.max(growth) - 1) * 100:.2g} % per step, about {over_run:.3g}x over '
            f'{duration:g} s '
            f'({where}); use splitting2 (no step limit for free rotation) or a smaller --step')
    return ('refuse' if np.max(growth) >= REFUSE_PER_STEP else 'warn'), text


def distortion(method: str, dynamics, m0, h: float):
    """(damping, z, growth) of ``method`` at step h along the motion through m0: damping is
    the least |R(hλ)| / e^{h Re λ} over the modes and states (< 1: a mode damped faster
    than the true motion damps it; Explorer 1 with RK4 at 0.05 s: 0.5 per step on the
    nutation mode, which the truth keeps), z = hλ of that mode, growth the largest
    spurious_growth. (1, 0, 1) for a method without a stability function here."""
    if method not in STABILITY_FUNCTIONS or not np.any(m0):
        return 1.0, 0j, 1.0
    R = STABILITY_FUNCTIONS[method]
    damping, where = 1.0, 0j
    for m in _states(dynamics, np.asarray(m0, float)):
        z = h * _eigenvalues(dynamics, m)
        ratio = np.abs(R(z)) / np.exp(np.clip(z.real, -700.0, 700.0))
        k = int(np.argmin(ratio))
        if ratio[k] < damping:
            damping, where = float(ratio[k]), complex(z[k])
    return damping, where, float(np.max(spurious_growth(method, dynamics, m0, h)))
