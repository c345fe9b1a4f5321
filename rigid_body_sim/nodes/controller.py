"""``attitude_controller``: detumble and slew a simulated (or real) spacecraft.

A thin shell over :mod:`rigid_body_sim.control` (the law, shared with offline runs):
messages and parameters in, ``torque_command`` out at ``control_rate`` — its own rate,
independent of the simulator's step and publish rate.

Topics (relative names, remappable):
    sub ``attitude`` (geometry_msgs/QuaternionStamped, body→``frame_id``),
        ``angular_velocity`` (geometry_msgs/Vector3Stamped, body frame),
        ``attitude_target`` (geometry_msgs/QuaternionStamped, in the attitude's frame_id or empty).
        With ``feedback: sensors``, instead of attitude and angular_velocity: ``gyro``
        (sensor_msgs/Imu, body frame) and ``star_tracker`` (geometry_msgs/QuaternionStamped)
        through ``sensors.estimator.AttitudeEstimator``; the estimate is the state (its
        age is the last gyro reading's; no state before the first fix). In lockstep,
        instead of attitude and angular_velocity: ``odometry`` (nav_msgs/Odometry, its
        orientation and its twist's angular rate, one message a state).
    pub ``torque_command`` (geometry_msgs/Vector3Stamped, body frame ``child_frame_id``,
        stamped with the node clock; in lockstep with the answered state's), ``/diagnostics``.

Time. The age of the state is the node clock minus the older of the two state stamps (a
zero stamp counts as received now), so it works with ``use_sim_time`` as well. State
older than ``state_timeout`` (or none yet) gives explicit zero torque and a throttled
warning; so does mode ``off``.

Lockstep (``lockstep: true``, for the simulator's lockstep: docs/live-nodes.md). No timer:
each state whose attitude and angular velocity share a stamp that is a multiple of the
control period (the simulator stamps with sim time) is answered at once with a command
stamped with that stamp; the law's time is the stamp, so no state is ever stale. The
commands are then published transient-local with a history of ``LOCKSTEP_HISTORY``: a
recorder this node discovers only after t = 0 (discovery between two processes can take
seconds on a loaded machine, and the simulator cannot see whether it has happened) still
gets every command from the first (recorder.py asks for the history). In ``bdot`` mode
the state is answered once the magnetometer's reading of that instant is in too, with the
dipole_command as well (zero while the mission is in another mode): the simulator awaits
both (bdot_commands.py).

Target. ``target_attitude`` (parameter) sets the target at start and whenever it is set;
an ``attitude_target`` message replaces it until the parameter is set again (latest wins).
NaN, zero-norm or non-unit targets (|norm − 1| > 1e-3) and targets in a frame other than
the attitude's are rejected with a warning naming the reason; the previous target stays.
"""
import math
import sys
import time

import numpy as np
import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, ReliabilityPolicy
from rcl_interfaces.msg import SetParametersResult

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import QuaternionStamped, Vector3Stamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu

from .. import control
from ..engine import ControlLaw, ControlSettings, specs
from ..sensors.estimator import AttitudeEstimator
from .bdot_commands import BdotCommands
from .commands import odometry_state, vector3_stamped_cdr
from .common import (changed_values, coerce_parameters, declare_parameters, frame_id_problem,
                     qos_profile, stamp_to_seconds, validate_update)
from .controller_diagnostics import Diagnostics
from .process import events_executor, run_node

NODE_NAME = 'attitude_controller'
DIAGNOSTICS_PERIOD_S = 1.0  # wall clock
WARN_THROTTLE_S = 2.0       # wall clock
# an attitude unit to this is used as sent: the law sees exactly what the simulator published
# (renormalising a normalised quaternion can move its last bit), as the offline law does
UNIT_TOLERANCE = 1e-12
LOCKSTEP_HISTORY = 1000     # lockstep: commands kept for late-joining subscribers


SPECS = specs.CONTROLLER  # ROS-free specs, shared with scene files and offline runs


def build_config(p) -> control.ControlConfig:
    """ControlConfig from coerced parameter values; ValueError with the reason."""
    return control.config_from_parameters(p)


def check_parameters(p):
    """(config, target) for a full set of coerced values; ValueError(reason)."""
    problem = frame_id_problem(p['child_frame_id'])
    if problem:
        raise ValueError(f'child_frame_id {p["child_frame_id"]!r} {problem}')
    try:
        target = control.validated_target(p['target_attitude'])
    except ValueError as exc:
        raise ValueError(f'target_attitude: {exc}') from None
    if p['lockstep'] and p['feedback'] != 'truth':
        raise ValueError('lockstep answers the simulator\'s state: it needs feedback truth, '
                         f'not {p["feedback"]!r}')
    return build_config(p), target


class Controller(Diagnostics, Node):
    """The ``attitude_controller`` node."""

    def __init__(self, **kwargs):
        # undeclared names reach our on-set check, which refuses them with a reason
        super().__init__(NODE_NAME, allow_undeclared_parameters=True, **kwargs)
        self._p = declare_parameters(self, SPECS)  # ValueError on bad overrides
        # `mode:=off` arrived as false
        if self.get_parameter('mode').type_ != Parameter.Type.STRING:
            self.set_parameters([Parameter('mode', Parameter.Type.STRING, self._p['mode'])])
        check_parameters(self._p)
        self._log = self.get_logger()
        # The law and its scene schedule: the object the offline engine runs as a torque source,
        # the law interpreted: one command per control period does not need numba, whose
        # import and kernel load cost each start 0.7 CPU-s (bit for bit the same torques)
        self._law = ControlLaw(ControlSettings.from_parameters(self._p), compiled=False)
        self._ctl = self._law.controller

        # latest state: value, stamp (s, node clock), frame of the attitude
        self._q = None
        self._w = None
        self._q_stamp = None
        self._w_stamp = None
        self._q_ns = self._w_ns = self._answered_ns = None  # lockstep: stamps in ns
        self._attitude_frame = None
        self._last = None           # last ControlOutput (None while stale / off / no state)
        self._age = math.inf
        self._stale_reason = 'no state received yet'
        self._published = 0
        # since the last diagnostics
        self._ticks = self._saturated_ticks = self._rate_limited_ticks = 0
        self._rejected_targets = 0
        self._last_reject = ''
        self._rejected_states = 0
        self._next_warn = {}

        qos = qos_profile(self._p['qos'])
        command_qos = qos
        if self._p['lockstep'] and qos.reliability == ReliabilityPolicy.RELIABLE:
            command_qos = qos_profile('reliable', LOCKSTEP_HISTORY)
            command_qos.durability = DurabilityPolicy.TRANSIENT_LOCAL
        self._pub = self.create_publisher(Vector3Stamped, 'torque_command', command_qos)
        self._diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics',
                                               qos_profile('reliable'))
        self._estimator = None
        if self._p['feedback'] == 'sensors':  # the law sees the estimator, never the truth
            self._estimator = AttitudeEstimator(self._p['estimator.bandwidth'])
            self.create_subscription(Imu, 'gyro', self._on_gyro, qos)
            self.create_subscription(QuaternionStamped, 'star_tracker', self._on_star_tracker,
                                     qos)
        elif self._p['lockstep']:  # one message a state, raw (_on_odometry: why)
            self.create_subscription(Odometry, 'odometry', self._on_odometry, qos, raw=True)
        else:
            self.create_subscription(QuaternionStamped, 'attitude', self._on_attitude, qos)
            self.create_subscription(Vector3Stamped, 'angular_velocity',
                                     self._on_angular_velocity, qos)
        self.create_subscription(QuaternionStamped, 'attitude_target', self._on_target, qos)
        lockstep_ns = round(1e9 / self._p['control_rate']) if self._p['lockstep'] else 0
        self._bdot = None if self._p['mode'] != 'bdot' else BdotCommands(  # the rods' law
            self, self._p, float(self._ctl.config.body.principal_moments.min()),
            qos, lockstep_ns, self._answer, command_qos)
        self._timer = None if self._p['lockstep'] else \
            self.create_timer(1.0 / self._p['control_rate'], self._tick)
        self.create_timer(DIAGNOSTICS_PERIOD_S, self._publish_diagnostics,
                          clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        self._log.info(self._summary())

    # ------------------------------------------------------------------ helpers
    def _summary(self) -> str:
        c = self._ctl.config
        limit = 'unlimited' if not math.isfinite(c.torque_limit) else f'{c.torque_limit:g} N*m'
        return (f'mode {self._ctl.mode}, {self._p["control_rate"]:g} Hz; '
                f'kp {np.round(c.kp_principal, 6).tolist()}, '
                f'kd {np.round(c.kd_principal, 6).tolist()}, '
                f'K_w {np.round(c.rate_gain_principal, 6).tolist()} '
                f'(principal axes), '
                f'gyroscopic compensation {"on" if c.gyroscopic_compensation else "off"}, '
                f'max_torque {limit}, target {np.round(self._ctl.target, 6).tolist()}')

    def _warn(self, key: str, text: str):
        now = time.monotonic()
        if now >= self._next_warn.get(key, 0.0):
            self._next_warn[key] = now + WARN_THROTTLE_S
            self._log.warn(text)

    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _stamp_or_now(self, header) -> float:
        s = stamp_to_seconds(header.stamp)
        return s if s != 0.0 else self._now()

    # ------------------------------------------------------------------ inputs
    def _on_attitude(self, msg: QuaternionStamped):
        o = msg.quaternion
        q = np.array((o.x, o.y, o.z, o.w))
        n = float(np.linalg.norm(q))
        if not (np.all(np.isfinite(q)) and n > 1e-6):
            self._rejected_states += 1
            return self._warn('bad_attitude', f'attitude {q.tolist()} ignored: '
                                              'not a rotation (NaN/Inf or zero)')
        self._q = q if abs(n - 1.0) <= UNIT_TOLERANCE else q / n
        self._q_stamp = self._stamp_or_now(msg.header)
        self._attitude_frame = msg.header.frame_id.lstrip('/')
        if self._timer is None:
            self._q_ns = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
            self._answer(msg.header.stamp)

    def _on_odometry(self, data: bytes):
        """Lockstep: the state as one nav_msgs/Odometry (CDR bytes, decoded by
        ``commands.odometry_state``), the attitude and body rate of one stamp, which the
        simulator publishes from the same values as attitude and angular_velocity. One
        message instead of those two halves the simulator's writes per exchange, each of
        which costs its process tens of µs (docs/live-nodes.md, "Lockstep")."""
        attitude, rate = odometry_state(data)
        self._on_attitude(attitude)
        self._on_angular_velocity(rate)

    def _on_angular_velocity(self, msg: Vector3Stamped):
        v = msg.vector
        w = np.array((v.x, v.y, v.z))
        if not np.all(np.isfinite(w)):
            self._rejected_states += 1
            return self._warn('bad_rate', f'angular_velocity {w.tolist()} ignored: not finite')
        self._w = w
        self._w_stamp = self._stamp_or_now(msg.header)
        if self._timer is None:
            self._w_ns = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
            self._answer(msg.header.stamp)

    def _answer(self, stamp):
        """Lockstep: the state at a control instant, once both halves of it are in, is
        answered now with a command stamped like it (its law time: the stamp)."""
        t_ns = self._q_ns
        period = round(1e9 / self._p['control_rate'])
        if t_ns is None or t_ns != self._w_ns or t_ns % period or t_ns == self._answered_ns:
            return
        if self._bdot is not None:  # B-dot: its reading of the instant too, then its law
            if not self._bdot.ready(t_ns):
                return
            self._bdot.step(t_ns, self._ctl.mode == 'bdot')
        self._answered_ns = t_ns
        self._age, self._stale_reason = 0.0, ''
        self._command(t_ns / 1e9, stamp)

    def _on_gyro(self, msg: Imu):
        """A gyro reading (body frame): propagate the estimate; it becomes the state."""
        v = msg.angular_velocity
        w = np.array((v.x, v.y, v.z))
        if not np.all(np.isfinite(w)):
            self._rejected_states += 1
            return self._warn('bad_gyro', f'gyro {w.tolist()} ignored: not finite')
        t = self._stamp_or_now(msg.header)
        t_ns = round(t * 1e9)
        self._estimator.gyro(t_ns, w)
        estimate = self._estimator.estimate(t_ns)
        if estimate is not None:  # after the first star-tracker fix
            self._q, self._w = estimate
            self._q_stamp = self._w_stamp = t

    def _on_star_tracker(self, msg: QuaternionStamped):
        """A star-tracker fix (body -> frame_id): correct the estimate."""
        o = msg.quaternion
        q = np.array((o.x, o.y, o.z, o.w))
        if not (np.all(np.isfinite(q)) and np.linalg.norm(q) > 1e-6):
            self._rejected_states += 1
            return self._warn('bad_fix', f'star_tracker {q.tolist()} ignored: not a rotation '
                                         '(NaN/Inf or zero)')
        self._estimator.star_tracker(round(self._stamp_or_now(msg.header) * 1e9), q)
        self._attitude_frame = msg.header.frame_id.lstrip('/')

    def _on_target(self, msg: QuaternionStamped):
        o = msg.quaternion
        frame = msg.header.frame_id.lstrip('/')
        try:
            if frame and self._attitude_frame is not None and frame != self._attitude_frame:
                raise ValueError(f'frame_id {msg.header.frame_id!r} differs from the attitude\'s '
                                 f'{self._attitude_frame!r} (or leave it empty)')
            self._ctl.set_target((o.x, o.y, o.z, o.w))
        except ValueError as exc:
            self._rejected_targets += 1
            self._last_reject = str(exc)
            self._log.warn(f'attitude_target rejected: {exc}; '
                           f'keeping target {np.round(self._ctl.target, 6).tolist()}')
            return
        self._log.info(f'new target {np.round(self._ctl.target, 6).tolist()}')

    # ------------------------------------------------------------------ control tick
    def _tick(self):
        now = self._now()
        if self._q is None or self._w is None:
            self._age = math.inf
            self._stale_reason = 'no state received yet' if self._estimator is None else \
                'no estimate yet (it needs gyro readings and a star_tracker fix)'
        else:
            self._age = now - min(self._q_stamp, self._w_stamp)
            if self._age > self._p['state_timeout']:
                self._stale_reason = (f'state is {self._age:.3g} s old (> state_timeout '
                                      f'{self._p["state_timeout"]:g} s)')
            else:
                self._stale_reason = ''
        if self._stale_reason:
            if self._ctl.mode not in ('off', 'bdot'):  # bdot needs the magnetometer only
                self._warn('no_state' if self._q is None or self._w is None else 'stale',
                           f'{self._stale_reason}: commanding zero torque')
        self._command(self._w_stamp, self.get_clock().now().to_msg())

    def _command(self, t: float, stamp):
        """Publish the law's torque for the current state at state time ``t`` (zero when
        stale, off or free), stamped ``stamp``."""
        torque = (0.0, 0.0, 0.0)
        self._last = None
        if not self._stale_reason and (self._ctl.mode != 'off' or self._law.mission.active):
            tau, free, switched = self._law.evaluate(t, self._q, self._w)
            if switched:
                self._log.info(f'|w| = {np.linalg.norm(self._w):.3g} rad/s < '
                               f'mission.detumble_exit_rate: switching to {switched}')
                self.set_parameters([Parameter('mode', value=switched)])
            if not free and self._ctl.mode != 'off':
                self._last = self._law.last
                torque = tuple(float(x) for x in tau)
                self._saturated_ticks += self._last.saturated
                self._rate_limited_ticks += self._last.rate_limited
        self._ticks += 1
        # its CDR bytes, built directly (commands.py: why); in lockstep the stamp is a
        # decoded state's (commands._Fields), else the clock's
        self._pub.publish(vector3_stamped_cdr(stamp.sec, stamp.nanosec,
                                              self._p['child_frame_id'], *torque))
        self._published += 1
        if self._bdot is not None and (self._ctl.mode == 'bdot' or self._timer is None):
            self._bdot.publish(stamp)  # lockstep: every instant, as the simulator awaits it

    # ------------------------------------------------------------------ parameters
    def _validate_parameters(self, params) -> SetParametersResult:
        return validate_update(SPECS, self._p, params, check_parameters)

    def _apply_parameters(self, params):
        changed = changed_values(SPECS, self._p, params)
        # setting it (even to the same value) re-asserts it
        if any(p.name == 'target_attitude' for p in params):
            changed['target_attitude'] = coerce_parameters(SPECS, params)['target_attitude']
        if not changed:
            return
        self._p.update(changed)
        config, target = check_parameters(self._p)
        self._ctl.set_config(config)
        if 'target_attitude' in changed:
            self._ctl.set_target(target)
        if 'mode' in changed:
            self._ctl.set_mode(self._p['mode'])
        if 'mission.free_time' in changed or 'mission.detumble_exit_rate' in changed:
            start = self._law.mission.start  # keep the schedule's time origin
            self._law.mission = control.Mission(self._p['mission.free_time'],
                                                self._p['mission.detumble_exit_rate'])
            self._law.mission.start = start
        if 'control_rate' in changed and self._timer is not None:
            self.destroy_timer(self._timer)
            self._timer = self.create_timer(1.0 / self._p['control_rate'], self._tick)
        self._log.info(f'{", ".join(sorted(changed))} changed: {self._summary()}')


def _spin(node: Controller):
    """In lockstep, rclpy's C++ events executor (turned as the viewer turns it): each
    exchange is two state callbacks, and the Python executor rebuilds its wait set over
    every subscription, service and timer at each, which held the simulator's round trip
    longer than the law and the messages together. Otherwise rclpy.spin: the control
    timer may run on sim time (use_sim_time), which the events executor is not used for."""
    if not node._p['lockstep']:
        return rclpy.spin(node)
    with events_executor(node) as executor:
        while node.context.ok():
            executor.spin_once(timeout_sec=0.1)


def main(args=None):
    """Entry point of ``ros2 run rigid_body_sim controller``; returns the exit code."""
    return run_node(NODE_NAME, Controller, run=_spin, args=args, lockstep=True)


if __name__ == '__main__':
    sys.exit(main())
