"""Test isolation for everything that touches ROS 2.

Every test session picks its own ROS_DOMAIN_ID (or takes RBS_TEST_DOMAIN_ID) and keeps
discovery on localhost, so parallel runs and other graphs on the machine never cross.
Node processes are started through :func:`ros_process` which always stops them.
"""
import os
import random
import sys

import pytest

os.environ.setdefault('RBS_TEST_DOMAIN_ID', str(random.Random().randint(1, 100)))
os.environ['ROS_DOMAIN_ID'] = os.environ['RBS_TEST_DOMAIN_ID']
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

sys.path.insert(0, os.path.dirname(__file__))
from ros_helpers import NodeProcess, unique_namespace  # noqa: E402


# `make check`: the physics and the engine, no ROS graph, under a minute.
FAST_FILES = {'test_body.py', 'test_exact.py', 'test_integrators.py', 'test_control.py',
              'test_engine.py', 'test_lint.py', 'test_kernels.py', 'test_batch.py',
              'test_dop853.py', 'test_viewer_geometry.py', 'test_actuators.py',
              'test_sensor_noise.py', 'test_sensors.py'}


def pytest_collection_modifyitems(config, items):
    for item in items:
        if item.path.name in FAST_FILES:
            item.add_marker(pytest.mark.fast)


@pytest.fixture
def namespace(request):
    """A ROS namespace unique to this test, e.g. /t_test_reset_4821."""
    return unique_namespace(request.node.name)


@pytest.fixture
def ros_process():
    """Start node processes; each is SIGINT-ed (then killed) at teardown, even on failure."""
    started = []

    def start(*cmd, **kwargs):
        proc = NodeProcess(list(cmd), **kwargs)
        started.append(proc)
        return proc

    yield start
    for proc in reversed(started):
        proc.stop()


@pytest.fixture
def rclpy_node(request):
    """rclpy initialised (default context) and a node for the test body; shut down at teardown."""
    import rclpy
    from rclpy.node import Node
    rclpy.init()
    node = Node('probe_' + unique_namespace(request.node.name).strip('/'))
    try:
        yield node
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
