"""The pilot's search for ``integrator: auto`` (:mod:`.selection`'s second pass): best
first, within what choosing may cost, step doubling (:mod:`.pilot`) refines the a-priori
choice where a worst-case constant reads far above what a scene errs (a body spinning near
a principal axis: Explorer 1).

What choosing may cost (SELECTION_SHARE, PAYBACK) and which of two choices is better
(:func:`better`) are shared with the a-priori pass."""
import math

from . import pilot

SELECTION_SHARE = 0.10    # the whole selection, a-priori pass included, at most this share
PAYBACK = 10.0            # ... unless a candidate could save this many times what it spent
# the pilot's costs, in the units of the run's cost model, set as answers.PRIOR_BASE is
LEVELS_COST = 3e-5        # s: setting up the pilot's states
ROUND_COST = 3e-5         # s per pilot round besides its runs (queue, models, notes)
PILOT_CALL = 5e-6         # s per pilot run call (Python around the compiled loop)
PERIODS_FROM = 5e-3       # s of pilot budget from which pilots resolve polhode periods
SAFETY_LOCAL, SAFETY_PATH = 1.25, 2.0  # × a pilot's error: at the initial state, along a path
PREFER = 0.1              # a geometric method within 10 % of the cheapest wins
ROUNDS = 4
GUARD_FROM = 100.0        # pilot readings within this factor of the budget bound later ones
MAX_SHRINK = 4.0          # a pilot's step at most this far below the previous one


def better(c, cost, best, accuracy):
    """Whether c at ``cost``, meeting the budget, beats ``best`` (candidate, h, cost, error):
    any choice meeting it beats one that does not; then the cheaper, with geometric methods
    preferred within PREFER (they keep |L| and the energy in free stretches)."""
    if best[3] > accuracy:
        return True
    # written out, not a nested function made at every call (asked several times a run)
    return cost * (1.0 if c.geometric else 1.0 + PREFER) < \
        best[2] * (1.0 if best[0].geometric else 1.0 + PREFER)


def _budget(strict, fallback, saving, spend, prior_cost):
    """The pilot's budget (s): ``strict`` (a share of the cheapest run in view), or
    ``fallback`` (that share of the run without the pilot) where the candidate could save
    at least PAYBACK times what the selection would have spent (``spend``, the round
    included, besides ``prior_cost``)."""
    if spend > strict and saving >= PAYBACK * (prior_cost + spend):
        return fallback
    return strict


NO_ROUND = f'none (a round would cost over {SELECTION_SHARE:.0%} of the run)'


def no_round_fits(s, best, prior_cost) -> bool:
    """Whether ``best`` meets the budget and no pilot round fits in the selection's share
    of its run (a short run's fixed cost dominates it)."""
    return best[3] <= s.accuracy and (SELECTION_SHARE * best[2] - prior_cost
                                      < LEVELS_COST + ROUND_COST + 8 * PILOT_CALL)


def piloted(s, usable, best, principal_attitude, prior_cost):
    """Generator: refine ``best`` (candidate, h, cost, error), the a-priori choice, by pilots
    within the budget; returns (candidate, h, cost, error, pilot steps, pilot cost, notes).
    ``principal_attitude()``: the initial attitude in the principal frame (asked only if a
    pilot runs); ``prior_cost``: what the a-priori pass cost (s, the run's cost model).

    Best first: every candidate waits with the cost it could reach, first at its largest
    plausible step, then at the step its last pilot extrapolates to; the lowest is piloted
    next, until none could beat the best verified choice or the budget is spent."""
    spent, steps, notes = 0.0, 0, []
    if no_round_fits(s, best, prior_cost):
        c, h, cost, err = best
        return c, h, cost, err, 0, 0.0, [NO_ROUND]
    levels, safety = None, SAFETY_LOCAL
    measured = {}  # method → (step, error) of its last pilot
    queue = [(s.run_cost(c, h), i, c, h, 0)
             for i, c in enumerate(usable) for h in (s.cap(c, True),)]
    while queue:
        queue.sort(key=lambda item: item[:2])
        estimate, i, c, h, rounds = queue.pop(0)
        if not better(c, estimate, best, s.accuracy):
            break  # nothing left can beat the best verified choice
        # the whole selection, a-priori pass included, at most SELECTION_SHARE of the
        # cheapest run still in view: the best choice's, or this one's (the queue is sorted:
        # nothing left is cheaper than this estimate), so of whatever run it picks. Except
        # where this candidate could save PAYBACK times what the pilot would then have
        # cost: up to SELECTION_SHARE of the run it would make without it (the stiff bench
        # scene at 1e-9 rad: 0.48 s a priori, RK4 verified at 3 ms with a 2 ms pilot)
        # (an adaptive best at its tightest rtol stays unless beaten within PAYBACK× its
        # cost: its run bounds the pilot as if it met the budget)
        met = best[3] <= s.accuracy or best[0].adaptive
        run = best[2] if met else max(best[2], estimate)
        budget = SELECTION_SHARE * min(run, estimate) - prior_cost
        fallback = SELECTION_SHARE * run - prior_cost
        if levels is None:  # the first round sets up the pilot's states
            least = 3 * pilot.MIN_STEPS * s.step_cost(c, h) + 8 * PILOT_CALL + ROUND_COST
            budget = _budget(budget, fallback, run - estimate, spent + LEVELS_COST + least,
                             prior_cost)
            if spent + LEVELS_COST + least > budget:
                notes.append(f'{c.name} h={h:.3g}: over the pilot budget '
                             f'({max(budget, 0.0):.2g} s)')
                continue
            s.q = principal_attitude()
            levels = pilot.levels(s.dyn, s.q, s.m, s.horizon, s.omega,
                                  periods=budget >= PERIODS_FROM)
            safety = SAFETY_PATH if len(levels) > 1 else SAFETY_LOCAL
            spent += LEVELS_COST
        n = sum(3 * pilot.steps_for(lv, h) for lv in levels)
        cost = n * s.step_cost(c, h) + 8 * len(levels) * PILOT_CALL + ROUND_COST
        budget = _budget(budget, fallback, run - estimate, spent + cost, prior_cost)
        if spent + cost > budget:
            notes.append(f'{c.name} h={h:.3g}: over the pilot budget ({max(budget, 0.0):.2g} s)')
            continue
        if spent + cost > SELECTION_SHARE * min(run, estimate) - prior_cost:
            notes.append(f'{c.name} h={h:.3g} could save {PAYBACK:g}× its pilot: up to '
                         f'{SELECTION_SHARE:.0%} of the run without it')
        p = s.order(c, h)
        err = 0.0
        for lv in levels:
            e, _ = yield from pilot.error(s.integrator(c), p, lv, h, s.horizon,
                                          c.growth == 'drift' or s.damping is not None)
            err = max(err, safety * e)
        # an error falling faster than h³ from the same method's pilot at a larger step, read
        # within GUARD_FROM of the budget, is not believed: a lucky reading of an oscillating
        # error, or a step still short of the asymptotic h^p regime (Explorer 1, 300 s:
        # splitting4 read 0.07 at 0.0312 s, then 0.0023 at 0.0172 s, and ended 0.011 off a
        # 0.01 budget; between those steps its true error fell as h^1.3 to h^2.7). Readings
        # far above the budget are far from that regime and bound nothing.
        if c.name in measured:
            h_big, e_big = measured[c.name]
            if e_big <= GUARD_FROM * s.accuracy:
                err = max(err, e_big * (h / h_big) ** min(p, 3.0))
        measured[c.name] = (h, err)
        floor = s.roundoff(c, h)
        err += floor
        spent += cost
        steps += n
        notes.append(f'{c.name} h={h:.3g}: E={err:.2g}')
        if err <= s.accuracy:
            if better(c, s.run_cost(c, h), best, s.accuracy):
                best = (c, h, s.run_cost(c, h), err)
            continue
        # none meets it yet: the most accurate, unless it costs PAYBACK× more than the best
        # (an adaptive method's bound at its tightest rtol is loose: dop853 at rtol 1e-13 is
        # bounded at 5e-7 rad where it errs 3e-11, and exact at 3 ms steps cost 1000× it)
        if best[3] > s.accuracy and err < best[3] and (
                not best[0].adaptive or s.run_cost(c, h) <= PAYBACK * best[2]):
            best = (c, h, s.run_cost(c, h), err)
        room = s.accuracy - floor
        if rounds + 1 >= ROUNDS or room <= 0.0:
            continue
        # the step the error law extrapolates to sets what c would cost; the next pilot
        # goes at most 4× below this one (far above the asymptotic regime a method's error
        # can fall much faster than h^p: exact's splitting at hΩ ≈ 2)
        shrink = 0.9 * (room / (err - floor)) ** (1.0 / p) if math.isfinite(err) else 0.0
        h_far = s.snap(max(h * shrink, 1e-9 * h))
        h_new = s.snap(max(h * shrink, h / MAX_SHRINK))
        if h_new >= h:
            h_new = s.max_step / (round(s.max_step / h) + 1)
        queue.append((s.run_cost(c, min(h_far, h_new)), i, c, h_new, rounds + 1))
    if not notes:
        notes.append('none (nothing could beat the a-priori choice)')
    if levels is not None:
        notes.append(f'{len(levels)} state(s): β = ' +
                     ', '.join(f'{lv.beta_deg:.3g}°' for lv in levels))
    c, h, cost, err = best
    return c, h, cost, err, steps, spent, notes
