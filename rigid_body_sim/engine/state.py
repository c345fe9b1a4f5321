"""The engine's mutable state as a record, handed to what advances it and taken back.

:class:`Engine` owns its state; the parts of the engine in other modules (the compiled
closed loop, the health report) receive a :class:`State` and, where they advance it,
return a new one in a :class:`Stretch` for the engine to take (cf. MuJoCo's mjData,
Drake's Context): nothing outside ``core.py`` and its mixins writes the engine's
attributes.

Both are named tuples, immutable like the frozen dataclasses they were but made in a
third of the time: a lockstep exchange makes three (1.1 µs each as dataclasses).
"""
from typing import NamedTuple, Optional

import numpy as np

from ..physics import IntegrationError


class State(NamedTuple):
    """q (4,) principal → inertial (x, y, z, w); m (3,) principal-frame momentum, kg·m²/s;
    t_ns: sim time, ns; next_sample: the next sample instant, ns; tau_body: the held total
    torque, body frame, N·m (None: none); tau_p: what acts on the body from outside,
    principal frame (None: none; with actuators allocating, they make the torque
    internally); torque_seen: a torque has acted since the start (auto's choice)."""
    q: np.ndarray
    m: np.ndarray
    t_ns: int
    next_sample: int
    tau_body: Optional[np.ndarray]
    tau_p: Optional[np.ndarray]
    torque_seen: bool


class Stretch(NamedTuple):
    """What advancing over a stretch of events gives back: the new ``state``, the sample
    ``rows`` written into the block, the method's ``steps`` and ``evaluations``, and the
    ``error`` that stopped it (None: none; the counts then include the failed steps).
    ``full``: it stopped because the block has no room for the next stretch's samples."""
    state: State
    rows: int
    steps: int
    evaluations: int
    error: Optional[IntegrationError] = None
    full: bool = False
