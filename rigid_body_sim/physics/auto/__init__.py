"""``integrator: auto``: the method and step that meet the scene's accuracy at least cost.

* :mod:`.selection` — the search (``select``, ``selecting``, :class:`Selection`).
* :mod:`.model` — the a-priori model: each registered method's facts, the run's time scales.
* :mod:`.pilot` — step doubling where the a-priori estimate is too uncertain.
* :mod:`.step_advice` — a fixed method's error predicted with the same model.
"""
from .selection import CANDIDATES, Candidate, Selection, select, selecting

__all__ = ['CANDIDATES', 'Candidate', 'Selection', 'select', 'selecting']
