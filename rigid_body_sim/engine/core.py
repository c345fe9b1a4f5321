"""The engine: one closed loop for every front end (live node, offline run, demo, bench).

It owns the state, sim time, the integrator (and ``auto``'s selection: the mixin of
``method_choice``), the torque sources, the schedule of events and faults, and produces
blocks of samples.

Time is an integer count of nanoseconds, never a float summed step by step. The engine
advances from event to event — sample instants (multiples of the sample period), source
events (control updates, command expiry), the end of the run (always sampled, on the grid
or not) — splitting each interval into equal steps no longer than the method's step
(offline, ``interpolate_samples``: samples are not among those events for a fixed-step
method, whose steps split only the intervals between the others; the compiled loop
interpolates the samples inside them, ``sample_kernel``). Its
state is always at an event instant, so where a front end stops it (a wall-clock deadline,
a command arriving) never changes the trajectory. Without torque or dissipation,
``exact`` is not stepped at all: the closed form is evaluated at each event from an
anchor, at the exact elapsed time.

Front ends differ only in how they pace :meth:`Engine.advance` and where the samples go.
"""
from dataclasses import replace
import time
from typing import Iterator, Optional

import numpy as np

from ..physics import Dynamics, IntegrationError, rotation
from . import health, sensing
from .actuators import Actuators
from .magnetic import Magnetics
from .method_choice import MethodChoice
from .stepping import Stepping
from .config import NS, EngineConfig
from .samples import BlockBuilder, SampleBlock
from .sources import NEVER, CommandHold, ControlLaw
from .state import State
from .specs import AUTO

__all__ = ['Engine', 'IntegrationError', 'NEVER']

class Engine(MethodChoice, Stepping):
    """Advance a rigid body through its events; see the module docstring.

    ``blocking_selection``: run ``auto``'s pilot to completion when a choice is needed
    (offline; its CPU is counted in ``selection_cpu``). Otherwise the engine runs
    ``splitting2`` meanwhile and the caller feeds the pilot with :meth:`work`.
    ``compiled_loop``: with a method that has a compiled loop, run the samples and the
    in-process control law's instants between other events in one compiled kernel
    (``closed_loop``) that writes the samples into the block, instead of event by event
    from Python; the samples are the same, bit for bit (test_samples).
    ``check_method``: whenever a fixed method is configured, predict its error against
    the scene's accuracy and check its step's stability (:meth:`_check_method`) into
    ``method_warnings`` for the front end to show or refuse (the CLI and the live node
    do; the benchmarks run bad steps on purpose and skip the pilot's cost).
    ``start_ns``: the sim time the body starts at (a spacecraft spawned into a running
    simulation); its samples stay on the grid of multiples of the sample period.
    ``interpolate_samples`` (offline runs): a fixed-step method's steps ignore the sample
    instants and the compiled loop interpolates the samples between them
    (``engine.sample_kernel``), so a run's steps and auto's choice do not depend on the
    sample rate; otherwise (live, lockstep) the state stops at every sample.
    """

    def __init__(self, config: EngineConfig, blocking_selection: bool = True,
                 block_size: int = 1024, compiled_loop: bool = True,
                 check_method: bool = False, start_ns: int = 0,
                 interpolate_samples: bool = False):
        self.config = config
        self.interpolate_samples = interpolate_samples
        self.check_method = check_method
        self.method_warnings = []  # [(verdict 'warn' | 'refuse', message)], fixed methods
        self.blocking_selection = blocking_selection
        self.compiled_loop = compiled_loop
        self.command = CommandHold(config.max_torque, config.command_timeout_ns)
        self.sources = [self.command]
        self._law = self._sensors = None
        env = config.environment
        # the rods' held dipole, the magnetometer, the in-process B-dot (engine.magnetic)
        self.magnetics = None if env is None or env.magnetic is None else Magnetics(
            env.magnetic, config.body, config.command_timeout_ns, config.control)
        if self.magnetics is not None:
            self.sources.extend(self.magnetics.sources)
        if config.sensors is not None:  # read before the law at a shared instant
            self._sensors = sensing.SensorSuite(config.sensors, sensing.estimator_bandwidth(
                config.control), config.environment)
            self.sources.append(self._sensors)
        if config.control is not None:
            observer = self._sensors.observe if sensing.estimator_bandwidth(config.control) \
                else None
            self._law = ControlLaw(config.control, clip=config.max_torque, observer=observer)
            self.sources.append(self._law)
            if self.magnetics is not None and self.magnetics.law is not None:
                # B-dot commands while the law's mode is bdot (its mission may leave it)
                self.magnetics.law.active = lambda: self._law.controller.mode == 'bdot'
        self._builder = BlockBuilder(config.body, block_size)
        self._compiled_samples = compiled_loop and self._sensors is None and \
            (self.magnetics is None or self.magnetics.compiled)
        self.steps = 0
        self.evaluations = 0   # closed-form evaluations (exact, torque-free)
        self._integ, self._retired_nfev = None, 0  # evaluations of methods replaced since
        self.selection_cpu = 0.0
        self.selected = None  # auto's last Selection (method, step, predicted error, pilot)
        p = config.sample_period_ns
        self._next_sample = -(-int(start_ns) // p) * p  # the first grid instant from the start
        self._start(int(start_ns))

    # ------------------------------------------------------------------ state
    def _start(self, t_ns: int):
        c = self.config
        self.body = self._builder.body = c.body
        # principal frame = body frame (diagonal inertia): skip the frame conversions at events
        self._aligned = bool(np.array_equal(c.body.principal_axes, np.eye(3)))
        self.dynamics = self._dynamics(c)
        self._q = self.body.attitude_to_principal(c.attitude)
        self._m = self.body.principal_moments * self.body.to_principal(c.angular_velocity)
        # wheels / CMGs: the gyrostat path (scenes without them build nothing of it)
        self.actuators = None if c.actuators is None else Actuators(c.actuators, self.body)
        if self.actuators is not None:
            self.actuators.reset(self._m / self.body.principal_moments)
        self.t_ns = t_ns
        self.start_ns = t_ns
        self.fault: Optional[str] = None
        self.finished = False
        self._anchor = None
        for s in self.sources:
            s.reset(t_ns)
        self._torque_seen = False
        self._tau_body = self._tau_p = None
        self.method = None
        self._choose()
        self._set_baseline()

    def _dynamics(self, c: EngineConfig) -> Dynamics:
        """The body's dynamics: dissipation, and the environment's torques along the orbit
        when the scene names them (``environment_specs``)."""
        return Dynamics(self.body.principal_moments, c.dissipation,
                        None if c.environment is None else
                        c.environment.elements(0.0, self.body.to_principal))

    @property
    def orbit_anchored(self) -> bool:
        """Whether the environment's array is re-anchored at each interval (SGP4's
        osculating conic, ``Sgp4Orbit.elements``; NRLMSIS's density fit), so steps run
        interval by interval."""
        env = self.config.environment
        return env is not None and env.anchored

    @property
    def environment_terms(self) -> tuple:
        """Names of the environment's torques in the model ('gravity gradient'), () if none."""
        env = self.config.environment
        return () if env is None else env.terms

    def reset(self):
        """Back to the configured initial state (inertia and initial state as configured
        now); sim time keeps running, so stamps and /clock stay monotonic."""
        self._start(self.t_ns)

    def set_state(self, attitude, angular_velocity):
        """Put the body in a new state now (attitude (x, y, z, w) body → inertial, ω body
        frame, rad/s); sim time, torques and the method stay. ValueError if not finite or
        not a rotation."""
        q = rotation.validated(list(attitude), 'attitude')
        w = np.asarray(angular_velocity, float).reshape(3)
        if not np.all(np.isfinite(w)):
            raise ValueError(f'angular velocity is not finite: {w.tolist()}')
        self._q = self.body.attitude_to_principal(q)
        self._m = self.body.principal_moments * self.body.to_principal(w)
        self._anchor = None
        self.fault = None
        self._set_baseline()

    @property
    def next_sample_ns(self) -> int:
        """The next sample instant on the grid the engine will produce (ns)."""
        return self._next_sample

    @property
    def t(self) -> float:
        return self.t_ns / NS

    @property
    def end_ns(self) -> int:
        d = self.config.duration_ns
        return self.start_ns + d if d > 0 else NEVER

    @property
    def attitude(self):
        """Quaternion (x, y, z, w), body → inertial."""
        return self._q.copy() if self._aligned else self.body.attitude_to_body(self._q)

    @property
    def angular_velocity(self):
        """ω, body frame, rad/s."""
        w = self._m / self.body.principal_moments
        return w if self._aligned else self.body.to_body(w)

    @property
    def angular_momentum(self):
        """L, inertial frame, kg·m²/s (with actuators: the total H = Iω + h_A)."""
        if self.actuators is not None:
            return rotation.rotate(self._q, self._m + self.actuators.momentum_principal())
        return rotation.rotate(self._q, self._m)

    @property
    def kinetic_energy(self) -> float:
        """J; with wheels, their spin energy too."""
        extra = 0.0 if self.actuators is None else self.actuators.energy()
        return float(self.dynamics.kinetic_energy(self._m)) + extra

    @property
    def principal_state(self):
        """(q principal → inertial, m principal frame): what the integrators advance."""
        return self._q.copy(), self._m.copy()

    @property
    def integrator(self):
        """The integrator instance in use (its ``nfev`` counts evaluations)."""
        return self._integ

    @property
    def total_evaluations(self) -> int:
        """Right-hand-side evaluations (or sub-flows) of every method stepped so far, free
        exact stretches' closed-form evaluations included, auto's pilot not."""
        return self._retired_nfev + (self._integ.nfev if self._integ else 0) + self.evaluations

    @property
    def torque(self):
        """Total held torque now (body frame, N·m), None if none."""
        return self._tau_body

    # ------------------------------------------------------------------ methods
    def reconfigure(self, config: EngineConfig):
        """Apply new settings now, state and time continuous. Inertia and the initial state
        take effect on :meth:`reset`; dissipation, numerics and limits at once."""
        old, self.config = self.config, config
        if config.dissipation != old.dissipation:
            self.dynamics = self._dynamics(config)
            self.method = None  # rebuild the integrator on the new dynamics
            self._set_baseline()
        if config.sample_period_ns != old.sample_period_ns:
            p = config.sample_period_ns
            self._next_sample = (self.t_ns // p + 1) * p
        self.command.set_limits(config.max_torque, config.command_timeout_ns, self.t_ns)
        if self.magnetics is not None and self.magnetics.hold is not None:
            self.magnetics.hold.set_limits(None, config.command_timeout_ns, self.t_ns)
        for s in self.sources:
            if isinstance(s, ControlLaw):
                s.clip = config.max_torque
        numerics = ('integrator', 'step', 'accuracy', 'sample_period_ns', 'duration_ns',
                    'integrator_options')
        if self.method is None or any(getattr(config, k) != getattr(old, k) for k in numerics):
            self._choose()

    # ------------------------------------------------------------------ torque
    def apply_actuator_command(self, values):
        """Hold a forward command (wheel torques N·m, then gimbal rates rad/s). ValueError
        (counted by the actuators; the last valid command stays) if invalid."""
        if self.actuators is None:
            raise ValueError('the scene has no actuators (actuators.wheels / actuators.cmgs)')
        self.actuators.command(values)

    def apply_dipole_command(self, dipole_body):
        """Hold a commanded dipole of the magnetorquers (body frame, A·m², finite) from now
        for the timeout, clipped per rod. ValueError if the scene has no rods."""
        if self.magnetics is None or self.magnetics.hold is None:
            raise ValueError('the scene has no magnetorquers (magnetorquer.max_dipole)')
        self.magnetics.hold.set(dipole_body, self.t_ns)

    def apply_command(self, torque_body):
        """Hold a commanded body-frame torque (N·m, finite) from now for the timeout."""
        self.command.set(torque_body, self.t_ns)
        self._update_torque()

    def _update_torque(self):
        sources, before = self.sources, self._tau_body  # the command alone: no list made
        active = sources if len(sources) == 1 else [s for s in sources if s.torque is not None]
        self._tau_body = None if not active else active[0].torque if len(active) == 1 else \
            np.sum([s.torque for s in active], axis=0)
        self._tau_p = None if self._tau_body is None else \
            self._tau_body if self._aligned else self.body.to_principal(self._tau_body)
        if self.actuators is not None and self.actuators.allocate:
            self.actuators.set_body_torque(self._tau_p)  # the actuators make it, internally
            self._tau_p = None
        if self._tau_body is not None:
            self._anchor = None
            if not self._torque_seen:
                self._torque_seen = True
                if self.config.integrator == AUTO:
                    self._choose()
        elif before is not None:
            self._set_baseline()  # drift is measured over torque-free stretches

    # ------------------------------------------------------------------ stepping
    # (between two events: the Stepping mixin, stepping.py)
    def _state(self) -> State:
        """The state record handed to the engine's other modules (arrays not copied)."""
        return State(self._q, self._m, self.t_ns, self._next_sample, self._tau_body,
                     self._tau_p, self._torque_seen)

    def advance(self, until_ns: int, deadline: Optional[float] = None,
                max_samples: Optional[int] = None) -> SampleBlock:
        """Process every event at or before ``until_ns`` (stopping early at ``deadline``,
        time.monotonic(), or after ``max_samples``); returns the samples produced.

        Raises IntegrationError (and sets ``fault``) if the method fails."""
        b = self._builder
        cap = min(b.capacity, max_samples or b.capacity)
        p = self.config.sample_period_ns
        while not (self.finished or self.fault) and b.n < cap:
            # the samples and law instants between other events in one compiled kernel,
            # written into the block; with sensors the law sees their events and with
            # actuators the gyrostat steps: the event path (Python) runs those
            if self._compiled_samples and not self._free_exact():
                added = self._advance_compiled(until_ns, cap)
                if added > 0:
                    # every event and sample through until_ns done (its limit was
                    # until_ns + 1): no second call to find none (lockstep); offline, a
                    # sample at the limit is the event path's (interpolate_samples), the run's
                    # end too: in this block (alone, simulate copied all to join: 15 ns each)
                    if self.t_ns >= until_ns and self._next_sample > until_ns \
                            and (self.finished or self.t_ns != self.end_ns):
                        break
                    continue
                if added < 0 and b.n:  # the next law interval's samples: the next block's
                    break
            if self._law is not None and self._free_exact():
                self._law.skip_free_instants()
            t_src = min(s.next_event() for s in self.sources)
            end = self.end_ns
            t_event = min(self._next_sample, t_src, end)
            if t_event > until_ns:
                break
            if self._free_exact() and t_event == self._next_sample:
                if self._free_samples(min(t_src, end, until_ns + 1), cap - b.n):
                    continue
            try:
                self._integrate(t_event)
            except IntegrationError as exc:
                self.fault = str(exc)
                raise
            self.t_ns = t_event
            if t_src == t_event:
                att, w = self.attitude, self.angular_velocity
                for s in self.sources:
                    if s.next_event() == t_event:
                        s.on_event(t_event, att, w)
                self._update_torque()
            # the end of the run is a sample instant too, on the grid or not: a run of 1.37 s
            # at 1 sample/s ends with its state at 1.37 s, not at 1.0 s
            if t_event == self._next_sample or t_event == end:
                if not (np.all(np.isfinite(self._q)) and np.all(np.isfinite(self._m))):
                    self.fault = f'state became non-finite at t = {self.t:.9g} s'
                    raise IntegrationError(self.method, self.step_max, self.t, self.fault)
                b.add(t_event, self._q, self._m, self._tau_body, None if self.actuators is None
                      else self.actuators.row(self._m, self.dynamics.moments),
                      None if self.magnetics is None or self.magnetics.hold is None
                      else self.magnetics.dipole())
                if t_event == self._next_sample:
                    self._next_sample += p
            if t_event >= end:
                self.finished = True
            if deadline is not None and time.monotonic() > deadline:
                break
        block = b.block()
        if self._sensors is not None:
            block = replace(block, sensors=self._sensors.drain())
        if self.magnetics is not None and self.magnetics.meter is not None:
            block = replace(block, magnetometer=self.magnetics.drain())
        return block

    def reserve(self, samples: int) -> None:
        """Blocks of ``samples`` rows from now on (before the first sample only): a run
        that keeps every sample takes them as one block, where concatenating blocks of
        16,384 copied each sample again (~45 ns a sample at 100 samples/s, as much as the
        physics of a slow body)."""
        if self._builder.n == 0 and samples > self._builder.capacity:
            self._builder = BlockBuilder(self.body, int(samples))

    def run(self, until_ns: Optional[int] = None) -> Iterator[SampleBlock]:
        """Blocks of samples up to ``until_ns`` (default: the end of the run), as a stream:
        memory does not grow with the length of the run."""
        until = self.end_ns if until_ns is None else until_ns
        if until >= NEVER:
            raise ValueError('an open-ended run (duration 0) needs an end time')
        while not (self.finished or self.fault) and self.t_ns <= until:
            block = self.advance(until)
            if len(block):
                yield block
            elif not self.finished:
                break

    # ------------------------------------------------------------------ diagnostics
    def _set_baseline(self):
        self._base = (self.kinetic_energy, self.angular_momentum.copy(), self.t_ns)

    def diagnostics(self) -> dict:
        """The physics' health (``engine.health.diagnostics``): method, step, invariants and
        their drift over the current torque-free stretch, quaternion norm error, dissipated
        energy, command counters."""
        return health.diagnostics(self, self._state(), self._base)
