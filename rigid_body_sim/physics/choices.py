"""The names a user chooses from (integrators, dissipation models), free of numba.

Parsing a scene file, checking a parameter and ``--help`` need only these names, not the
methods: importing the registry loads every method's compiled loop and numba (~0.35 CPU-s
a process, and the suite starts hundreds of them). The registry and the dynamics import
the names from here, and the registry checks on import that they name its methods.
"""

DISSIPATION_MODELS = ('none', 'double_bracket', 'viscous')

# every registered integrator, in the registry's order (integrators._METHODS)
INTEGRATOR_NAMES = ('splitting2', 'splitting4', 'splitting6', 'rk4', 'implicit_midpoint',
                    'splitting2_lstable', 'exact', 'dop853', 'euler', 'gyrostat_strang')

# the methods that carry wheels or CMGs (``Integrator.requires_actuators``)
CARRY_ACTUATORS = ('gyrostat_strang',)

# the methods a scene without actuators can run
BODY_ONLY = tuple(name for name in INTEGRATOR_NAMES if name not in CARRY_ACTUATORS)
