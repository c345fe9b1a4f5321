"""The simulation engine: one closed loop for every front end, free of ROS.

* :mod:`.params` / :mod:`.specs` — parameter specs (name, type, unit, range) of the nodes.
* :mod:`.config` — typed, validated configuration built from parameter values.
* :mod:`.sources` — torque sources held between their events (commands, control law).
* :mod:`.samples` — blocks of samples in the user's frames, stamped with sim time (ns).
* :mod:`.core` — :class:`Engine`: state, sim time, integrator and ``auto``, events.
"""
from .config import NS, ControlSettings, EngineConfig
from .core import Engine
from .samples import SampleBlock
from .sources import CommandHold, ControlLaw, TorqueSource

__all__ = ['NS', 'ControlSettings', 'EngineConfig', 'Engine', 'SampleBlock', 'CommandHold',
           'ControlLaw', 'TorqueSource']
