"""What an event (a sample instant) costs in the engine's compiled closed loop, measured on
this machine for ``auto``'s cost model (``physics.auto.calibration``: the setup's
``python -m rigid_body_sim.compiled`` passes :func:`measure` in; physics does not import
the engine).

The same run twice, the same steps, 1 and 1000 samples a second: the CPU difference per
extra sample is what an event adds (the kernel writes the sample into the block and goes
on). auto's constant (15 µs an event, the event-by-event loop from Python, plus 2.5 µs a
call around the compiled loop) was 100× this where the loop is compiled (0.08–0.2 µs
measured at load 8), and drowned the methods' per-step costs: within its 10 % preference
for a geometric method, auto took splitting4 at 3× the CPU of dop853 (generated orbit
scenes 5, 10 and 28 of seed 20261125).
"""
import time

DURATION, STEP = 20.0, 1e-3       # s: 20,000 steps
RATES = (1.0, 1000.0)             # samples per second: 20 and 20,000 events
METHODS = ('rk4', 'splitting2')   # the largest of the two loops' figures
REPEATS = 5


def _run(method: str, rate: float) -> float:
    """CPU s of one engine run (built and run) of the timed scene."""
    from .config import EngineConfig
    from .core import Engine
    config = EngineConfig.from_parameters({
        'integrator': method, 'duration': DURATION, 'publish_rate': rate, 'step': STEP,
        'inertia': [1.0, 2.0, 3.0], 'initial_angular_velocity': [0.3, 0.1, 0.2],
        'dissipation.model': 'viscous', 'dissipation.coefficient': 1e-3})
    t0 = time.process_time()
    for _ in Engine(config).run():
        pass
    return time.process_time() - t0


def measure(repeats: int = REPEATS) -> float:
    """µs per event of the compiled closed loop: the least CPU of ``repeats`` runs at each
    rate (the runs least disturbed by the rest of the machine), the largest over METHODS."""
    extra = DURATION * (RATES[1] - RATES[0])
    worst = 0.0
    for method in METHODS:
        _run(method, RATES[1])  # kernels loaded, blocks sized, before timing
        few, many = (min(_run(method, rate) for _ in range(repeats)) for rate in RATES)
        worst = max(worst, (many - few) / extra * 1e6)
    return worst
