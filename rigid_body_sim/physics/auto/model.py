"""The a-priori model behind ``integrator: auto`` (:mod:`.selection`): the candidate
methods with their measured costs and error constants, and :class:`RunModel`, the time
scales of a run and what each candidate would cost and err on it.

Kept apart from the search (selection.py, the pilot's best-first loop) so that a new
method is one ``Candidate`` line here and nothing there.
"""
import math
from dataclasses import dataclass
from typing import Tuple

import numpy as np

from ..integrators import create, get_integrator

@dataclass(frozen=True)
class Candidate:
    """A method auto may choose.

    cost: CPU µs per step (compiled loops; only ratios matter), free and with weak
        dissipation (inside the compositions); stiff double-bracket damping outside a
        composition adds DAMP_SUBSTEP per substep. Measured on a 2-core AMD EPYC by
        ``python -m rigid_body_sim.bench.candidate_costs``, which flags a ratio gone stale
        (the earlier table, from slower loops, had RK4 at 6× and the damped compositions at
        2.5× their cost, and steered auto off them).
    k: a-priori error constant, the largest of E/((hΩ)^p·ΩT) over 80 random bodies and
        states (near-symmetric bodies and near-axis spins included), 30 turns, hΩ ≤ 0.1;
        inf: the method is chosen only after a pilot.
    growth: 'linear' or 'drift' (energy drift: phase error ∝ T²).
    stability: largest h·max(Ω, stiffness) (explicit methods).
    stiff_only: considered only where dissipation is stiff at the step (A-stable methods).
    exact_damping: the double bracket's sub-flow in closed form: considered with that
        damping, in torque-free runs at any stiffness (the same splitting as splitting2, its
        damping exact at a lower cost than splitting2's substeps; Explorer 1 over 30 s at
        h = 0.0119 s: the same error, 0.92 against 1.17 ms) and with torque only where it
        is stiff (the engine's compiled closed loop damps by substeps, so it runs event by
        event there).
    supersedes: a candidate not asked where this one is usable without torque (the same
        scheme at no lower cost: asking both would only double the pilot).
    coupled_only: considered only with torque or dissipation (``exact`` splits them off).
    adaptive: the step follows a tolerance (dop853): not stepped at h, not piloted; its rtol,
        cost and error come from :meth:`RunModel.tolerance`, and ``k`` bounds its error
        per rtol and radian turned (see DOP853_*).
    geometric: Lie–Poisson (|L| exact, bounded energy error). Only these can err far less
        than ``k`` says (a spin near a principal axis is an exact axis rotation for them),
        so only they are piloted from hΩ = 2; and within PREFER of the cheapest they win.
    stages: round-off weight: the attitude error from rounding is ROUNDOFF·stages·N·ΩT
        after N steps (a rotation by the same angle every step rounds alike every step,
        so |L| drifts and the phase error grows with N·T; measured on Explorer 1: 1e-6 rad
        after 3·10⁵ steps of splitting6 over 300 s, ~5·10⁻⁸ after 5·10⁴ over 100 s).
        ``exact`` evaluates a closed form at each step: no repeated rotation, 0.
    call: µs per engine interval around the compiled loop (the compositions check the
        damping's stiffness in Python on every call).
    """
    name: str
    cost: Tuple[float, float]
    k: float
    stages: float
    call: Tuple[float, float] = (2.5, 2.5)
    growth: str = 'linear'
    stability: float = math.inf
    stiff_only: bool = False
    exact_damping: bool = False
    supersedes: str = ''
    coupled_only: bool = False
    geometric: bool = True
    adaptive: bool = False


CANDIDATES = (
    Candidate('splitting2', (0.092, 0.23), 0.30, 1),
    Candidate('splitting4', (0.24, 0.83), 0.07, 3, call=(2.5, 11.0)),
    Candidate('splitting6', (0.52, 1.96), 1.2e-3, 7, call=(2.5, 11.0)),
    Candidate('rk4', (0.047, 0.056), 1.2e-3, 4, growth='drift', stability=2.5,
              geometric=False),
    Candidate('implicit_midpoint', (0.12, 0.17), 0.025, 1, stiff_only=True, geometric=False),
    # L-stable: the double bracket's sub-flow in closed form, the same cost at any hλ
    Candidate('splitting2_lstable', (0.092, 0.16), 0.30, 1, exact_damping=True,
              supersedes='splitting2'),
    # with dissipation or torque each step builds a closed form from its state (~18 µs)
    # exact keeps hΩ ≤ 2 like the others, though it rotates exactly: at steps that are
    # multiples of the rotation period its splitting error aliases (Explorer 1 spins at
    # 10 rev/s; exact at h = 1 s and 0.5 s agree to 1e-6 and are 0.02 rad off after 690 s),
    # which step doubling cannot see
    Candidate('exact', (18.0, 18.0), math.inf, 0.0, coupled_only=True),
    # cost: µs per step (12 evaluations); k: see DOP853_*
    Candidate('dop853', (1.2, 1.3), 2.0, 0.0, call=(3.0, 3.0), growth='drift', adaptive=True,
              coupled_only=True, geometric=False),
)
# dop853's a-priori model, from 60 runs on 20 generated dissipative scenes (seed 7,
# ``bench.generated``; 150–2·10⁴ rad turned, rtol 1e-5–1e-9): its attitude error was
# E/(rtol·ΩT) ≤ 60, median 0.09, growing with ΩT beyond a few hundred rad (energy drift):
# E ≤ k·rtol·ΩT·max(1, ΩT/DOP853_DRIFT) held on all with k = 2. An rtol 10× too tight costs
# only 10^(1/8) = 1.33× the steps, so the bound errs toward accuracy at little cost.
# Steps: 0.027–0.14 (median 0.08) × ΩT·rtol^(-1/8); explicit, so at least stiffness·T/6.
DOP853_DRIFT = 300.0      # rad turned from which the error grows as (ΩT)²
DOP853_STEPS = 0.1        # steps per rad turned at rtol 1
DOP853_STABLE = 6.0       # its real-axis stability limit, roughly (h·stiffness)
RTOL_RANGE = (1e-13, 1e-3)
ROUNDOFF = 2.5e-17        # rad per stage, step and radian turned (see Candidate.stages)
DAMP_SUBSTEP = 0.068      # µs per double-bracket substep outside a composition
RUN_COST = 3e-4           # s: building and finishing a run (engine, first and last sample)
EVENT_COST = 1.5e-5       # s per event interval (a sample or control instant from Python)
DRIFT_TURNS = 30          # the calibration horizon of ``k``, in turns (growth 'drift')
H_OMEGA_PRIOR = 1.0       # a-priori steps keep hΩ ≤ 1 (the asymptotic regime of k)
H_OMEGA_PLAUSIBLE = 2.0   # the largest step a pilot starts from
SPREAD = 30.0             # non-geometric methods err at least k/SPREAD (calibration: k/4 median)


def is_symmetric(moments, rtol=1e-12):
    a, b, c = np.sort(moments)
    return abs(b - a) <= rtol * c or abs(c - b) <= rtol * c


class RunModel:
    """The time scales of a run, and the cost and a-priori error of a method on it."""

    def __init__(self, dyn, q, m, accuracy, horizon, max_step, torque_rate):
        self.dyn, self.q, self.m = dyn, q, m
        self.accuracy, self.horizon, self.max_step = accuracy, horizon, max_step
        self.G = math.sqrt(sum(x * x for x in m.tolist()))  # floats: numpy's per-call cost
        self.stiffness = dyn.dissipation_stiffness(self.G)
        spin = self.G / min(dyn.moments.tolist())
        self.omega = spin + torque_rate + self.stiffness
        self.events = max(1, math.ceil(horizon / max_step - 1e-9))
        self.turned = spin * horizon  # rad, for the round-off
        d = dyn.dissipation
        self.damping = d.model if d.active else None
        self.integrators = {}
        self.memo = {}  # costs and steps per (method, step): asked for many times
        self.orders = {}  # effective order per (method, step)

    def integrator(self, c):
        if c.name not in self.integrators:
            self.integrators[c.name] = create(c.name, self.dyn)
        return self.integrators[c.name]

    def order(self, c, h):
        """The effective order of c at h (``Integrator.order_on``: no instance needed)."""
        key = (c.name, h)
        p = self.orders.get(key)
        if p is None:
            p = self.orders[key] = get_integrator(c.name).order_on(self.dyn, self.G, h)
        return p

    def snap(self, h):
        """The largest step ≤ h that divides the event spacing."""
        return self.max_step / max(1, math.ceil(self.max_step / h - 1e-9))

    def step_cost(self, c, h):
        """CPU s per step of c at h."""
        key = ('cost', c.name, h)
        if key not in self.memo:
            self.memo[key] = self._step_cost(c, h)
        return self.memo[key]

    def _step_cost(self, c, h):
        if self.damping is None:
            return c.cost[0] * 1e-6
        if not c.name.startswith('splitting') or c.name == 'splitting2_lstable':
            return c.cost[1] * 1e-6
        composed = c.name != 'splitting2'
        if composed and self.order(c, h) > 2:  # the damping goes inside the composition
            return c.cost[1] * 1e-6
        if self.damping == 'viscous':
            return c.cost[0] * 1.3e-6
        substeps = max(1, math.ceil(self.stiffness * h))  # two half-steps of ≤ 0.5 each
        return (c.cost[0] + 2 * DAMP_SUBSTEP * substeps) * 1e-6

    def run_cost(self, c, h):
        steps = self.events * round(self.max_step / h)
        call = c.call[0 if self.damping is None else 1] * 1e-6
        return RUN_COST + self.events * (EVENT_COST + call) + steps * self.step_cost(c, h)

    def least_cost(self, c):
        """A lower bound of c's run cost, at no call to the models: the fewest steps (at
        its largest step) at its least cost per step (auto orders candidates by it)."""
        h = min(H_OMEGA_PRIOR / self.omega, c.stability / max(self.omega, self.stiffness),
                self.max_step)
        call = c.call[0 if self.damping is None else 1] * 1e-6
        return (RUN_COST + self.events * (EVENT_COST + call)
                + self.horizon / h * min(c.cost) * 1e-6)

    def tolerance(self, c):
        """(rtol, run cost s, a-priori error rad) of an adaptive candidate: the loosest rtol
        in RTOL_RANGE whose bound meets the budget (the tightest if none does)."""
        turned = self.omega * self.horizon
        scale = c.k * turned * max(1.0, turned / DOP853_DRIFT)
        rtol = RTOL_RANGE[1]
        for _ in range(2):  # the round-off depends on the steps, weakly on rtol
            steps = max(DOP853_STEPS * turned * rtol ** -0.125,
                        self.stiffness * self.horizon / DOP853_STABLE, 1.0)
            room = self.accuracy - ROUNDOFF * steps * turned
            rtol = min(max(room / scale, RTOL_RANGE[0]), RTOL_RANGE[1])
        call = c.call[0 if self.damping is None else 1] * 1e-6
        per_step = c.cost[0 if self.damping is None else 1] * 1e-6
        cost = RUN_COST + self.events * (EVENT_COST + call) + steps * per_step
        return rtol, cost, scale * rtol + ROUNDOFF * steps * turned

    def roundoff(self, c, h):
        """Attitude error (rad) from rounding over the run at step h."""
        return ROUNDOFF * c.stages * self.events * round(self.max_step / h) * self.turned

    def cap(self, c, plausible=False):
        """The largest step worth considering for c (``plausible``: where a pilot starts)."""
        key = ('cap', c.name, plausible)
        if key not in self.memo:
            self.memo[key] = self._cap(c, plausible)
        return self.memo[key]

    def _cap(self, c, plausible):
        h = (H_OMEGA_PLAUSIBLE if plausible and c.geometric else H_OMEGA_PRIOR) / self.omega
        h = min(h, c.stability / max(self.omega, self.stiffness))
        if plausible and not c.geometric and math.isfinite(c.k):
            # no exact axis rotations: the error is within SPREAD of the bound k
            prior = self.prior_step(c)
            if prior is not None:
                h = min(h, prior * SPREAD ** (1.0 / self.order(c, prior)))
        return self.snap(min(self.max_step, h))

    def growth(self, c):
        if c.growth == 'drift':
            return max(1.0, self.omega * self.horizon / (2 * math.pi * DRIFT_TURNS))
        return 1.0

    def prior_error(self, c, h):
        """A-priori error bound at h: truncation (module docstring) plus round-off."""
        return self._truncation(c, h, self.order(c, h)) + self.roundoff(c, h)

    def _truncation(self, c, h, p):
        return c.k * (h * self.omega) ** p * self.omega * self.horizon * self.growth(c)

    def prior_step(self, c):
        """The a-priori step of c (the largest meeting the budget), or None."""
        key = ('prior', c.name)
        if key not in self.memo:
            self.memo[key] = self._prior_step(c)
        return self.memo[key]

    def _prior_step(self, c):
        if not math.isfinite(c.k):
            return None
        h = self.cap(c)
        # prior_error and snap written out: asked for every candidate of every run, where
        # their calls were most of the a-priori pass
        scale = c.k * self.omega * self.horizon * self.growth(c)
        per_step = ROUNDOFF * c.stages * self.events * self.turned
        accuracy, omega, spacing = self.accuracy, self.omega, self.max_step
        for _ in range(4):  # the order may change with h (damping inside or outside)
            p = self.order(c, h)
            truncation, roundoff = scale * (h * omega) ** p, per_step * round(spacing / h)
            if truncation + roundoff <= accuracy:
                return h
            room = accuracy - roundoff
            if room <= 0.0:
                return None  # below its round-off floor
            h = spacing / max(1, math.ceil(spacing / (h * (room / truncation) ** (1.0 / p))
                                           - 1e-9))
        return h if self.prior_error(c, h) <= accuracy else None

    def most_accurate(self, c):
        """(h, error): the step of c with the least a-priori error (best effort)."""
        top = self.cap(c)
        steps = [self.snap(top * 0.7 ** k) for k in range(40)]
        return min(((h, self.prior_error(c, h)) for h in steps), key=lambda he: he[1])

    def applicable(self, c, torque):
        if c.adaptive:  # its restarts at every control instant are not in its cost model
            return not torque and self.damping is not None
        if c.coupled_only and not (torque or self.damping):
            return False
        if c.exact_damping:
            if self.damping != 'double_bracket':
                return False
            if not torque:
                return True
        elif not c.stiff_only:
            return True
        # A-stability only pays off when dissipation is stiff at the step; the bound on cap
        # first (cap ≤ H_OMEGA_PLAUSIBLE/Ω) spares building the method to ask its order
        return not (self.stiffness * H_OMEGA_PLAUSIBLE < self.omega
                    or self.stiffness * self.cap(c, True) < 1.0)
