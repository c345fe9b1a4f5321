"""Model selection for ``integrator: auto``: the cheapest method and step meeting the budget.

* **Torque-free, no dissipation → ``exact``:** no stepping error at any horizon.
* **Otherwise, a priori** (no run, ~0.1 ms): for every candidate of order p (its effective
  order at the step, ``Integrator.effective_order``) the error over the horizon T is
  bounded by E(h) = k·(hΩ)^p·ΩT·g + round-off, with Ω = |L|/I_min + the torque's rate
  scale + the dissipation stiffness (the fastest time scale of the scene), k the largest
  constant measured over random bodies and states (``CANDIDATES``) and g the growth of
  the error: 1 for the geometric methods (bounded energy error, phase error linear in
  T), ΩT/(30 turns) for RK4 (its energy drifts, so its phase error grows as T²). Steps
  divide the event spacing (each interval between events is split into equal steps) and
  are not capped by the scene's ``step``. With each candidate's CPU per step and per
  event this predicts the run's cost; the cheapest meeting the budget wins (a geometric
  method within 10 %).
* **Symmetric body, dissipation alone → ``exact`` a priori** where 2·Δβ (the damping's
  turning of the momentum over the run) meets the budget, at the event spacing: its split
  error is at most Δβ at any step (:func:`.answers.symmetric_split`).
* **Pilot, only where needed:** k is a worst case; a body spinning near a principal axis
  (Explorer 1) errs 10⁴× less with a splitting. For torque-free dissipative runs the
  pilot (:mod:`.pilot_search`, with :mod:`.pilot`'s step doubling at the initial state
  and at states along the dissipation's exponential path) searches best first: each
  candidate waits with the cost it could reach (at its largest plausible step, hΩ = 2 for
  a splitting, then at the step its last pilot extrapolates to); the lowest is piloted
  next, at most 4× below its previous step and 4 times, until nothing left could beat the
  best verified choice.
  The measured error gets a safety factor (1.25 at the initial state alone, 2 along a
  path, where the largest rate × T was measured up to 1.3× short of the run's error).
* **What choosing may cost:** the whole selection, this a-priori pass included, at most
  10 % of the run it picks, in the run's own cost model (per-step costs, plus measured
  costs of the a-priori pass, of setting up the pilot and of each round). A round starts
  only if it fits in 10 % of the cheapest run still in view; where none fits (a short
  run, whose fixed cost dominates), the a-priori choice stands. The a-priori pass asks
  the candidates cheapest first by the least each could cost and skips one that could not
  save what asking it costs (PRIOR_EACH); once a further question would take the pass
  past 10 % of the run, only a candidate that could save PAYBACK times its cost is asked
  (the preference for geometric methods then yields: it buys quality, not time).
* **Commanded torque:** the pilot cannot know future commands, so controlled runs take
  the a-priori choice with the control bandwidth as the torque's rate scale: typically
  a high-order splitting at the control period, whose per-event work dominates the cost.
  Where the commands are an in-process law's, the law runs in the engine's compiled
  loop, and a pilot runs the candidates with it from the current state
  (:mod:`.law_pilot`, ``law_runner``).
* **Budget below the round-off floor:** no method meets it; auto picks the most
  accurate it can predict and says so in its reason.

Adding a method needs nothing here: its class states its ``auto`` facts (a ``Candidate``:
cost per step, error constant, …), which :mod:`.model` (the a-priori model: time scales,
costs, errors) collects from the registry.
"""
import math
from .. import rotation
from ..body import RigidBody
from ..dynamics import Dissipation, Dynamics
from . import law_pilot, libration
from .answers import (PRIOR_EACH, Selection, checked, free_choice, options,
                      prior_cost as _prior_cost, symmetric_split, unknowable)
from .pilot_search import (NO_ROUND, PAYBACK, PREFER, SELECTION_SHARE, better as _better,
                           no_round_fits, piloted)
from ..integrators import Candidate
from .kinds import by_stiff, kind_of, least as least_costs
from .model import (CANDIDATES, H_OMEGA_PRIOR, MEASURED_K, RTOL_RANGE, RUN_COST, RunModel,
                    is_symmetric)

__all__ = ['CANDIDATES', 'Candidate', 'Selection', 'free_choice', 'select', 'selecting']


DEFAULT_HORIZON = 600.0   # s: the budget horizon for open-ended (duration 0) runs
# the reason: what the model holds, the budget, horizon and Ω, the costs' source and the
# a-priori pass; after a pilot (or where none could run) what it found. One % each, its
# figures formatted there (see .answers): formatted in parts and joined, the text (not
# ASCII: Ω, →) was copied three times more, a share of a short run's choosing
# (callgrind: Explorer 1 over 1 s)
REASON = ('%s → cheapest method meeting %g rad over %g s; Ω = %.3g rad/s; %s; '
          'a priori (k·(hΩ)^p·ΩT): %s')
CONCLUDED = REASON + '; %s: %s'


def _worth_asking(c, floor, best, accuracy, asked):
    """Whether the a-priori pass asks c, whose run costs at least ``floor`` (s), having
    asked ``asked`` candidates: while nothing meets the budget, always; while the pass stays
    within SELECTION_SHARE of the best run, if c could beat it by what asking costs
    (geometric methods preferred within PREFER); past that share, only if c could save
    PAYBACK times what asking costs (Explorer 1 over 1 s: a 0.32 ms run, all but 6 µs of it
    fixed, where asking three candidates took 15 % of it)."""
    if best is None or best[3] > accuracy:
        return True
    if _prior_cost(asked + 1) <= SELECTION_SHARE * best[2]:
        return _better(c, floor + PRIOR_EACH, best, accuracy)
    return floor + PAYBACK * PRIOR_EACH < best[2]


def select(body: RigidBody, dissipation: Dissipation, attitude, angular_velocity, **kw):
    """Pick integrator and step for a scene (see :func:`selecting` for the arguments)."""
    work = selecting(body, dissipation, attitude, angular_velocity, **kw)
    while True:
        try:
            next(work)
        except StopIteration as done:
            return done.value


def selecting(body: RigidBody, dissipation: Dissipation, attitude, angular_velocity, **kw):
    """Generator form of :func:`select`: yields often (every few ms of pilot work) so that a
    caller can interleave the selection with its own work; its return value is the Selection
    (the arguments: :func:`choosing`)."""
    work = choosing(body, dissipation, attitude, angular_velocity, **kw)
    if isinstance(work, Selection):
        return work
    return (yield from work)


def choosing(body: RigidBody, dissipation: Dissipation, attitude, angular_velocity, *,
             torque: bool, accuracy: float, duration: float, max_step: float,
             torque_rate: float = 0.0, prior_only: bool = False,
             dynamics: Dynamics = None, environment: tuple = (), forced: bool = False,
             restarting: bool = False, orbit_state: tuple = None,
             law_in_loop: bool = False, law_runner=None, control_period: float = 0.0,
             momentum=None):
    """The selection's a-priori pass, at once: the Selection where no pilot runs, else the
    generator that pilots and returns it (:func:`selecting`'s form; a caller that needs no
    generator where none pilots is spared making one and its StopIteration: a share of a
    short run's choosing, Explorer 1's over 1 s).

    Args:
        body, dissipation: the model.
        attitude, angular_velocity: initial state (body→inertial quaternion; ω body frame;
            ω may be None where ``momentum`` is given and ``orbit_state`` is not).
        torque: whether commanded torques will act.
        accuracy: attitude-error budget in rad over ``duration``.
        duration: horizon in s (0 = open-ended: budget per DEFAULT_HORIZON s).
        max_step: the event spacing (sample and control period), s: steps divide it.
        torque_rate: rate scale of the torque, 1/s (control bandwidth; √(τ_max/I_min)).
        prior_only: the a-priori choice only (no pilot, returns at once).
        dynamics: the body's ``Dynamics`` with this dissipation if the caller has one (else
            built here).
        environment: names of the environment's torques in the model ('gravity gradient'):
            torques from the start (``torque`` is implied), asked of the methods that
            integrate them only (``Integrator.environment``), named in the reason.
        forced: the environment's torque is periodic in time along the orbit (the gravity
            gradient on a non-circular orbit). Where its rate (``torque_rate``) reaches the
            body's own (|L|/I_min) the body librates under a periodic forcing, which can be
            chaotic (an eccentric orbit's pitch libration: Beletsky; Tong & Rimrott): an
            error grows exponentially there, not as the a-priori bound's T or T², and no
            pilot of a share of the run can see how far (generated orbit scenes: rk4 within
            its bound erred 66–3·10⁴× the budget, dop853 at rtol 1e-9 3 rad). auto cannot
            know that error, says so (``predicted_error`` inf), and takes the most
            accurate: dop853 at its tightest rtol. Without commands only (a control law
            drives the motion), and not on a circular orbit: a small libration there is
            all but linear (config/gravity_gradient.yaml), though a larger one can exceed
            dop853's bound too (seed 7, orbit scene 21: 4.6×).
        restarting: the engine restarts an adaptive method at every event (SGP4's or
            NRLMSIS's anchored environment), as commanded torque does: in its cost.
        orbit_state: (r, v), the orbit's position and velocity (m, m/s, inertial) now, where
            the gravity gradient acts: a body starting near an LVLH equilibrium that is
            unstable (or marginal, :mod:`.libration`) leaves it exponentially, and so does
            any error (seed 7's orbit scenes 21 and 28: dop853 and rk4 within their bounds
            erred 4.6× and 700× the budget). auto cannot know that error and takes the most
            accurate, as for ``forced``. Without commands only.
        law_in_loop: the commands are an in-process control law's, evaluated inside the
            engine's compiled closed loop: an event costs what the calibration measured
            there (``model.LAW_EVENT``), not a Python round trip.
        law_runner: where that law runs in this process, a callable giving a runner of
            the closed loop from the current state (``engine.law_pilot``): the a-priori
            choice is then refined by a pilot with the law in the loop
            (:mod:`.law_pilot`); ``control_period``: the law's period, s.
        momentum: the angular momentum in the principal frame (I·ω, an array the
            selection keeps) if the caller holds it (the engine's state), else from
            ``angular_velocity``.
    """
    commanded, torque = torque, torque or bool(environment)
    checked(accuracy, max_step)
    moments = body.principal_moments
    m = moments * body.to_principal(angular_velocity) if momentum is None else momentum
    horizon = duration if duration > 0 else DEFAULT_HORIZON
    # the attitude matters to the pilot only (set below): the a-priori pass skips its cost.
    # Positional (costs None: the calibrated; environment, commanded, controlled,
    # law_in_loop): a class called with keywords makes a dict of them for its __init__
    # (callgrind: ~4.7k instructions of Explorer 1's ~130k a choice over 1 s)
    s = RunModel(dynamics or Dynamics(moments, dissipation), None, m, accuracy, horizon,
                 max_step, torque_rate, None, environment, commanded or restarting,
                 commanded, law_in_loop and commanded and not restarting)
    # the free body (the engine chooses it itself): asked of the model's damping, where
    # the dissipation's active (a property) was asked once more per choice
    if not torque and s.damping is None:
        return free_choice(moments, m, accuracy, max_step)
    if s.omega == 0.0:
        return Selection('splitting2', max_step, 'body at rest, no torque: any step is exact',
                         0.0, s.run_cost(CANDIDATES[0], max_step))
    # the kind's facts in one lookup, then one per answer of the stiffness (kinds.py)
    k = kind_of(commanded, s.damping, environment)
    adaptive, what = k.adaptive, k.effects
    stiff = tuple(map(s.stiff_enough, k.deciding)) if k.deciding else ()
    kind = torque, s.damping, k.environment, stiff
    usable, bounded, finite, split = k.stiff.get(stiff) or by_stiff(k, stiff)
    if forced and not commanded and adaptive and s.torque_rate >= s.spin:
        return unknowable(s, adaptive[0], accuracy, horizon, (
            f'{what} on a non-circular orbit → libration under a periodic forcing (torque '
            f'rate {s.torque_rate:.3g} rad/s ≥ the body\'s {s.spin:.3g}), possibly chaotic'))
    if orbit_state is not None and not commanded and adaptive \
            and 'gravity gradient' in environment:
        near = libration.nearest(moments, body.attitude_to_principal(
            rotation.validated(attitude)), body.to_principal(angular_velocity), *orbit_state)
        if near is not None and not near.stable:
            return unknowable(s, adaptive[0], accuracy, horizon, (
                f'{what}: the body starts {near.describe()} → it leaves it exponentially'))
    best, why, unasked, asked = None, [], [], 0
    if not torque and is_symmetric(s.moment_floats):  # exact's split error is known a priori
        best, asked = symmetric_split(s, split, why)
    # cheapest first by the least each could cost (at its largest step); one that could not
    # save more than asking it costs is not asked: on a short run the fixed part of the run
    # dominates every candidate's cost, and the a-priori pass would be its largest share
    # (a loop and a sort in place over the kind's bounded candidates, not sorted() of a
    # generator resumed per candidate; the same order: they keep usable's)
    least, settled = [], _settled(s, best, accuracy)
    if not settled and not _none_could_pay(s, usable, kind, best, accuracy):
        for i, c in enumerate(bounded):
            least.append((s.least_cost(c), i, c))
        least.sort()
    if not least and best is not None:
        unasked += finite
    for floor, _, c in least:
        if not _worth_asking(c, floor, best, accuracy, asked):
            unasked.append(c.name)
            continue
        asked += 1
        h = s.prior_step(c)
        if h is None:
            continue
        cost = s.run_cost(c, h)
        why.append('%s h=%.3g' % (c.name, h))
        if best is None or _better(c, cost, best, accuracy):
            best = (c, h, cost, s.prior_error(c, h))
    # an adaptive candidate is not asked where its run's fixed part alone (building and
    # events, no step), then its run at its loosest rtol, could not save what asking costs
    # (Explorer 1 over 1–100 s: exact at the sample period, one step per event, where its
    # tolerance was a tenth of the selection)
    asking = []  # a loop, not two comprehensions: each a function call of its own
    for c in adaptive:
        if not settled and (best is None or best[3] > accuracy or (
                _better(c, RUN_COST + s.events * s.per_event(c) + PRIOR_EACH, best, accuracy)
                and _better(c, s.at_tolerance(c, RTOL_RANGE[1])[0] + PRIOR_EACH, best,
                            accuracy))):
            asking.append(c)
        else:
            unasked.append(c.name)
    if unasked:
        why.append('not asked (could not save what asking costs): ' + ', '.join(unasked))
    prior_cost = _prior_cost(asked)
    if best is None:  # nothing meets it a priori: the most accurate, unless a pilot helps
        c, h, err = min(((c, *s.most_accurate(c)) for c in usable if math.isfinite(c.k)),
                        key=lambda che: che[2])
        best = (c, h, s.run_cost(c, h), err)
        why.append(f'none meets the budget; the most accurate: {c.name} h={h:.3g} '
                   f'(E={err:.2g}, round-off included)')
    tolerances = {}
    for c in asking:  # a tolerance a priori (RunModel.tolerance): bounded, never piloted
        rtol, cost, err = s.tolerance(c)
        why.append('%s rtol=%.2g (E≤%.2g)' % (c.name, rtol, err))
        if err > accuracy:
            # no promise: tighter, as far as its measured error law asks (RTOL_FLOOR)
            why.append(f'{c.name} cannot promise {accuracy:g} rad even at rtol '
                       f'{rtol:.0e}')
            rtol, cost, err = s.beyond_bound(c)
            if rtol < RTOL_RANGE[0]:
                why.append(f'{c.name} at rtol {rtol:.2g} instead: its measured error '
                           f'{MEASURED_K:g}·rtol·ΩT at the budget (E≤{err:.2g} by the bound; '
                           'not a promise)')
            if s.measured_law_holds(rtol):  # competes on cost with the fixed methods'
                why.append(f'{c.name}: under the control law its measured law stands as its '
                           'prediction (rtol clear of its floor, restarts the minor '
                           'term), as the fixed methods\' measured constants do')
                err = accuracy
        tolerances[c.name] = rtol
        if (_better(c, cost, best, accuracy) if err <= accuracy
                else best[3] > accuracy and err < best[3]):
            best = (c, max_step, cost, err)
    # the reason's fields, formatted once where the choice is made (REASON, CONCLUDED)
    said = ((what, accuracy, horizon, s.omega, s.costs.source, ', '.join(why)), prior_cost,
            tolerances)
    if torque and law_runner is not None and s.law_alone and not prior_only:
        planned = law_pilot.plans(s, best, usable)
        if not planned and not (best[3] > accuracy and adaptive and not best[0].adaptive):
            # nothing to pilot and nothing to weigh (_under_law's two questions): at once
            return _concluded(s, (*best, 0, 0.0, [law_pilot.NO_PLAN]), said,
                              'pilot under the law')
        return _under_law(s, best, usable, adaptive, law_runner, control_period, said,
                          planned)
    if torque or prior_only:
        c, h, cost, err = best
        return Selection(c.name, h, REASON % said[0], err, cost, prior_cost=prior_cost,
                         options=options(c, tolerances, s.G))
    if no_round_fits(s, best, prior_cost):  # the pilot's first question, asked here
        return _concluded(s, (*best, 0, 0.0, [NO_ROUND]), said, 'pilot')
    return _piloting(s, usable, best, lambda: body.attitude_to_principal(
        rotation.validated(attitude)), said)


def _under_law(s, best, usable, adaptive, law_runner, control_period, said, planned):
    """Generator: the a-priori choice ``best`` refined by the law's pilot (:mod:`.law_pilot`),
    and dop853 weighed where nothing promises; returns the Selection. ``said``: the
    reason's fields so far (REASON), the a-priori pass's cost and the adaptive candidates'
    rtols (updated here); ``planned``: what the pilot would run (``law_pilot.plans``)."""
    (c, h, cost, err), spent, steps, notes = yield from law_pilot.refine(
        s, best, usable, law_runner, control_period, planned)
    if err > s.accuracy and adaptive and not c.adaptive:  # nothing promises: weighed
        (c, h, cost, err), rtol, more, done, more_notes = yield from law_pilot.weigh(
            s, (c, h, cost, err), adaptive[0], law_runner, control_period)
        spent, steps, notes = spent + more, steps + done, notes + more_notes
        if rtol is not None:
            said[2][c.name] = rtol
    return _concluded(s, (c, h, cost, err, steps, spent, notes), said, 'pilot under the law')


def _piloting(s, usable, best, principal_attitude, said):
    """Generator: the a-priori choice ``best`` refined by the free body's pilots
    (:mod:`.pilot_search`); returns the Selection."""
    found = yield from piloted(s, usable, best, principal_attitude, said[1])
    return _concluded(s, found, said, 'pilot')


def _concluded(s, found, said, pilot):
    """The Selection of ``found`` (candidate, h, cost, error, pilot steps, pilot cost, notes),
    with what the ``pilot`` noted, and where it misses the budget, that it does."""
    (c, h, cost, err, steps, spent, notes), (fields, prior_cost, tolerances) = found, said
    if err > s.accuracy:
        notes.append(f'no method can be shown to meet {s.accuracy:g} rad here; the most '
                     f'accurate predicted ({err:.2g} rad)')
    return Selection(c.name, h, CONCLUDED % (*fields, pilot, '; '.join(notes)), err, cost,
                     steps, spent, prior_cost,
                     options(c, tolerances, s.G) if c.adaptive else ())


def _settled(s, best, accuracy) -> bool:
    """Whether no other candidate, step-based or adaptive, could save what asking it costs,
    by one bound asked of neither's table: where every run pays the same per event (the
    compiled closed loop's, calibrated: ``RunModel.event``), a run's fixed part and events
    alone, plus what asking costs, at or above ``best``'s run. Both tests it stands for
    (:func:`_none_could_pay`, whose floor adds the steps; the adaptive candidates' first)
    then answer no, to the last bit (sums of the same terms, rounding monotonic): Explorer 1
    over 1–100 s, exact at the sample period, where they were a tenth of its choosing."""
    return best is not None and s.event is not None and best[3] <= accuracy and \
        RUN_COST + s.events * s.event + PRIOR_EACH >= \
        best[2] * (1.0 if best[0].geometric else 1.0 + PREFER)


def _none_could_pay(s, usable, kind, best, accuracy) -> bool:
    """Whether no step-based candidate could save what asking it costs, by one bound for
    all (each one's ``least_cost`` asked for nothing; Explorer 1 over 1 s, exact at the
    sample period): the fewest steps any takes (hΩ ≤ H_OMEGA_PRIOR, at most the event
    spacing) at the least cost per step and per event of all, beside the run's fixed part.
    ``usable``: the candidates of ``kind`` (:func:`.kinds.usable`, already asked)."""
    if best is None or best[3] > accuracy or not usable:
        return False
    h = H_OMEGA_PRIOR / s.omega  # a compare, not min(): see model.RunModel
    h = s.max_step if s.max_step < h else h
    per_step, event = least_costs(s, kind)
    floor = RUN_COST + s.events * event + s.horizon / h * per_step * 1e-6
    # as _worth_asking, for a geometric candidate (the preference can only favour it)
    return floor + PRIOR_EACH >= best[2] * (1.0 if best[0].geometric else 1.0 + PREFER)


