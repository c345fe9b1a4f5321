"""Torque sources: each holds a body-frame torque between its own events (zero-order hold).

The engine sums the torques of its sources and hands the sum to the integrator as a
constant over each step; it stops at every source's next event, so no step straddles a
change. State-dependent dissipation is not here: it is part of the dynamics that every
integrator integrates (``physics.dynamics``).

A new source (an actuator, an environment torque) is a subclass with its own parameters;
the engine and the integrators need no change.
"""
import math
from typing import Optional

import numpy as np

from .. import control
from .config import ControlSettings

NEVER = 1 << 62  # ns: no event scheduled


class TorqueSource:
    """Base: ``torque`` is the held body-frame torque (N·m), None when it adds nothing."""
    name = ''

    def __init__(self):
        self.torque: Optional[np.ndarray] = None

    def next_event(self) -> int:
        """Sim time (ns) of this source's next event, NEVER if none."""
        return NEVER

    def on_event(self, t_ns: int, attitude, angular_velocity) -> None:
        """Called at ``next_event()`` with the body state (attitude body→inertial, ω body)."""

    def reset(self, t_ns: int) -> None:
        """Start over at ``t_ns`` (the scene was reset)."""
        self.torque = None


class CommandHold(TorqueSource):
    """Commanded torque from outside (ROS messages): clipped per axis to ``max_torque``,
    applied from the instant it is set, held for ``timeout_ns``, then zero."""
    name = 'command'

    def __init__(self, max_torque: float, timeout_ns: int):
        super().__init__()
        self.max_torque, self.timeout_ns = float(max_torque), int(timeout_ns)
        self.expiry = NEVER
        self.accepted = self.saturated = self.timed_out = 0

    def set(self, torque, t_ns: int) -> None:
        """Hold ``torque`` (body frame, finite) from ``t_ns``; a zero torque ends the hold.
        Clipped in Python floats, as np.clip would (a live lockstep exchange applies one
        command: five small numpy calls cost more than the rest of it)."""
        x, y, z = torque  # (no generator: one apply per lockstep exchange)
        x, y, z = float(x), float(y), float(z)
        m = self.max_torque  # one limit, or one per axis (the magnetorquers' rods)
        if isinstance(m, float):
            mx = my = mz = m
        else:
            mx, my, mz = float(m[0]), float(m[1]), float(m[2])
        if abs(x) > mx or abs(y) > my or abs(z) > mz:
            x, y, z = min(max(x, -mx), mx), min(max(y, -my), my), min(max(z, -mz), mz)
            self.saturated += 1
        self.accepted += 1
        if x == 0.0 and y == 0.0 and z == 0.0:
            self.torque, self.expiry = None, NEVER
            return
        self.torque, self.expiry = np.array((x, y, z)), t_ns + self.timeout_ns

    def set_limits(self, max_torque: float, timeout_ns: int, t_ns: int) -> None:
        self.max_torque, self.timeout_ns = float(max_torque), int(timeout_ns)
        if self.torque is not None:
            np.clip(self.torque, -self.max_torque, self.max_torque, out=self.torque)
            self.expiry = t_ns + self.timeout_ns

    def next_event(self) -> int:
        return self.expiry

    def on_event(self, t_ns, attitude, angular_velocity):
        self.torque, self.expiry = None, NEVER
        self.timed_out += 1

    def reset(self, t_ns):
        super().reset(t_ns)
        self.expiry = NEVER


class ControlLaw(TorqueSource):
    """The attitude control law with its scene schedule, sampled every control period.

    The same object serves the offline engine (as a torque source) and the controller
    node (through :meth:`evaluate`), so both run one law. ``clip``: the simulator's
    per-axis saturation (N·m), as applied to every command it receives.
    """
    name = 'control'

    def __init__(self, settings: ControlSettings, clip: float = math.inf, observer=None,
                 compiled: bool = True):
        super().__init__()
        self.settings, self.clip = settings, float(clip)
        self.compiled = compiled  # the law compiled or interpreted (control.AttitudeController)
        # observer(t_ns) -> (attitude, ω) or None: the law sees an estimate, not the truth
        self.observer = observer
        self.reset(0)

    def reset(self, t_ns):
        super().reset(t_ns)
        s = self.settings
        self.controller = control.AttitudeController(s.config, s.mode, s.target, self.compiled)
        self.mission = control.Mission(s.free_time, s.detumble_exit_rate)
        self.next_t = t_ns
        self.last: Optional[control.ControlOutput] = None
        self.free = False

    def evaluate(self, t: float, attitude, angular_velocity):
        """(torque body frame, free, switched_to): the law at state time ``t`` (s)."""
        free, switched = self.mission.update(self.controller, t, angular_velocity)
        self.free = free
        if free:
            self.last = None
            return np.zeros(3), True, switched
        self.last = self.controller.compute(attitude, angular_velocity)
        return self.last.torque, False, switched

    def next_event(self):
        return self.next_t

    def first_instant_after_free(self, t_ns: int) -> int:
        """The first law instant at or after ``t_ns`` (one of the law's) outside the
        mission's free phase: the first that may give a torque (Mission.update's test,
        ``t - start < free_time``, in the same arithmetic)."""
        mission, period = self.mission, self.settings.period_ns
        start = self.next_t / 1e9 if mission.start is None else mission.start
        if not mission.free_time > 0.0:
            return t_ns
        k = max(0, int((start + mission.free_time) * 1e9 - t_ns) // period - 1)
        while (t_ns + k * period) / 1e9 - start < mission.free_time:
            k += 1
        return t_ns + k * period

    def skip_free_instants(self):
        """In the free phase the law gives no torque and changes nothing: where the state
        between instants does not depend on them (the exact torque-free flow, anchored: up
        to round-off), its next instant is the first that may give a torque (~20 µs saved at
        each, e.g. 850 in the default scene's free phase at 50 Hz)."""
        if self.observer is None and self.free and self.mission.start is not None:
            self.next_t = self.first_instant_after_free(self.next_t)

    def on_event(self, t_ns, attitude, angular_velocity):
        if self.observer is not None:
            estimate = self.observer(t_ns)
            if estimate is None:  # no estimate yet (before the first fix): no torque
                self.torque, self.next_t = None, t_ns + self.settings.period_ns
                return
            attitude, angular_velocity = estimate
        else:
            attitude = published_attitude(attitude)
        tau, _, _ = self.evaluate(t_ns / 1e9, attitude, angular_velocity)
        if self.clip < math.inf:
            tau = np.clip(tau, -self.clip, self.clip)
        self.torque = tau if tau.any() else None
        self.next_t = t_ns + self.settings.period_ns


def published_attitude(attitude) -> np.ndarray:
    """The attitude as the simulator publishes it (``samples._row_values``: divided by its
    norm, summed in this order). The in-process law sees it, as the controller node does
    (which uses a quaternion unit to round-off as sent), so a lockstep run's commands are
    the offline run's bit for bit; ``closed_loop`` normalises alike."""
    x, y, z, w = (float(v) for v in attitude)
    n = math.sqrt(x * x + y * y + z * z + w * w)
    return np.array((x / n, y / n, z / n, w / n))
