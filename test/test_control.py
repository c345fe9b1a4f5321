"""The control law (rigid_body_sim.control), alone and in closed loop with the physics core.

Offline closed loop = the simulation engine with the law as its in-process torque source,
sampled at 50 Hz with the torque held over each period (zero-order hold, like the node).
Deterministic and fast; the same claims are checked over real ROS messages in
test_controller_node.py.
"""
import numpy as np
import pytest

from rigid_body_sim import control as C
from rigid_body_sim.engine import NS, ControlSettings, Engine, EngineConfig
from rigid_body_sim.physics import Dissipation, RigidBody, rotation
from rigid_body_sim.physics.dynamics import Dynamics

pytestmark = pytest.mark.fast  # make check

INERTIA = [1.0, 2.0, 3.0]
WN = 1.0
DT = 0.02  # 50 Hz, the node's default control_rate


def run(config, mode, target, duration, attitude=(0, 0, 0, 1), angular_velocity=(0, 0, 0),
        events=None, integrator='splitting2'):
    """The engine's closed loop, one sample per control period; ``events``: {time (s):
    callable(controller)} run at that sample instant, before the law's next update."""
    period = int(round(DT * NS))
    settings = ControlSettings(config, mode, C.validated_target(target), period)
    engine = Engine(EngineConfig(config.body, Dissipation(), rotation.validated(attitude),
                                 np.asarray(angular_velocity, float), integrator=integrator,
                                 step=DT, sample_period_ns=period,
                                 duration_ns=int(round(duration * NS)), max_torque=np.inf,
                                 control=settings))
    law = engine.sources[-1]
    pending = sorted((events or {}).items())
    out = {k: [] for k in ('t', 'attitude', 'angular_velocity', 'torque', 'saturated',
                           'error_angle')}
    for k in range(int(round(duration / DT)) + 1):
        while pending and pending[0][0] <= k * DT + 1e-12:
            pending.pop(0)[1](law.controller)
        block = engine.advance(k * period)
        assert len(block) == 1 and block.t_ns[0] == k * period
        for key in ('attitude', 'angular_velocity', 'torque'):
            out[key].append(block[key][0])
        out['t'].append(block.t[0])
        out['saturated'].append(law.last.saturated)
        out['error_angle'].append(law.last.error_angle)
    return {k: np.asarray(v) for k, v in out.items()}


def signed_error_about(result, target, axis):
    """Signed rotation angle (rad) about ``axis`` from the target to the attitude."""
    qe = C.error_quaternion(result['attitude'], target)
    return 2.0 * np.arctan2(qe[:, axis], qe[:, 3])


def settling_time(t, error, tolerance):
    """First time after which |error| stays within ``tolerance``."""
    outside = np.nonzero(np.abs(error) > tolerance)[0]
    if outside.size == 0:
        return t[0]
    assert outside[-1] + 1 < len(t), 'never settled'
    return t[outside[-1] + 1]


# --- gains and helpers ---------------------------------------------------------------

def test_bandwidth_gains_factor_two_from_the_half_angle():
    kp, kd = C.bandwidth_gains([1.0, 2.0, 3.0], 0.5, 0.7)
    np.testing.assert_allclose(kp, 2 * np.array([1.0, 2.0, 3.0]) * 0.25)
    np.testing.assert_allclose(kd, 2 * 0.7 * 0.5 * np.array([1.0, 2.0, 3.0]))


@pytest.mark.parametrize('gyro', [True, False])
def test_linearised_closed_loop_has_the_requested_poles(gyro):
    """Jacobian of (attitude error, ω) dynamics at the target: poles −ζω_n ± ω_n√(ζ²−1) per axis.

    This is what makes the factor 2 in k_p = 2Iω_n² right: ζ = 1 gives a double pole at −ω_n.
    """
    inertia = np.array([1.0, 2.0, 3.0])
    wn = np.array([0.5, 1.0, 2.0])
    for zeta, expected in ((1.0, None), (0.5, None)):
        cfg = C.ControlConfig(inertia=inertia, natural_frequency=wn, damping_ratio=zeta,
                              gyroscopic_compensation=gyro)
        ctl = C.AttitudeController(cfg, 'slew')
        dyn = Dynamics(cfg.body.principal_moments)

        def f(x):  # x = (rotation vector of the attitude error, ω), target = identity
            q = rotation.exp(x[:3])
            w = x[3:]
            tau = ctl.torque(q, w)
            wdot = dyn.momentum_rate(inertia * w, tau) / inertia
            return np.concatenate((w, wdot))  # small-angle: d(rotvec)/dt = ω
        eps = 1e-7
        jac = np.column_stack([(f(eps * e) - f(-eps * e)) / (2 * eps) for e in np.eye(6)])
        poles = np.sort_complex(np.linalg.eigvals(jac))
        want = np.sort_complex(np.concatenate([np.roots([1.0, 2 * zeta * w, w * w]) for w in wn]))
        np.testing.assert_allclose(poles, want, atol=1e-4)


def test_critical_settling_time():
    x = C.critical_settling_time(1.0, 0.02)
    assert (1 + x) * np.exp(-x) == pytest.approx(0.02, rel=1e-12)
    assert x == pytest.approx(5.8339, abs=1e-4)
    assert C.critical_settling_time(2.0) == pytest.approx(x / 2)


def test_error_quaternion_takes_the_short_way():
    q = rotation.axis_rotation(2, np.radians(-100.0))
    target = rotation.axis_rotation(2, np.radians(100.0))  # 200° one way, 160° the other
    qe = C.error_quaternion(q, target)
    assert qe[3] >= 0.0
    # error +160° → torque −z... short way
    assert 2 * np.arctan2(qe[2], qe[3]) == pytest.approx(np.radians(160.0))
    assert C.error_angle(q, target) == pytest.approx(np.radians(160.0))
    # q and −q are the same attitude: same error.
    np.testing.assert_allclose(C.error_quaternion(-q, target), qe)


@pytest.mark.parametrize('bad, reason', [
    ([np.nan, 0, 0, 1], 'not finite'),
    ([0, 0, 0, 0], 'zero norm'),
    ([0, 0, 1, 1], 'not a unit'),
    ([0, 0, 1], '4 components'),
])
def test_bad_target_rejected_and_previous_kept(bad, reason):
    ctl = C.AttitudeController(C.ControlConfig(inertia=INERTIA), 'slew', [0, 0, 0.6, 0.8])
    with pytest.raises(ValueError, match=reason):
        ctl.set_target(bad)
    np.testing.assert_allclose(ctl.target, [0, 0, 0.6, 0.8])


def test_slightly_off_unit_target_is_normalised():
    ctl = C.AttitudeController(C.ControlConfig(inertia=INERTIA))
    ctl.set_target([0, 0, 0.7071, 0.7071])
    assert np.linalg.norm(ctl.target) == pytest.approx(1.0)


@pytest.mark.parametrize('kwargs, reason', [
    ({'inertia': [1, 2]}, '3 principal moments or 9'),
    ({'inertia': [1, 1, 5]}, 'triangle'),
    ({'natural_frequency': -1.0}, 'natural_frequency must be > 0'),
    ({'natural_frequency': [1.0, 2.0]}, 'natural_frequency needs 1 or 3'),
    ({'damping_ratio': 0.0}, 'damping_ratio must be > 0'),
    ({'damping_ratio': np.inf}, 'damping_ratio is not finite'),
    ({'kp': [1, 1, 1]}, 'set both kp and kd'),
    ({'kp': [1, -1, 1], 'kd': [1, 1, 1]}, 'kp must be > 0'),
    ({'rate_gain': [-1.0]}, 'rate_gain must be > 0'),
    ({'max_torque': -0.1}, 'max_torque must be >= 0'),
    ({'max_rate': np.nan}, 'max_rate must be >= 0'),
])
def test_invalid_config_rejected_with_reason(kwargs, reason):
    with pytest.raises(ValueError, match=reason):
        C.ControlConfig(**kwargs)


def test_unknown_mode_rejected():
    ctl = C.AttitudeController()
    with pytest.raises(ValueError, match='unknown mode'):
        ctl.set_mode('spin')
    assert ctl.mode == 'detumble'


def test_direct_gains_win_and_modes():
    cfg = C.ControlConfig(inertia=INERTIA, natural_frequency=3.0, kp=[1, 2, 3], kd=[4, 5, 6],
                          gyroscopic_compensation=False)
    np.testing.assert_allclose(cfg.kp_principal, [1, 2, 3])
    np.testing.assert_allclose(cfg.kd_principal, [4, 5, 6])
    ctl = C.AttitudeController(cfg, 'slew', rotation.axis_rotation(0, 0.2))
    w = np.array([0.1, -0.2, 0.3])
    e = C.error_quaternion([0, 0, 0, 1], ctl.target)[:3]
    np.testing.assert_allclose(ctl.torque([0, 0, 0, 1], w),
                               -np.array([1, 2, 3]) * e - np.array([4, 5, 6]) * w)
    ctl.set_mode('detumble')  # default K_ω = k_d
    np.testing.assert_allclose(ctl.torque([0, 0, 0, 1], w), -np.array([4, 5, 6]) * w)
    ctl.set_mode('off')
    np.testing.assert_array_equal(ctl.torque([0, 0, 0, 1], w), np.zeros(3))
    isotropic = C.AttitudeController(C.ControlConfig(inertia=INERTIA, rate_gain=[0.5]), 'detumble')
    np.testing.assert_allclose(isotropic.torque([0, 0, 0, 1], w), -0.5 * w)


def test_non_diagonal_inertia_gains_live_in_the_principal_frame():
    tensor = np.array([[2.0, 0.3, 0.1], [0.3, 1.5, -0.2], [0.1, -0.2, 2.5]])
    cfg = C.ControlConfig(inertia=tensor.ravel(), natural_frequency=0.7,
                          gyroscopic_compensation=False)
    # K_d = 2ζω_n I as a body-frame matrix, K_p = 2ω_n² I.
    np.testing.assert_allclose(cfg.kd_body, 2 * 0.7 * tensor, atol=1e-12)
    np.testing.assert_allclose(cfg.kp_body, 2 * 0.49 * tensor, atol=1e-12)


def test_saturation_scales_the_whole_vector():
    cfg = C.ControlConfig(inertia=INERTIA, max_torque=0.1)
    out = C.AttitudeController(cfg, 'detumble').compute([0, 0, 0, 1], [1.0, -2.0, 0.5])
    assert out.saturated
    assert np.linalg.norm(out.torque) == pytest.approx(0.1)
    # same direction
    np.testing.assert_allclose(np.cross(out.torque, out.unsaturated_torque), 0.0, atol=1e-12)
    assert np.dot(out.torque, out.unsaturated_torque) > 0


# --- offline closed loop -------------------------------------------------------------

@pytest.mark.parametrize('axis', [0, 1, 2])
def test_slew_90_critically_damped_overshoot_and_settling(axis):
    cfg = C.ControlConfig(inertia=INERTIA, natural_frequency=WN, damping_ratio=1.0)
    target = rotation.axis_rotation(axis, np.pi / 2)
    r = run(cfg, 'slew', target, 12.0)
    err = signed_error_about(r, target, axis)  # starts at −90°
    overshoot = max(0.0, err.max()) / (np.pi / 2)
    assert overshoot < 0.01
    t_settle = settling_time(r['t'], r['error_angle'], 0.02 * np.pi / 2)
    predicted = C.critical_settling_time(WN, 0.02)  # (1 + ω_n t) e^(−ω_n t) = 0.02
    assert predicted * 0.8 <= t_settle <= predicted * 1.2, (t_settle, predicted)
    # The motion stays about the slew axis (eigenaxis rotation).
    other = [i for i in range(3) if i != axis]
    assert np.abs(r['angular_velocity'][:, other]).max() < 1e-9


def test_slew_179_takes_the_short_way():
    cfg = C.ControlConfig(inertia=INERTIA, natural_frequency=WN)
    target = rotation.axis_rotation(2, np.radians(179.0))
    r = run(cfg, 'slew', target, 15.0)
    wz = r['angular_velocity'][:, 2]
    assert wz.min() > -1e-9  # never turns the long (negative) way
    turned = np.sum(wz[:-1]) * DT  # rectangle rule = exact for the ZOH samples up to O(DT)
    assert turned == pytest.approx(np.radians(179.0), abs=np.radians(1.0))
    assert r['error_angle'][-1] < np.radians(0.5)
    assert r['error_angle'].max() <= np.radians(179.0) + 1e-9


def test_second_target_while_slewing_is_followed():
    cfg = C.ControlConfig(inertia=INERTIA, natural_frequency=WN)
    first = rotation.axis_rotation(2, np.pi / 2)
    second = rotation.axis_rotation(0, -np.pi / 3)
    r = run(cfg, 'slew', first, 16.0, events={2.0: lambda ctl: ctl.set_target(second)})
    assert r['error_angle'][-1] < 0.02 * np.pi / 3
    assert rotation.angle_between(r['attitude'][-1], second) < 1e-3
    assert rotation.angle_between(r['attitude'][-1], first) > 1.0


@pytest.mark.parametrize('axis, angle', [(2, np.pi / 2), (0, np.pi / 2), (1, np.radians(179.0))])
def test_saturated_slew_at_ten_percent_converges_without_limit_cycle(axis, angle):
    target = rotation.axis_rotation(axis, angle)
    free = run(C.ControlConfig(inertia=INERTIA, natural_frequency=WN), 'slew', target, 1.0)
    peak = np.linalg.norm(free['torque'], axis=1).max()  # unsaturated peak (at t = 0)
    cfg = C.ControlConfig(inertia=INERTIA, natural_frequency=WN, max_torque=0.1 * peak)
    r = run(cfg, 'slew', target, 40.0)
    torque = np.linalg.norm(r['torque'], axis=1)
    assert torque.max() <= 0.1 * peak * (1 + 1e-12)
    assert r['saturated'].any()
    err = signed_error_about(r, target, axis)
    assert max(0.0, err.max()) / angle < 0.01  # no overshoot either
    t_settle = settling_time(r['t'], r['error_angle'], 0.02 * angle)
    assert t_settle < 30.0
    tail = r['t'] > t_settle
    assert not r['saturated'][tail].any()  # no saturation chattering after settling
    assert r['error_angle'][-1] < 1e-4 and np.linalg.norm(r['angular_velocity'][-1]) < 1e-4


def test_detumble_near_intermediate_axis_within_linear_prediction():
    """τ = −K_ω ω with the default K_ω = k_d = 2ζω_n I: |L| = |L₀| e^(−ct), c = 2ζω_n.

    Linear prediction t = ln(|ω₀| / 1e-3) / c; the test allows +20 %. (The guaranteed bound
    ln(|L₀| / (I_min 1e-3)) / c is ln(I₂/I₁)/c ≈ 0.35 s later here: within 10 %.)
    """
    w0 = np.array([0.02, 1.0, 0.02])  # near the intermediate axis: unstable without control
    cfg = C.ControlConfig(inertia=INERTIA, natural_frequency=WN)
    r = run(cfg, 'detumble', [0, 0, 0, 1], 6.0, angular_velocity=w0)
    rate = np.linalg.norm(r['angular_velocity'], axis=1)
    t_detumbled = r['t'][np.argmax(rate < 1e-3)]
    assert rate[-1] < 1e-3
    c = 2 * 1.0 * WN
    predicted = C.detumble_time(w0, c)
    bound = C.detumble_time(w0, c, 1e-3, moments=INERTIA, bound=True)
    assert t_detumbled <= 1.2 * predicted, (t_detumbled, predicted)
    assert t_detumbled <= bound + DT
    # |L| decays like e^(−ct) (the law is ∝ inertia); sampled with a zero-order hold that is
    # (1 − c·DT)^k, up to the body turning within a period.
    L = np.linalg.norm(np.array(INERTIA) * r['angular_velocity'], axis=1)
    np.testing.assert_allclose(L, L[0] * (1 - c * DT) ** np.arange(len(L)), rtol=2e-3)


def test_detumble_saturated_still_converges():
    w0 = np.array([0.02, 1.0, 0.02])
    cfg = C.ControlConfig(inertia=INERTIA, natural_frequency=WN, max_torque=0.5)
    r = run(cfg, 'detumble', [0, 0, 0, 1], 12.0, angular_velocity=w0)
    T = 0.5 * np.sum(np.array(INERTIA) * r['angular_velocity'] ** 2, axis=1)
    assert np.all(np.diff(T) <= 1e-12)  # energy never increases
    assert np.linalg.norm(r['angular_velocity'][-1]) < 1e-3


FULL_TENSOR = [2.0, 0.3, 0.1, 0.3, 1.5, -0.2, 0.1, -0.2, 2.5]


@pytest.mark.parametrize('inertia, gyro, max_torque', [  # make check: the first and last
    (INERTIA, True, 0.3), pytest.param(INERTIA, False, 0.3, marks=pytest.mark.slow),
    pytest.param(FULL_TENSOR, False, 0.0, marks=pytest.mark.slow), (FULL_TENSOR, True, 0.3)])
def test_random_slews_from_tumbling_converge(inertia, gyro, max_torque):
    rng = np.random.default_rng(7)
    cfg = C.ControlConfig(inertia=inertia, natural_frequency=WN, gyroscopic_compensation=gyro,
                          max_torque=max_torque)
    for _ in range(2):
        q0, qt = (v / np.linalg.norm(v) for v in rng.normal(size=(2, 4)))
        w0 = 0.3 * rng.normal(size=3)
        r = run(cfg, 'slew', qt, 45.0, attitude=q0, angular_velocity=w0)
        assert r['error_angle'][-1] < 1e-3
        assert np.linalg.norm(r['angular_velocity'][-1]) < 1e-3
        if max_torque:
            assert np.linalg.norm(r['torque'], axis=1).max() <= max_torque * (1 + 1e-12)


def test_slew_with_a_different_integrator_matches():
    cfg = C.ControlConfig(inertia=INERTIA, natural_frequency=WN)
    target = rotation.axis_rotation(1, np.pi / 2)
    a = run(cfg, 'slew', target, 8.0)
    b = run(cfg, 'slew', target, 8.0, integrator='rk4')
    np.testing.assert_allclose(a['error_angle'], b['error_angle'], atol=1e-6)


def test_the_interpreted_law_is_the_compiled_one_bit_for_bit():
    """The controller node's law (``compiled=False``: control_law.py interpreted, no
    numba) gives the compiled kernel's torques, flags and angles bit for bit: tumbling
    states, full tensors, saturation and the rate limit, every mode."""
    rng = np.random.default_rng(11)
    rows = 0
    for k in range(200):
        cfg = C.ControlConfig(inertia=(FULL_TENSOR, INERTIA)[k % 2], natural_frequency=0.8,
                              max_torque=(0.0, 0.05, 0.5)[k % 3],
                              gyroscopic_compensation=bool(k % 5),
                              max_rate=(0.0, 0.02)[k % 2])
        q, w, t = rng.normal(size=4), rng.normal(size=3), rng.normal(size=4)
        for mode in C.MODES:
            a, b = (C.AttitudeController(cfg, mode, t / np.linalg.norm(t), compiled=compiled)
                    .compute(q / np.linalg.norm(q), w) for compiled in (True, False))
            assert a.torque.tobytes() == b.torque.tobytes(), (k, mode)
            assert a.unsaturated_torque.tobytes() == b.unsaturated_torque.tobytes(), (k, mode)
            assert (a.saturated, a.rate_limited, a.error_angle, a.rate_norm) == \
                (b.saturated, b.rate_limited, b.error_angle, b.rate_norm), (k, mode)
            rows += bool(a.saturated)
    assert rows > 0  # some commands saturate


def test_rigid_body_import_is_the_physics_one():
    assert isinstance(C.ControlConfig(inertia=INERTIA).body, RigidBody)


def test_control_settings_from_the_node_parameters():
    """The engine's ControlLaw is built from the controller node's parameters and specs."""
    from rigid_body_sim.engine import ControlLaw, ControlSettings
    from rigid_body_sim.nodes.controller import SPECS  # the node's defaults are the law's
    defaults = {s.name: s.default for s in SPECS}
    for name, value in C.PARAMETER_DEFAULTS.items():
        assert defaults[name] == value, name
    law = ControlLaw(ControlSettings.from_parameters(
        {'mode': 'slew', 'natural_frequency': [1.0], 'control_rate': 25.0,
         'target_attitude': [0, 0, 1, 0], 'state_timeout': 0.3}))
    assert not law.mission.active and law.settings.period_ns == 40_000_000
    assert law.controller.mode == 'slew'
    np.testing.assert_allclose(law.controller.target, [0, 0, 1, 0])
    np.testing.assert_allclose(law.controller.config.kp_principal, 2 * np.array(INERTIA))
    with pytest.raises(ValueError, match='target_attitude'):
        ControlSettings.from_parameters({'target_attitude': [0, 0, 0, 0]})
    with pytest.raises(ValueError, match="mode = 'spin' is not one of"):
        ControlSettings.from_parameters({'mode': 'spin'})
    with pytest.raises(ValueError, match='mission.free_time = -1 out of range'):
        ControlSettings.from_parameters({'mission.free_time': -1.0})


def test_mission_free_phase_then_detumble_then_slew():
    """Zero torque for free_time (state time), then detumble until |ω| < exit rate, then slew."""
    from rigid_body_sim.engine import ControlLaw, ControlSettings
    law = ControlLaw(ControlSettings.from_parameters(
        {'mode': 'detumble', 'mission.free_time': 2.0, 'mission.detumble_exit_rate': 0.05}))
    ctl, mission = law.controller, law.mission
    assert mission.active
    assert mission.update(ctl, 10.0, [0.0, 1.0, 0.0]) == (True, None)   # first state: t0 = 10 s
    assert mission.update(ctl, 11.9, [0.0, 1.0, 0.0]) == (True, None)
    assert mission.update(ctl, 12.0, [0.0, 1.0, 0.0]) == (False, None)  # detumbling
    assert ctl.mode == 'detumble'
    assert mission.update(ctl, 15.0, [0.0, 0.04, 0.0]) == (False, 'slew')
    assert ctl.mode == 'slew'
    assert mission.update(ctl, 16.0, [0.0, 0.01, 0.0]) == (False, None)  # switches once


def test_a_held_command_is_clipped_as_numpy_clips_it():
    """CommandHold.set clips in Python floats (a live exchange's cost): the held torque,
    bit for bit, and the saturation count are numpy's clip of the command, signed zeros,
    limits and subnormals included; an all-zero command ends the hold."""
    import random
    import struct
    from rigid_body_sim.engine.sources import NEVER, CommandHold
    rng = random.Random(7)
    for _ in range(5000):
        m = rng.choice([0.01, 1.0, 5e-3])
        torque = [rng.choice([0.0, -0.0, m, -m, rng.uniform(-2 * m, 2 * m),
                              rng.uniform(-1e-300, 1e-300), 5e-324]) for _ in range(3)]
        hold = CommandHold(m, NS)
        hold.set(torque, 5)
        tau = np.array(torque, dtype=float)
        assert hold.saturated == int(bool(np.any(np.abs(tau) > m)))
        np.clip(tau, -m, m, out=tau)
        if not tau.any():
            assert hold.torque is None and hold.expiry == NEVER, torque
        else:
            assert struct.pack('<3d', *hold.torque) == struct.pack('<3d', *tau), torque
            assert hold.torque.dtype == np.float64 and hold.expiry == 5 + NS
