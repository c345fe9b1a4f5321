"""Compile every numba kernel once (or load it from the on-disk cache): ``make`` runs this
at setup, and a colcon user runs it once after ``colcon build``, so that compile time
never lands in the middle of a run::

    python3 -c "import rigid_body_sim.compiled as c; c.warm()"

Each registered method names its kernel modules (``Integrator.kernel_modules``), each of
which warms its own kernels; the engine's closed loop is warmed through a short controlled
run, so it sees the argument types the engine passes (read-only model arrays).

Run as a module it then calibrates ``auto``'s per-step costs on this machine (once per
machine and kernel sources: ``physics.auto.calibration``), cached beside the kernels.
"""


def warm() -> bool:
    """Warm everything; True when numba compiled (False with NUMBA_DISABLE_JIT=1)."""
    from . import control_kernel
    from .engine import Engine, EngineConfig
    from .physics import INTEGRATORS, jit
    from .sensors import noise
    modules = [m for cls in INTEGRATORS.values() for m in cls.kernel_modules]
    for module in dict.fromkeys(modules + [control_kernel, noise]):
        module.warm()
    compiled = jit.COMPILED
    from .physics.auto import calibration
    calibration.current()  # auto's costs read now, not inside the first run's selection
    for method in ('splitting2', 'rk4'):
        config = EngineConfig.from_parameters(
            {'integrator': method, 'duration': 0.1, 'publish_rate': 20.0},
            {'mode': 'slew', 'target_attitude': [0.0, 0.0, 0.6, 0.8]})
        for _ in Engine(config).run():
            pass
    return compiled


def setup(log=print) -> bool:
    """What the setup does (``python -m rigid_body_sim.compiled``): :func:`warm`, then
    auto's costs calibrated if missing or stale, with the cost of an event in the engine's
    compiled loop. A benchmark starts with it, so that it measures the choices a user's
    set-up machine makes (where the calibration is stale, auto uses class constants)."""
    compiled = warm()
    from .physics.auto import calibration
    from .engine import event_cost
    # after warm: the loops timed are the ones runs will load
    calibration.ensure(log=log, events=event_cost.measure)
    return compiled


if __name__ == '__main__':
    import argparse
    argparse.ArgumentParser(prog='python3 -m rigid_body_sim.compiled', description=__doc__.split(
        '::')[0].replace('\n', ' ')).parse_args()  # -h/--help answered without compiling
    setup()
