"""Compile every numba kernel once (or load it from the on-disk cache): ``make`` runs this
at setup, and a colcon user runs it once after ``colcon build``, so that compile time
never lands in the middle of a run::

    python3 -m rigid_body_sim.compiled

Each registered method names its kernel modules (``Integrator.kernel_modules``), each of
which warms its own kernels; the engine's closed loop is warmed through a short controlled
run, so it sees the argument types the engine passes (read-only model arrays).

The built-in scenes then run briefly with every method (:func:`warm_scenes`), for the
loops only a scene's features reach (an orbit's torques, wheels and gimbals, a law).

Run as a module it then calibrates ``auto``'s per-step costs on this machine (once per
machine and kernel sources: ``physics.auto.calibration``), cached beside the kernels.
"""
import os


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
    from .engine import lockstep_direct  # a lockstep node's period (nodes/sim_lockstep.py)
    lockstep_direct.warm()
    if compiled:
        _warm_exchanges(Engine(config))
    return compiled


def _warm_exchanges(engine):
    """A lockstep node's compiled exchanges (``nodes/rcl_loop.py``), where rcl's calls can
    be had: compiled here, once, not before a lockstep node's first instant (~10 CPU-s).
    Where they cannot (no rclpy, no librcl mapped), the node takes the Python way and
    says why; so does this."""
    import logging
    try:
        from .nodes.sim_rcl import Compiled
    except ImportError as exc:  # no rclpy: offline use only
        logging.getLogger(__name__).info(f'lockstep exchanges not compiled: {exc}')
        return
    Compiled(logging.getLogger(__name__)).warm(engine)


def warm_scenes() -> int:
    """Every built-in scene run briefly with every registered method and with ``auto``, the
    offline way and the live way (the state on each sample): the kernels and argument types
    that only a scene's features reach (an orbit's environment torques, the gyrostat's
    wheels and gimbals, dop853 with an environment, the compiled closed loop of each law)
    compiled here, once, not in a user's first run of that scene (a live node's start, a
    CLI run's clock) nor in each test worker that first meets them (~30 kernels, 5-30
    CPU-s each, compiled in parallel by several workers). A combination the scene refuses
    (a fixed method that cannot take its torques) is skipped: its error is the user's, at
    its own run. Each runs as far as :func:`engine.warm.warm_for` runs a scene before its
    clock. Returns how many runs it made."""
    from . import offline
    from .physics import INTEGRATORS
    from .scene import SceneError, list_scenes, load
    from .engine.specs import AUTO
    from .engine import lockstep_direct
    from .engine.warm import warm_span
    runs = 0
    for name, _, _ in list_scenes():
        scene = load(name)
        if scene.spacecraft:
            continue  # several spacecraft: the node's fleet, whose bodies run the same loops
        for method in (AUTO, *INTEGRATORS):
            for live in (False, True):
                try:
                    engine = offline.engine_for(scene, integrator=method,
                                                interpolate_samples=not live)
                    until = min(engine.end_ns, engine.t_ns + warm_span(engine.config))
                    for _ in engine.run(until):
                        pass
                    if live and engine.config.environment is not None:
                        # lockstep's direct period with an environment's array (the
                        # one without: warm)
                        lockstep_direct.warm_engine(engine)
                except (SceneError, ValueError):
                    continue
                runs += 1
    return runs + _warm_wheels_in_an_orbit()


def _warm_wheels_in_an_orbit() -> int:
    """wheel_slew in a circular orbit with the gravity gradient, the offline way and the live
    way: the gyrostat's loop with an environment's array, which no built-in scene has (wheels
    or CMGs in an orbit; any orbit term, as they share the array). It compiled in a user's
    first such run, and in the test that first met it (~5-7 CPU-s). Returns the runs."""
    from .engine import Engine, EngineConfig
    from .engine.warm import warm_span
    from .scene import load
    sim = dict(load('wheel_slew').simulator, **{
        'orbit.model': 'kepler', 'orbit.semi_major_axis': 6.778e6,
        'environment.gravity_gradient': True})
    runs = 0
    for live in (False, True):
        engine = Engine(EngineConfig.from_parameters(sim), interpolate_samples=not live)
        for _ in engine.run(min(engine.end_ns, engine.t_ns + warm_span(engine.config))):
            pass
        runs += 1
    return runs


def sources_digest() -> str:
    """sha256 of the package's sources (.py, .yaml) and numba's version: what a result
    kept beside the kernels' cache was computed for."""
    import hashlib
    import numba
    package = os.path.dirname(os.path.abspath(__file__))
    digest = hashlib.sha256(f'numba {numba.__version__}'.encode())
    for root, dirs, files in sorted(os.walk(package)):
        dirs[:] = sorted(d for d in dirs if d != '__pycache__')
        for name in sorted(f for f in files if f.endswith(('.py', '.yaml'))):
            digest.update(name.encode())
            with open(os.path.join(root, name), 'rb') as f:
                digest.update(f.read())
    return digest.hexdigest()


def _warm_scenes_once() -> None:
    """:func:`warm_scenes` unless it ran for these sources and this numba already (its
    stamp beside auto's calibration): ``make test`` calls the setup each time, and the
    runs cost ~1.5 CPU-s even from a warm cache."""
    from .physics.auto import calibration
    digest = sources_digest()
    stamp = os.path.join(calibration.cache_dir(), 'scenes_warmed.sha256')
    try:
        with open(stamp, encoding='utf-8') as f:
            if f.read().strip() == digest:
                return
    except OSError:
        pass
    warm_scenes()
    try:
        os.makedirs(os.path.dirname(stamp), exist_ok=True)
        with open(stamp, 'w', encoding='utf-8') as f:
            f.write(digest + '\n')
    except OSError:
        pass  # a read-only install: warmed again next time, nothing lost


def setup(log=print) -> bool:
    """What the setup does (``python -m rigid_body_sim.compiled``): :func:`warm`, then
    auto's costs calibrated if missing or stale, with the cost of an event in the engine's
    compiled loop. A benchmark starts with it, so that it measures the choices a user's
    set-up machine makes (where the calibration is stale, auto uses class constants)."""
    compiled = warm()
    if compiled:
        _warm_scenes_once()
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
