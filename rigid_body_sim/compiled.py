"""Compile every numba kernel once (or load it from the on-disk cache): ``make`` runs this
at setup, and a colcon user runs it once after ``colcon build``, so that compile time
never lands in the middle of a run::

    python3 -c "import rigid_body_sim.compiled as c; c.warm()"

Each kernel module warms its own kernels; the engine's closed loop is warmed through a
short controlled run, so it sees the argument types the engine passes (read-only model
arrays).
"""


def warm() -> bool:
    """Warm everything; True when numba compiled (False with NUMBA_DISABLE_JIT=1)."""
    from . import control_kernel
    from .engine import Engine, EngineConfig
    from .physics import exact
    from .physics.integrators import (dop853_dense, dop853_kernel, explicit_kernel,
                                      gyrostat_kernel, implicit_kernel, splitting_batch_kernel,
                                      splitting_kernel)
    from .sensors import noise
    compiled = splitting_kernel.warm()
    for module in (explicit_kernel, splitting_batch_kernel, implicit_kernel, dop853_kernel,
                   dop853_dense, exact, control_kernel, gyrostat_kernel, noise):
        module.warm()
    for method in ('splitting2', 'rk4'):
        config = EngineConfig.from_parameters(
            {'integrator': method, 'duration': 0.1, 'publish_rate': 20.0},
            {'mode': 'slew', 'target_attitude': [0.0, 0.0, 0.6, 0.8]})
        for _ in Engine(config).run():
            pass
    return compiled


if __name__ == '__main__':
    warm()
