"""A node's log calls name their caller as rclpy does, without rclpy's ``inspect`` walk
(nodes/log_caller.py, installed by ``process.start_ros``, which every node calls): it cost
every node process 30 ms of CPU at its first log line and 1.5-3 ms at each later one
(issue 32)."""
import json
import subprocess
import sys

_PROBE = r'''
import inspect, json, os, sys
import rclpy
import rclpy.logging
from rclpy.impl.rcutils_logger import CallerId
from rigid_body_sim.nodes import log_caller

def where():
    return CallerId()

before = where()  # rclpy's own walk (it fills its list of internal files)
from rigid_body_sim.nodes.process import start_ros
assert start_ros('log_caller_probe', ['probe']) is None  # every node's rclpy.init
assert getattr(CallerId.__new__, 'rigid_body_sim', False), 'start_ros did not install it'
log_caller.install()  # twice is once
after = where()
logger = rclpy.logging.get_logger('log_caller_probe')

def refused(*args, **kwargs):
    raise AssertionError('inspect.getframeinfo called')
inspect.getframeinfo = refused

def caller():
    logger.info('after')
    for _ in range(2):  # one call site: its throttle lets one through
        logger.warning('throttled', throttle_duration_sec=10.0)
caller()
keys = [k for k in logger.contexts if k.function_name == 'caller']
print(json.dumps({'before': list(before), 'after': list(after),
                  'callers': sorted([k.file_path, k.line_number] for k in keys),
                  'file': os.path.abspath(__file__)}))
rclpy.shutdown()
'''


def test_the_caller_is_rclpys_and_no_log_call_reads_source(tmp_path):
    probe = tmp_path / 'probe.py'
    probe.write_text(_PROBE)
    out = subprocess.run([sys.executable, str(probe)], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr[-3000:]
    found = json.loads(out.stdout.strip().splitlines()[-1])
    # the same function, file, line and instruction as rclpy's own answer
    assert found['before'] == found['after'] and found['after'][0] == 'where', found
    assert found['after'][1] == found['file'], found
    # the log calls inside caller() are keyed by their own lines in the probe, not by
    # rclpy's logging files: the info and the throttled warning
    lines = _PROBE.splitlines()
    expected = sorted([found['file'], k + 1] for k, line in enumerate(lines)
                      if line.strip().startswith(("logger.info('after'",
                                                  "logger.warning('throttled'")))
    assert len(expected) == 2
    assert found['callers'] == expected, (found, expected)
    assert 'throttled' in out.stderr and out.stderr.count('throttled') == 1, out.stderr
