"""``auto``'s pilot under a control law: it measures the scene where the a-priori constants
can only promise the budget at a step far below what the scene needs.

Under an in-process law the a-priori choice (:mod:`.selection`) rests on the fixed
methods' error constants measured under laws (``Candidate.torque``), set 3× above their
largest reading, which spreads 100× from scene to scene. So most scenes got a step
several times shorter than they need (generated detumble scenes: rk4 at 2.5–3× the CPU of
the same method at the step that met the budget; splitting6 at 37× rk4's step on one).

The pilot measures instead. From the current state, with the law in the loop (the
engine's compiled closed loop: its runner, ``engine.law_pilot``, writes nothing of the
engine), each fixed candidate that could beat the a-priori choice runs at h and h/2 over a
share H of the run (step doubling: the difference × 2^p/(2^p − 1) is the error at h). The
error is read at each quarter of H and extrapolated to the run's horizon T by the
free-body pilot's growth law (:mod:`.pilot`): (T/H)·e(H), or a power law where e(H)/e(H/2)
exceeds pilot.SUPERLINEAR; then SAFETY and the a-priori round-off. On 15 generated
detumble scenes (seed 20261125, e(t) at t = T/256 … T) rk4's error grew as t^0.1–t^1.1
past T/32 on 13 and as t^1.7 at most on two (130, 189): the linear law reads high, the
quarters' growth law catches the two. From the extrapolation, the step meeting the budget
follows by h^p; where it moved far (VERIFY_SHRINK) it is piloted again, and a longer step
only so (seed 20261125 scene 13: 2.17 → 3.34 ms, erred 7.3e-10 of 1e-8). Candidates go best
first by what they could cost; one is piloted only if it could beat the best choice so far.

dop853 is not piloted for a promise: its error under a law jumps late in a run (the same
15 scenes, r against r/100: 10–100× within the last half of the run on scenes 4 and 107,
after t^1 before), 27× above a linear extrapolation from T/32 and 1.6× above a power law
fitted on the pilot's quarters, so a pilot on a share of the run cannot promise it. Its
a-priori handling stands (``model.RunModel.tolerance``, ``measured_law_holds``); only
where nothing promises does a pilot set its rtol (below), as a guess.

Under a law, rk4's rounding is what its pilot reads where that is less than the a-priori
figure, fitted torque-free (:func:`_rounding`): a law that damps the rate damps its
rounding too. A third run parts it from the truncation (:func:`_spread`; seed 20261125
scene 191 at 0.504 ms: E 2.6e-8 → 9.5e-9, the run erred 2.0e-9).

Where nothing promises the budget a priori (the fixed methods' most accurate step
predicts more than it), :func:`weigh` runs that step and dop853 at its floor rtol and at
PROBE side by side over a share of the run, and takes dop853 where it errs less and costs
less, as measured (seed 7 scene 158, seed 8 scene 98, seed 20261125 scene 105: dop853 met
budgets rk4's most accurate step met at 4–7× its CPU), at the rtol its own measured error
puts MARGIN under the budget; a guess, not a promise. (It ran at the floor rtol, 3e-15,
wherever it was taken: seed 20261125 scene 106 at 3.2× the CPU of dop853 at 1e-13, which
met the budget, two thirds of it the pilot's.)

What the pilot may cost: SHARE of the a-priori choice's run (the run's cost model), its
first round FIRST_ROUND of that; H is the longest share of the run that fits, at least
MIN_PERIODS control periods and pilot.ROTATIONS rotations, else there is no pilot (a
short run: the a-priori choice stands).
"""
import math
import time

import numpy as np

from .. import rotation
from . import pilot
from .kinds import applicable
from .model import RTOL_FLOOR, RTOL_RANGE, RUN_COST
from .pilot_search import PREFER

SHARE = 0.1          # the pilot at most this share of the a-priori choice's run
FIRST_ROUND = 0.6    # of that, the first round's (it sets the horizon)
SAFETY = 2.0         # × the extrapolated error
MIN_PERIODS = 8      # the pilot's horizon at least this many control periods
CALL = 1e-5          # s per pilot run part (Python around the compiled loop)
SETUP = 5e-5         # s: the runner (the law's and the state's arrays)
VERIFY_SHRINK = 1.5  # a step this much below the piloted one is piloted again
MAX_PLANS = 3        # candidates piloted at most
NO_PLAN = 'none (no candidate could beat the a-priori choice)'  # where plans() is empty
# dop853 weighed where nothing promises: only where its model cost is WEIGH_GAIN× below the
# fixed method's (where the pilot keeps the fixed method its cost is lost: seed 20261125
# scenes 13 and 105 went from 2.95× to 3.3× the oracle's CPU), the pilot at most
# WEIGH_SHARE of that run: over about H = 3 % of the run, as it was with rk4's step
# doubling (a 10 % budget, three runs; at 5 %, H = 1.5 %, seed 7 scene 158 and seed 8 scene
# 98, where dop853 errs 8× less at a fifth of rk4's CPU, read too short to tell), now at
# 40 % of that CPU
WEIGH_GAIN = 3.0
WEIGH_SHARE = 0.04
# dop853's rtol where it is weighed: its error measured at PROBE against its floor run,
# taken linear in rtol (model.MEASURED_K's law), then MARGIN under the budget. PROBE: the
# bound's tightest rtol, never looser (the error is not monotonic in rtol: seed 20261125
# scene 106 erred 7.6e-11 at 3e-14, 2.5e-11 at 1e-13).
PROBE = RTOL_RANGE[0]
MARGIN = 10.0
# dop853's error under a law from the pilot's share H to the run's T: as (T/H)^1.5. On the
# pilot's quarters it grew as t^1.9–2.3 (seed 20261125 scenes 105, 106, 136, seed 7 scene
# 158, seed 8 scene 98, at rtol 1e-13 against 3e-15), over the run as t^0.8–1.7: the
# power law of its quarters read the end 7–38× high, the linear law 0.5–10× low; t^1.5
# (a random walk of the rate's errors) read it 0.09–1.9×.
DOP853_GROWTH = 1.5
SPREAD = 100.0       # a pilot starts where the a-priori truncation is this × the budget


def _extrapolate(errors, horizon, reached):
    """The error at ``horizon`` s from errors at the quarters of a pilot that reached
    ``reached`` s: the free-body pilot's growth law (:mod:`.pilot`)."""
    if not all(map(math.isfinite, errors)):
        return math.inf
    m1, m2 = max(errors[:len(errors) // 2]), max(errors)
    growth = m2 / m1 if m1 > 0.0 else 2.0
    later = max(1.0, horizon / reached)
    if growth > pilot.SUPERLINEAR:
        return m2 * later ** math.log2(growth)
    return m2 * later


def _rounding(s, c, piloted, spread, horizon, reached):
    """h ↦ c's rounding error over the run at step h: the a-priori one (``s.roundoff``),
    or for a random rounding (rk4) where less, SAFETY × ``spread`` (:func:`_spread`, else
    the step-doubling reading) at ``piloted`` grown as t^1.5 from ``reached`` s (a random
    walk of the rate's rounding errors) and as √N to h's steps. Under a damping law the
    a-priori one (torque-free) read 30–75× high (seed 20261125 scene 13 at 1.2 ms)."""
    if c.rounding != 'random' or not spread or not all(map(math.isfinite, spread)):
        return lambda h: s.roundoff(c, h)
    at = SAFETY * max(spread) * max(1.0, horizon / reached) ** 1.5
    return lambda h: min(s.roundoff(c, h), at * math.sqrt(piloted / h))


def _spread(a, b, r, ratio, f):
    """Run a's rounding (rad, at each mark) from runs a at h, b at h/2 and r at the next
    shorter step h_r: in ε_a − ε_r − f·ratio·(ε_a − ε_b), f = 1 − (h_r/h)^p, the truncation
    cancels, ρ_a − ρ_r − f·ratio·(ρ_a − ρ_b) is left: ~√2 × a's (independent walks)."""
    def apart(x, y):  # rotation vector from y to x (small: twice the vector part)
        d = rotation.multiply(rotation.conjugate(y[1]), x[1])
        return (2.0 if d[3] >= 0.0 else -2.0) * d[:3]
    return [float(np.linalg.norm(apart(x, z) - f * ratio * apart(x, y)))
            for x, y, z in zip(a, b, r)]


def _pilot_cost(s, c, h, share, rounding=True):
    """CPU s of c's pilot at h over ``share`` of the run (``rounding``: :func:`_parts`')."""
    per = s.run_cost(c, h) + s.run_cost(c, s.snap(0.5 * h)) - 2 * RUN_COST
    if rounding and _parts(s, c, h):
        per += s.run_cost(c, _next_step(s, h)) - RUN_COST
    return share * per + 12 * CALL


def _next_step(s, h):  # the next step shorter than h that divides the event spacing
    return s.max_step / (round(s.max_step / h) + 1)


def _parts(s, c, h):
    """Whether a third run parts c's (random) rounding at h: not where it would be b's."""
    return c.rounding == 'random' and round(s.max_step / h) >= 2


def _start(s, c):
    """The step a pilot of c starts from: where its a-priori truncation error is SPREAD
    times the budget (the least constant measured under laws is ~100× below the bound's),
    at most its largest plausible step."""
    h, target = s.cap(c, True), SPREAD * s.accuracy
    for _ in range(4):  # the order may change with h
        p = s.order(c, h)
        error = s._truncation(c, h, p)
        if error <= target:
            break
        h = s.snap(h * (target / error) ** (1.0 / p))
    return h


def plans(s, best, usable):
    """[(cost at its largest plausible step, index, candidate, that step)]: the fixed
    candidates that could beat ``best``, cheapest first (at most MAX_PLANS); none: no
    generator for :func:`refine` is made (``selection``)."""
    c0, _, cost0, err0 = best
    found, met = [], err0 <= s.accuracy
    for i, c in enumerate(usable):
        if not math.isfinite(c.k) or c.adaptive:
            continue
        # its run at one step per event at its least cost per step, not below best's: no
        # step of it can beat best, so its start is not sought (those of the bench's
        # controlled scenes, rk4 at the control period there, were a fifth of their choosing)
        # (written as run_cost sums, so that the bound is never above it, to the last bit)
        if met and RUN_COST + s.events * s.per_event(c) + s.events * s.least_step_cost(c) \
                >= cost0:
            continue
        h = _start(s, c)
        cost = s.run_cost(c, h)
        # where its round-off alone (a priori) takes the budget at that step, no pilot can
        # promise it (generated detumble scenes at 1e-8–1e-9 rad over 10⁴ rad: rk4's
        # most accurate step, piloted for nothing at 5–7 % of the run)
        # (a random rounding, rk4's, is measured by the pilot instead, :func:`_rounding`,
        # but not where dop853 is weighed: there the pilot of rk4 was paid for nothing,
        # seed 20261125 scenes 105, 106, 136, seed 7 scene 158, seed 8 scene 98: 20–70 %
        # more CPU, each kept dop853)
        if s.roundoff(c, h) >= s.accuracy / SAFETY and (
                c.rounding != 'random' or _weighed(s, cost0, _adaptive(s))):
            continue
        if not met or cost < cost0:
            found.append((cost, i, c, h))
    return sorted(found, key=lambda p: p[:2])[:MAX_PLANS]


def refine(s, best, usable, make_runner, period, planned=None):
    """Generator: ``best`` (candidate, h, cost, error), the a-priori choice under a law,
    refined by pilots (module docstring). ``usable``: the fixed candidates;
    ``make_runner()``: made only if a pilot runs, gives ``runner(name, options, h_max,
    ends)``, a generator that runs the method with the law in the loop
    (``engine.law_pilot.LawRunner.run``); ``period``: the control period (s); ``planned``:
    :func:`plans` if already asked. Returns (best, pilot cost s, pilot steps, notes)."""
    T = s.horizon
    planned = plans(s, best, usable) if planned is None else planned
    if not planned:
        return best, 0.0, 0, [NO_PLAN]
    budget = SHARE * best[2]
    least = max(MIN_PERIODS * period, pilot.ROTATIONS * 2 * math.pi / s.omega)
    room = FIRST_ROUND * budget - SETUP - 12 * CALL * len(planned)
    for third in (True, False):  # where the rounding's runs leave no pilot, none of them
        unit = sum(_pilot_cost(s, c, h, 1.0, third) - 12 * CALL for _, _, c, h in planned)
        share = min(1.0, room / unit) if unit > 0 else 1.0
        if share * T >= least:
            break
    if share * T < least or least > T:
        return best, 0.0, 0, [f'none (a pilot over {least:.3g} s would cost over '
                              f'{SHARE:.0%} of the run)']
    runner, H = make_runner(), share * T
    ends = [H * (k + 1) / 4 for k in range(4)]
    spent, steps, notes = SETUP, 0, []
    queue = [(cost, i, c, h, 0, None) for cost, i, c, h in planned]
    while queue:
        queue.sort(key=lambda q: q[:2])
        estimate, i, c, h, rounds, known = queue.pop(0)
        if best[3] <= s.accuracy and not _cheaper(c, estimate, best):
            break  # nothing left can beat the best choice
        cost = _pilot_cost(s, c, h, share, third and known is None)
        if spent + cost > budget:
            notes.append(f'{c.name} h={h:.3g}: over the pilot budget ({budget:.2g} s)')
            continue
        order = s.order(c, h)
        ratio = 2.0 ** order / (2.0 ** order - 1.0)
        a = yield from runner(c.name, (), h, ends)
        b = yield from runner(c.name, (), s.snap(0.5 * h), ends)
        r = (yield from runner(c.name, (), _next_step(s, h), ends)) \
            if third and known is None and _parts(s, c, h) else []
        spent += cost
        if a is None or b is None or r is None:
            notes.append(f'{c.name} h={h:.3g}: failed')
            continue
        steps += a[-1][2] + b[-1][2] + (r[-1][2] if r else 0)
        errors = [pilot.angle(x[1], y[1]) * ratio for x, y in zip(a, b)]
        f = 1.0 - (_next_step(s, h) / h) ** order
        rounding = known or _rounding(s, c, h, _spread(a, b, r, ratio, f) if r else errors,
                                      T, a[-1][0])
        floor = rounding(h)
        err = SAFETY * _extrapolate(errors, T, a[-1][0]) + floor
        notes.append(f'{c.name} h={h:.3g}: E={err:.2g} (rounding {floor:.2g})')
        if err <= s.accuracy:
            if best[3] > s.accuracy or _cheaper(c, s.run_cost(c, h), best):
                best = (c, h, s.run_cost(c, h), err)
            # far under: a longer step (by h^p, the rounding as at h), piloted again
            h_up = min(s.cap(c, True), s.snap(h * 0.9 * (
                (s.accuracy - floor) / max(err - floor, 1e-300)) ** (1.0 / order)))
            if rounds < 1 and h_up >= VERIFY_SHRINK * h:
                queue.append((s.run_cost(c, h_up), i, c, h_up, rounds + 1, rounding))
            continue
        room = s.accuracy - floor
        if room <= 0.0 or not math.isfinite(err) or rounds >= 1:
            continue
        h_new = s.snap(h * 0.9 * (room / (err - floor)) ** (1.0 / order))
        e_new = (err - floor) * (h_new / h) ** order + rounding(h_new)
        if h_new * VERIFY_SHRINK <= h:  # far from what was measured: pilot it again
            queue.append((s.run_cost(c, h_new), i, c, h_new, rounds + 1, rounding))
        elif e_new <= s.accuracy and (best[3] > s.accuracy
                                      or _cheaper(c, s.run_cost(c, h_new), best)):
            best = (c, h_new, s.run_cost(c, h_new), e_new)
    notes.append(f'over {H:.3g} s of {T:.3g} s')
    return best, spent, steps, notes


def weigh(s, best, adaptive, make_runner, period):
    """Generator: where nothing promises the budget (``best``, the fixed method's most
    accurate step, predicts more), whether dop853 errs less, and at which rtol, measured:
    over a share H of the run the fixed method runs at h (a), dop853 at its floor
    RTOL_FLOOR (d) and at PROBE (e). e's error is |e − d| over 1 − RTOL_FLOOR/PROBE (d's
    own is RTOL_FLOOR/PROBE of it by dop853's measured law, linear in rtol), extrapolated
    to the run as t^DOP853_GROWTH; dop853's rtol is the one that law puts MARGIN under the
    budget, within [RTOL_FLOOR, PROBE] (:func:`_rtol`). a's error is |a − d| plus d's,
    extrapolated by :func:`_extrapolate` (its rounding as t^1.5), at most its a-priori
    figure (the distance bounds a's error only from above). dop853 is taken where it
    errs less at that rtol and costs less (both costs as the pilot measured them, scaled to
    the run); it promises nothing (its error jumps late in some runs: module docstring),
    so its predicted error stays over the budget. Returns (best, rtol or None, pilot cost
    s, pilot steps, notes)."""
    c, h, cost0, err0 = best
    T = s.horizon
    if not _weighed(s, cost0, adaptive):  # the pilot is paid back only where it switches
        return best, None, 0.0, 0, []
    dop_cost = s.at_tolerance(adaptive, RTOL_FLOOR)[0]
    budget = WEIGH_SHARE * cost0
    probe_cost = s.at_tolerance(adaptive, PROBE)[0]
    unit = s.run_cost(c, h) + dop_cost + probe_cost - 3 * RUN_COST
    least = max(MIN_PERIODS * period, pilot.ROTATIONS * 2 * math.pi / s.omega)
    share = min(1.0, (budget - SETUP - 12 * CALL) / unit) if unit > 0 else 1.0
    if share * T < least or least > T:
        return best, None, 0.0, 0, [f'dop853 not weighed (a pilot over {least:.3g} s would '
                                    f'cost over {WEIGH_SHARE:.0%} of the run)']
    runner, H = make_runner(), share * T
    ends = [H * (k + 1) / 4 for k in range(4)]
    cpu_a, cpu_d, cpu_e = [0.0], [0.0], [0.0]
    a = yield from _timed(runner(c.name, (), h, ends), cpu_a)
    d = yield from _timed(runner(adaptive.name, _rtol_options(s, RTOL_FLOOR), s.max_step,
                                 ends), cpu_d)
    e = yield from _timed(runner(adaptive.name, _rtol_options(s, PROBE), s.max_step, ends),
                          cpu_e)
    spent = SETUP + share * unit + 12 * CALL
    if a is None or d is None or e is None:
        return best, None, spent, 0, ['dop853 not weighed (a pilot run failed)']
    steps = a[-1][2] + d[-1][2] + e[-1][2]
    probe = [pilot.angle(z[1], y[1]) / (1.0 - RTOL_FLOOR / PROBE) for z, y in zip(e, d)]
    rtol, e_dop = _rtol(s, probe, T, e[-1][0])
    # a's error: at most its distance from d plus d's own (dop853's law: RTOL_FLOOR/PROBE
    # of e's). (b, a at h/2, as the reference of both, was dropped: its error, not
    # dop853's, then bounded dop853's, at two thirds of the pilot's CPU: seed 20261125
    # scene 106 ran at rtol 3e-15 where 1e-13 erred 2.5e-11 rad of a 1e-10 budget)
    own = [pilot.angle(x[1], y[1]) + p * RTOL_FLOOR / PROBE for x, y, p in zip(a, d, probe)]
    e_fixed = _extrapolate(own, T, a[-1][0])
    if c.rounding == 'random':
        # at its most accurate step its rounding rules, and a random walk of rounding
        # errors in the rate turns the attitude as t^1.5, beyond the linear law (seed 7
        # scene 158: rk4 at 5.3e-5 s read 1.2e-10 rad by it, 1.1e-9 at the end)
        e_fixed *= math.sqrt(max(1.0, T / a[-1][0]))
    e_fixed = min(e_fixed, err0)  # 191: 1.2e-6 read so, 2.8e-8 a priori, erred 1.9e-9
    room = (f'{MARGIN:g}× under the budget' if e_dop * MARGIN <= s.accuracy * (1 + 1e-9)
            else 'its floor')
    note = (f'measured over {H:.3g} s of {T:.3g} s: {c.name} h={h:.3g} E={e_fixed:.2g}, '
            f'dop853 rtol {PROBE:.0e} E={e_dop * PROBE / rtol:.2g} (by its run at '
            f'{RTOL_FLOOR:.0e}), at rtol {rtol:.2g} E={e_dop:.2g} ({room})')
    if not e_dop < e_fixed:
        return best, None, spent, steps, [note + f'; {c.name} stays']
    # both runs' costs as the pilot measured them, over the whole run: the model read
    # dop853's restarts at the law's instants low (seed 20261125 scenes 60 and 132: taken
    # at a predicted 0.6× rk4's cost, it ran at 1.1–1.3×)
    run = RUN_COST + T * _per_second(rtol, (cpu_d[0] / d[-1][0], cpu_e[0] / e[-1][0]))
    if run >= RUN_COST + cpu_a[0] * T / a[-1][0]:
        return best, None, spent, steps, [note + f'; dop853 no cheaper: {c.name} stays']
    err = max(SAFETY * e_dop, math.nextafter(s.accuracy, math.inf))
    return ((adaptive, s.max_step, run, err), rtol, spent, steps,
            [note + '; dop853 errs less: taken, a measured guess, not a promise'])


def _rtol(s, errors, horizon, reached):
    """(rtol, its error rad over the run): dop853's rtol in [RTOL_FLOOR, PROBE] whose error,
    linear in rtol from ``errors`` (at PROBE, at the pilot's quarters, which reached
    ``reached`` s) grown as t^DOP853_GROWTH to ``horizon``, is MARGIN under the budget."""
    at_probe = max(errors) * max(1.0, horizon / reached) ** DOP853_GROWTH
    if not math.isfinite(at_probe):
        return RTOL_FLOOR, math.inf
    rtol = PROBE if at_probe <= 0.0 else \
        min(PROBE, max(RTOL_FLOOR, PROBE * s.accuracy / (MARGIN * at_probe)))
    return rtol, at_probe * rtol / PROBE


def _per_second(rtol, measured):
    """dop853's CPU s per simulated second at ``rtol``: log-linear in rtol between its two
    pilot runs' (``measured``: at RTOL_FLOOR and at PROBE)."""
    floor, probe = measured
    if floor <= 0.0 or probe <= 0.0:
        return max(floor, probe)
    x = math.log(rtol / RTOL_FLOOR) / math.log(PROBE / RTOL_FLOOR)
    return math.exp((1.0 - x) * math.log(floor) + x * math.log(probe))


def _weighed(s, cost, adaptive):
    """Whether dop853 (``adaptive``, None where none applies) is weighed against a fixed
    choice costing ``cost`` s: where its cost at RTOL_FLOOR is WEIGH_GAIN× below."""
    return adaptive is not None and \
        s.at_tolerance(adaptive, RTOL_FLOOR)[0] * WEIGH_GAIN < cost


def _adaptive(s):
    """The adaptive candidate :func:`weigh` is given (``selection``: the first that applies
    under a law alone), or None."""
    found = applicable(True, s.damping, False)[1]
    return found[0] if found else None


def _timed(work, cpu):
    """Generator: ``work``'s, its CPU (s, between its yields) added into ``cpu[0]``."""
    start = time.process_time()
    try:
        while True:
            next(work)
            cpu[0] += time.process_time() - start
            yield
            start = time.process_time()
    except StopIteration as done:
        cpu[0] += time.process_time() - start
        return done.value


def _rtol_options(s, rtol):
    """dop853's options at ``rtol``, as :func:`.answers.options` gives them."""
    return (('rtol', rtol), ('atol', rtol * 1e-3 * min(1.0, s.G)))


def _cheaper(c, cost, best):
    """Whether c at ``cost`` beats ``best`` (geometric methods preferred, as
    :func:`.pilot_search.better`)."""
    return cost * (1.0 if c.geometric else 1.0 + PREFER) < \
        best[2] * (1.0 if best[0].geometric else 1.0 + PREFER)
