"""The viewer across a simulator reset, against the real Foxglove client (see test_viewer):
after ``~/reset`` into a different initial state, the drift channels start again from zero
and the polhode/herpolhode traces restart (sim time keeps running across a reset, so only
the simulator's ``resets`` diagnostics count tells the viewer)."""
import numpy as np
import pytest

from test_viewer import MOMENTS, W0, client_js, finish_client, live, run_client  # noqa: F401

W1 = np.array([0.3, 0.2, 0.9])  # rad/s, base_link: the state after the reset
SECONDS = 9.0
RESET_AFTER_S = 3.0  # s into the client's stream
TOL = 1e-9  # relative: T and |L| of a torque-free run, from float64 samples


def _call(probe, future, what):
    assert probe.spin(20.0, future.done), f'{what}: no answer'
    return future.result()


def _reset_into(probe, w):
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient
    from std_srvs.srv import Trigger
    params = AsyncParameterClient(probe.node, 'attitude_simulator')
    assert params.wait_for_services(20.0)
    result = _call(probe, params.set_parameters(
        [Parameter('initial_angular_velocity', value=[float(x) for x in w])]), 'set parameter')
    assert result.results[0].successful, result
    reset = probe.node.create_client(Trigger, 'attitude_simulator/reset')
    assert reset.wait_for_service(20.0)
    assert _call(probe, reset.call_async(Trigger.Request()), 'reset').success


def _stamp(ts):
    return int(ts['sec']) * 1_000_000_000 + int(ts['nsec'])


def _scene_stamp(scene):
    t = scene['entities'][0]['timestamp']
    return int(t['seconds']) * 1_000_000_000 + int(t['nanos'])


def test_reset_restarts_drift_and_traces(live, client_js):  # noqa: F811
    probe = live['probe']

    def subscriptions():
        return int((probe.latest('attitude_viewer') or {}).get('subscriptions', 0))
    before_client = subscriptions()
    proc = run_client(client_js, live['port'], SECONDS, '--subscribe', '/state,/scene',
                      '--dump', '/state,/scene', wait=False)
    try:
        # the reset RESET_AFTER_S into the client's stream (its two subscriptions in the
        # viewer's 1 Hz diagnostics), not into this probe's time: a client starting late on
        # a loaded machine left too little of its 9 s after the reset (54 samples, load 12)
        assert probe.spin(30.0, lambda: subscriptions() >= before_client + 2), \
            probe.latest('attitude_viewer')
        probe.spin(RESET_AFTER_S)
        _reset_into(probe, W1)
        probe.spin_while(proc)
    finally:
        _reset_into(probe, W0)  # as the module's other tests expect it (none yet)
    (s,) = finish_client(proc, SECONDS)
    rows = s['dumped']['/state']
    T0, T1 = (0.5 * float(w @ (MOMENTS * w)) for w in (W0, W1))
    L1 = float(np.linalg.norm(MOMENTS * W1))
    new = [i for i, r in enumerate(rows) if r['kinetic_energy'] == pytest.approx(T1, rel=TOL)]
    # at least a second of the 50 Hz stream on either side of the reset (under load the
    # simulator may run behind real time: 54 samples in the 5 s after it at load 12)
    assert new and len(new) >= 50, f'{len(new)} samples after the reset'
    first = new[0]
    assert new == list(range(first, first + len(new)))  # one run after the other
    before = rows[:first]
    assert len(before) >= 50
    assert all(r['kinetic_energy'] == pytest.approx(T0, rel=TOL) for r in before)
    assert max(abs(r['kinetic_energy_drift']) for r in before) < TOL
    # the baselines restart at the new state: drift ~0 from (almost) its first sample — the
    # count travels on /diagnostics, published before that sample but on another topic
    after = [rows[i] for i in new]
    late = [i for i, r in enumerate(after) if abs(r['kinetic_energy_drift']) > TOL
            or abs(r['angular_momentum_drift']) > TOL]
    assert not late or max(late) < 3, (late[:10], (T1 - T0) / T0)
    assert after[-1]['angular_momentum_norm'] == pytest.approx(L1, rel=TOL)
    # the traces restart: fewer points in the first scene after the reset than before it
    t_reset = _stamp(after[0]['timestamp'])
    counts = []
    for scene in s['dumped']['/scene']:
        ents = {e['id']: e for e in scene['entities']}
        if 'polhode' in ents and 'herpolhode' in ents:
            counts.append((_scene_stamp(scene), ents['polhode']['lines'][0]['points'],
                           ents['herpolhode']['lines'][0]['points']))
    pre = [c for c in counts if c[0] < t_reset]
    post = [c for c in counts if c[0] >= t_reset]
    assert pre and post
    assert pre[-1][1] > 50 and pre[-1][2] > 50, pre[-1]   # 4 s of trace at 50 Hz
    # the first update after the reset: at most a scene period (0.1 s = 5 samples) of trace
    assert post[0][1] <= 8 and post[0][2] <= 8, (pre[-1], post[:3])
    assert post[-1][1] > post[0][1]  # and it grows again
    assert 'simulator reset (resets = 1)' in live['viewer'].output()  # logged
