"""A simulator flooded with commands, valid and garbage, on real processes."""
import json
import sys
import time

import numpy as np

from ros_helpers import pace, spin_until, stamp_ns, venv_exe


def _rss_kb(pid):
    with open(f'/proc/{pid}/status') as f:
        return next(int(line.split()[1]) for line in f if line.startswith('VmRSS:'))


def test_flood_of_commands_and_garbage(ros_process, namespace, rclpy_node):
    """4 kHz of valid commands and 4 kHz of garbage (NaN, wrong frame, future and stale
    stamps) for 8 s: the simulator keeps real time (its achieved real-time factor within
    10 % over the flood), keeps publishing, counts every garbage class it read as rejected
    and never applies one, and its memory does not grow (≤ 8 MB over 64,000 commands).

    Why 4 kHz, not the 10 kHz this test once used: at 10 + 10 kHz the node takes about 1.2
    cores here (~30 µs a command in our code, the rest rclpy's and Fast DDS's), so it
    falls behind, and rclpy's events executor queues an event for every arrival, without
    bound: memory then grows with the backlog (3-9 MB over 8 s, old code and new alike),
    which is not the leak this test looks for. A leak per command still shows here."""
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import QuaternionStamped
    sim = ros_process(venv_exe('simulator'), '--ros-args', '-r', f'__ns:={namespace}',
                      '-p', 'publish_rate:=50.0', '-p', 'integrator:=splitting2')
    diags, att = [], []
    rclpy_node.create_subscription(
        DiagnosticArray, '/diagnostics',
        lambda m: diags.extend({kv.key: kv.value for kv in s.values} for s in m.status
                               if s.hardware_id == f'{namespace}/attitude_simulator'), 100)
    rclpy_node.create_subscription(  # (receive time, stamp s): the simulator's pace
        QuaternionStamped, f'{namespace}/attitude',
        lambda m: att.append((time.monotonic(), stamp_ns(m) * 1e-9)), 1000)  # 20 s of them
    assert spin_until(rclpy_node, lambda: len(att) > 20 and diags, 60.0), sim.output()[-2000:]
    flood = ros_process(sys.executable, '-m', 'rigid_body_sim.tools.flood', namespace,
                        '--rate', '4000', '--duration', '8')
    n_diag, n_att = len(diags), len(att)
    # the baseline once the flood's commands are applied: the first one loads the compiled
    # loop for a held torque (a one-time ~10 MB), which is not growth with the flood
    assert spin_until(rclpy_node, lambda: any(int(d.get('commands_accepted', 0)) > 0
                                              for d in diags[n_diag:]), 30.0)
    rss0 = _rss_kb(sim.pid)
    assert spin_until(rclpy_node, lambda: flood.poll() is not None, 120.0)
    flooded = att[n_att:]
    sent = json.loads(flood.output().strip().splitlines()[-1])['sent']
    assert sent['valid'] > 10_000, sent
    assert spin_until(rclpy_node, lambda: len(diags) > n_diag + 2, 30.0)
    during = diags[n_diag:]
    last = during[-1]
    for reason in ('non_finite', 'wrong_frame', 'future_stamp', 'stale_stamp'):
        assert int(last[f'commands_rejected.{reason}']) > 0, (reason, last)
    assert int(last['commands_accepted']) > 0
    # real time over the flood, within 10 %: the pace of the attitude stamps from their least
    # delayed arrivals (ros_helpers.pace); a stall the simulator catches up on does not
    # count (the 1 s reports' rates did: a shared machine finishing another job's hour-long
    # bag beside it made one 0.71 then 1.30), falling behind for good does
    assert 0.9 <= pace(flooded) <= 1.1, (pace(flooded), len(flooded))
    # kept publishing at 50 Hz: every sample, none missing (no step over 20 ms; a shorter
    # one would be an extra sample at an event), in order
    steps = np.diff([s for _, s in flooded])
    assert len(flooded) >= 0.8 * 50 * 8 and 0 < steps.min() and steps.max() < 0.02 + 1e-6, \
        (len(flooded), steps.min(), steps.max())
    assert _rss_kb(sim.pid) - rss0 <= 8 * 1024, (rss0, _rss_kb(sim.pid))
    assert sim.poll() is None
