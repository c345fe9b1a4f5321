"""Test isolation for everything that touches ROS 2.

Every test session picks its own ROS_DOMAIN_ID (or takes RBS_TEST_DOMAIN_ID) and keeps
discovery on localhost, so parallel runs and other graphs on the machine never cross. Under
pytest-xdist each worker (gw0, gw1, ...) takes the session's domain plus its index: the
workers' nodes share global topics (/clock, /diagnostics, /tf), which must not cross either.
Node processes are started through :func:`ros_process` which always stops them.

`make check` runs the tests marked ``fast`` (``pytestmark = pytest.mark.fast`` in the file):
physics, engine and lint, no ROS graph.
"""
import os
import random
import sys

import pytest

# Domains 0-101 keep every participant's ports valid; xdist runs at most a few workers.
os.environ.setdefault('RBS_TEST_DOMAIN_ID', str(random.Random().randint(1, 80)))
_WORKER = os.environ.get('PYTEST_XDIST_WORKER', '')
_OFFSET = int(_WORKER[2:]) if _WORKER.startswith('gw') and _WORKER[2:].isdigit() else 0
os.environ['ROS_DOMAIN_ID'] = str(int(os.environ['RBS_TEST_DOMAIN_ID']) + _OFFSET)
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
# auto's costs: the classes' constants, not this machine's calibration (the tests' choices
# must not depend on the machine; test_auto_costs.py covers the calibration)
os.environ.setdefault('RIGID_BODY_SIM_AUTO_COSTS', 'constants')

sys.path.insert(0, os.path.dirname(__file__))
from ros_helpers import NodeProcess, unique_namespace  # noqa: E402


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


# Longest files first. xdist's loadfile hands each worker whole files from a queue; by
# default it queues the files with the most tests first, which put the few-test, minutes-long
# ones (the bench's quick run, the demo, Dask, the 40-digit references) last: the suite then
# waited minutes on one or two workers at the end. Each file's wall time is kept in pytest's
# cache (.pytest_cache) and the next run starts with the longest (the Makefile passes
# --no-loadscope-reorder so that xdist keeps this order). A fresh clone has no cache: it
# takes the committed table (FILE_SECONDS_TABLE, the files of 15 s or more in a full run;
# by name, test_viewer*'s module fixtures came last and fresh clones took 7:18-8:18 where a
# cached run took 6:51). Files it does not list come after, in collection order.
_FILE_SECONDS = 'rigid_body_sim/file_seconds'
FILE_SECONDS_TABLE = os.path.join(os.path.dirname(__file__), 'file_seconds.json')
_SPENT = {}


def committed_seconds():
    """{test file: wall s} of the committed table (what a run without a cache orders by)."""
    import json
    with open(FILE_SECONDS_TABLE) as f:
        return json.load(f)


def pytest_collection_modifyitems(config, items):
    cache = getattr(config, 'cache', None)
    seconds = (cache.get(_FILE_SECONDS, {}) if cache is not None else {}) or \
        committed_seconds()
    if seconds:  # a stable sort: each file's tests stay together and in their order
        items.sort(key=lambda item: -seconds.get(item.nodeid.split('::')[0], 0.0))


def pytest_runtest_logreport(report):
    # under xdist the controller receives every worker's reports: it alone keeps the sum
    path = report.nodeid.split('::')[0]
    _SPENT[path] = _SPENT.get(path, 0.0) + report.duration


def pytest_sessionfinish(session):
    cache = getattr(session.config, 'cache', None)
    option = session.config.option
    if cache is None or hasattr(session.config, 'workerinput') or not _SPENT or \
            option.markexpr or option.keyword:  # a selection's times are not its files'
        return
    cache.set(_FILE_SECONDS, dict(cache.get(_FILE_SECONDS, {}), **_SPENT))
