"""The one interface every integrator has (cf. scipy.integrate.OdeSolver).

An integrator advances the principal-frame state (q, m) of one body or a batch
(q: (..., 4), m: (..., 3)) by a step h, with a body torque τ (principal frame) held
constant over the step (zero-order hold). Methods differ only in ``_step``.
"""
from dataclasses import dataclass
from typing import Callable, ClassVar, FrozenSet, Mapping, Optional, Tuple

import math

import numpy as np

from ..dynamics import Dynamics
from ..integration_error import IntegrationError  # noqa: F401 - its home for the registry


@dataclass(frozen=True)
class Candidate:
    """A method's facts for ``integrator: auto`` (its class's ``auto``; None: auto never
    picks it). ``name`` and ``stages`` come from the class (``auto.model.CANDIDATES``).

    cost: CPU µs per step (compiled loops; only ratios matter), free and with weak
        dissipation (inside the compositions); stiff double-bracket damping outside a
        composition adds DAMP_SUBSTEP per substep. Measured on a 2-core AMD EPYC by
        ``python -m rigid_body_sim.tools.candidate_costs``, which flags a ratio gone stale
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
        is stiff (it was chosen when it ran event by event in the engine's closed loop;
        the compiled loop now runs it with its own damping code, ``loop_model``).
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
    rounding: 'systematic' (exact axis rotations: the same rotation rounds alike every
        step, ROUNDOFF·stages·N·ΩT, above) or 'random' (a polynomial step: its rounding
        errors do not line up, so they add as a random walk, ROUNDOFF_RANDOM·stages·√N·ΩT;
        ``auto.model``, under a control law: ``RunModel.roundoff``).
    torque: (k₁, k₂) the error constants under a control law (the 'torque' kind: a held
        torque re-set at every control instant, no environment torques), measured on
        generated detumble scenes: E ≤ k₁·(hΩ)^p·ΩT + k₂·(hΩ)^(p+1)·(ΩT)² (k₂: an energy
        drift ∝ h^(p+1), RK4's: its amplification |R(ihω)|² = 1 − (hω)⁶/72 per step), in
        place of ``k`` and ``growth``, which are worst cases of free bodies over 30 turns
        and over-read such runs 10²–10⁵×; the controlled runs take the a-priori choice (no
        pilot), so this is where it counts. None: ``k`` and ``growth`` there too.
    """
    cost: Tuple[float, float]
    k: float
    call: Tuple[float, float] = (2.5, 2.5)
    growth: str = 'linear'
    stability: float = math.inf
    stiff_only: bool = False
    exact_damping: bool = False
    supersedes: str = ''
    coupled_only: bool = False
    geometric: bool = True
    adaptive: bool = False
    name: str = ''
    stages: float = 0.0
    environment: bool = False  # the class's ``environment``: auto asks it with those torques
    environment_evals: float = 0.0  # the class's ``environment_evaluations`` (its cost there)
    rounding: str = 'systematic'
    torque: Optional[Tuple[float, float]] = None


# The kinds of dynamics a method's order is stated for (``Integrator.orders``), as the tests
# measure them: free rotation, each dissipation model (weak: λh ≪ 1), a held torque.
KINDS = ('torque_free', 'double_bracket', 'viscous', 'torque')


def same_order(order: int) -> dict:
    """``orders`` of a method whose order is the same on every kind of dynamics."""
    return dict.fromkeys(KINDS, order)


# Names of invariants a method may keep exactly (to round-off) in free rotation.
PRESERVES = ('angular_momentum_norm', 'kinetic_energy', 'unit_quaternion', 'poisson',
             'time_reversible')


class Integrator:
    """Base class. Subclasses set the class attributes and implement ``_step``.

    Attributes:
        name: registry key.
        order: classical order of accuracy (for the free rigid body).
        implicit: solves equations each step.
        adaptive: chooses its own internal steps (h is then an output interval).
        preserves: invariants kept exactly in torque-free motion (see PRESERVES).
        stability: known stability limit, in words.
        orders: the order per kind of dynamics (see KINDS) as the tests measure it; None
            where the method has no stepping error (exact, torque-free) or does not apply.
        stages: sub-steps per step (evaluations of an explicit method, stages of a
            composition): auto's round-off weight (0: exact and dop853, modelled otherwise).
        amplification: the stability function R(z) of a linear method (explicit Runge–Kutta),
            None for the others (``stability.py`` checks steps against it).
        loop_code: the method's code in the engine's compiled closed loop
            (``engine/closed_loop.py``), None if it runs event by event there.
        auto: its :class:`Candidate` facts for ``integrator: auto`` (cost per step, error
            constant, …), None if auto never picks it.
        requires_actuators: it advances a body's wheels/CMGs with it (``gyrostat.py``), so
            it runs only in a scene with actuators, given as the ``actuators`` option;
            sites iterating the registry skip it elsewhere.
        kernel_modules: modules of its compiled loops, each with ``warm()``
            (``rigid_body_sim.compiled.warm`` warms the registry's).
        environment: it integrates the environment's torques (the gravity gradient along
            the orbit, ``Dynamics.environment``) for one body: a term of its right-hand
            side (Runge–Kutta, dop853) or a kick at fixed attitude at the kick's instant
            (the splittings). Built on a dynamics with them, the others refuse.
        environment_evaluations: evaluations of the environment's torques per step (the
            kicks of a splitting, the stages of a Runge–Kutta method, dop853's per own
            step): with the gravity gradient each costs several times a free step
            (Kepler's equation and the orbit's rotation), so auto's cost model counts them.
        nfev: right-hand-side evaluations (or equivalent sub-flows) so far.
    """
    name: ClassVar[str] = ''
    order: ClassVar[int] = 0
    implicit: ClassVar[bool] = False
    adaptive: ClassVar[bool] = False
    preserves: ClassVar[FrozenSet[str]] = frozenset()
    stability: ClassVar[str] = ''
    orders: ClassVar[Mapping[str, Optional[int]]] = {}
    stages: ClassVar[float] = 0.0
    amplification: ClassVar[Optional[Callable]] = None
    loop_code: ClassVar[Optional[int]] = None
    auto: ClassVar[Optional[Candidate]] = None
    requires_actuators: ClassVar[bool] = False
    kernel_modules: ClassVar[tuple] = ()
    environment: ClassVar[bool] = False
    environment_evaluations: ClassVar[float] = 0.0

    def __init__(self, dynamics: Dynamics, **options):
        if options:
            raise TypeError(f'{self.name} takes no options {sorted(options)}')
        if dynamics.environment_active and not self.environment:
            what = 'the gravity-gradient torque' if dynamics.gravity_gradient else \
                'the environment\'s torques'
            raise ValueError(f'integrator {self.name} does not integrate {what} '
                             f'({dynamics.environment_terms}); use auto or a splitting, '
                             'rk4, euler or dop853')
        self.dynamics = dynamics
        self.nfev = 0

    def _one_body_only(self, q, t):
        """IntegrationError if a batch (q (..., 4), N > 1 bodies) meets the environment's
        torques: only the one-body loops evaluate them."""
        if np.ndim(q) > 1 and self.dynamics.environment_active:
            raise IntegrationError(self.name, 0.0, t, 'the environment\'s torques (gravity '
                                   'gradient, rods, SRP, drag) are integrated for one body at '
                                   'a time, not a batch')

    def step(self, q, m, h: float, torque: Optional[np.ndarray] = None, t: float = 0.0):
        """Advance (q, m) by h seconds; returns new arrays. Raises IntegrationError."""
        if not (np.isfinite(h) and h > 0.0):
            raise IntegrationError(self.name, h, t, 'step must be finite and positive')
        q_new, m_new = self._step(np.asarray(q, float), np.asarray(m, float), float(h),
                                  None if torque is None else np.asarray(torque, float), t)
        if not (np.all(np.isfinite(m_new)) and np.all(np.isfinite(q_new))):
            raise IntegrationError(self.name, h, t,
                                   'state became non-finite (the method diverged)')
        return q_new, m_new

    def _step(self, q, m, h, torque, t):
        raise NotImplementedError

    def effective_order(self, m, h) -> int:
        """The order on this dynamics at step h for one body's momentum m (measured by the
        tests per kind of scene): :meth:`order_on` at |m|."""
        x, y, z = (float(v) for v in m)
        return self.order_on(self.dynamics, math.sqrt(x * x + y * y + z * z), h)

    @classmethod
    def order_on(cls, dynamics: Dynamics, momentum_norm: float, h: float) -> int:
        """The order on ``dynamics`` at step h for |m| = ``momentum_norm``, asked without
        an instance (``auto`` asks it per candidate and step): ``orders`` for the
        dissipation model (torque-free without one). Methods whose order depends on the
        damping's stiffness override this."""
        d = dynamics.dissipation
        return cls.orders.get(d.model if d.active else 'torque_free') or cls.order

    def run(self, q, m, h: float, n: int, torque: Optional[np.ndarray] = None, t0: float = 0.0):
        """``n`` steps of ``h`` from (q, m) at time t0; new arrays. Methods with a compiled
        loop (``integrators/*_kernel.py``) override this for one body; IntegrationError names the
        step and time where the state stopped being finite."""
        for k in range(n):
            q, m = self.step(q, m, h, torque, t0 + k * h)
        return q, m

    def _run_kernel(self, kernel, q, m, h, n, torque, t0):
        """Shared shell of the compiled loops: copies in, checks, failure with its time."""
        if not (math.isfinite(h) and h > 0.0):
            raise IntegrationError(self.name, h, t0, 'step must be finite and positive')
        q = np.array(q, dtype=float)
        m = np.array(m, dtype=float)
        tau = np.zeros(3) if torque is None else np.array(torque, dtype=float).reshape(3)
        failed = kernel(q, m, float(h), int(n), tau, torque is not None, float(t0))
        if failed >= 0:
            raise IntegrationError(self.name, h, t0 + (failed + 1) * h,
                                   'state became non-finite (the method diverged)')
        return q, m

    def reset(self):
        """Forget any state carried between steps (caches, solver warm starts)."""

    def loop_spec(self):
        """(weights, split_axes) of this method's compiled one-body loop for kernels that
        drive it themselves (the engine's compiled closed loop), or None if it has none."""
        return None

    def loop_model(self) -> int:
        """The dissipation code its compiled loop runs (``dynamics_kernel.MODEL_CODES``; 0:
        none): the dynamics' own unless the method takes the damping another way."""
        from .. import dynamics_kernel
        d = self.dynamics.dissipation
        return dynamics_kernel.MODEL_CODES[d.model] if d.active else 0

    def loop_memory(self):
        """(memory, rtol, atol) of a method whose compiled loop carries its step in progress
        from call to call (``dop853_dense.advance``), None for the others."""
        return None

    @classmethod
    def describe(cls) -> dict:
        return {'name': cls.name, 'order': cls.order, 'implicit': cls.implicit,
                'adaptive': cls.adaptive, 'preserves': sorted(cls.preserves),
                'stability': cls.stability, 'summary': (cls.__doc__ or '').strip().splitlines()[0]}
