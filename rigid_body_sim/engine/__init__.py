"""The simulation engine: one closed loop for every front end, free of ROS.

* :mod:`.specs` — the nodes' parameter specs (name, type, unit, range; the ParamSpec type
  is ``rigid_body_sim.param_spec``, shared with the sensors and the viewer).
* :mod:`.config` — typed, validated configuration built from parameter values.
* :mod:`.sources` — torque sources held between their events (commands, control law).
* :mod:`.samples` — blocks of samples in the user's frames, stamped with sim time (ns).
* :mod:`.core` — :class:`Engine`: state, sim time, integrator and ``auto``, events.
* :mod:`.state` — the State record the engine hands to its other modules and takes back.
* :mod:`.lockstep` — the live simulator's lockstep: its checks and round-trip figures.
"""
from .config import NS, ControlSettings, EngineConfig
from .core import Engine
from .samples import SampleBlock
from .sources import CommandHold, ControlLaw, TorqueSource

__all__ = ['NS', 'ControlSettings', 'EngineConfig', 'Engine', 'SampleBlock', 'CommandHold',
           'ControlLaw', 'TorqueSource']
