"""How the engine advances its state between two events: the event path's equal steps
(``_integrate``; with an anchored orbit, ``_anchor_orbit``), the torque-free exact flow from
an anchor (``_free_exact``, ``_anchored``) and its grid of many samples at once
(``_free_samples``), and the stretches of many events in the compiled closed loop
(``_advance_compiled``: ``closed_loop_args`` packs the kernel's arguments and takes its
results back).

A mixin of :class:`~rigid_body_sim.engine.core.Engine`: these are the engine's own methods,
kept apart for the module's size (as ``method_choice``). They read and write the engine's
state like any other of its methods; :meth:`Engine.advance` decides which runs when.
"""
import math

import numpy as np

from ..physics import IntegrationError
from ..physics.exact import TorqueFreeSolution
from ..physics.orbit import OrbitError
from . import closed_loop_args, sample_kernel
from .config import NS


class Stepping:
    """The engine's stepping between events (see the module docstring)."""

    _loop_args = None  # the compiled loop's arguments (closed_loop_args.Packing), reused

    def _anchor_orbit(self, t_ns: int, t_end: int):
        """The osculating conic at the interval's midpoint (its error grows as the square of
        the distance from it) into the dynamics' element array, in place (the integrators
        hold it); an adaptive method starts afresh on it, its steps kept inside the
        interval. IntegrationError with the time and SGP4's code if SGP4 fails."""
        try:
            self.dynamics.environment[:] = self.config.environment.elements(
                (t_ns + t_end) / (2 * NS), self.body.to_principal)
        except OrbitError as exc:
            self.fault = str(exc)
            raise IntegrationError(self.method, self.step_max, exc.t, exc.reason) from None
        if self._integ.adaptive:
            self._integ.reset()

    def _free_exact(self) -> bool:
        return (self.method == 'exact' and self._tau_p is None
                and not self.dynamics.dissipation.active
                and not self.dynamics.environment_active)

    def _anchored(self):
        if self._anchor is None:
            self._anchor = (self.t_ns, TorqueFreeSolution(self.dynamics.moments, self._q, self._m))
        return self._anchor

    def _integrate(self, t_end: int):
        span = t_end - self.t_ns
        if span <= 0:
            return
        if self._free_exact():
            t0, solution = self._anchored()
            self._q, self._m = solution.at((t_end - t0) / NS)
            self.evaluations += 1
            return
        # equal steps no longer than step_max (to 1 ppb: a step given as span/n stays n steps)
        n = max(1, math.ceil(span / (self.step_max * NS) - 1e-9))
        h = span / (n * NS)
        if self.orbit_anchored:
            self._anchor_orbit(self.t_ns, t_end)
        if self.magnetics is not None and self.magnetics.anchor(
                self.dynamics.environment, self.t_ns / NS, t_end / NS, self._aligned) \
                and self._integ.adaptive:
            self._integ.reset()  # its step in progress saw the previous dipole or field
        self._q, self._m = self._integ.run(self._q, self._m, h, n, self._tau_p, self.t_ns / NS)
        self.steps += n

    def _advance_compiled(self, until_ns: int, cap: int) -> int:
        """``closed_loop_args.advance`` from the state; take back what it returns (state, counts,
        rows in the block) and the law's new torque. Rows added; 0 where it does not apply;
        -1 where the block has no room for the next law interval's samples.
        IntegrationError (``fault`` set) if the method failed."""
        mag, first = self.magnetics, self._builder.n
        if mag is not None and mag.anchor(self.dynamics.environment, self.t_ns / NS,
                                          self.t_ns / NS, self._aligned) \
                and self._integ.adaptive:
            self._integ.reset()  # its step in progress saw the previous dipole
        if self._loop_args is None:
            self._loop_args = closed_loop_args.Packing()
        done = closed_loop_args.advance(self, self._state(), self._law, self._builder,
                                        until_ns, cap, self._loop_args)
        if done is None:
            return 0
        if mag is not None and done.rows:  # the stretch ends at the hold's next event
            self._builder.n += done.rows
            self._builder.fill_dipole(first, mag.dipole())
            self._builder.n -= done.rows
        self.steps += done.steps
        self._integ.nfev += done.evaluations
        self._builder.n += done.rows
        if done.error is not None:
            self.fault = done.error.reason
            raise done.error
        s = done.state
        self._q, self._m, self.t_ns, self._next_sample = s.q, s.m, s.t_ns, s.next_sample
        if self._law is not None:
            self._update_torque()
        return -1 if done.full and not done.rows else done.rows

    def _free_samples(self, limit: int, room: int) -> int:
        """Exact flow at many sample instants < ``limit`` at once (vectorised); count added."""
        p = self.config.sample_period_ns
        k = min(room, (limit - 1 - self._next_sample) // p + 1)
        if k < 2:
            return 0
        t0, solution = self._anchored()
        # a grid: by addition theorems from an evaluation every few samples (grid_kernel),
        # written straight into the block's rows; the instants in one compiled pass
        b = self._builder
        t_col, q_col, m_col, tau_col = b.free_columns(b.n + k)  # (tau: see BlockBuilder)
        ts = np.empty(k)
        sample_kernel.grid_instants(self._next_sample, p, t0, t_col[b.n:], ts)
        q, m = solution.at_grid(ts, p / NS, out=(q_col[b.n:], m_col[b.n:]))
        if tau_col is not None:
            tau_col[b.n:] = 0.0
        b.n += k
        self._q, self._m = q[-1].copy(), m[-1].copy()
        self.t_ns = int(t_col[b.n - 1])
        self._next_sample = self.t_ns + p
        self.evaluations += k
        return k
