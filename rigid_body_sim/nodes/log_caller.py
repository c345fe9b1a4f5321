"""A node's log calls without rclpy's ``inspect`` walk (installed by ``process.start_ros``).

rclpy names the caller of every log call (``rcutils_logger.CallerId``: the key of its
once/throttle filters and the file and line handed to rcutils) through
``inspect.getframeinfo`` and ``os.path.realpath`` on each frame it skips. That reads and
scans source files: the first call of a process cost 30 ms of CPU and every later one
1.5-3 ms, throttled warnings included (measured in a node process with the simulator's
imports: 30.5 ms, then 1.5-2.9 ms a call; 0.6 ms, then 0.02 ms with this). With ~400 node
processes in ``make test`` and a node's own start-up lines, that was seconds of CPU.

The same caller, found from the frame's code object: the function name, the absolute
file path and the line rclpy gives (``getframeinfo(frame).filename`` is the code's file
name for Python source), skipping rclpy's own logging files as rclpy does.
"""
import functools
import os
import sys


@functools.lru_cache(maxsize=None)
def _realpath(path: str) -> str:
    return os.path.realpath(path)


def install() -> None:
    """Replace ``CallerId``'s construction in this process (idempotent)."""
    import rclpy.logging
    from rclpy.impl import rcutils_logger
    if not all(hasattr(rcutils_logger, name) for name in (
            'CallerId', '_internal_callers', '_populate_internal_callers')):
        return  # another rclpy than the pinned Jazzy wheels: its own walk, as it is
    if getattr(rcutils_logger.CallerId.__new__, 'rigid_body_sim', False):
        return
    if rcutils_logger._populate_internal_callers:  # as rclpy does at its first call
        rcutils_logger._internal_callers.extend(
            [_realpath(rcutils_logger.__file__), _realpath(rclpy.logging.__file__)])
        rcutils_logger._populate_internal_callers = False
    internal = rcutils_logger._internal_callers  # a list third parties may extend

    def caller_id(cls, frame=None):
        if not frame:
            frame = sys._getframe(1)
            while any(f in _realpath(frame.f_code.co_filename) for f in internal):
                frame = frame.f_back
        code = frame.f_code
        return tuple.__new__(cls, (code.co_name, os.path.abspath(code.co_filename),
                                   frame.f_lineno, frame.f_lasti))

    caller_id.rigid_body_sim = True
    rcutils_logger.CallerId.__new__ = staticmethod(caller_id)
