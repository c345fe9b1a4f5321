"""The pilot of ``integrator: auto``: short runs that measure a method's error where the
a-priori estimate of :mod:`.selection` is too uncertain to set the step.

* **Error at a step h:** step doubling (Richardson): the method runs from the same state
  at h and at h/2; the attitude difference times 2^p/(2^p − 1) estimates the error of the
  run at h (p the method's effective order at h).
* **Which states:** the run's initial state and, when dissipation moves the motion within
  the run, states along its predicted path. Both dissipation models turn the momentum
  from the minor axis a towards the major axis c at constant |L|; in the (a, c) plane,
  m = G(cos β, 0, sin β), tan β grows as exp(κ t) with κ = α G²(1/I_a − 1/I_c) (double
  bracket; c_v(1/I_a − 1/I_c) viscous): exponential departure from the unstable spin,
  the growth that made a pilot at the initial state alone miss Explorer 1 by 11×.
  Each state in the plane has the energy of one polhode, so a pilot there measures that
  polhode's error rate. Levels are spaced by e in tan β from β0 to β(T).
* **Growth law:** the error at each quarter of the pilot horizon H; m1, m2 the largest in
  the first and second half. m2/m1 > 2.5 is growth faster than linear (an instability):
  the power law (T/H)^log2(m2/m1). Otherwise linear: (T/H)·m2 (phase error of a periodic
  motion, the Lie–Poisson case), or, when each half spans a polhode period (the error
  oscillates with it), its secular part: m2 + (m2 − m1)·(T − H)/(H/2). That separates a
  bounded offset from growth: exact's splitting with weak damping errs 2·10⁻⁹ rad and
  back every nutation period on Explorer 1, while its secular growth is 10⁻¹⁰ per second.
  A method whose energy and |L| drift (RK4) adds a phase error growing as T²: the pilot
  measures both drifts (coarse against fine run, per second, the largest over its parts);
  a relative error δ in T or |L| is one in the mean rate of rotation about L, 2T/|L|, so
  a drift rate r turns the attitude by (2T/|L|)·r·T²/2 by the horizon. This replaced a
  fixed T² law on the whole pilot error, which read RK4 on Explorer 1 100× too high (a
  0.4 s pilot extrapolated 1.2 rad over 30 s at h = 0.0054 s; the run erred 0.013 rad,
  growing linearly to 300 s) and kept auto off RK4 at any step a pilot could check.
  Under dissipation every method drifts so (the split damping's rate is off by O(h^p), so
  the energy error accumulates): exact on generated scene 0 (seed 20261125) erred as t²,
  9.5e-6 rad where a linear extrapolation read 8e-8; the pilot measures it for all there.
* **Horizon:** at least four rotation periods 2π/Ω and, when the pilot budget allows, one
  polhode period of each level (its error oscillates with that period), but no more than
  HORIZON_SHARE of the run: a run short against its polhode period (the stiff bench scene,
  ~19 s, over 5 s) was piloted over its whole length on every level, and the pilot cost
  5.8× the run it chose.
"""
import math
from dataclasses import dataclass

import numpy as np

from ..exact import TorqueFreeSolution
from ..integrators import IntegrationError

LEVEL_SPACING = 1.0    # in u = ln tan β: one level per factor e in tan β
# the end state of the path joins the levels once tan β grows by more than this (in u) over
# the run: a splitting's error rate grows with β, so the initial state alone under-reads it
# (Explorer 1 over 690 s: tan β × 1.9, one level, splitting4 chosen at 0.0149 s ended
# 0.026 rad off a 0.01 budget; its error grew 3.1× from half the run to the end)
END_LEVEL_FROM = 0.1
MAX_LEVELS = 6
BETA_LIMIT = 1e-3      # rad: β kept this far from the axes (tan β finite)
ROTATIONS = 4          # least pilot horizon, in rotation periods 2π/Ω
HORIZON_SHARE = 0.02   # a level's pilot horizon at most this share of the run (see levels)
MIN_STEPS = 16         # least coarse steps of a pilot run (the half-horizon check needs some)
SUPERLINEAR = 2.5      # e(H)/e(H/2) above this is growth faster than linear
YIELD_EVERY = 2048     # pilot steps per chunk (well under 1 ms compiled): a caller interleaves


@dataclass(frozen=True)
class Level:
    """A pilot state (principal frame) and the least horizon (s) that resolves its motion."""
    q: np.ndarray
    m: np.ndarray
    horizon: float
    beta_deg: float
    period: float = math.inf  # polhode period, s (inf: not computed)


def path_rate(dynamics, momentum_norm: float) -> float:
    """κ, 1/s: rate of ln tan β, β the angle of the momentum from the minor axis towards the
    major axis in the (minor, major) plane, under the scene's dissipation (0 without)."""
    d = dynamics.dissipation
    if not d.active:
        return 0.0
    spread = dynamics.inverse_moment_spread  # 1/I_min − 1/I_max
    if d.model == 'double_bracket':
        return d.coefficient * momentum_norm ** 2 * spread
    return d.coefficient * spread  # viscous: m_i ∝ exp(−c t / I_i)


def _floats(x) -> list:
    if isinstance(x, list):
        return x
    return x.tolist() if isinstance(x, np.ndarray) else [float(v) for v in x]


def _beta(moments, m):
    """β of the plane state with the energy of m (same |m|)."""
    # plain floats: asked once per selection, where numpy's per-call cost would dominate
    # (tolist, not map(float, …): that makes a numpy scalar of each element first)
    return _beta_of(_floats(moments), _floats(m))


def _beta_of(moments: list, m: list):
    """:func:`_beta` of plain floats."""
    (i0, i1, i2), (m0, m1, m2) = moments, m
    # comparisons, not min()/max(): asked in every selection under dissipation, where a
    # builtin's call costs ~20× a compare (Explorer 1 over 1 s: callgrind)
    i_a = i1 if i1 < i0 else i0
    i_a = i2 if i2 < i_a else i_a
    i_c = i1 if i1 > i0 else i0
    i_c = i2 if i2 > i_c else i_c
    G2 = m0 * m0 + m1 * m1 + m2 * m2
    if i_c - i_a <= 1e-12 * i_c or G2 == 0.0:
        return BETA_LIMIT
    two_t = m0 * m0 / i0 + m1 * m1 / i1 + m2 * m2 / i2
    s2 = (1.0 / i_a - two_t / G2) / (1.0 / i_a - 1.0 / i_c)
    s2 = 0.0 if 0.0 > s2 else s2  # clamped to [0, 1] as min(max(s2, 0.0), 1.0)
    beta = math.asin(math.sqrt(1.0 if 1.0 < s2 else s2))
    beta = BETA_LIMIT if BETA_LIMIT > beta else beta
    top = 0.5 * math.pi - BETA_LIMIT
    return top if top < beta else beta


def turning(dynamics, m0, horizon: float, momentum_norm: float = None,
            moments=None) -> float:
    """|β(T) − β(0)| (rad): how far the dissipation turns the momentum in the body over the
    run, along its path (tan β ∝ exp(κ t), :func:`path_rate`). On a symmetric body that is
    the whole of the damping's turning: there its rate is (κ/2)·sin 2β, whose integral is
    Δβ (the Gudermannian of κt). ``momentum_norm``: |m0|, and ``moments``: the dynamics'
    moments as floats, if the caller has them."""
    # lists passed through without a call (_floats): the selection's own (RunModel's)
    a, b, c = m0 = m0 if isinstance(m0, list) else _floats(m0)
    beta0 = _beta_of(_floats(dynamics.moments) if moments is None else moments, m0)
    if momentum_norm is None:
        momentum_norm = math.sqrt(a * a + b * b + c * c)
    u = math.log(math.tan(beta0)) + path_rate(dynamics, momentum_norm) * horizon
    return abs(math.atan(math.exp(700.0 if 700.0 < u else u)) - beta0)


def levels(dynamics, q0, m0, horizon: float, rate: float, periods: bool = True):
    """The pilot states for a run of ``horizon`` s from (q0, m0): the initial state, then
    plane states spaced by e in tan β up to where the dissipation takes β by the end.
    ``rate`` (rad/s) bounds |ω|; ``periods``: resolve each polhode period (costs a
    closed-form set-up per level, so short runs skip it)."""
    moments = dynamics.moments
    G = math.sqrt(sum(float(x) ** 2 for x in m0))
    rotation_time = ROTATIONS * 2 * math.pi / rate
    beta0 = _beta(moments, m0)
    u0 = math.log(math.tan(beta0))
    u_end = min(u0 + path_rate(dynamics, G) * horizon,
                math.log(math.tan(0.5 * math.pi - BETA_LIMIT)))
    count = 1 + min(MAX_LEVELS - 1, math.ceil((u_end - u0) / LEVEL_SPACING - END_LEVEL_FROM))
    states = [(np.asarray(q0, float), np.asarray(m0, float), math.degrees(beta0))]
    a, c = (int(np.argmin(moments)), int(np.argmax(moments))) if count > 1 else (0, 0)
    for k in range(1, count):
        beta = math.atan(math.exp(u0 + (u_end - u0) * k / (count - 1)))
        m = np.zeros(3)
        m[a], m[c] = G * math.cos(beta), G * math.sin(beta)
        states.append((np.array([0.0, 0.0, 0.0, 1.0]), m, math.degrees(beta)))
    period = [math.inf] * len(states)
    if periods:
        period = TorqueFreeSolution(moments, np.array([s[0] for s in states]),
                                    np.array([s[1] for s in states])).omega_period.tolist()
    cap = max(rotation_time, horizon * HORIZON_SHARE)
    return [Level(q, m, min(max(rotation_time, p if math.isfinite(p) else 0.0), cap, horizon), b,
                  float(p)) for (q, m, b), p in zip(states, period)]


def angle(a, b) -> float:
    """Rotation angle between unit quaternions a and b (rad), accurate for tiny angles:
    4·atan2(|a − b|, |a + b|) with b's sign matched to a."""
    a0, a1, a2, a3 = a.tolist()  # floats: numpy's per-call cost dominates on 4 numbers
    b0, b1, b2, b3 = b.tolist()
    if a0 * b0 + a1 * b1 + a2 * b2 + a3 * b3 < 0.0:
        b0, b1, b2, b3 = -b0, -b1, -b2, -b3
    d = (a0 - b0) ** 2 + (a1 - b1) ** 2 + (a2 - b2) ** 2 + (a3 - b3) ** 2
    p = (a0 + b0) ** 2 + (a1 + b1) ** 2 + (a2 + b2) ** 2 + (a3 + b3) ** 2
    return 4.0 * math.atan2(math.sqrt(d), math.sqrt(p))


def steps_for(level: Level, h: float) -> int:
    """Coarse steps (a multiple of 4, ≥ MIN_STEPS) a pilot of ``level`` at step h takes."""
    n = max(MIN_STEPS, int(math.ceil(level.horizon / h)))
    return n + (-n % 4)


def _advance(integ, q, m, h, n):
    """Generator: n steps of h in chunks of YIELD_EVERY; returns (q, m)."""
    done = 0
    while done < n:
        k = min(YIELD_EVERY, n - done)
        q, m = integ.run(q, m, h, k)
        done += k
        if done < n:
            yield
    return q, m


def _invariants(moments, m):
    """(2T, |L|) of momentum m (floats: numpy's per-call cost dominates on 3 numbers)."""
    a, b, c = m.tolist()
    return a * a / moments[0] + b * b / moments[1] + c * c / moments[2], \
        math.sqrt(a * a + b * b + c * c)


def error(integ, order: int, level: Level, h: float, horizon: float, drift: bool = False):
    """Generator: the attitude error of ``integ`` at step h over ``horizon`` s from
    ``level``, extrapolated from its pilot with the fitted growth law (module docstring);
    ``drift``: the method's energy and |L| drift (RK4), whose measured rates add a phase
    error growing as T². Its return value is (error, growth ratio), inf if the method
    fails."""
    n = steps_for(level, h)
    span = n * h
    periodic = span >= 2.0 * level.period  # each half spans a polhode period
    parts = 4 if periodic else 2           # quarters only where the envelope is used
    ratio = 2.0 ** order / (2.0 ** order - 1.0)
    qc, mc, qf, mf = level.q, level.m, level.q, level.m
    moments = integ.dynamics.moments.tolist() if drift else None
    errors, drift_rate, spin = [], 0.0, 0.0
    try:
        for j in range(parts):
            qc, mc = yield from _advance(integ, qc, mc, h, n // parts)
            qf, mf = yield from _advance(integ, qf, mf, 0.5 * h, 2 * n // parts)
            errors.append(angle(qc, qf) * ratio)
            if drift:  # relative energy and |L| error per second, the largest seen
                (tc, lc), (tf, lf) = _invariants(moments, mc), _invariants(moments, mf)
                spin = max(spin, tf / lf)  # 2T/|L|: the mean rate of rotation about L
                rel = ratio * (abs(tc - tf) / tf + abs(lc - lf) / lf)
                drift_rate = max(drift_rate, rel / (span * (j + 1) / parts))
            yield
    except IntegrationError:
        return math.inf, math.inf
    if not all(map(math.isfinite, errors)) or not math.isfinite(drift_rate):
        return math.inf, math.inf
    m1, m2 = max(errors[:parts // 2]), max(errors)
    growth = m2 / m1 if m1 > 0.0 else 2.0
    later = max(1.0, horizon / span)
    # a rate of rotation off by δ(t) = spin·drift_rate·t turns the attitude by that
    # integral: spin·drift_rate·T²/2 (the mean rotation rate about L is 2T/|L|, so a
    # relative error in T or |L| is one in that rate)
    drifted = 0.5 * spin * drift_rate * horizon * horizon
    if growth > SUPERLINEAR:
        return m2 * later ** math.log2(growth) + drifted, growth
    if periodic:
        return m2 + (m2 - m1) * 2.0 * (later - 1.0) + drifted, growth
    return m2 * later + drifted, growth
