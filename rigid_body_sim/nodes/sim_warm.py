"""The simulator node's kernels before t = 0 (a mixin of ``simulator.Simulator``).

A kernel first loaded (or compiled) inside the paced loop stalls it for that long, so the
node loads every kernel its spacecraft will use before its first sample (``warm_live``),
and its diagnostics count what still came after t = 0 (``kernels_loaded_after_t0``).
"""
import time

# engine.warm, engine.lockstep_direct and physics.jit are imported in the methods: each
# loads numba (~0.4 CPU-s), which the node needs only once it has an engine to warm
# (a node refused for its parameters exits before; spacecraft.py)


class Warming:
    """Reads the node's ``_crafts``, ``_log`` and ``_started``."""

    def _mark_t0(self):
        """The first sample is next: what loads from now on stalls the loop."""
        from ..physics import jit
        self._kernels_at_t0 = jit.signatures()

    def _warm(self):
        """Load every kernel the spacecraft will use before t = 0 (``warm_live``): one
        spacecraft per kind of model, since a fleet's alike share their kernels."""
        from ..engine import lockstep_direct
        from ..engine.warm import warm_live
        from ..physics import jit
        kinds = {}
        for craft in self._crafts.values():
            c = craft.engine.config
            kinds.setdefault((c.integrator, c.dissipation.model, c.actuators is None,
                              c.sensors is None, c.environment is None), craft)
        start = time.monotonic()
        for craft in kinds.values():
            try:
                warm_live(craft.engine)
                if self._lockstep and not craft.name:  # its direct period (sim_lockstep)
                    lockstep_direct.warm_engine(craft.engine)
            except Exception as exc:  # noqa: BLE001 - the run itself reports its failure
                self._log.warning(f'{craft.prefix}kernels not loaded before t = 0: '
                                  f'{type(exc).__name__}: {exc}')
        self._log.info(f'kernels loaded in {time.monotonic() - start:.3g} s '
                       f'({jit.signatures()} compiled versions)')

    def kernels_after_t0(self) -> int:
        """Compiled versions loaded (or compiled) since t = 0: each stalled the loop."""
        if not self._started:
            return 0
        from ..physics import jit
        return jit.signatures() - self._kernels_at_t0
