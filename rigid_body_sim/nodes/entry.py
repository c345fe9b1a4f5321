"""The nodes' console scripts (``ros2 run rigid_body_sim simulator`` and the others).

Why not each node module's ``main`` directly: a console script imports its module before
it calls anything, and a node's imports (numpy, scipy, numba, rclpy and the message
packages) take about a second, several under load. Ctrl-C in that second raised
KeyboardInterrupt inside some import and printed its traceback: a launch group's Ctrl-C
caught the recorder importing scipy on a loaded machine (1 run in 45 of the launch-style
signals test). Here SIGINT and SIGTERM end the process at once, quietly, with 0 until the
node module is imported, as they do once it runs (``process.run_node``); then Python's default
handlers are back before ``main`` starts.

This module imports nothing heavy, so its own import is over before a user could press
Ctrl-C. ``-h``/``--help`` and ROS arguments that cannot work (a missing params file) are
answered here too (``nodes.usage``), before the node's module is imported: help never
starts ROS nor writes a file.
"""
import importlib
import os
import signal
import sys


def _quiet_exit(signum, frame):
    # os._exit, not SystemExit: an exception raised here lands inside some module's
    # initialisation, and a compiled one turns it into "ImportError: initialization
    # failed" with a traceback. Nothing is open yet that needs closing.
    os._exit(0)


def _run(module: str) -> int:
    previous = {sig: signal.signal(sig, _quiet_exit) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        from . import usage
        code = usage.answer(module, sys.argv)
        if code is not None:
            return code
        main = importlib.import_module(f'rigid_body_sim.nodes.{module}').main
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    code = main()
    process = sys.modules.get('rigid_body_sim.nodes.process')
    if process is not None and process.executors_kept():
        # an events executor rclpy could not tear down (process.events_executor): the
        # interpreter's teardown would destroy it and abort the process
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code


def simulator() -> int:
    return _run('simulator')


def controller() -> int:
    return _run('controller')


def recorder() -> int:
    return _run('recorder')


def replay() -> int:
    return _run('replay')


def viewer() -> int:
    return _run('viewer')
