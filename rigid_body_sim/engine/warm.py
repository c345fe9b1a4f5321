"""Kernels loaded before a run's clock starts, for every front that has a clock (the CLI's
CPU figure, the live node's real-time pacing)."""
from .core import Engine


def warm_for(engine: Engine) -> None:
    """Load every kernel ``engine``'s run will use, with the argument types it will pass,
    before its clock starts: :func:`compiled.warm` loads each module's kernels, but some
    are first called inside a run (the gyrostat loop of wheel scenes: 60 ms of a 64 ms
    run). A fresh engine of the same configuration (so ``auto`` chooses the same) runs the
    first few sample periods, past the mission's free phase, where the law's method starts."""
    c = engine.config
    span = 3 * c.sample_period_ns
    if c.control is not None:
        span += round(c.control.free_time * 1e9) + 3 * c.control.period_ns
    copy = Engine(c)
    for _ in copy.run(min(copy.end_ns, copy.t_ns + span)):
        pass
