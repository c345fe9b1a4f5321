"""rigid_body_sim: live spacecraft attitude simulation for ROS 2 Jazzy.

The physics lives in :mod:`rigid_body_sim.physics` (numpy/scipy only); ROS nodes in
:mod:`rigid_body_sim.nodes`; MCAP I/O in :mod:`rigid_body_sim.bag`.
"""
import os
import sys

__version__ = '0.1.0'


def _ensure_ament_prefix() -> None:
    """Put this interpreter's prefix on AMENT_PREFIX_PATH when it is an ament prefix.

    A venv built from the ROS wheels (``make venv``) is an ament prefix but nothing sets
    AMENT_PREFIX_PATH for it; ament_index lookups (message definitions, share/ files)
    would fail. A sourced ROS install already sets it and keeps precedence.
    """
    marker = os.path.join(sys.prefix, 'share', 'ament_index', 'resource_index', 'packages')
    if not os.path.isdir(marker):
        return
    paths = [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    if sys.prefix not in paths:
        os.environ['AMENT_PREFIX_PATH'] = os.pathsep.join(paths + [sys.prefix])


def command(name: str = 'rigid-body-sim') -> str:
    """How to call this package's executable ``name`` here, for hints and examples the
    software prints: the bare name if this interpreter's own copy is on PATH (an activated
    venv) or, for ``rigid-body-sim``, any copy is; the venv's script by its path
    (``.venv/bin/NAME``, relative when under the working directory); else the colcon way
    (``ros2 run``; colcon installs the executables under lib/rigid_body_sim, not on PATH)."""
    import shutil
    found = shutil.which(name)
    beside = os.path.join(os.path.dirname(sys.executable), name)
    if os.path.isfile(beside):
        if found and os.path.realpath(found) == os.path.realpath(beside):
            return name
        rel = os.path.relpath(beside)
        return beside if rel.startswith(os.pardir) else rel
    if found and name == 'rigid-body-sim':
        return name
    return f'ros2 run rigid_body_sim {name}'


def cli_command() -> str:
    """How to call ``rigid-body-sim`` here (see :func:`command`)."""
    return command('rigid-body-sim')


_ensure_ament_prefix()
