"""Closed loop over real messages: simulator and controller as separate processes.

The offline tests (test_control.py) check the law's claims exactly; here the same claims
are re-checked through ROS with the latency of real messages (state published at 100 Hz,
torque at 50 Hz, each hop adding up to one period of delay). At ω_n = 1 rad/s a loop delay
of ~30 ms is a ~2° phase lag, so overshoot and settling time keep the issue's tolerances;
only the start time t0 (the stamp of the first non-zero torque command) is taken from the
messages instead of being known.
"""
import math
import signal
import time

import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy')
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from geometry_msgs.msg import QuaternionStamped, Vector3Stamped  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from ros_helpers import spin_until, venv_exe  # noqa: E402
from rigid_body_sim import control as C  # noqa: E402
from rigid_body_sim.physics import rotation  # noqa: E402

INERTIA = [1.0, 2.0, 3.0]
WN = 1.0


def ros_args(namespace, params):
    args = ['--ros-args', '-r', f'__ns:={namespace}', '--log-level', 'info']
    for k, v in params.items():
        if isinstance(v, bool):
            v = 'true' if v else 'false'
        elif isinstance(v, (list, tuple)):
            v = '[' + ','.join(repr(float(x)) for x in v) + ']'
        args += ['-p', f'{k}:={v}']
    return args


def start_simulator(ros_process, namespace, **params):
    base = dict(inertia=INERTIA, initial_attitude=[0.0, 0.0, 0.0, 1.0],
                initial_angular_velocity=[0.0, 0.0, 0.0],
                integrator='splitting2', step=0.001, publish_rate=100.0, real_time_factor=1.0,
                max_torque=100.0, command_timeout=0.5)
    base.update(params)
    return ros_process(venv_exe('simulator'), *ros_args(namespace, base))


def start_controller(ros_process, namespace, **params):
    base = dict(inertia=INERTIA, natural_frequency=WN, control_rate=50.0,
                max_torque=0.0)  # unlimited
    base.update(params)
    return ros_process(venv_exe('controller'), *ros_args(namespace, base))


def stamp(msg):
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


class Recorder:
    """Collects state, torque and diagnostics of one namespace on the probe node."""

    def __init__(self, node, namespace):
        self.node, self.ns = node, namespace
        self.attitude, self.rate, self.torque, self.diagnostics = [], [], [], []
        node.create_subscription(QuaternionStamped, f'{namespace}/attitude', self._att, 50)
        node.create_subscription(Vector3Stamped, f'{namespace}/angular_velocity', self._rate, 50)
        node.create_subscription(Vector3Stamped, f'{namespace}/torque_command', self._torque, 50)
        node.create_subscription(DiagnosticArray, '/diagnostics', self._diag, 50)
        self.target_pub = node.create_publisher(QuaternionStamped,
                                                f'{namespace}/attitude_target', 10)

    def _att(self, m):
        q = m.quaternion
        self.attitude.append((stamp(m), (q.x, q.y, q.z, q.w)))

    def _rate(self, m):
        v = m.vector
        self.rate.append((stamp(m), (v.x, v.y, v.z)))

    def _torque(self, m):
        v = m.vector
        self.torque.append((stamp(m), (v.x, v.y, v.z), m.header.frame_id))

    def _diag(self, m):
        for s in m.status:
            if s.hardware_id == f'{self.ns}/attitude_controller':
                self.diagnostics.append(s)

    def spin(self, seconds):
        spin_until(self.node, lambda: False, seconds)

    def spin_sim(self, seconds, timeout=120.0):
        """Until the state has advanced ``seconds`` of sim time past the first torque (the
        stamps' time; a loaded machine's real-time run may lag the wall clock)."""
        def done():
            onset = self.first_torque_time()
            return onset is not None and self.attitude and \
                self.attitude[-1][0] - onset >= seconds
        assert self.spin_until(done, timeout), (self.first_torque_time(), self.attitude[-1:])

    def spin_until(self, predicate, timeout):
        return spin_until(self.node, predicate, timeout)

    def arrays(self, which):
        rows = getattr(self, which)
        return np.array([r[0] for r in rows]), np.array([r[1] for r in rows])

    def first_torque_time(self):
        """Stamp of the first non-zero torque command received by the probe."""
        for t, v, _ in self.torque:
            if any(v):
                return t
        return None

    def torque_onset(self):
        """The loop's t0 from the body's own state, immune to discovery delays: the first state
        sample where the torque has visibly acted, i.e. |L| = |Iω| (constant while torque-free)
        moved by more than 1e-4 relative, or ω left 0 (at rest). Late by at most one publish
        period (10 ms). Returns (t0, |ω| at the sample before)."""
        t, w = self.arrays('rate')
        L = np.linalg.norm(np.asarray(INERTIA) * w, axis=1)
        moved = np.abs(L - L[0]) > max(1e-4 * L[0], 1e-9)
        assert moved.any(), 'the torque never acted'
        k = int(np.argmax(moved))
        return t[k], float(np.linalg.norm(w[max(k - 1, 0)]))

    def send_target(self, q, frame_id='world'):
        assert spin_until(self.node, lambda: self.target_pub.get_subscription_count() > 0, 10.0)
        msg = QuaternionStamped()
        msg.header.stamp = self.node.get_clock().now().to_msg()
        msg.header.frame_id = frame_id
        (msg.quaternion.x, msg.quaternion.y, msg.quaternion.z,
         msg.quaternion.w) = (float(x) for x in q)
        self.target_pub.publish(msg)

    def last_diagnostic(self):
        return {kv.key: kv.value for kv in self.diagnostics[-1].values} if self.diagnostics else {}


def set_params(node, namespace, **values):
    """Set parameters of the controller in ``namespace``; returns the SetParametersResults."""
    from rclpy.parameter_client import AsyncParameterClient
    client = AsyncParameterClient(node, f'{namespace}/attitude_controller')
    assert client.wait_for_services(10.0)
    future = client.set_parameters([Parameter(k, value=v) for k, v in values.items()])
    assert spin_until(node, future.done, 30.0)
    return future.result().results


def start_loop(rec, ros_process, namespace, mode, sim_params=None, ctl_params=None):
    """Simulator + controller (started in mode 'off'); once the probe hears state, torque and
    diagnostics, switch the controller to ``mode``. The probe then has the whole run on
    record (messages sent before discovery completes would otherwise be lost)."""
    sim = start_simulator(ros_process, namespace, **(sim_params or {}))
    ctl = start_controller(ros_process, namespace, mode='off', **(ctl_params or {}))
    if not rec.spin_until(lambda: len(rec.torque) > 5 and len(rec.rate) > 5
                          and len(rec.attitude) > 5 and rec.diagnostics, 30.0):
        raise AssertionError('loop did not start:\n' + ctl.output() + sim.output())
    assert all(r.successful for r in set_params(rec.node, namespace, mode=mode))
    return sim, ctl


def signed_error_about(attitudes, target, axis):
    qe = C.error_quaternion(attitudes, target)
    return 2.0 * np.arctan2(qe[:, axis], qe[:, 3])


def test_detumble_near_intermediate_axis(ros_process, namespace, rclpy_node):
    rec = Recorder(rclpy_node, namespace)
    w0 = [1e-3, 1.0, 1e-3]  # the intermediate-axis instability grows it ~e^(0.58 t) while we wait
    sim, ctl = start_loop(rec, ros_process, namespace, 'detumble',
                          sim_params=dict(initial_angular_velocity=w0))
    assert rec.spin_until(lambda: rec.rate and np.linalg.norm(rec.rate[-1][1]) < 1e-3,
                          60.0), ctl.output()  # ~3.5 s of sim time; a loaded run lags
    t0, w_start = rec.torque_onset()
    t, w = rec.arrays('rate')
    norm = np.linalg.norm(w, axis=1)
    t_done = t[np.argmax((t > t0) & (norm < 1e-3))] - t0
    # K_ω = k_d = 2ζω_n I: the linear decay |ω₀| e^(−ct), c = 2ω_n, predicts ln(|ω₀|/1e-3)/c.
    predicted = C.detumble_time([w_start], 2.0 * WN)
    print(f'detumble: {t_done:.3f} s, linear prediction {predicted:.3f} s')
    assert t_done <= 1.2 * predicted, (t_done, predicted)
    assert all(frame == 'base_link' for _, _, frame in rec.torque)


def test_slew_90_critically_damped(ros_process, namespace, rclpy_node):
    rec = Recorder(rclpy_node, namespace)
    angle = math.pi / 2
    target = rotation.axis_rotation(2, angle)
    sim, ctl = start_loop(rec, ros_process, namespace, 'slew',
                          ctl_params=dict(target_attitude=list(target)))
    predicted = C.critical_settling_time(WN, 0.02)  # (1 + ω_n t) e^(−ω_n t) = 2 %
    rec.spin_sim(1.3 * predicted + 0.5)
    t0, _ = rec.torque_onset()
    t, q = rec.arrays('attitude')
    err = signed_error_about(q, target, 2)  # −90° at the start
    overshoot = max(0.0, err.max()) / angle
    outside = np.nonzero(np.abs(err) > 0.02 * angle)[0]
    assert outside.size and outside[-1] + 1 < len(t), 'did not settle'
    t_settle = t[outside[-1] + 1] - t0
    print(f'slew 90°: overshoot {100 * overshoot:.3f} %, settling {t_settle:.3f} s, '
          f'linear prediction {predicted:.3f} s')
    assert overshoot < 0.01
    assert 0.8 * predicted <= t_settle <= 1.2 * predicted, (t_settle, predicted)


def test_slew_179_and_retarget(ros_process, namespace, rclpy_node):
    rec = Recorder(rclpy_node, namespace)
    # target: identity = current attitude
    sim, ctl = start_loop(rec, ros_process, namespace, 'slew')
    first = rotation.axis_rotation(2, math.radians(179.0))
    rec.send_target(first)
    # until settled on it (~9 s of sim time): beside the suite's CPU hogs this real-time
    # loop ran behind the wall clock, and a fixed 9 s had turned only 175.8°
    assert rec.spin_until(
        lambda: rec.attitude and rec.rate and
        rotation.angle_between(rec.attitude[-1][1], first) < 0.02 * math.radians(179.0)
        and np.linalg.norm(rec.rate[-1][1]) < 0.01 * WN, 60.0)
    t, w = rec.arrays('rate')
    _, q = rec.arrays('attitude')
    # the whole record: at rest on its target until the new one (ω = 0), so no sample
    # needs picking by time. The states' stamps are the simulator's clock, which a loaded
    # machine puts behind the wall clock that stamped the target: picking the samples
    # after the send by their stamps cut off the start of the turn (174.9°, load ~5)
    assert w[:, 2].min() > -1e-3, 'turned the long way'
    turned = np.trapezoid(w[:, 2], t)
    print(f'slew 179°: turned {math.degrees(turned):.2f}° about +z, '
          f'min ω_z {w[:, 2].min():.2e} rad/s')
    assert turned == pytest.approx(math.radians(179.0), abs=math.radians(3.0))
    assert rotation.angle_between(q[-1], first) < 0.02 * math.radians(179.0)
    # A second target while slewing: send it 1.5 s into a new slew.
    second = rotation.axis_rotation(0, -math.pi / 3)
    rec.send_target(rotation.axis_rotation(1, math.pi / 2))
    rec.spin(1.5)
    rec.send_target(second)
    # settled: inside 2 % and nearly at rest. A loaded machine delays the controller's
    # commands in this real-time loop, and a delayed PD loop can pass through the band
    # before it settles (once at load ~10: 0.076 rad a second after entering it)
    assert rec.spin_until(
        lambda: rotation.angle_between(rec.attitude[-1][1], second) < 0.02 * math.pi / 3
        and np.linalg.norm(rec.rate[-1][1]) < 0.01 * WN, 60.0)
    rec.spin(1.0)
    assert rotation.angle_between(rec.attitude[-1][1], second) < 0.02 * math.pi / 3


def test_saturated_slew_converges(ros_process, namespace, rclpy_node):
    """max_torque = 10 % of the unsaturated peak k_p,z sin(45°) = 2 I_z ω_n² sin 45°
    (at t0, ω = 0)."""
    rec = Recorder(rclpy_node, namespace)
    wn = 1.5
    angle = math.pi / 2
    target = rotation.axis_rotation(2, angle)
    limit = 0.1 * 2 * INERTIA[2] * wn ** 2 * math.sin(angle / 2)
    # The whole saturated start (the first 1/(2ω_n) s) is on record, see start_loop.
    sim, ctl = start_loop(rec, ros_process, namespace, 'slew',
                          ctl_params=dict(natural_frequency=wn, max_torque=limit,
                                          target_attitude=list(target)))
    # saturated at the start (ω = 0, rate error max)
    assert rec.spin_until(lambda: (rec.diagnostics
                                   and rec.last_diagnostic().get('saturation_active') == 'true'),
                          5.0), 'saturation never reported'
    settle_band = 0.02 * angle
    assert rec.spin_until(
        lambda: rotation.angle_between(rec.attitude[-1][1], target) < 0.1 * settle_band, 25.0)
    t_reached = rec.attitude[-1][0]
    rec.spin(2.0)
    t0, _ = rec.torque_onset()
    print(f'saturated slew 90° (|τ| <= {limit:.4g} N·m, ω_n = {wn}): '
          'within 0.2 % of the angle after '
          f'{t_reached - t0:.3f} s')
    t, q = rec.arrays('attitude')
    err = signed_error_about(q, target, 2)
    _, tau = rec.arrays('torque')
    assert np.linalg.norm(tau, axis=1).max() <= limit * (1 + 1e-9)
    assert max(0.0, err.max()) / angle < 0.01  # no overshoot
    tail = t >= t_reached
    assert np.abs(err[tail]).max() < settle_band  # stays settled: no limit cycle
    assert np.linalg.norm(tau, axis=1).max() >= 0.999 * limit  # the limit was reached
    seen = [{kv.key: kv.value for kv in s.values} for s in rec.diagnostics]
    assert any(d['rate_limit_active'] == 'true' for d in seen)
    diag = rec.last_diagnostic()
    assert diag['mode'] == 'slew' and diag['saturation_active'] == 'false'
    for key in ('attitude_error_angle', 'rate_norm', 'state_age'):
        assert math.isfinite(float(diag[key]))
    assert float(diag['state_age']) < 0.5


def test_stale_state_nan_target_modes_and_parameters(ros_process, namespace, rclpy_node):
    """Controller alone; the probe plays the simulator so that stamps can be made stale."""
    rec = Recorder(rclpy_node, namespace)
    ctl = start_controller(ros_process, namespace, mode='detumble', state_timeout=0.3)
    att_pub = rclpy_node.create_publisher(QuaternionStamped, f'{namespace}/attitude', 10)
    rate_pub = rclpy_node.create_publisher(Vector3Stamped, f'{namespace}/angular_velocity', 10)
    assert rec.spin_until(lambda: rate_pub.get_subscription_count() > 0 and len(rec.torque) > 2,
                          20.0), ctl.output()
    # No state yet: explicit zeros, still published.
    assert rec.torque[-1][1] == (0.0, 0.0, 0.0)

    def publish_state(age=0.0, w=(0.1, 0.0, 0.0), q=(0.0, 0.0, 0.0, 1.0)):
        now = rclpy_node.get_clock().now().nanoseconds * 1e-9 - age
        a, r = QuaternionStamped(), Vector3Stamped()
        for m in (a, r):
            m.header.stamp.sec, m.header.stamp.nanosec = int(now), int((now % 1) * 1e9)
        a.header.frame_id, r.header.frame_id = 'world', 'base_link'
        a.quaternion.x, a.quaternion.y, a.quaternion.z, a.quaternion.w = q
        r.vector.x, r.vector.y, r.vector.z = w
        att_pub.publish(a)
        rate_pub.publish(r)

    def feed(seconds, **kw):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            publish_state(**kw)
            rec.spin(0.02)

    def feed_until(predicate, timeout=15.0, **kw):
        """Feed state until the last torque received satisfies ``predicate``: on a loaded
        machine the controller's answer may take longer than any fixed slice (loaded CI)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and not predicate(rec.torque[-1][1]):
            feed(0.1, **kw)
        return rec.torque[-1][1]

    kd_x = 2 * WN * INERTIA[0]  # detumble K_ω = k_d
    expected = pytest.approx((-kd_x * 0.1, 0.0, 0.0), abs=1e-9)
    # fresh state in, the law's torque out
    assert feed_until(lambda tau: tau == expected) == expected
    # Stale: stop publishing -> zeros after state_timeout (waited for: the controller's
    # timer and this probe may each stall past a fixed 0.6 s on a loaded machine)
    assert rec.spin_until(lambda: rec.torque[-1][1] == (0.0, 0.0, 0.0), 15.0), rec.torque[-1]
    assert rec.spin_until(
        lambda: rec.diagnostics and float(rec.last_diagnostic()['state_age']) > 0.3, 30.0)
    assert rec.diagnostics[-1].level == DiagnosticStatus.WARN
    # Old stamps are stale too.
    feed(0.5, age=1.0)
    assert rec.torque[-1][1] == (0.0, 0.0, 0.0)
    assert 'state is' in ctl.output() and 'state_timeout' in ctl.output()

    # Runtime mode switch and parameter validation.
    def set_params(**values):
        return globals()['set_params'](rclpy_node, namespace, **values)

    for bad, reason in ((dict(natural_frequency=-1.0), 'out of range'),
                        (dict(damping_ratio=0.0), 'out of range'),
                        (dict(mode='spin'), 'not one of'),
                        (dict(inertia=[1.0, 2.0]), 'needs 3 or 9'),
                        (dict(inertia=[1.0, 1.0, 5.0]), 'triangle'),
                        (dict(kp=[1.0, 1.0, 1.0]), 'set both kp and kd'),
                        (dict(target_attitude=[0.0, 0.0, 0.0, 0.0]), 'zero norm'),
                        (dict(state_timeout=float('nan')), 'out of range'),
                        (dict(kd=[1.0, float('inf'), 1.0]), 'finite')):
        (result,) = set_params(**bad)
        assert not result.successful and reason in result.reason, (bad, result.reason)
    target = rotation.axis_rotation(2, 0.4)
    results = set_params(mode='slew', target_attitude=[float(x) for x in target])
    assert all(r.successful for r in results)
    tau_slew = np.array(feed_until(lambda tau: tau[2] > 0.1))
    assert tau_slew[2] > 0.1  # towards +z

    # NaN / non-unit / zero / wrong-frame targets are rejected, the previous target kept.
    for q, frame in (([math.nan, 0.0, 0.0, 1.0], 'world'), ([0.0, 0.0, 1.0, 1.0], 'world'),
                     ([0.0, 0.0, 0.0, 0.0], 'world'), ([0.0, 0.0, 0.0, 1.0], 'map')):
        rec.send_target(q, frame)
        feed(0.15)
    np.testing.assert_allclose(rec.torque[-1][1], tau_slew, atol=1e-9)
    assert rec.spin_until(lambda: rec.last_diagnostic().get('targets_rejected') == '4', 30.0)
    out = ctl.output()
    for reason in ('not finite', 'not a unit quaternion', 'zero norm',
                   "differs from the attitude's"):
        assert reason in out, reason

    results = set_params(mode='off')
    assert results[0].successful
    assert feed_until(lambda tau: tau == (0.0, 0.0, 0.0)) == (0.0, 0.0, 0.0)
    assert_clean_exit(ctl, signal.SIGINT)


def assert_clean_exit(ctl, sig):
    """``sig`` to a running controller: it exits with 0 within 10 s, no traceback. (Each
    signal once had a test of its own, a controller started for it alone: issue 32.)"""
    ctl.signal(sig)
    assert ctl.wait(10.0) == 0, ctl.output()[-3000:]
    assert 'Traceback' not in ctl.output()


def test_invalid_startup_parameters_exit_2(ros_process, namespace):
    ctl = start_controller(ros_process, namespace, inertia=[1.0, 2.0])
    assert ctl.wait(20.0) == 2
    out = ctl.output()
    assert 'invalid parameters' in out and 'Traceback' not in out


def test_the_node_computes_its_commands_without_numba(ros_process, namespace, rclpy_node):
    """The node's law runs interpreted (control_law.py): a controller that has computed
    a non-zero detumble torque has not loaded numba (its llvmlite library is not mapped).
    Loading numba and the compiled law cost each controller start 0.8 CPU-s (issue 32)."""
    rec = Recorder(rclpy_node, namespace)
    ctl = start_controller(ros_process, namespace, mode='detumble')
    att_pub = rclpy_node.create_publisher(QuaternionStamped, f'{namespace}/attitude', 10)
    rate_pub = rclpy_node.create_publisher(Vector3Stamped, f'{namespace}/angular_velocity', 10)

    def publish_state():
        now = rclpy_node.get_clock().now().to_msg()
        a, r = QuaternionStamped(), Vector3Stamped()
        a.header.stamp = r.header.stamp = now
        a.header.frame_id, r.header.frame_id = 'world', 'base_link'
        a.quaternion.w = 1.0
        r.vector.x = 0.1
        att_pub.publish(a)
        rate_pub.publish(r)
        return False

    expected = (-2 * WN * INERTIA[0] * 0.1, 0.0, 0.0)  # detumble K_ω = k_d = 2 ω_n I
    assert rec.spin_until(lambda: publish_state() or (
        rec.torque and rec.torque[-1][1] == pytest.approx(expected, abs=1e-9)), 30.0), \
        ctl.output()
    with open(f'/proc/{ctl.pid}/maps') as f:
        mapped = f.read()
    assert 'llvmlite' not in mapped and '/numba/' not in mapped, \
        [line for line in mapped.splitlines() if 'llvmlite' in line or '/numba/' in line][:3]
    assert_clean_exit(ctl, signal.SIGTERM)
