"""The controller's modes and the law's parameter defaults, free of numba.

The engine's specs (and so parsing a scene file and ``--help``) need only these values;
:mod:`.control` (which re-exports them) imports its compiled law and with it numba.
"""

MODES = ('detumble', 'slew', 'off', 'bdot')  # bdot: the rods, no torque (bdot.py)

# Defaults of the controller node's parameters that concern the law (the node's SPECS use
# these; offline runs fill missing scene values from them).
PARAMETER_DEFAULTS = {
    'mode': 'detumble',
    'inertia': [1.0, 2.0, 3.0],
    'control_rate': 50.0,
    'natural_frequency': 0.5,
    'damping_ratio': 1.0,
    'kp': [0.0, 0.0, 0.0],
    'kd': [0.0, 0.0, 0.0],
    'rate_gain': 0.0,
    'gyroscopic_compensation': True,
    # = the simulator's default (per-axis there; a norm here, so never clipped there)
    'max_torque': 1.0,
    'max_rate': 0.0,
    'target_attitude': [0.0, 0.0, 0.0, 1.0],
    'mission.free_time': 0.0,
    'mission.detumble_exit_rate': 0.0,
}
CONFIG_PARAMETERS = ('inertia', 'natural_frequency', 'damping_ratio', 'kp', 'kd', 'rate_gain',
                     'gyroscopic_compensation', 'max_torque', 'max_rate')
