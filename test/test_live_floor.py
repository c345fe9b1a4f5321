"""tools/live_floor.py: a bare rclpy publisher of the nine state topics, paced as the
simulator is, delivers to the bench's subscriber (real processes, real messages)."""
import json
import subprocess
import sys


def test_the_floor_tool_measures_a_bare_publisher_of_the_state_topics():
    proc = subprocess.run([sys.executable, '-m', 'rigid_body_sim.tools.live_floor',
                           # 3 s: a wait for acknowledgements may take its whole 1 s
                           # timeout on a loaded machine (sim_acks.ACK_TIMEOUT), and a 1 s
                           # window then saw no message on a topic (make test, load 4)
                           '--runs', '1', '--seconds', '3'],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    run, summary = [json.loads(line) for line in proc.stdout.strip().splitlines()[-2:]]
    # every topic's messages were taken (the least count of the nine is the figure)
    assert run['samples_per_s'] > 0 and run['publisher_cpu_share'] > 0, run
    assert run['real_time_factor'] == run['samples_per_s'] / 100.0
    assert summary['floor_real_time_factor_runs'] == [run['real_time_factor']]
    assert 'keep-all' in summary['subscriber']
