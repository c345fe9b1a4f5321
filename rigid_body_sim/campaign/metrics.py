"""Per-run metrics, computed as the samples stream by (memory does not grow with the run).

Every metric is taken at the sample instants (the scene's ``publish_rate``); t in seconds
of sim time from the start of the run. Definitions:

* ``final_pointing_error`` [rad]: the rotation angle from the attitude to the controller's
  target, 2·acos(|q·q_target|) (both body → inertial, x, y, z, w), at the last sample.
  NaN unless the scene slews (controller mode ``slew``, or a mission that exits detumble).
* ``settling_time`` [s]: the first sample time after which the pointing error stays at or
  below ``pointing_tolerance`` to the end; NaN if the last sample is above it.
* ``detumble_time`` [s]: the first sample time after which |ω| (body frame) stays at or
  below ``rate_tolerance`` to the end; NaN if the last sample is above it.
* ``peak_torque`` [N·m]: the largest Euclidean norm of the applied torque (body frame).
  ``saturated``: some sample's torque reached the simulator's per-axis ``max_torque``, or
  the controller's norm bound ``max_torque`` when it has one (to 1e-9 relative).
* ``energy_dissipated`` [J]: T(0) − T(end), the kinetic energy removed by the controller's
  torque and by dissipation (negative if the run gained energy).
* ``flip_count`` and ``flip_times`` [s] (free tumbles only, null / empty when a controller
  acts): sign changes of ω along the principal axis of intermediate inertia, each at the
  linearly interpolated zero crossing between two samples.
* ``final_angular_momentum`` [kg·m²/s]: |L| at the end. ``angular_momentum_drift`` and
  ``kinetic_energy_drift``: |L|(end)/|L|(0) − 1 and T(end)/T(0) − 1. In a torque- and
  dissipation-free scene both are invariants, so these are integration errors; otherwise
  they are the physical change.

The row adds ``integrator`` (the method that ran; ``auto``'s choice) and ``cpu_time``
(CPU seconds of the thread that drew and ran it: a Dask worker's other threads excluded).
"""
import math

import numpy as np

METRICS = ('final_pointing_error', 'settling_time', 'detumble_time', 'peak_torque',
           'saturated', 'energy_dissipated', 'flip_count', 'flip_times',
           'final_angular_momentum', 'angular_momentum_drift', 'kinetic_energy_drift')
# columns that can be plotted as numbers (histograms, scatter)
NUMERIC = ('final_pointing_error', 'settling_time', 'detumble_time', 'peak_torque',
           'energy_dissipated', 'flip_count', 'final_angular_momentum',
           'angular_momentum_drift', 'kinetic_energy_drift', 'cpu_time')
SATURATION_RTOL = 1e-9


class Settle:
    """Streaming "first time after which a condition holds to the end"."""

    def __init__(self):
        self.since = 0.0     # start of the current good stretch (None while bad)
        self.pending = False  # the last sample seen was bad

    def add(self, t: np.ndarray, good: np.ndarray):
        bad = np.flatnonzero(~good)
        if bad.size:
            i = bad[-1]
            self.pending = i == len(t) - 1
            self.since = None if self.pending else float(t[i + 1])
        elif self.pending and len(t):
            self.since, self.pending = float(t[0]), False

    @property
    def time(self) -> float:
        return math.nan if self.since is None else self.since


class MetricsSink:
    """A sink for :func:`rigid_body_sim.offline.simulate`: call with each SampleBlock, then
    :meth:`result` gives the metrics dict (see the module docstring)."""

    def __init__(self, scene, pointing_tolerance=0.01, rate_tolerance=0.01):
        ctl = scene.controller
        self.controlled = scene.controlled
        slews = self.controlled and (ctl.get('mode') == 'slew' or
                                     ctl.get('mission.detumble_exit_rate', 0.0) > 0)
        self.target = None
        if slews:
            from ..control import validated_target
            self.target = np.asarray(validated_target(ctl['target_attitude']), float)
        self.axis_max = float(scene.simulator['max_torque'])
        self.norm_max = float(ctl.get('max_torque', 0.0)) if self.controlled else 0.0
        self.pointing_tolerance, self.rate_tolerance = pointing_tolerance, rate_tolerance
        self.pointing, self.rate = Settle(), Settle()
        self.first = self.last = None
        self.last_error = math.nan
        self.peak = 0.0
        self.saturated = False
        self.flips = []
        self._prev = None  # (t, ω_mid) of the previous sample, across blocks
        self._mid = None

    def __call__(self, block):
        n = len(block)
        if not n:
            return
        t = block.t
        if self.first is None:
            self.first = self._state(block, 0)
            self._mid = int(np.argsort(block.body.principal_moments)[1])
        self.last = self._state(block, n - 1)
        if self.target is not None:
            dots = np.abs(block.attitude @ self.target)
            err = 2.0 * np.arccos(np.minimum(1.0, dots))
            self.pointing.add(t, err <= self.pointing_tolerance)
            self.last_error = float(err[-1])
        self.rate.add(t, np.linalg.norm(block.angular_velocity, axis=1) <= self.rate_tolerance)
        tau = block.torque
        if np.any(tau):
            self.peak = max(self.peak, float(np.max(np.linalg.norm(tau, axis=1))))
            limit = 1.0 - SATURATION_RTOL
            if np.any(np.abs(tau) >= self.axis_max * limit) or (
                    self.norm_max > 0 and np.any(np.linalg.norm(tau, axis=1)
                                                 >= self.norm_max * limit)):
                self.saturated = True
        if not self.controlled:
            self._count_flips(t, block.m[:, self._mid])

    def _count_flips(self, t, w):
        if self._prev is not None:
            t = np.concatenate(([self._prev[0]], t))
            w = np.concatenate(([self._prev[1]], w))
        self._prev = (float(t[-1]), float(w[-1]))
        s = np.sign(w)
        # a crossing between samples i and i+1 of opposite signs (an exact zero is skipped
        # over: the crossing is counted between its nonzero neighbours)
        nz = np.flatnonzero(s != 0)
        change = nz[:-1][s[nz[:-1]] != s[nz[1:]]]
        nxt = nz[1:][s[nz[:-1]] != s[nz[1:]]]
        for i, j in zip(change, nxt):
            self.flips.append(float(t[i] + (t[j] - t[i]) * w[i] / (w[i] - w[j])))

    @staticmethod
    def _state(block, i):
        return (float(block.kinetic_energy[i]), float(np.linalg.norm(block.angular_momentum[i])))

    def result(self) -> dict:
        T0, L0 = self.first
        T1, L1 = self.last
        return {
            'final_pointing_error': self.last_error,
            'settling_time': self.pointing.time if self.target is not None else math.nan,
            'detumble_time': self.rate.time,
            'peak_torque': self.peak,
            'saturated': self.saturated,
            'energy_dissipated': T0 - T1,
            'flip_count': None if self.controlled else len(self.flips),
            'flip_times': [] if self.controlled else list(self.flips),
            'final_angular_momentum': L1,
            'angular_momentum_drift': L1 / L0 - 1.0 if L0 > 0 else math.nan,
            'kinetic_energy_drift': T1 / T0 - 1.0 if T0 > 0 else math.nan,
        }


def empty() -> dict:
    """The metrics of a run that did not produce samples (all NaN / empty)."""
    out = {k: math.nan for k in METRICS}
    out.update(saturated=False, flip_count=None, flip_times=[])
    return out
