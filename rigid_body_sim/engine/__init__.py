"""The simulation engine: one closed loop for every front end, free of ROS.

* :mod:`.specs` — the nodes' parameter specs (name, type, unit, range; the ParamSpec type
  is ``rigid_body_sim.param_spec``, shared with the sensors and the viewer).
* :mod:`.config` — typed, validated configuration built from parameter values.
* :mod:`.sources` — torque sources held between their events (commands, control law).
* :mod:`.samples` — blocks of samples in the user's frames, stamped with sim time (ns).
* :mod:`.core` — :class:`Engine`: state, sim time, integrator and ``auto``, events.
* :mod:`.state` — the State record the engine hands to its other modules and takes back.
* :mod:`.lockstep` — the live simulator's lockstep: its checks and round-trip figures.

The names below are imported on first use (module ``__getattr__``): ``from .engine import
specs`` (a node's ``--help``, a bad parameter) then does not load the physics and numba
(0.4 CPU-s of a 0.5 CPU-s ``simulator --help``).
"""
from ..lazy_exports import lazy_exports

_HOME = {'NS': 'config', 'ControlSettings': 'config', 'EngineConfig': 'config',
         'Engine': 'core', 'SampleBlock': 'samples', 'CommandHold': 'sources',
         'ControlLaw': 'sources', 'TorqueSource': 'sources'}

__all__ = list(_HOME)


__getattr__, __dir__ = lazy_exports(__name__, globals(), _HOME)
