"""The spacecraft's environment in orbit (no ROS): the rotating Earth, its magnetic field,
the Sun's direction and the Earth's shadow. Positions are inertial (``world``), in m."""
from . import earth, magnetic_field, sunlight

__all__ = ['earth', 'magnetic_field', 'sunlight']
