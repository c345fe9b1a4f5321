"""Kernels loaded before a run's clock starts, for every front that has a clock (the CLI's
CPU figure, the live node's real-time pacing).

Only the kernels the run can use: loading all of them (:func:`compiled.warm`, 19 modules
from the disk cache) cost a 1 s offline run ~0.5 CPU-s whatever its scene needed."""
from .config import NS
from .core import Engine
from .specs import AUTO
from ..physics import INTEGRATORS


def start_numba() -> None:
    """numba's own start-up now (the runtime a kernel loaded from the disk cache needs;
    its import paid the rest): a front that times its kernel loading counts it there, not
    in whatever first calls a kernel (an orbit scene's engine build). The registries'
    refresh (0.1-0.2 CPU-s) is left to a compilation, which does it itself
    (physics/numba_start.py). Nothing without the JIT."""
    from ..physics import jit
    if jit.COMPILED:
        from ..physics.numba_start import start_runtime
        start_runtime()


def warm_selection(integrator: str, dissipation_model: str) -> None:
    """Before an offline engine is built (its build makes ``auto``'s choice, counted as
    selection CPU): auto's costs read, and where its pilot may run (torque-free with
    dissipation: the pilot runs candidates), every candidate's kernels loaded, so that
    the selection's CPU is the choice's, not the loading's (0.22 s of a 0.23 s selection
    on explorer1)."""
    if integrator != AUTO:
        return
    from ..physics.auto import calibration
    calibration.current()
    if dissipation_model != 'none':
        from ..physics.integrators import AUTO_CANDIDATES
        _load_modules(c.name for c in AUTO_CANDIDATES)


def _load_modules(methods) -> None:
    """Each of ``methods``' kernel modules' own warm-up (every loop of the module: a
    partial step to an event's instant runs another loop than the samples do)."""
    for module in dict.fromkeys(m for name in methods if name in INTEGRATORS
                                for m in INTEGRATORS[name].kernel_modules):
        module.warm()


def warm_for(engine: Engine) -> set:
    """Load every kernel ``engine``'s run will use, with the argument types it will pass,
    before its clock starts: a fresh engine of the same configuration (so ``auto``
    chooses the same, and re-chooses the same when the law's torque first appears) runs
    the first few sample periods, past the mission's free phase, where the law's method
    starts. Some loops are first called inside a run (the gyrostat loop of wheel scenes:
    60 ms of a 64 ms run). Returns the names of the methods it ran (:func:`load_kernels`)."""
    c = engine.config
    span = warm_span(c)
    copy = Engine(c, interpolate_samples=engine.interpolate_samples)
    methods = {copy.method}
    for _ in copy.run(min(copy.end_ns, copy.t_ns + span)):
        methods.add(copy.method)
    methods.add(copy.method)
    return methods


def warm_span(config) -> int:
    """The sim time (ns) a warm-up runs: three sample periods, and with a law, its free
    phase and three of its periods."""
    span = 3 * config.sample_period_ns
    if config.control is not None:
        span += round(config.control.free_time * 1e9) + 3 * config.control.period_ns
    return span


def load_kernels(config, methods) -> None:
    """Every loop of ``methods`` (what :func:`warm_for` ran) and, for a scene with them,
    the control law's and the sensor noise's kernels: what the rest of the run may call
    that its first periods did not. Not last before the clock: a :func:`warm_for` after it
    leaves the caches warm with the run's own code."""
    _load_modules(sorted(methods))
    if config.control is not None:
        from .. import control_kernel
        control_kernel.warm()
    if config.sensors is not None:
        from ..sensors import noise
        noise.warm()


def warm_live(engine: Engine) -> None:
    """The same for the live simulator's engine, before its t = 0: it advances sample by
    sample with ``auto``'s pilot worked between samples (``blocking_selection=False``), and
    commands switch it to the torque's path. A kernel first loaded (or, cache cold, compiled)
    after t = 0 stalls the real-time loop: seconds, 26 s with an empty cache. A fresh engine
    of the same configuration advances a few samples, lets the pilot choose, then runs with
    a small command and without it again."""
    c = engine.config
    copy = Engine(c, blocking_selection=False)
    p = c.sample_period_ns
    methods = {copy.method}

    def advance(samples):
        """``samples`` one call each (a live loop's turn, at real time), then as many
        in one call (catching up: the block path)."""
        for stop in [copy.t_ns + (k + 1) * p for k in range(samples)] + [
                copy.t_ns + 2 * samples * p]:
            if copy.finished or copy.fault:
                return
            if copy.selection_pending:
                copy.work()
            copy.advance(min(copy.end_ns, stop))
            methods.add(copy.method)
        copy.diagnostics()  # the state between samples
    advance(3)
    while copy.selection_pending and not copy.fault:
        copy.work()
    advance(3)
    copy.apply_command((1e-3 * c.max_torque,) * 3 if c.max_torque else (1e-6,) * 3)
    advance(3)
    copy.apply_command((0.0, 0.0, 0.0))
    advance(3)
    if copy.magnetics is not None and copy.magnetics.hold is not None:  # magnetorquers
        copy.apply_dipole_command((1e-3, 1e-3, 1e-3))
        advance(3)
    # past the command's expiry: the hold then has no event left and the block path runs
    # the samples in one compiled loop (splitting_run), a path of its own
    if 0 < c.command_timeout_ns < 600 * NS:
        until, before = copy.t_ns + c.command_timeout_ns + 3 * p, -1
        while not (copy.finished or copy.fault) and before < copy.t_ns:  # until no progress
            before = copy.t_ns
            copy.advance(until)
        advance(3)
    # and each method's loops as its module loads them (a partial step to an event's
    # instant runs another of its loops than the samples do)
    _load_modules(methods)
