"""auto's per-kind candidate facts (physics/auto/kinds.py), kept once per process: each
answers as asking every candidate of the run would, and follows what differs between runs
of one kind (the damping's stiffness, the costs in use). test_selection_identity checks
the choices they lead to on 400 scenes."""
import numpy as np
import pytest

from rigid_body_sim.physics.auto import CANDIDATES, calibration, kinds
from rigid_body_sim.physics.auto.model import RunModel
from rigid_body_sim.physics.dynamics import Dissipation, Dynamics

pytestmark = pytest.mark.fast

MOMENTS = np.array([0.04, 0.15, 0.2])
M = np.array([2.5, 0.04, 0.0])


def _asked_one_by_one(s, torque, environment):
    """The usable and adaptive candidates as the selection asked them before kinds.py."""
    usable = [c for c in CANDIDATES if s.applicable(c, torque)
              and (c.environment or not environment)]
    adaptive = [c for c in usable if c.adaptive]
    usable = [c for c in usable if not c.adaptive]
    if not torque:
        superseded = {c.supersedes for c in usable}
        usable = [c for c in usable if c.name not in superseded]
    return usable, adaptive


def _kind(s, torque, environment):
    fixed, _ = kinds.applicable(torque, s.damping, environment)
    return torque, s.damping, environment, tuple(s.stiff_enough(c) for c, decides in fixed
                                                if decides)


def _kept(s, torque, environment):
    return (list(kinds.usable(*_kind(s, torque, environment))),
            list(kinds.applicable(torque, s.damping, environment)[1]))


@pytest.mark.parametrize('torque', [False, True])
@pytest.mark.parametrize('environment', [False, True])
@pytest.mark.parametrize('model,coefficients', [
    ('none', [0.0]), ('double_bracket', [1e-6, 1e-2, 1e3]), ('viscous', [1e-4, 1.0, 1e4])])
def test_the_kept_facts_are_what_asking_each_candidate_gives(torque, environment, model,
                                                            coefficients):
    """From damping far too weak to make an A-stable method pay to stiff damping, where
    under torque it does: the same candidates, in the registry's order."""
    stiff_seen = set()
    for coefficient in coefficients:
        dyn = Dynamics(MOMENTS, Dissipation(model, coefficient))
        s = RunModel(dyn, None, M, 1e-6, 100.0, 0.01, 0.5 if torque else 0.0)
        assert _kept(s, torque, environment) == _asked_one_by_one(s, torque, environment)
        stiff_seen.update(_kind(s, torque, environment)[3])
    if model == 'double_bracket' and torque:
        # both sides of the stiffness test were asked (splitting2_lstable's; implicit
        # midpoint's largest step keeps h·stiffness < 1 on every scene: never enough)
        assert stiff_seen == {False, True}


def test_the_least_costs_are_those_of_the_costs_in_use():
    """Kept per kind and per costs: a run with other costs (another calibration) reads its
    own least cost per step and per event, not the first run's."""
    dyn = Dynamics(MOMENTS, Dissipation('double_bracket', 1e-6))
    own = RunModel(dyn, None, M, 1e-6, 100.0, 0.01, 0.0)
    kind = _kind(own, False, False)
    usable = kinds.usable(*kind)
    cheap = calibration.Costs(per_step={c.name: (0.01, 0.02) for c in CANDIDATES},
                              event=0.05)
    other = RunModel(dyn, None, M, 1e-6, 100.0, 0.01, 0.0, costs=cheap)
    assert _kind(other, False, False) == kind
    for s in (own, other, own, other):  # each twice: the kept figure as the first
        per_step, event = kinds.least(s, kind)
        assert per_step == min(min(s.costs.cost(c)) for c in usable)
        assert event == min(s.per_event(c) for c in usable)
    assert kinds.least(other, kind) != kinds.least(own, kind)


def test_environment_terms_are_costed_per_run():
    """With environment torques the least cost per step includes their evaluations, which
    differ between runs of one kind: computed per run, not kept."""
    dyn = Dynamics(MOMENTS, Dissipation('double_bracket', 1e-6))
    s = RunModel(dyn, None, M, 1e-6, 100.0, 0.01, 0.5, environment=('gravity gradient',))
    kind = _kind(s, True, True)
    usable = kinds.usable(*kind)
    per_step, _ = kinds.least(s, kind)
    assert per_step == min(min(s.costs.cost(c)) + s.term_cost * c.environment_evals
                           for c in usable) > min(min(s.costs.cost(c)) for c in usable)


@pytest.mark.parametrize('commanded', [False, True])
@pytest.mark.parametrize('environment', [(), ('gravity gradient',)])
@pytest.mark.parametrize('model,coefficients', [
    ('none', [0.0]), ('double_bracket', [1e-6, 1e3]), ('viscous', [1e-4, 1e4])])
def test_one_lookup_per_kind_answers_as_each_question(commanded, environment, model,
                                                      coefficients):
    """kinds.kind_of and by_stiff (the selection's one lookup) give what the kind's
    separate questions give, for each answer of the stiffness the runs ask, and keep each
    answer in the kind."""
    torque = commanded or bool(environment)
    for coefficient in coefficients:
        dyn = Dynamics(MOMENTS, Dissipation(model, coefficient))
        s = RunModel(dyn, None, M, 1e-6, 100.0, 0.01, 0.5 if torque else 0.0)
        k = kinds.kind_of(commanded, s.damping, environment)
        assert k is kinds.kind_of(commanded, s.damping, environment)
        env = bool(environment)
        assert (k.torque, k.damping, k.environment) == (torque, s.damping, env)
        assert k.adaptive == kinds.applicable(torque, s.damping, env)[1]
        assert k.deciding == kinds.deciding(torque, s.damping, env)
        assert k.effects == kinds.effects(commanded, s.damping, environment)
        kind = _kind(s, torque, env)
        stiff = kind[3]
        assert stiff == tuple(map(s.stiff_enough, k.deciding))
        found = k.stiff.get(stiff) or kinds.by_stiff(k, stiff)
        usable = kinds.usable(*kind)
        assert found == (usable, tuple(c for c in usable if np.isfinite(c.k)),
                         kinds.finite_names(*kind), kinds.split_exact(*kind))
        assert k.stiff[stiff] is found


def test_without_damping_a_candidates_order_is_its_classs_at_any_step_and_momentum():
    """RunModel.order keeps the undamped order per candidate for the process
    (model.FREE_ORDERS): it holds only while Integrator.order_on depends on the step and
    |m| through the damping alone, which this checks for every registered candidate."""
    from rigid_body_sim.physics.integrators import get_integrator
    for c in CANDIDATES:
        seen = set()
        for moments in (MOMENTS, np.array([0.2, 0.2, 0.04]), np.array([1.0, 2.0, 3.0])):
            dyn = Dynamics(moments, Dissipation('none', 0.0))
            for norm in (1e-3, 2.5, 1e3):
                for h in (1e-4, 0.02, 1.0, 1e3):
                    seen.add(get_integrator(c.name).order_on(dyn, norm, h))
        assert len(seen) == 1, c.name
        s = RunModel(Dynamics(MOMENTS, Dissipation('none', 0.0)), None, M, 1e-6, 100.0,
                     0.01, 0.5)
        assert s.order(c, 0.01) == s.order(c, 1e-5) == seen.pop()
    # damped, the order may depend on the step (a composition with the damping outside)
    dyn = Dynamics(MOMENTS, Dissipation('double_bracket', 1e3))
    s = RunModel(dyn, None, M, 1e-6, 100.0, 1.0, 0.0)
    orders = {s.order(c, h) for c in CANDIDATES if c.name == 'splitting4'
              for h in (1e-9, 1.0)}
    assert orders == {2, 4}
