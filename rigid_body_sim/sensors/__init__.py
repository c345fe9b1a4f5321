"""Sensors the controller may see instead of the truth: a rate gyro and a star tracker.

* :mod:`.noise` — the error processes (angle/rate random walk, Gauss–Markov bias
  instability, star-tracker noise) in discrete time, seeded, in vectorised blocks; the
  overlapping Allan deviation.
* :mod:`.estimator` — gyro-propagated attitude corrected by the star tracker.
* :mod:`.specs` — the ``seed`` and ``sensors.*`` parameters of the simulator and the
  ``feedback`` / ``estimator.*`` parameters of the controller; typed settings.

ROS-free. Sensors are off by default: a scene without them builds none of this.
"""
