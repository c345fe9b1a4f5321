"""Adaptive DOP853, the high-accuracy reference method: compiled for one body, scipy's
solve_ivp for a batch."""
from typing import NamedTuple

import numpy as np

from .. import dynamics_kernel
from . import dop853_dense, dop853_kernel
from .base import Candidate, IntegrationError, Integrator, same_order

_UNUSED_WEIGHTS, _UNUSED_AXES = np.ones(1), np.array([0, 2, 1])


class SampleCost(NamedTuple):
    """What samples add to a run of a method beyond its unsampled steps, for ``auto`` to
    weigh a run's sample rate (it does not read it yet). CPU in units of the method's own
    step (``auto.cost``), measured in the same run, so the ratios hold across machines.

    per_sample: each sample (the interpolant evaluated and its row written).
    per_sampled_step: each step holding at least one sample (the interpolant built).
    evaluations: right-hand-side evaluations per step holding a sample (counted in nfev)."""
    per_sample: float
    per_sampled_step: float
    evaluations: int


class DOP853(Integrator):
    """Dormand–Prince 8(5,3), adaptive with rtol/atol; continues across output steps.

    Options: rtol (default 1e-10), atol (default 1e-12). One body runs the compiled kernel
    (``physics.dop853_dense``: scipy's method, same steps, dense output): ``run``/``step``
    return the state at the end of the interval, and consecutive calls continue one
    integration of natural steps — an end inside a step is interpolated (7th order, as
    scipy's dense output), so outputs cost 3 evaluations per step that has any, not a
    clipped step each. A torque change restarts from the returned state keeping the step
    size; any other input state, or ``reset``, starts afresh. q is returned normalised.
    A batch is one system for scipy's solve_ivp, restarted each step.
    """
    name = 'dop853'
    order = 8
    orders = same_order(8)
    stages = 0.0  # auto bounds its error per rtol (auto.model.DOP853_*), round-off included
    # cost: µs per step (12 evaluations), in the table's EPYC units: 5.0–5.1× splitting2's
    # free step, free and damped, rtol 1e-6–1e-13 (a natural-step run, measured against
    # splitting2 on an Intel Xeon; calibration.measure agrees). It was 1.2/1.3, 2.7× too
    # dear, which kept auto off dop853 where it was the cheapest. k: see auto.model.DOP853_*
    auto = Candidate((0.47, 0.48), 2.0, call=(3.0, 3.0), growth='drift', adaptive=True,
                     coupled_only=True, geometric=False)
    # samples: a step holding any builds the 7th-order interpolant (3 evaluations and the
    # 4x16 product, once however many samples it holds); each sample evaluates it. A
    # run's extra CPU is then per_sample·samples + per_sampled_step·min(samples, steps)
    # steps: ~3 samples a step (a fast body at 100 samples/s) nearly doubles the run, 100
    # a step adds ~2 steps' worth per step. Measured on the generated scenes (seed
    # 20261125, dop853 at 1 and 100 samples/s in one process, least of 9; the data in
    # the notes of ``python -m rigid_body_sim.bench.sampling``'s dop853 rows): 0.74-0.85
    # a sampled step on scenes of ~1 sample a step, 0.010-0.03 a sample on scenes of ~100
    # (the rows' first-touch page faults, ~2 µs a 4 KB page on a loaded 2-core VM, add
    # up to ~0.04 in a fresh process)
    sample_cost = SampleCost(per_sample=0.02, per_sampled_step=0.8, evaluations=3)
    loop_code = 3  # dop853_dense.advance from the closed loop, its memory carried along
    kernel_modules = (dop853_kernel, dop853_dense)
    environment = True  # a term of the right-hand side, at each stage's instant
    environment_evaluations = 12  # per own step (13 stages, the first reused)
    adaptive = True
    stability = 'adaptive; step shrinks under stiff dissipation (cost grows with stiffness)'

    def __init__(self, dynamics, rtol: float = 1e-10, atol: float = 1e-12):
        super().__init__(dynamics)
        if not (rtol > 0 and atol > 0):
            raise ValueError('dop853 needs rtol > 0 and atol > 0')
        self.rtol, self.atol = float(rtol), float(atol)
        d = dynamics.dissipation
        self._model = dynamics_kernel.MODEL_CODES[d.model] if d.active else 0
        self._coefficient = d.coefficient
        self._moments = np.array(dynamics.moments, dtype=float)
        self._zero = np.zeros(3)
        # the kernel's memory between calls: the step in progress, its interpolant, the
        # last output and torque (dop853_dense.advance)
        self._memory = np.zeros(dop853_dense.MEMORY)
        self.reset()

    def reset(self):
        self._memory[:] = 0.0  # no step in progress, no step proposed: afresh

    def loop_spec(self):
        return _UNUSED_WEIGHTS, _UNUSED_AXES  # the closed loop's splitting arguments

    def loop_memory(self):
        """The kernel's memory (written in place by the closed loop, as by ``run``)."""
        return self._memory, self.rtol, self.atol

    def run(self, q, m, h, n, torque=None, t0=0.0):
        """One body: one integration over n·h (h is an output interval, not a step)."""
        if np.ndim(q) != 1 or np.ndim(m) != 1:
            self._one_body_only(q, t0)
            return super().run(q, m, h, n, torque, t0)
        if not (np.isfinite(h) and h > 0.0):
            raise IntegrationError(self.name, h, t0, 'step must be finite and positive')
        return self._advance(q, m, h * n, torque, t0)

    def _step(self, q, m, h, torque, t):
        if q.ndim == 1 and m.ndim == 1:
            return self._advance(q, m, h, torque, t)
        self._one_body_only(q, t)
        return self._scipy_step(q, m, h, torque, t)

    def _advance(self, q, m, span, torque, t0):
        q = np.array(q, dtype=float)  # fresh arrays: the kernel writes the result into them
        m = np.array(m, dtype=float)
        tau = self._zero if torque is None else np.asarray(torque, dtype=float).reshape(3)
        status, t, h, nfev = dop853_dense.advance(q, m, float(span), tau, self._memory,
                                                  self._moments, self._model,
                                                  self._coefficient, self.rtol, self.atol,
                                                  float(t0), self.dynamics.environment)
        self.nfev += nfev
        if status != dop853_kernel.OK:
            self.reset()  # the state is garbage: start afresh next time
            raise IntegrationError(self.name, h if h > 0.0 else span, t0 + t,
                                   dop853_kernel.REASONS[status])
        return q, m

    def _scipy_step(self, q, m, h, torque, t):
        shape_q, shape_m = q.shape, m.shape
        nq = q.size
        dyn = self.dynamics

        def rhs(_, y):
            qq = y[:nq].reshape(shape_q)
            mm = y[nq:].reshape(shape_m)
            return np.concatenate((dyn.attitude_rate(qq, mm).ravel(),
                                   dyn.momentum_rate(mm, torque).ravel()))

        from scipy.integrate import solve_ivp  # batches only: not at every process's start
        sol = solve_ivp(rhs, (0.0, h), np.concatenate((q.ravel(), m.ravel())), method='DOP853',
                        rtol=self.rtol, atol=self.atol)
        self.nfev += sol.nfev
        if not sol.success:
            raise IntegrationError(self.name, h, t, sol.message)
        y = sol.y[:, -1]
        q_new = y[:nq].reshape(shape_q)
        return q_new / np.linalg.norm(q_new, axis=-1, keepdims=True), y[nq:].reshape(shape_m)
