"""The a-priori model behind ``integrator: auto`` (:mod:`.selection`): the candidate
methods with their measured costs and error constants, and :class:`RunModel`, the time
scales of a run and what each candidate would cost and err on it.

Kept apart from the search (selection.py, the pilot's best-first loop). The candidates
are the registered methods' own facts (``Integrator.auto``, a :class:`Candidate`): a new
method states them on its class and nothing here changes.
"""
import math

import numpy as np

from ..integrators import AUTO_CANDIDATES, create, get_integrator
from . import calibration
from .kinds import FREE_ORDERS, applicability
from .calibration import DAMP_SUBSTEP

# What auto may choose: the registry's candidates (integrators.AUTO_CANDIDATES).
CANDIDATES = AUTO_CANDIDATES
# dop853's a-priori model, from 60 runs on 20 generated dissipative scenes (seed 7,
# ``bench.generated``; 150–2·10⁴ rad turned, rtol 1e-5–1e-9): its attitude error was
# E/(rtol·ΩT) ≤ 60, median 0.09, growing with ΩT beyond a few hundred rad (energy drift):
# E ≤ k·rtol·ΩT·max(1, ΩT/DOP853_DRIFT) held on all with k = 2. An rtol 10× too tight costs
# only 10^(1/8) = 1.33× the steps, so the bound errs toward accuracy at little cost.
# Steps: 0.027–0.14 (median 0.08) × ΩT·rtol^(-1/8); explicit, so at least stiffness·T/6.
DOP853_DRIFT = 300.0      # rad turned from which the error grows as (ΩT)²
DOP853_STEPS = 0.1        # steps per rad turned at rtol 1
DOP853_STABLE = 6.0       # its real-axis stability limit, roughly (h·stiffness)
# A restart (commanded torque: one at every control instant) errs on its own: the bound
# above was fitted on uncommanded runs. Detumble scenes erred ~3·rtol per restart beyond it:
# seed 20261125 scene 13 (3.4·10⁵ restarts, 9.3e-8 rad at rtol 1e-13, 2.7·rtol each), seed
# 20261126 scene 166 (1345 restarts at 90 Hz over 15 s, 1.08× its budget at the rtol the
# bound alone gave, 0.55·rtol each past the bound).
RESTART_K = 3.0
RTOL_RANGE = (1e-13, 1e-3)
# Past that range, where the bound cannot promise the budget even at 1e-13 (long horizons,
# tight budgets), dop853 runs tighter, down to RTOL_FLOOR: its measured error, not the
# bound, sets how far. At rtol 1e-13 on the body scenes of seed 20261125 (bench.generated)
# it erred E = K·rtol·ΩT with K 0.1–30 (median 2; one scene 140, where no fixed choice met
# the budget), so the bound (quadratic in ΩT) was 30–4000× high; three scenes missed
# (K = 2, 7 and 20: 1.75, 1.55 and 9.3× their budgets) where rtol 3e-15 meets them. The
# reference ladder (bench.oracle) still converges at 1e-15 (~7× a decade) on those
# scenes, but not on every one: a detumble with 2·10⁶ control restarts (seed 20261126,
# scene 18) erred 6× more at 1e-15 than at 3e-15, so the floor is Hairer's own limit for
# DOP853, rtol > 10·uround (2.2e-15). Each decade costs 10^(1/8) = 1.33× the steps, so
# erring towards accuracy costs at most 1.6× the run at 1e-13 (events apart).
RTOL_FLOOR = 3e-15
MEASURED_K = 30.0         # the largest K above but one: rtol = budget/(K·ΩT)
# Under a control law alone the fixed methods' errors are measured laws too (Candidate.torque,
# 3× above their largest reading, which spreads 100× from scene to scene), so where dop853's
# measured law holds it competes with them on cost, as a prediction at the budget; else
# a fixed method that meets the budget a priori beat it at any cost (generated detumble
# scenes: rk4 at 6–18× dop853's CPU, which met those budgets). It holds where its main term
# K·rtol·ΩT (60 runs) outweighs its restarts' (two scenes) and rtol is TRUST_FROM above
# RTOL_FLOOR (round-off, not rtol, rules near it): the three detumble misses of seed
# 20261125 had 3·10⁶ restarts against K·ΩT = 9·10⁵ (scene 60), 4.4·10⁶ against 3·10⁶ (72),
# and rtol 4.9e-15 (191: 1.1× its budget even with its restarts counted). 3×, not 10×:
# seed 20261127's scene 11 (rtol 1.6e-14, 6·10⁴ restarts against 6·10⁶) went to rk4 at
# 18× dop853's CPU at 10× (that scene of the held-out seed informed this figure)
TRUST_FROM = 3.0          # × RTOL_FLOOR
ROUNDOFF = 2.5e-17        # rad per stage, step and radian turned (see Candidate.stages)
# A polynomial step (rk4: Candidate.rounding 'random') rounds differently every step: its
# errors add as a random walk, ROUNDOFF_RANDOM·stages·√N·ΩT. Measured on torque-free
# generated bodies of seed 7 against the exact solution, at hΩ ≤ 3e-3 (truncation under
# the reading): E/(√N·ΩT) ≤ 6e-17 at 300 rad with N = 10⁵–4·10⁶ and at 10⁴ rad with
# N = 4·10⁶ (still part truncation), 1.8–2.6e-17 at 10⁴ rad with N = 1.6·10⁷: ≤ 1.5e-17 a
# stage, set 2× above. The linear law read those runs 10³–10⁴× high and kept auto off rk4
# wherever it takes 10⁶ steps (generated detumble scene 191 of seed 20261125: 2.9e-9 rad
# in all at 6·10⁶ steps, where that law put the round-off at 3e-5).
ROUNDOFF_RANDOM = 3e-17
RUN_COST = 3e-4           # s: building and finishing a run (engine, first and last sample)
EVENT_COST = 1.5e-5       # s per event interval (a sample or control instant from Python)
# A control instant of an in-process law inside the compiled closed loop (engine.closed_loop)
# beyond a sample's event (calibrated, Costs.event): generated detumble scene 12 of seed
# 20261125 run 20 s with rk4 at 1 ms, law at 10 and 1000 Hz: 0.44 µs per extra instant (least
# of 7, load ~6), where EVENT_COST + the call (17.5 µs) drowned the methods' step costs and
# auto took splitting4 at 1.5–1.7× rk4's CPU on the bench's default, slew and detumble.
LAW_EVENT = 0.5           # µs
SAMPLE_EVENT = 0.2        # µs: a sample's event there, uncalibrated (measured 0.08–0.2)
# (an uncommanded run's events are the compiled closed loop's: calibrated, Costs.event)
DRIFT_TURNS = 30          # the calibration horizon of ``k``, in turns (growth 'drift')
H_OMEGA_PRIOR = 1.0       # a-priori steps keep hΩ ≤ 1 (the asymptotic regime of k)
H_OMEGA_PLAUSIBLE = 2.0   # the largest step a pilot starts from
SPREAD = 30.0             # non-geometric methods err at least k/SPREAD (calibration: k/4 median)


def is_symmetric(moments, rtol=1e-12):
    # plain floats: asked once per selection, where np.sort's per-call cost is a share of it;
    # sorted by compares (a ≤ b ≤ c), so no abs(): sorted() and abs() were ~1 µs of a short
    # run's choosing with cold caches (Explorer 1 over 1 s), the compares ~0.1
    a, b, c = moments.tolist() if isinstance(moments, np.ndarray) else moments
    if b < a:
        a, b = b, a
    if c < b:
        b, c = c, b
        if b < a:
            a, b = b, a
    return b - a <= rtol * c or c - b <= rtol * c


class RunModel:
    """The time scales of a run, and the cost and a-priori error of a method on it."""
    # slots: one per choice, ~25 figures set and read often (its init: a tenth of Explorer 1's)
    __slots__ = ('dyn', 'q', 'm', 'commanded', 'controlled', 'law_alone', 'costs', 'term_cost',
                 'event', 'accuracy', 'horizon', 'max_step', 'm_floats', 'moment_floats', 'G',
                 'damping', 'stiffness', 'spin', 'torque_rate', 'omega', 'events', 'turned',
                 'integrators', 'memo', 'orders')

    def __init__(self, dyn, q, m, accuracy, horizon, max_step, torque_rate, costs=None,
                 environment=(), commanded=False, controlled=False, law_in_loop=False):
        self.dyn, self.q, self.m = dyn, q, m
        # commanded torque: held between control instants, so an adaptive method restarts
        # at each (its cost in ``tolerance``)
        self.commanded = commanded
        # a control law's torque: each restart errs too (RESTART_K). Not an environment
        # re-made per event: B-dot scenes erred ~1e-3·rtol per restart (weak torques)
        self.controlled = controlled
        # the kind Candidate.torque and the random round-off were measured on: a control
        # law's torque on the body alone (generated detumble scenes). With environment
        # torques (B-dot's magnetorquers, the gravity gradient) the free-body worst case stays
        self.law_alone = controlled and not environment
        # per-step costs: measured on this machine if calibrated, else the classes' own
        self.costs = costs or calibration.current()
        # µs per evaluation of the environment's torques ('gravity gradient'): a method pays
        # it at each of its evaluations (Candidate.environment_evals) every step
        self.term_cost = sum(map(self.costs.term_cost, environment)) if environment else 0
        # s per event where the compiled closed loop runs every event (no commands from
        # outside, no environment re-made per interval) and the calibration measured it;
        # else None: EVENT_COST and the method's call, the event-by-event loop
        # ``law_in_loop``: the commands are an in-process law's, run inside that loop
        # (uncalibrated, a law's instant there costs the sample's largest reading besides)
        event = self.costs.event
        if law_in_loop:
            event = (SAMPLE_EVENT if event is None else event) + LAW_EVENT
        self.event = None if (commanded and not law_in_loop) or event is None else event * 1e-6
        self.accuracy, self.horizon, self.max_step = accuracy, horizon, max_step
        # plain floats, kept for the selection's closed forms (pilot.turning): numpy's
        # per-call cost is a share of a short run's selection; the sum in the order sum() took
        self.m_floats = a, b, c = m.tolist()
        self.moment_floats = dyn.moments.tolist()
        self.G = math.sqrt(a * a + b * b + c * c)
        d = dyn.dissipation  # without it no stiffness, not asked (a controlled run's call)
        self.damping = d.model if d.active else None
        self.stiffness = dyn.dissipation_stiffness(self.G) if self.damping else 0.0
        # comparisons, not min()/max(), here and in what a selection asks of the model: a
        # builtin's call (its argument tuple, iterator, compares) is ~1,000 instructions
        # against ~50, and 13–33 of them were a tenth of a short run's choosing (callgrind)
        a, b, c = self.moment_floats
        least = b if b < a else a
        spin = self.G / (c if c < least else least)
        self.spin, self.torque_rate = spin, torque_rate
        self.omega = spin + torque_rate + self.stiffness
        events = math.ceil(horizon / max_step - 1e-9)
        self.events = events if events > 1 else 1
        self.turned = spin * horizon  # rad, for the round-off
        self.integrators = {}
        self.memo = {}  # costs and steps per (method, step): asked for many times
        self.orders = {}  # effective order per (method, step)

    def integrator(self, c):
        if c.name not in self.integrators:
            self.integrators[c.name] = create(c.name, self.dyn)
        return self.integrators[c.name]

    def order(self, c, h):
        """The effective order of c at h (``Integrator.order_on``: no instance needed)."""
        if self.damping is None:  # a fact of c's class: kept for the process (FREE_ORDERS)
            p = FREE_ORDERS.get(c.name)
            if p is None:
                p = FREE_ORDERS[c.name] = get_integrator(c.name).order_on(self.dyn, self.G, h)
            return p
        key = (c.name, h)
        p = self.orders.get(key)
        if p is None:
            p = self.orders[key] = get_integrator(c.name).order_on(self.dyn, self.G, h)
        return p

    def snap(self, h):
        """The largest step ≤ h that divides the event spacing."""
        n = math.ceil(self.max_step / h - 1e-9)
        return self.max_step / (n if n > 1 else 1)

    def step_cost(self, c, h):
        """CPU s per step of c at h."""
        key = ('cost', c.name, h)
        if key not in self.memo:
            self.memo[key] = self._step_cost(c, h) + self.term_cost * c.environment_evals * 1e-6
        return self.memo[key]

    def _step_cost(self, c, h):
        cost = self.costs.cost(c)
        if self.damping is None:
            return cost[0] * 1e-6
        if not c.name.startswith('splitting') or c.name == 'splitting2_lstable':
            return cost[1] * 1e-6
        composed = c.name != 'splitting2'
        if composed and self.order(c, h) > 2:  # the damping goes inside the composition
            return cost[1] * 1e-6
        if self.damping == 'viscous':
            return cost[0] * self.costs.viscous_factor * 1e-6
        substeps = max(1, math.ceil(self.stiffness * h))  # two half-steps of ≤ 0.5 each
        substep = self.costs.damp_substep or DAMP_SUBSTEP
        return (cost[0] + 2 * substep * substeps) * 1e-6

    def least_step_cost(self, c):
        """A lower bound of c's CPU s per step at any step (:meth:`step_cost`): the least
        of its branches, each written as there so that the bound is never above it."""
        cost = self.costs.cost(c)
        least = cost[0] * 1e-6 if self.damping is None else \
            min(cost[0], cost[1], cost[0] * self.costs.viscous_factor) * 1e-6
        return least + self.term_cost * c.environment_evals * 1e-6

    def run_cost(self, c, h):
        steps = self.events * round(self.max_step / h)
        call = self.event if self.event is not None else self.per_event(c)
        return RUN_COST + self.events * call + steps * self.step_cost(c, h)

    def per_event(self, c):
        """s per event of a run with c: the closed loop's (calibrated), else the
        event-by-event loop's (EVENT_COST and c's call around its compiled loop). The
        run's costs read ``event`` first (12 calls of a controlled run's choosing)."""
        if self.event is not None:
            return self.event
        return EVENT_COST + c.call[0 if self.damping is None else 1] * 1e-6

    def least_cost(self, c):
        """A lower bound of c's run cost, at no call to the models: the fewest steps (at
        its largest step) at its least cost per step (auto orders candidates by it)."""
        omega, stiffness = self.omega, self.stiffness
        h, x = H_OMEGA_PRIOR / omega, c.stability / (stiffness if stiffness > omega else omega)
        h = x if x < h else h
        h = self.max_step if self.max_step < h else h
        call = self.event if self.event is not None else self.per_event(c)
        free, damped = self.costs.cost(c)
        return (RUN_COST + self.events * call
                + self.horizon / h * ((damped if damped < free else free)
                                      + self.term_cost * c.environment_evals) * 1e-6)

    def tolerance(self, c):
        """(rtol, run cost s, a-priori error rad) of an adaptive candidate: the loosest rtol
        in RTOL_RANGE whose bound meets the budget (the tightest if none does)."""
        turned = self.omega * self.horizon
        scale = self._adaptive_scale(c, turned)
        rtol = RTOL_RANGE[1]
        for _ in range(2):  # the round-off depends on the steps, weakly on rtol
            steps = self._adaptive_steps(turned, rtol)
            room = self.accuracy - ROUNDOFF * steps * turned
            rtol = min(max(room / scale, RTOL_RANGE[0]), RTOL_RANGE[1])
        call = self.event if self.event is not None else self.per_event(c)
        per_step = (self.costs.cost(c)[0 if self.damping is None else 1]
                    + self.term_cost * c.environment_evals) * 1e-6
        cost = RUN_COST + self.events * call + steps * per_step
        return rtol, cost, scale * rtol + ROUNDOFF * steps * turned

    def tightest(self, c):
        """(rtol, run cost s, a-priori error rad) of an adaptive candidate at its tightest
        rtol (RTOL_RANGE[0])."""
        return (RTOL_RANGE[0], *self.at_tolerance(c, RTOL_RANGE[0]))

    def beyond_bound(self, c):
        """(rtol, run cost s, a-priori error rad) of an adaptive candidate whose bound cannot
        promise the budget in RTOL_RANGE: the rtol its measured error law E = K·rtol·ΩT
        (MEASURED_K) puts at the budget, within [RTOL_FLOOR, RTOL_RANGE[0]]. The error is
        still the bound's (over the budget): a measured law over some scenes is no promise."""
        # a control law's restarts err on their own (RESTART_K), beside the measured law:
        # without them, detumble scenes 60, 72 and 191 of seed 20261125 (4.7·10⁵, 1.5·10⁶
        # and 1.6·10⁵ restarts) erred 1.3–1.8× their budgets
        restarts = RESTART_K * self.events if self.controlled else 0.0
        rtol = self.accuracy / (MEASURED_K * self.omega * self.horizon + restarts)
        rtol = min(max(rtol, RTOL_FLOOR), RTOL_RANGE[0])
        return (rtol, *self.at_tolerance(c, rtol))

    def measured_law_holds(self, rtol):
        """Whether dop853's measured law at ``rtol`` (``beyond_bound``) stands as its
        prediction: under a control law alone, TRUST_FROM above the floor, its restarts'
        term no larger than its main term."""
        return (self.law_alone and rtol >= TRUST_FROM * RTOL_FLOOR
                and RESTART_K * self.events <= MEASURED_K * self.omega * self.horizon)

    def at_tolerance(self, c, rtol):
        """(run cost s, a-priori error rad) of an adaptive candidate at ``rtol``."""
        turned = self.omega * self.horizon
        steps = self._adaptive_steps(turned, rtol)
        call = self.event if self.event is not None else self.per_event(c)
        per_step = (self.costs.cost(c)[0 if self.damping is None else 1]
                    + self.term_cost * c.environment_evals) * 1e-6
        scale = self._adaptive_scale(c, turned)
        return (RUN_COST + self.events * call + steps * per_step,
                scale * rtol + ROUNDOFF * steps * turned)

    def _adaptive_scale(self, c, turned):
        """The adaptive method's a-priori error per unit rtol (rad): the bound's
        k·ΩT·max(1, ΩT/DOP853_DRIFT), plus, where a control law's torque restarts it at
        every event, RESTART_K per restart (``controlled``)."""
        drift = turned / DOP853_DRIFT
        scale = c.k * turned * (drift if drift > 1.0 else 1.0)
        return scale + (RESTART_K * self.events if self.controlled else 0.0)

    def _adaptive_steps(self, turned, rtol):
        """The adaptive method's steps over the run at rtol: its natural steps (at least
        stiffness·T/DOP853_STABLE), plus, with commanded torque, one step more per event:
        a new torque restarts it, and the last step before each instant is cut short."""
        natural, x = (DOP853_STEPS * turned * rtol ** -0.125,
                      self.stiffness * self.horizon / DOP853_STABLE)
        natural = x if x > natural else natural
        natural = 1.0 if 1.0 > natural else natural
        return natural + (self.events if self.commanded else 0)

    def roundoff(self, c, h):
        """Attitude error (rad) from rounding over the run at step h (N steps): growing as N
        where the rounding is systematic, as √N where it is random (``Candidate.rounding``),
        the latter under a control law alone (``law_alone``): there the a-priori choice is
        final, while elsewhere it seeds the pilot, and with √N rk4 at 10⁶–10⁷ steps became
        the 'most accurate' a priori where nothing meets the budget (Explorer 1 at 1e-9 rad
        over 100 s), in place of dop853 whose measured law met those budgets on the suite: the
        linear law there errs towards accuracy, and changing it is for a suite run to show."""
        n = self.events * round(self.max_step / h)
        if c.rounding == 'random' and self.law_alone:
            return ROUNDOFF_RANDOM * c.stages * math.sqrt(n) * self.turned
        return ROUNDOFF * c.stages * n * self.turned

    def cap(self, c, plausible=False):
        """The largest step worth considering for c (``plausible``: where a pilot starts)."""
        key = ('cap', c.name, plausible)
        if key not in self.memo:
            self.memo[key] = self._cap(c, plausible)
        return self.memo[key]

    def _cap(self, c, plausible):
        h = (H_OMEGA_PLAUSIBLE if plausible and c.geometric else H_OMEGA_PRIOR) / self.omega
        omega, stiffness = self.omega, self.stiffness
        x = c.stability / (stiffness if stiffness > omega else omega)
        h = x if x < h else h
        if plausible and not c.geometric and math.isfinite(c.k):
            # no exact axis rotations: the error is within SPREAD of the bound k
            prior = self.prior_step(c)
            if prior is not None:
                x = prior * SPREAD ** (1.0 / self.order(c, prior))
                h = x if x < h else h
        return self.snap(h if h < self.max_step else self.max_step)

    def growth(self, c):
        if c.growth == 'drift':
            return max(1.0, self.omega * self.horizon / (2 * math.pi * DRIFT_TURNS))
        return 1.0

    def prior_error(self, c, h):
        """A-priori error bound at h: truncation (module docstring) plus round-off."""
        return self._truncation(c, h, self.order(c, h)) + self.roundoff(c, h)

    def _truncation(self, c, h, p):
        x, turned = h * self.omega, self.omega * self.horizon
        if self.law_alone and c.torque is not None:
            # under a control law: the constants measured there (Candidate.torque)
            k1, k2 = c.torque
            return (k1 + k2 * x * turned) * x ** p * turned
        return c.k * x ** p * turned * self.growth(c)

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
        accuracy = self.accuracy
        for _ in range(4):  # the order may change with h (damping inside or outside)
            p = self.order(c, h)
            truncation, roundoff = self._truncation(c, h, p), self.roundoff(c, h)
            if truncation + roundoff <= accuracy:
                return h
            room = accuracy - roundoff
            if room <= 0.0:
                return None  # below its round-off floor
            # the truncation falls as h^p or faster (Candidate.torque's h^(p+1) term): a
            # step from h^p lands at or under the budget
            h = self.snap(h * (room / truncation) ** (1.0 / p))
        return h if self.prior_error(c, h) <= accuracy else None

    def most_accurate(self, c):
        """(h, error): the step of c with the least a-priori error (best effort)."""
        top = self.cap(c)
        steps = [self.snap(top * 0.7 ** k) for k in range(40)]
        return min(((h, self.prior_error(c, h)) for h in steps), key=lambda he: he[1])

    def applicable(self, c, torque):
        kind = applicability(c, bool(torque), self.damping)
        return kind if kind is not None else self.stiff_enough(c)

    def stiff_enough(self, c):
        """Whether the dissipation is stiff at c's steps: where A-stability pays off (the
        bound on cap first: cap ≤ H_OMEGA_PLAUSIBLE/Ω spares building the method to ask
        its order)."""
        return not (self.stiffness * H_OMEGA_PLAUSIBLE < self.omega
                    or self.stiffness * self.cap(c, True) < 1.0)

