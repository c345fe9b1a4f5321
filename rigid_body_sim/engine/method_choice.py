"""How the engine takes its method: the scene's fixed one (checked), the one that carries
wheels and CMGs, or ``auto``'s choice with its pilot (physics.auto).

A mixin of :class:`~rigid_body_sim.engine.core.Engine`: these are the engine's own methods,
kept apart for the module's size. They read and write the engine's state like any other of
its methods; nothing outside the engine calls them but ``work`` and ``selection_pending``.
"""
import time
from typing import Optional

from ..physics import INTEGRATORS, IntegrationError, create
from ..physics.auto import Selection, select, selecting
from ..physics.auto.selection import choosing, free_choice
from . import law_pilot
from .config import NS
from .specs import AUTO

# the method of scenes with wheels or CMGs: the registered one that advances them
ACTUATED = next(name for name, cls in INTEGRATORS.items() if cls.requires_actuators)
# auto's longest step without a law when samples are interpolated (s): its model counts
# events at this spacing; a sample period longer than this still bounds it
FREE_SPACING = 1.0


class MethodChoice:
    """The engine's method choice (see the module docstring)."""

    def _use(self, name, h_max, reason, **options):
        if name != self.method or options:
            self._retired_nfev += self._integ.nfev if self._integ else 0
            self._integ = create(name, self.dynamics, **options)
        terms = self.environment_terms
        if terms and not reason.startswith('auto'):  # auto's reason names them itself
            reason = f'{reason}; model: free body + {" + ".join(terms)}'
        self.method, self.reason = name, reason
        self.step_max = float(h_max)
        self._anchor = None

    def _spacing(self) -> float:
        """The longest step (s). Where samples are interpolated between steps
        (``interpolate_samples``: offline), they do not bound it, so that denser samples
        change neither auto's choice nor the steps: the control period, and a fixed
        method's step or auto's FREE_SPACING (or the sample period if longer). Otherwise
        ``EngineConfig.event_spacing``: samples are events the steps land on."""
        c = self.config
        if not self.interpolate_samples:
            return c.event_spacing()
        # compares, not max()/min(): asked in each of auto's choices, where a builtin's call
        # costs ~20× a compare (callgrind: a short run's choosing)
        if c.integrator == AUTO:
            h = c.sample_period
            h = FREE_SPACING if FREE_SPACING > h else h
        else:
            h = c.step
        if c.control is not None:
            period = c.control.period_ns / NS
            h = period if period < h else h
        return h

    def _choose(self):
        """Pick the method for the current state (``auto``) or take the configured one."""
        c = self.config
        self._selection = None
        if self.actuators is not None:  # wheels / CMGs: the method that carries them
            self._use(ACTUATED, min(c.step, c.event_spacing()),
                      f'actuators (wheels/CMGs): {ACTUATED}, |H| kept to round-off; at the '
                      'scene\'s step', actuators=self.actuators)
            return
        if c.integrator != AUTO:
            self._use(c.integrator, self._spacing(),
                      f'set by the scene or parameter ({c.integrator})',
                      **dict(c.integrator_options))
            self.method_warnings = self._check_method() if self.check_method else []
            return
        # all of auto's choosing counts in selection_cpu, building its arguments and the
        # free body's choice included (they were outside it: 30-40 µs of default's 1.3 ms
        # run, uncounted); creating the chosen method is the run's (_use)
        cpu0 = time.process_time()
        # the environment's torques act from the start, as a torque the pilot cannot foresee
        # (environment_terms and orbit_anchored read here, not asked: a property call each)
        env = c.environment
        terms = () if env is None else env.terms
        torque = self._torque_seen or bool(terms)
        if not torque and not c.dissipation.active:  # the free body: exact, no model needed
            sel = free_choice(self.body.principal_moments, self._m, c.accuracy,
                              self._spacing())
            self.selection_cpu += time.process_time() - cpu0
            self._use(sel.name, sel.step,
                      f'auto: {sel.reason}; evaluated at sample and event instants only')
            return
        # the budget covers the rest of the run (what went before was exact or is done)
        left = (self.end_ns - self.t_ns) / NS if c.duration_ns > 0 else 0.0
        # ω only where the selection reads it, the gravity gradient's equilibrium test (the
        # momentum stands for it elsewhere); the torque's rate and the environment's terms
        # asked only where there are any: each a share of a short dissipative run's
        # choosing (Explorer 1, 1 s); without them, choosing's defaults
        omega = orbit_state = runner = None
        forced, rate, period = False, 0.0, 0.0
        if torque:
            rate = c.torque_rate(self._torque_seen)
        if terms:
            forced = env.periodic_forcing
            if env.gravity_gradient:  # auto tests the equilibrium it starts near
                orbit_state = env.orbit.state(self.t_ns / NS)
                omega = self.angular_velocity
        # the state's own arrays where the choice is made at once (blocking, or with torque
        # a priori), before the state moves; copies where the pilot outlives this instant
        # (a numpy call each, cold, was a share of a short run's choosing: Explorer 1, 1 s)
        at_once = self.blocking_selection or torque
        state = (self.body, c.dissipation,
                 self._q if at_once and self._aligned else self.attitude, omega)
        if torque:
            runner = self._law_runner()
            if runner is not None:  # the law runs here: a pilot can measure it
                period = c.control.period_ns / NS
        spacing = self._spacing()
        # an adaptive method restarts where the environment is re-made per event
        restarting = env is not None and (env.anchored or bool(terms) and env.magnetorquers)
        if at_once:  # with torque the choice is a priori: at once
            try:
                # keywords written out, not a dict unpacked (**kw): building, updating and
                # unpacking it was a share of a short run's choosing (callgrind, Explorer 1
                # over 1 s); commands priced as the compiled closed loop's instants
                # (law_in_loop, Engine.advance), whoever makes them: the choice is the
                # scene's, not the path's, so the event-by-event loop, the live node and
                # lockstep (the law in another process) choose as the offline run does and
                # their samples stay equal (selecting leaves out restarting runs, an
                # orbit's among them); the state's own momentum, not I·ω from the ω it
                # gives (two array operations of the selection's time)
                work = choosing(*state, torque=self._torque_seen, accuracy=c.accuracy,
                                duration=left, max_step=spacing, torque_rate=rate,
                                dynamics=self.dynamics, environment=terms, forced=forced,
                                restarting=restarting, orbit_state=orbit_state,
                                law_in_loop=True, law_runner=runner, control_period=period,
                                momentum=self._m)
            except (ValueError, IntegrationError) as exc:
                self.selection_cpu += time.process_time() - cpu0
                self._failed(exc)
                return
            if isinstance(work, Selection):  # no pilot: no generator to feed
                self.selection_cpu += time.process_time() - cpu0
                self._take(work)
                return
            self._selection = work
            self.work(cpu0=cpu0)  # one bracket: each clock reading is a ~0.7 µs system call
        else:
            # the pilot outlives this instant: a copy of the momentum (no torque here, so
            # no rate, law or period: choosing's defaults)
            kw = dict(torque=self._torque_seen, accuracy=c.accuracy, duration=left,
                      max_step=spacing, dynamics=self.dynamics, environment=terms,
                      forced=forced, restarting=restarting, orbit_state=orbit_state,
                      law_in_loop=True, momentum=self._m.copy())
            work = selecting(*state, **kw)
            sel = select(*state, prior_only=True, **kw)
            self.selection_cpu += time.process_time() - cpu0
            self._use(sel.name, sel.step, f'auto: provisional a-priori choice while the '
                      f'selection pilot runs: {sel.reason}', **dict(sel.options))
            self._selection = work

    def _law_runner(self):
        """A maker of the pilot's runner of the law from the current state
        (``law_pilot.LawRunner``), where the in-process law alone acts in the compiled
        closed loop (no held command, wheels, sensors, rods, environment torques or
        re-anchored orbit); else None."""
        law = self._law
        if law is None or law.free or not self._compiled_samples or self.actuators is not None \
                or self.magnetics is not None or self.environment_terms \
                or self.orbit_anchored or self.command.torque is not None:
            return None
        return lambda: law_pilot.LawRunner(law, self._state(), self.dynamics, self.body).run

    def _check_method(self):
        """[(verdict, message)] for the fixed method at its step from the current state:
        outside its stability region ('refuse' far outside, else 'warn'), or a predicted
        error (auto's error model, physics.auto.step_advice) far from the accuracy budget,
        too damped or too amplified alike ('warn', with the step that would meet it)."""
        from ..physics.auto.step_advice import advise, run_step
        from ..physics.integrators.stability import check_step
        c = self.config
        spacing = c.sample_period if c.control is None else \
            min(c.sample_period, c.control.period_ns / NS)
        left = (self.end_ns - self.t_ns) / NS if c.duration_ns > 0 else 0.0
        torque = c.control is not None or self._torque_seen
        verdict, message = check_step(self.method, self.dynamics, self._m,
                                      run_step(c.step, spacing), left)
        if verdict == 'refuse':
            return [(verdict, message)]
        out = [(verdict, message)] if verdict == 'warn' else []
        advice = advise(self.method, self.dynamics, self._q, self._m, c.step,
                        accuracy=c.accuracy, duration=left, spacing=spacing, torque=torque,
                        torque_rate=c.torque_rate() if torque else 0.0)
        if advice is not None and advice.far:
            out.append(('warn', advice.message()))
        return out

    @property
    def selection_pending(self) -> bool:
        return self._selection is not None

    def work(self, deadline: Optional[float] = None, cpu0: Optional[float] = None) -> bool:
        """Feed ``auto``'s pilot until done or ``deadline`` (time.monotonic()); True while
        it is still pending. The choice applies at the current instant. ``cpu0``: the
        process time the caller's share of the choosing started at (``_choose``), counted
        with this in selection_cpu."""
        work = self._selection
        if work is None:
            return False
        cpu0 = time.process_time() if cpu0 is None else cpu0
        try:
            while deadline is None or time.monotonic() < deadline:
                next(work)
        except StopIteration as done:
            self.selection_cpu += time.process_time() - cpu0  # setting up the run is the run's
            self._take(done.value)
        except (ValueError, IntegrationError) as exc:
            self.selection_cpu += time.process_time() - cpu0
            self._failed(exc)
        else:
            self.selection_cpu += time.process_time() - cpu0
        return self._selection is not None

    def _take(self, sel):
        """Run with auto's Selection ``sel`` from now."""
        self._selection = None
        self.selected = sel
        self._use(sel.name, min(sel.step, self._spacing()) if sel.step > 0
                  else self._spacing(), f'auto: {sel.reason}', **dict(sel.options))

    def _failed(self, exc):
        """Run with splitting2 at the scene's step where auto's selection failed (``exc``)."""
        self._selection = None
        self._use('splitting2', min(self.config.step, self._spacing()),
                  f'auto: selection failed ({exc}); splitting2 at the scene\'s step')
