"""The runs of ``auto``'s pilot under an in-process control law (``physics.auto.law_pilot``
decides what to run and what it means; this module only runs it).

Under a law the error of a method cannot be known a priori: the law's torque changes at
every control instant and feeds the state back, and dop853's error there spread 10⁴×
from scene to scene. So the pilot runs the candidates themselves from the current state,
with the law in the loop, in the engine's own compiled closed loop
(``closed_loop.closed_loop_run``, the kernel the run itself will use): the same law, mode,
clip and mission, samples off, stopped at the control instant before each part's end.
Nothing of the engine is written: the state, the held torque and the law's mode and
schedule are copied into the pilot's own arrays, and each run gets a fresh integrator.
"""
import numpy as np

from ..control_kernel import MODE_CODES
from ..physics import create
from .closed_loop import (ADAPTIVE_FAILED, ATOL, CLIP, COEFFICIENT, CONTROL_NS, EXIT_RATE,
                          FREE, FREE_TIME, GYROSCOPIC, H_MAX, INTERPOLATE, LIMIT_NS, METHOD,
                          MISSION_START, MODE, MODEL, PERIOD_NS, RATE_LIMIT, ROW, RTOL,
                          SAMPLE_NS, SAMPLE_PERIOD_NS, T_NS, TORQUE_LIMIT, closed_loop_run)
from .closed_loop_args import Packing
from .config import NS
from .samples import BlockBuilder
from .sources import NEVER


class LawRunner:
    """Runs a method with the law in the loop from a copy of the engine's state.

    ``law``: the engine's in-process ControlLaw (read, never written); ``state``: the
    engine's :class:`~.state.State` now; ``dynamics``, ``body``: the engine's. The engine
    makes it (``MethodChoice._law_runner``) where the law alone acts on the body."""

    def __init__(self, law, state, dynamics, body):
        ctl, mission, settings = law.controller, law.mission, law.settings
        cfg = ctl.config
        self.t0, self.control0 = state.t_ns, law.next_t
        self.q0, self.m0 = state.q.copy(), state.m.copy()
        self.tau0 = np.zeros(3) if law.torque is None else np.array(law.torque, float)
        self.period = settings.period_ns
        self.dynamics = dynamics
        self.packing = Packing()
        self.body = self.packing.body(dynamics, body)
        self.law = self.packing.law(ctl)
        builder = BlockBuilder(body, 1)  # no samples: the kernel needs a block
        self.block = builder.columns(1)
        ticks, reals = self.packing.ticks, self.packing.reals
        ticks[SAMPLE_NS], ticks[SAMPLE_PERIOD_NS], ticks[ROW], ticks[INTERPOLATE] = \
            NEVER, 1, 0, 0
        ticks[PERIOD_NS], ticks[GYROSCOPIC] = self.period, cfg.gyroscopic_compensation
        self.mode0, self.free0 = MODE_CODES[ctl.mode], int(law.free)
        reals[RATE_LIMIT], reals[TORQUE_LIMIT], reals[CLIP] = \
            cfg.rate_limit, cfg.torque_limit, law.clip
        start = law.next_t / NS if mission.start is None else mission.start
        reals[MISSION_START], reals[FREE_TIME], reals[EXIT_RATE] = \
            start, mission.free_time, mission.detumble_exit_rate
        reals[COEFFICIENT] = dynamics.dissipation.coefficient

    def run(self, name, options, h_max, ends):
        """Generator: ``name`` (with ``options``, at most ``h_max`` s a step) from the
        current state through each of ``ends`` (s from now, increasing), stopping at the
        last control instant before each; yields between them. Returns [(t s from now,
        q principal, steps so far)], or None if the method failed."""
        integ = create(name, self.dynamics, **dict(options))
        spec, model, rtol, atol = self.packing.method(integ)
        ticks, reals, out = self.packing.ticks, self.packing.reals, self.packing.out
        ticks[METHOD], ticks[MODEL] = integ.loop_code, model
        reals[H_MAX], reals[RTOL], reals[ATOL] = h_max, rtol, atol
        q, m, tau = self.q0.copy(), self.m0.copy(), self.tau0.copy()
        tau_p = np.zeros(3)
        t, control, mode, free = self.t0, self.control0, self.mode0, self.free0
        steps, marks = 0, []
        for end in ends:
            ticks[T_NS], ticks[CONTROL_NS], ticks[MODE], ticks[FREE] = t, control, mode, free
            ticks[LIMIT_NS] = self.t0 + int(end * NS) + 1
            closed_loop_run((q, m, tau, tau_p), ticks, reals, spec, self.body, self.body[3],
                            self.law, self.block, out)
            failed = int(out[5])
            if failed >= 0 or failed in (ADAPTIVE_FAILED, -2):
                return None
            control, mode, free, done, t = (int(out[0]), int(out[1]), int(out[2]),
                                            int(out[3]), int(out[7]))
            steps += done
            marks.append(((t - self.t0) / NS, q.copy(), steps))
            yield
        return marks
