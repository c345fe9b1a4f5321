"""``attitude_simulator``: live rigid-body attitude simulation on standard ROS 2 topics.

A thin shell over :class:`rigid_body_sim.physics.Propagator`: parameters and messages are
translated into physics-core calls, the state is published on standard Jazzy messages.

Time. The node owns the simulated time t (s, from 0 at start). Physics steps of ``h``
seconds run in sim time; every ``1/publish_rate`` sim seconds the state is published.
Sim time is paced against the wall clock by ``real_time_factor`` (0 = as fast as
possible). Stamps are the sim time when ``publish_clock`` is true (equal to the published
``/clock``), otherwise the node clock at publication.

Main loop (``Simulator.run``): a single-threaded executor is spun with a timeout until the
next publish instant is due; between those, callbacks (commands, parameters, services) are
served. With ``real_time_factor: 0`` the physics advances in chunks of at most
``CHUNK_WALL_S`` wall seconds between executor turns, so the node stays responsive.

Commands (``torque_command``, ``wrench_command``) are validated, saturated per axis to
``max_torque`` and applied from the next physics step on, held (zero-order) until a newer
command arrives or ``command_timeout`` sim seconds have passed, then the torque drops to 0.

State topics are only serialised for publishers that have a matched subscriber (checked
every ``SUBSCRIBER_REFRESH_S`` wall seconds), so unobserved topics cost nothing.
"""
import math
import sys
import threading
import time
from dataclasses import dataclass

import numpy as np
import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rcl_interfaces.msg import SetParametersResult

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped, WrenchStamped
from rosgraph_msgs.msg import Clock
from std_srvs.srv import Trigger

from ..physics import DISSIPATION_MODELS, INTEGRATORS, Dissipation, IntegrationError, Propagator
from ..physics.selection import select
from .state_messages import StateMessages
from .common import (QOS_CHOICES, ParamSpec, changed_values, declare_parameters, diagnostic_status,
                     frame_id_problem, qos_profile, quaternion_from_parameter, rigid_body_from_parameter,
                     set_stamp, validate_update)

try:  # /tf only where tf2_msgs exists (a full ROS install); the PyPI venv has none
    from tf2_msgs.msg import TFMessage
except ImportError:  # pragma: no cover - depends on the installation
    TFMessage = None

NODE_NAME = 'attitude_simulator'
CHUNK_WALL_S = 0.02          # longest stretch of physics between executor turns
SUBSCRIBER_REFRESH_S = 0.25  # how often matched-subscriber counts are re-read
DIAGNOSTICS_PERIOD_S = 1.0   # wall clock
MAX_LAG_S = 1.0              # behind the wall-clock target by more: drop the backlog (re-anchor)
WARN_THROTTLE_S = 2.0
AUTO = 'auto'

SPECS = (
    ParamSpec('inertia', [1.0, 2.0, 3.0], 'inertia: 3 principal moments or 9 values row-major (body frame)',
              kind='float_array', unit='kg*m^2', sizes=(3, 9),
              note='positive definite, symmetric, triangle inequalities; takes effect on ~/reset'),
    ParamSpec('initial_attitude', [0.0, 0.0, 0.0, 1.0],
              'initial attitude quaternion (x, y, z, w), rotation child_frame_id -> frame_id',
              kind='float_array', sizes=(4,), note='non-zero, normalised on use; takes effect on ~/reset'),
    ParamSpec('initial_angular_velocity', [0.05, 1.0, 0.0], 'initial angular velocity, body frame',
              kind='float_array', unit='rad/s', sizes=(3,), note='takes effect on ~/reset'),
    ParamSpec('dissipation.model', 'none', 'internal/external dissipation model', kind='string',
              choices=DISSIPATION_MODELS, note='applies at once, state continuous'),
    ParamSpec('dissipation.coefficient', 0.0,
              'dissipation coefficient: double_bracket alpha [s/(kg*m^2)], viscous c [N*m*s]',
              kind='float', low=0.0, note='applies at once, state continuous'),
    ParamSpec('integrator', AUTO, 'integration method, or auto (chosen from the scene and accuracy)',
              kind='string', choices=(AUTO,) + tuple(INTEGRATORS), note='may change while running'),
    ParamSpec('step', 0.001, 'physics step (upper bound: the step used is the largest one <= this '
              'that divides the publish period; auto may choose a smaller one)',
              kind='float', unit='s', low=1e-9, high=1e7),
    ParamSpec('accuracy', 1e-6, 'attitude-error budget used by integrator auto', kind='float', unit='rad',
              low=1e-15, high=1.0),
    ParamSpec('publish_rate', 100.0, 'state publication rate in simulated time', kind='float', unit='Hz',
              low=1e-9, high=10000.0),
    ParamSpec('real_time_factor', 1.0, 'simulated seconds per wall second; 0 = as fast as possible',
              kind='float', low=0.0, high=1e9),
    ParamSpec('publish_clock', False, 'publish /clock (sim time) and stamp messages with it', kind='bool'),
    ParamSpec('duration', 0.0, 'simulated time to run from start (or last ~/reset), then exit; 0 = until stopped',
              kind='float', unit='s', low=0.0, high=1e12),
    ParamSpec('frame_id', 'world', 'inertial frame (REP-105)', kind='string'),
    ParamSpec('child_frame_id', 'base_link', 'body frame (REP-103); commands must use it or empty',
              kind='string'),
    ParamSpec('max_torque', 1.0, 'per-axis saturation of commanded torque', kind='float', unit='N*m',
              low=0.0, high=1e9),
    ParamSpec('command_timeout', 0.5, 'a command held longer than this (sim time) drops to zero torque',
              kind='float', unit='s', low=1e-6, high=1e6, low_open=True),
    ParamSpec('command_stamp_tolerance', 0.5,
              'commands stamped further than this in the future (vs. the stamps this node publishes) '
              'are rejected; a zero stamp is accepted', kind='float', unit='s', low=0.0, high=1e6),
    ParamSpec('qos', 'reliable', 'QoS of state topics and command subscriptions', kind='string',
              choices=QOS_CHOICES, read_only=True),
)
SPEC_BY_NAME = {s.name: s for s in SPECS}
SCENE_PARAMS = ('inertia', 'initial_attitude', 'initial_angular_velocity')
REJECT_REASONS = ('non_finite', 'wrong_frame', 'future_stamp', 'stale_stamp')


class SceneError(ValueError):
    """Start-up parameters that cannot make a scene (the node exits with code 2)."""


@dataclass(frozen=True)
class Scene:
    body: object
    dissipation: Dissipation
    attitude: np.ndarray
    angular_velocity: np.ndarray


def build_scene(p) -> Scene:
    """Scene from coerced parameter values; ValueError with the reason."""
    try:
        body = rigid_body_from_parameter(p['inertia'])
    except ValueError as exc:
        raise ValueError(f'inertia: {exc}') from None
    q = quaternion_from_parameter(p['initial_attitude'], 'initial_attitude')
    w = np.asarray(p['initial_angular_velocity'], float)
    dissipation = Dissipation(p['dissipation.model'], p['dissipation.coefficient'])
    return Scene(body, dissipation, q, w)


def check_parameters(p) -> Scene:
    """Cross-parameter validation of a full set of coerced values; ValueError(reason)."""
    for name in ('frame_id', 'child_frame_id'):
        problem = frame_id_problem(p[name])
        if problem:
            raise ValueError(f'{name} {p[name]!r} {problem}')
    if p['frame_id'] == p['child_frame_id']:
        raise ValueError(f'frame_id and child_frame_id must differ (both {p["frame_id"]!r})')
    return build_scene(p)


def choose_integrator(p, scene: Scene, attitude, angular_velocity, torque: bool):
    """(name, step upper bound, reason, pending) for the configured ``integrator`` parameter.

    ``auto``: torque-free without dissipation is the exact flow at once (select() answers
    that without a pilot run). Otherwise :func:`rigid_body_sim.physics.selection.select`
    needs a pilot run of seconds, so the node starts with ``splitting2`` at ``max_step``
    (structure-preserving, torque kick exact) and ``pending`` is True: the caller runs
    :func:`run_selection` in the background and switches when it returns.
    ``max_step`` is the smaller of ``step`` and the publish period.
    """
    if p['integrator'] != AUTO:
        return p['integrator'], p['step'], 'set by parameter', False
    max_step = min(p['step'], 1.0 / p['publish_rate'])
    if not torque and not scene.dissipation.active:
        return run_selection(p, scene, attitude, angular_velocity, torque) + (False,)
    return 'splitting2', max_step, 'auto: provisional splitting2 while the selection pilot runs', True


def run_selection(p, scene: Scene, attitude, angular_velocity, torque: bool):
    """(name, step, reason) from select(); a failure gives splitting2 with the reason (never raises)."""
    max_step = min(p['step'], 1.0 / p['publish_rate'])
    try:
        sel = select(scene.body, scene.dissipation, attitude, angular_velocity, torque=torque,
                     accuracy=p['accuracy'], duration=p['duration'], max_step=max_step)
    except Exception as exc:  # noqa: BLE001
        return 'splitting2', max_step, f'auto: selection failed ({exc}); splitting2 as the safe default'
    step = sel.step if 0 < sel.step <= max_step else max_step
    if sel.name == 'exact' and not torque:
        # The exact flow has no stepping error: step once per publish instant.
        return sel.name, 1.0 / p['publish_rate'], f'auto: {sel.reason}; evaluated once per publish instant'
    return sel.name, step, f'auto: {sel.reason}'


class Simulator(Node):
    """The ``attitude_simulator`` node. Build, then call :meth:`run` (or drive :meth:`run_once`)."""

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        try:
            self._p = declare_parameters(self, SPECS)
            self._scene = check_parameters(self._p)
        except ValueError as exc:
            raise SceneError(str(exc)) from None
        self._log = self.get_logger()

        # --- messages, built once and mutated in place (the hot path allocates nothing) ---
        self._msgs = StateMessages(self._p['frame_id'], self._p['child_frame_id'])
        self._stamp = self._msgs.stamp
        self._clock_msg = Clock(clock=self._stamp)
        self._tfs_msg = TFMessage(transforms=[self._msgs.transform]) if TFMessage is not None else None

        # --- interfaces ---
        qos = qos_profile(self._p['qos'])
        pub = self.create_publisher
        # (publisher, message): published every publish tick when subscribed
        self._pubs = [(pub(type(msg), name, qos), msg) for name, msg in self._msgs.topics()]
        if TFMessage is not None:
            self._pubs.append((pub(TFMessage, '/tf', qos_profile('reliable', 100)), self._tfs_msg))
        self._clock_pub = None
        if self._p['publish_clock']:
            self._clock_pub = pub(Clock, '/clock', qos_profile('reliable'))
        self._diag_pub = pub(DiagnosticArray, '/diagnostics', qos_profile('reliable'))
        self._active = []
        self.create_subscription(Vector3Stamped, 'torque_command',
                                 lambda m: self._on_command(m.header, m.vector, 'torque_command'), qos)
        self.create_subscription(WrenchStamped, 'wrench_command',
                                 lambda m: self._on_command(m.header, m.wrench.torque, 'wrench_command'), qos)
        self.create_service(Trigger, '~/reset', self._on_reset)

        # --- counters (diagnostics) ---
        self._rejected = dict.fromkeys(REJECT_REASONS, 0)
        self._accepted = 0
        self._saturated = 0
        self._timed_out = 0
        self._missed = 0
        self._missed_at_last_diag = 0
        self._next_warn = {}
        self._published_ticks = 0

        # --- state ---
        self._torque_seen = False
        self._selection_generation = 0
        self._selection_result = None
        self._h_max = 0.0
        self._start_scene(initial=True)
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        self._log.info(self._summary())

    # ======================================================================== scene/state
    def _start_scene(self, initial=False):
        """(Re)start from the scene's initial state; sim time keeps running (monotonic /clock)."""
        t = 0.0 if initial else self._t()
        if not initial:
            self._scene = build_scene(self._p)  # scene parameters changed since take effect now
        s = self._scene
        self._torque_seen = False
        name, h_max, reason, pending = choose_integrator(self._p, s, s.attitude, s.angular_velocity, torque=False)
        self._prop = Propagator(s.body, attitude=s.attitude, angular_velocity=s.angular_velocity,
                                dissipation=s.dissipation, integrator=name, t=t)
        self._integrator, self._integrator_reason = name, reason
        self._selection_generation += 1
        if pending:
            self._start_selection()
        self._torque = None
        self._cmd_expiry_t = math.inf
        self._fault = None
        self._finished = False
        self._scene_t0 = t
        self._set_grid(h_max, t=t, k=0 if initial else self._k)
        self._set_baseline()
        self._anchor()
        self._last_diag_wall = time.monotonic()
        self._last_diag_t = t
        self._next_diag_wall = self._last_diag_wall  # first diagnostics at once
        self._next_refresh_wall = 0.0

    def _set_grid(self, h_max, t=None, k=None):
        """Step h = largest step <= h_max dividing the publish period; publish ticks from t on.

        Between publish instants the change waits for the next one (``_advance`` applies
        it), so the publish grid keeps its phase and sim time its spacing.
        """
        if t is None and k is None and (self._k - self._seg_k) % self._steps_per_publish:
            self._pending_h_max = self._h_max = h_max  # requested now, applied at the next instant
            return
        self._pending_h_max = None
        # Read the current time before the step changes: _t() depends on _h.
        seg_t = self._t() if t is None else t
        period = 1.0 / self._p['publish_rate']
        self._steps_per_publish = max(1, math.ceil(period / h_max - 1e-9))
        self._h = period / self._steps_per_publish
        self._h_max = h_max
        self._seg_t = seg_t
        self._k = self._k if k is None else k  # total steps taken (monotonic)
        self._seg_k = self._k
        self._cmd_expiry_k = self._expiry_step()

    def _t(self) -> float:
        """Current sim time (s)."""
        return self._seg_t + (self._k - self._seg_k) * self._h

    def _expiry_step(self):
        """First step index at which the held command no longer applies."""
        if self._torque is None or not math.isfinite(self._cmd_expiry_t):
            return sys.maxsize
        return self._seg_k + max(0, math.ceil((self._cmd_expiry_t - self._seg_t) / self._h - 1e-9))

    def _set_baseline(self):
        """Reference T, |L| and L_inertial for drift (at start, reset, torque end, scene change)."""
        p = self._prop
        self._base_T = float(p.kinetic_energy)
        self._base_L = p.angular_momentum_inertial.copy()
        self._base_Lnorm = float(np.linalg.norm(self._base_L))
        self._base_t = self._t()

    def _anchor(self):
        """Pace from now: sim time self._t() corresponds to wall time now."""
        self._wall_anchor = time.monotonic()
        self._sim_anchor = self._t()

    def _reselect(self):
        """Choose the integrator again (after a torque, parameter or scene change), state continuous."""
        s = self._scene
        name, h_max, reason, pending = choose_integrator(self._p, s, self._prop.attitude,
                                                         self._prop.angular_velocity, torque=self._torque_seen)
        self._selection_generation += 1
        self._use_integrator(name, h_max, reason)
        if pending:
            self._start_selection()

    def _use_integrator(self, name, h_max, reason):
        if name != self._integrator:
            self._prop.set_integrator(name)
        self._integrator, self._integrator_reason = name, reason
        if abs(h_max - self._h_max) > 1e-15 * h_max:
            self._set_grid(h_max)
            self._anchor()

    def _start_selection(self):
        """Run select() in a worker thread for the current state; applied by _poll_selection."""
        generation = self._selection_generation
        args = (dict(self._p), self._scene, self._prop.attitude.copy(), self._prop.angular_velocity.copy(),
                self._torque_seen)

        def work():
            self._selection_result = (generation, run_selection(*args))

        threading.Thread(target=work, name='integrator-selection', daemon=True).start()

    def _poll_selection(self):
        result, self._selection_result = self._selection_result, None
        if result is None:
            return
        generation, (name, h_max, reason) = result
        if generation != self._selection_generation or self._p['integrator'] != AUTO:
            return  # superseded by a later reset/parameter change
        self._catch_up()
        self._use_integrator(name, h_max, reason)
        self._log.info(f'integrator selected: {name}, step {self._h:.6g} s ({reason})')

    def _summary(self) -> str:
        p = self._p
        duration = 'until stopped' if p['duration'] == 0 else f"{p['duration']:g} s"
        rtf = 'as fast as possible' if p['real_time_factor'] == 0 else f'{p["real_time_factor"]:g}x real time'
        return (f'{NODE_NAME}: integrator {self._integrator} ({self._integrator_reason}), step {self._h:.6g} s, '
                f'publish {1.0 / (self._h * self._steps_per_publish):g} Hz, {rtf}, '
                f'clock {"on" if p["publish_clock"] else "off"}, '
                f'frames {p["frame_id"]} <- {p["child_frame_id"]}, qos {p["qos"]}, '
                f'duration {duration}')

    def _apply_frames(self):
        self._msgs.set_frames(self._p['frame_id'], self._p['child_frame_id'])

    # ======================================================================== hot path
    def _advance(self, n_steps: int, wall_deadline: float) -> int:
        """Up to ``n_steps`` physics steps, publishing at publish ticks; stops at ``wall_deadline``."""
        if self._fault or self._finished:
            return 0
        prop_step = self._prop.step
        h, spp = self._h, self._steps_per_publish
        done = 0
        end_k = self._end_step()
        try:
            while done < n_steps:
                k = self._k
                m = min(spp - (k - self._seg_k) % spp, n_steps - done, end_k - k)
                if m <= 0 and k >= end_k:
                    self._finish()
                    return done
                torque = self._torque
                if torque is not None:
                    if k >= self._cmd_expiry_k:
                        self._expire_command()
                        continue
                    m = min(m, self._cmd_expiry_k - k)
                for _ in range(m):
                    prop_step(h, torque)
                self._k = k = k + m
                done += m
                if (k - self._seg_k) % spp == 0:
                    self._publish_tick()
                    if self._fault:
                        return done
                    if self._pending_h_max is not None:  # a step change waiting for this instant
                        self._set_grid(self._pending_h_max)
                        self._anchor()
                        h, spp, end_k = self._h, self._steps_per_publish, self._end_step()
                if k >= end_k:
                    self._finish()
                    return done
                if time.monotonic() > wall_deadline:
                    break
        except IntegrationError as exc:
            self._set_fault(f'integrator failed: {exc}')
        except Exception as exc:  # noqa: BLE001 - never die with a traceback on bad input
            self._set_fault(f'physics error: {type(exc).__name__}: {exc}')
        return done

    def _end_step(self) -> int:
        if self._p['duration'] <= 0:
            return sys.maxsize
        t_end = self._scene_t0 + self._p['duration']
        return self._seg_k + max(0, math.ceil((t_end - self._seg_t) / self._h - 1e-9))

    def _publish_tick(self):
        """Publish the state at the current step (a publish instant)."""
        t = self._t()
        p = self._prop
        q = p.attitude
        qx, qy, qz, qw = (q / math.sqrt(float(q @ q))).tolist()
        wx, wy, wz = p.angular_velocity.tolist()
        lx, ly, lz = p.angular_momentum_inertial.tolist()
        bx, by, bz = p.angular_momentum_body.tolist()
        ke = float(p.kinetic_energy)
        if not math.isfinite(qx + qy + qz + qw + wx + wy + wz + lx + ly + lz + bx + by + bz + ke):
            self._set_fault(f'state became non-finite at t = {t:.9g} s')
            return
        if self._p['publish_clock']:
            set_stamp(self._stamp, t)
        else:
            self._stamp.sec, self._stamp.nanosec = divmod(self.get_clock().now().nanoseconds, 1_000_000_000)
        m = self._msgs
        quat, omega = m.quaternion, m.omega
        quat.x, quat.y, quat.z, quat.w = qx, qy, qz, qw
        omega.x, omega.y, omega.z = wx, wy, wz
        v = m.angular_momentum.vector
        v.x, v.y, v.z = lx, ly, lz
        v = m.angular_momentum_body.vector
        v.x, v.y, v.z = bx, by, bz
        m.kinetic_energy.data = ke
        for publisher, msg in self._active:
            publisher.publish(msg)
        self._published_ticks += 1
        rtf = self._p['real_time_factor']
        if rtf > 0:  # missed deadline: published later than one publish period after its due time
            late = time.monotonic() - (self._wall_anchor + (t - self._sim_anchor) / rtf)
            if late > self._h * self._steps_per_publish / rtf:
                self._missed += 1

    def _expire_command(self):
        self._torque = None
        self._cmd_expiry_k = sys.maxsize
        self._cmd_expiry_t = math.inf
        self._timed_out += 1
        self._set_baseline()

    def _finish(self):
        self._finished = True
        self._log.info(f'duration {self._p["duration"]:g} s reached at t = {self._t():.6g} s; stopping')
        self._publish_diagnostics()

    def _set_fault(self, reason: str):
        self._fault = reason
        self._torque = None
        self._log.error(f'simulation stopped: {reason}; fix parameters and call ~/reset')
        self._publish_diagnostics()

    # ======================================================================== loop
    def run_once(self) -> float:
        """Advance what is due; returns the seconds the executor may wait before the next call."""
        if self._selection_result is not None:
            self._poll_selection()
        now = time.monotonic()
        if now >= self._next_refresh_wall:
            self._refresh_subscribers()
            self._next_refresh_wall = now + SUBSCRIBER_REFRESH_S
        rtf = self._p['real_time_factor']
        wait = 0.0
        if self._fault or self._finished:
            wait = 0.1
        elif rtf == 0:
            self._advance(sys.maxsize, now + CHUNK_WALL_S)
        else:
            self._catch_up(now)
            period = self._h * self._steps_per_publish
            next_tick_t = self._seg_t + (((self._k - self._seg_k) // self._steps_per_publish) + 1) * period
            wait = self._wall_anchor + (next_tick_t - self._sim_anchor) / rtf - time.monotonic()
        now = time.monotonic()
        if now >= self._next_diag_wall:
            self._publish_diagnostics()
        return min(max(wait, 0.0), self._next_diag_wall - now, 0.1)

    def _catch_up(self, now=None):
        """Real-time modes: take the steps that are due by the wall clock."""
        rtf = self._p['real_time_factor']
        if rtf == 0 or self._fault or self._finished:
            return
        now = time.monotonic() if now is None else now
        target = self._sim_anchor + rtf * (now - self._wall_anchor)
        t = self._t()
        n_due = math.floor((target - t) / self._h + 1e-9)
        if n_due > 0:
            self._advance(n_due, now + CHUNK_WALL_S * 5)
        if (target - self._t()) / rtf > MAX_LAG_S:  # cannot keep up: drop the backlog
            self._anchor()

    def _refresh_subscribers(self):
        self._active = [(pub, msg) for pub, msg in self._pubs if pub.get_subscription_count() > 0]
        if self._clock_pub is not None:
            self._active.append((self._clock_pub, self._clock_msg))

    def run(self):
        """Spin until shutdown or ``duration`` is reached."""
        executor = SingleThreadedExecutor(context=self.context)
        executor.add_node(self)
        self._anchor()  # pace from the first turn of the loop, not from construction
        try:
            while self.context.ok() and not self._finished:
                executor.spin_once(timeout_sec=self.run_once())
        finally:
            executor.remove_node(self)
            executor.shutdown(timeout_sec=0)

    @property
    def finished(self) -> bool:
        return self._finished

    # ======================================================================== commands
    def _current_stamp_time(self) -> float:
        if self._p['publish_clock']:
            return self._t()
        return self.get_clock().now().nanoseconds * 1e-9

    def _reject(self, reason: str, source: str, detail: str):
        """Count, warn (throttled per reason), never apply."""
        self._rejected[reason] += 1
        now = time.monotonic()
        if now >= self._next_warn.get(reason, 0.0):
            self._next_warn[reason] = now + WARN_THROTTLE_S
            self._log.warn(f'{source} rejected ({reason}): {detail}; torque not applied '
                           f'({self._rejected[reason]} {reason} rejections so far)')

    def _on_command(self, header, vector, source):
        x, y, z = vector.x, vector.y, vector.z
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
            return self._reject('non_finite', source, f'torque ({x}, {y}, {z}) is not finite')
        frame = header.frame_id.lstrip('/')
        if frame not in ('', self._p['child_frame_id']):
            return self._reject('wrong_frame', source, f'frame_id {header.frame_id!r}: torque must be in the '
                                f'body frame {self._p["child_frame_id"]!r} (or frame_id empty)')
        stamp = header.stamp.sec + 1e-9 * header.stamp.nanosec
        if stamp != 0.0:
            now = self._current_stamp_time()
            if stamp - now > self._p['command_stamp_tolerance']:
                hint = ' (does the sender use_sim_time? this node publishes /clock)' \
                    if self._p['publish_clock'] else ''
                return self._reject('future_stamp', source, f'stamp {stamp:.6f} is {stamp - now:.3g} s ahead '
                                    f'of this node\'s clock{hint}')
            if now - stamp > self._p['command_timeout']:
                return self._reject('stale_stamp', source, f'stamp {stamp:.6f} is {now - stamp:.3g} s old, '
                                    f'more than command_timeout')
        if self._fault or self._finished:
            return
        self._catch_up()  # steps due before the arrival run with the previous command
        limit = self._p['max_torque']
        torque = np.array((x, y, z))
        if np.any(np.abs(torque) > limit):
            np.clip(torque, -limit, limit, out=torque)
            self._saturated += 1
        self._accepted += 1
        if not torque.any():
            if self._torque is not None:
                self._torque = None
                self._set_baseline()
            self._cmd_expiry_t = math.inf
            self._cmd_expiry_k = sys.maxsize
            return
        if self._torque is None and not self._torque_seen:
            self._torque_seen = True
            if self._p['integrator'] == AUTO:
                self._reselect()
                self._log.info(f'first torque command: integrator {self._integrator} ({self._integrator_reason})')
        self._torque = torque
        self._cmd_expiry_t = self._t() + self._p['command_timeout']
        self._cmd_expiry_k = self._expiry_step()

    # ======================================================================== reset
    def _on_reset(self, request, response):
        self._start_scene()
        response.success = True
        response.message = (f'reset to the initial state at t = {self._t():.6g} s; integrator '
                            f'{self._integrator} ({self._integrator_reason})')
        self._log.info(response.message)
        self._next_diag_wall = time.monotonic()
        return response

    # ======================================================================== parameters
    def _validate_parameters(self, params) -> SetParametersResult:
        return validate_update(SPECS, self._p, params, check_parameters)

    def _apply_parameters(self, params):
        changed = changed_values(SPECS, self._p, params)
        if not changed:
            return
        self._catch_up()  # what was due runs under the old values
        self._p.update(changed)
        scene = check_parameters(self._p)
        if any(k in changed for k in SCENE_PARAMS):
            self._log.info(f'{", ".join(k for k in SCENE_PARAMS if k in changed)} changed: '
                           'takes effect on ~/reset')
        if 'dissipation.model' in changed or 'dissipation.coefficient' in changed:
            # applies at once with the state carried over; other scene changes wait for ~/reset
            self._scene = Scene(self._scene.body, scene.dissipation, self._scene.attitude,
                                self._scene.angular_velocity)
            p = self._prop
            self._prop = Propagator(p.body, attitude=p.attitude, angular_velocity=p.angular_velocity,
                                    dissipation=scene.dissipation, integrator=self._integrator, t=p.t)
            self._set_baseline()
        if {'integrator', 'step', 'accuracy', 'publish_rate', 'duration',
                'dissipation.model', 'dissipation.coefficient'} & changed.keys():
            self._reselect()
            self._set_grid(self._h_max)
        if 'frame_id' in changed or 'child_frame_id' in changed:
            self._apply_frames()
        if 'publish_clock' in changed and self._p['publish_clock'] and self._clock_pub is None:
            self._clock_pub = self.create_publisher(Clock, '/clock', qos_profile('reliable'))
        if 'max_torque' in changed and self._torque is not None:
            np.clip(self._torque, -self._p['max_torque'], self._p['max_torque'], out=self._torque)
        if 'command_timeout' in changed and self._torque is not None:
            self._cmd_expiry_t = self._t() + self._p['command_timeout']
            self._cmd_expiry_k = self._expiry_step()
        self._anchor()
        self._refresh_subscribers()
        self._next_diag_wall = time.monotonic()
        self._log.info('parameters changed: ' + ', '.join(f'{k}={v}' for k, v in changed.items())
                       + f' -> {self._summary()}')

    # ======================================================================== diagnostics
    def _publish_diagnostics(self):
        now = time.monotonic()
        t = self._t()
        wall = now - self._last_diag_wall
        achieved = (t - self._last_diag_t) / wall if wall > 0 else 0.0
        self._last_diag_wall, self._last_diag_t = now, t
        self._next_diag_wall = now + DIAGNOSTICS_PERIOD_S
        p = self._prop
        T = float(p.kinetic_energy)
        L = p.angular_momentum_inertial
        Lnorm = float(np.linalg.norm(L))
        q_int, _ = p.principal_state
        torque_on = self._torque is not None
        values = {
            'integrator': self._integrator,
            'integrator_reason': self._integrator_reason,
            'step': self._h,
            'publish_rate': 1.0 / (self._h * self._steps_per_publish),
            'sim_time': t,
            'real_time_factor_target': self._p['real_time_factor'],
            'real_time_factor_achieved': achieved,
            'kinetic_energy': T,
            'angular_momentum_norm': Lnorm,
            'drift_since': self._base_t,
            'kinetic_energy_drift': 'n/a (torque applied)' if torque_on else
            (T - self._base_T) / self._base_T if self._base_T > 0 else 0.0,
            'angular_momentum_norm_drift': 'n/a (torque applied)' if torque_on else
            (Lnorm - self._base_Lnorm) / self._base_Lnorm if self._base_Lnorm > 0 else 0.0,
            'angular_momentum_inertial_drift': 'n/a (torque applied)' if torque_on else
            float(np.linalg.norm(L - self._base_L)) / self._base_Lnorm if self._base_Lnorm > 0 else 0.0,
            'quaternion_norm_error': abs(float(np.linalg.norm(q_int)) - 1.0),
            'energy_dissipated': max(0.0, self._base_T - T) if self._scene.dissipation.active and not torque_on
            else 0.0,
            'torque_applied': torque_on,
            'commands_accepted': self._accepted,
            'commands_saturated': self._saturated,
            'commands_timed_out': self._timed_out,
            **{f'commands_rejected.{r}': n for r, n in self._rejected.items()},
            'missed_deadlines': self._missed,
            'fault': self._fault or '',
        }
        if self._fault:
            level, message = 'ERROR', f'stopped: {self._fault}'
        elif self._finished:
            level, message = 'OK', f'duration reached at t = {t:.6g} s'
        elif self._missed > self._missed_at_last_diag:
            level, message = 'WARN', (f'{self._missed - self._missed_at_last_diag} missed deadlines in the last '
                                      f'{wall:.2g} s: cannot keep the real-time factor')
        else:
            level, message = 'OK', f'running, t = {t:.3f} s'
        self._missed_at_last_diag = self._missed
        status = diagnostic_status(f'{self.get_name()}: simulation', self.get_fully_qualified_name(), level,
                                   message, values)
        array = DiagnosticArray(status=[status])
        if self._p['publish_clock']:
            set_stamp(array.header.stamp, t)
        else:
            array.header.stamp = self.get_clock().now().to_msg()
        self._diag_pub.publish(array)


def main(args=None):
    """Entry point of ``ros2 run rigid_body_sim simulator``; returns the exit code."""
    try:
        rclpy.init(args=args)
    except Exception as exc:  # bad --ros-args (e.g. an invalid name in a remap): no traceback
        print(f'[FATAL] [{NODE_NAME}]: cannot initialise ROS: {exc}', file=sys.stderr)
        return 2
    node = None
    try:
        node = Simulator()
        node.run()
        return 0
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    except SceneError as exc:
        rclpy.logging.get_logger(NODE_NAME).fatal(f'invalid parameters: {exc}')
        return 2
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
