"""What a run of one kind may ask of the registry's candidates, kept once per process.

A kind is what a run's selection asks the candidates by, before any figure of the run:
commanded or environment torque, the dissipation model, environment torques at all; and,
for the A-stable candidates, whether the dissipation is stiff at their steps. The answers
are facts of the registry (``Candidate``) and of the costs in use, the same for every run
of the kind: asked per selection they were a quarter of a short run's (Explorer 1 over
1-100 s, whose selection must stay within a tenth of its run). No choice is kept here:
each run's figures (its time scales, steps, errors and costs) are its own.
"""
import functools
import math
from typing import NamedTuple

from ..integrators import AUTO_CANDIDATES as CANDIDATES  # model.CANDIDATES
from ..integrators import get_integrator


# the candidates' orders without dissipation, by name (RunModel.order): Integrator.order_on
# depends on the step and |m| only through the damping's stiffness (its contract:
# test_auto_kinds), so without damping each is its class's; asked per run they were ~10
# calls of a controlled run's choosing (the registry, order_on, the dissipation's active)
FREE_ORDERS = {}


def applicability(c, torque: bool, damping):
    """Whether c applies to a run with (``torque``) or without commanded or environment
    torque, under ``damping`` (the dissipation model, None without): True, False, or None
    where the dissipation's stiffness decides (:meth:`RunModel.stiff_enough`)."""
    if c.adaptive:  # its restarts at control instants are in its cost (tolerance)
        return bool(torque or damping is not None)
    if c.coupled_only and not (torque or damping):
        return False
    if c.exact_damping:
        if damping != 'double_bracket':
            return False
        if not torque:
            return True
    elif not c.stiff_only:
        return True
    return None  # A-stability only pays off where the dissipation is stiff at the step


@functools.lru_cache(maxsize=None)
def applicable(torque: bool, damping, environment: bool):
    """((candidate, whether the dissipation's stiffness decides), …) of the step-based
    candidates, and (candidate, …) of the adaptive ones, that apply to a run of this kind
    (:func:`applicability`), in the registry's order: facts of the registry, once
    per kind (asking each candidate per selection was a tenth of a short run's)."""
    kinds = [(c, applicability(c, torque, damping)) for c in CANDIDATES
             if c.environment or not environment]
    return (tuple((c, kind is None) for c, kind in kinds if not c.adaptive and kind is not False),
            tuple(c for c, kind in kinds if c.adaptive and kind))


@functools.lru_cache(maxsize=None)
def deciding(torque: bool, damping, environment: bool) -> tuple:
    """The step-based candidates of :func:`applicable` whose use the dissipation's stiffness
    decides (``RunModel.stiff_enough``), in its order: what a kind's ``stiff`` answers."""
    return tuple(c for c, decides in applicable(torque, damping, environment)[0] if decides)


@functools.lru_cache(maxsize=None)
def usable(torque: bool, damping, environment: bool, stiff: tuple) -> tuple:
    """The step-based candidates a run of this kind asks (:func:`applicable`), ``stiff``
    saying for each one whose dissipation's stiffness decides whether it is stiff enough
    (``RunModel.stiff_enough``); without torque, none another one supersedes
    (``Candidate.supersedes``)."""
    decided = iter(stiff)
    usable = [c for c, decides in applicable(torque, damping, environment)[0]
              if not decides or next(decided)]
    if not torque:
        superseded = {c.supersedes for c in usable}
        usable = [c for c in usable if c.name not in superseded]
    return tuple(usable)


@functools.lru_cache(maxsize=None)
def finite_names(torque: bool, damping, environment: bool, stiff: tuple) -> tuple:
    """The names of the :func:`usable` candidates with an a-priori bound (a finite k): the
    ones a run of this kind could ask a priori (named where none is asked)."""
    return tuple(c.name for c in usable(torque, damping, environment, stiff)
                 if math.isfinite(c.k))


# (kind, the costs' id, the event's cost) → (the costs, kept so that their id stays theirs;
# the least µs per step and s per event of the kind's usable candidates)
_LEAST = {}


def least(s, kind: tuple):
    """(µs, s): the least cost per step and per event of any of the usable candidates of
    ``kind`` (the arguments of :func:`usable`) on the run ``s`` (RunModel.costs,
    .per_event). Without environment torques they are the same for every run of the kind
    and costs, so kept (a loop over the candidates was a fifth of Explorer 1's selection);
    with them the terms' cost is the run's own."""
    key = (kind, id(s.costs), s.event)
    known = _LEAST.get(key) if not s.term_cost else None
    if known is not None and known[0] is s.costs:
        return known[1]
    cost, term, per_event = s.costs.cost, s.term_cost, s.per_event
    per_step = event = math.inf  # loops: a generator per min is dearer
    for c in usable(*kind):
        x = min(cost(c)) + term * c.environment_evals
        per_step = x if x < per_step else per_step
        x = per_event(c)
        event = x if x < event else event
    if not s.term_cost:
        _LEAST[key] = (s.costs, (per_step, event))
    return per_step, event


@functools.lru_cache(maxsize=None)
def split_exact(torque: bool, damping, environment: bool, stiff: tuple) -> tuple:
    """The :func:`usable` candidates of a kind whose free flow is exact
    (:func:`free_flow_exact`), in its order."""
    exact = free_flow_exact()
    return tuple(c for c in usable(torque, damping, environment, stiff) if c.name in exact)


@functools.lru_cache(maxsize=None)
def effects(commanded: bool, damping, environment: tuple) -> str:
    """What the model holds besides the free body, for the reason: commanded torque,
    ``damping`` (the dissipation model, None without) and the environment's torques."""
    parts = ['commanded torque'] if commanded else []
    if damping is not None:
        parts.append(damping + ' dissipation')
    parts.extend(environment)
    return ' + '.join(parts)


@functools.lru_cache(maxsize=None)
def free_flow_exact() -> frozenset:
    """The candidates whose free flow has no stepping error (``orders['torque_free']``
    None: exact), so that under dissipation alone only their splitting with the damping
    errs (once: a registry lookup per candidate is a share of a short run's selection)."""
    return frozenset(c.name for c in CANDIDATES
                     if get_integrator(c.name).orders.get('torque_free', 0) is None)


class Kind(NamedTuple):
    """What a run of one kind asks, in one lookup (:func:`kind_of`): its torque (commanded
    or environment), dissipation model and environment torques at all, the adaptive
    candidates that apply (:func:`applicable`), the step-based ones whose stiffness decides
    (:func:`deciding`), what the model holds for the reason (:func:`effects`), and per
    answer of the stiffness (``stiff``, the argument of :func:`usable`): (usable, those with
    an a-priori bound, their names, split exact), filled by :func:`by_stiff`."""
    torque: bool
    damping: object
    environment: bool
    adaptive: tuple
    deciding: tuple
    effects: str
    stiff: dict


@functools.lru_cache(maxsize=None)
def kind_of(commanded: bool, damping, environment: tuple) -> Kind:
    """The :class:`Kind` of a run with (``commanded``) or without commands, under
    ``damping`` (the dissipation model, None without) and the environment's torques named
    in ``environment``: one lookup where a selection asked six (each a share of a short
    run's choosing: Explorer 1 over 1 s, callgrind)."""
    torque, env = commanded or bool(environment), bool(environment)
    return Kind(torque, damping, env, applicable(torque, damping, env)[1],
                deciding(torque, damping, env), effects(commanded, damping, environment), {})


def by_stiff(kind: Kind, stiff: tuple) -> tuple:
    """(:func:`usable`, those of them with a finite k, :func:`finite_names`,
    :func:`split_exact`) of ``kind`` with the stiffness answers ``stiff``, kept in the kind
    (a caller asks ``kind.stiff`` first)."""
    key = kind.torque, kind.damping, kind.environment, stiff
    fixed = usable(*key)
    found = kind.stiff[stiff] = (fixed, tuple(c for c in fixed if math.isfinite(c.k)),
                                 finite_names(*key), split_exact(*key))
    return found
