"""Basilisk on the generated scenes, run as its users run it: the state recorded each sample.

The generalisation suite's peers (``generated_peers``) are scipy's solve_ivp, MuJoCo
(``generated_mujoco``) and, where it is installed (PyPI ``bsk``, pinned in
requirements-peers.txt), Basilisk. A Basilisk user with a free rigid body builds a
``spacecraft.Spacecraft`` hub with the inertia (diagonal here: principal = body frame), no
gravity field, a dynamics task at the integrator's step and a recorder on
``scStateOutMsg`` at the sample period (``basilisk_gg.build``, its gravity left out), and
runs ``ExecuteSimulation`` to the end; the attitude is its MRPs σ_BN as (x, y, z, w).

* RK4 (``svIntegratorRK4``): the task period is the step, from ~0.5 rad a step down by
  about halves to the first that meets the budget (a divisor of the sample period in ns,
  so that the ticks land on the samples; the recorder takes them there).
* RKF78 (``svIntegratorRKF78``): adaptive within each task period (the sample period),
  ``relTol`` down by decades, ``absTol`` = 1e-3·relTol, as in ``basilisk_gg``.

The duration is off the sample grid by a fraction of a period: the run goes on the task's
ticks to the last before the end, then one shorter update (the modules' ``UpdateState`` at
the end, in their task order) ends on the last sample, as MuJoCo's shortened last step.

Dissipative scenes: Basilisk has no internal-dissipation model. Its user writes a Python
module (``sysModel.SysModel``) that reads the hub's state message and writes the damping
torque (``peers._damper``) into an ``extForceTorque``'s ``cmdTorqueInMsg``, both ahead of
the hub in the task. It runs once per task period, so the torque is held over a step (over
a sample period with RKF78): that is the accuracy and the Python cost its user gets. The
error is then first order in the step (RK4 meets only loose budgets, at many steps) and,
with RKF78, of the held torque over a whole sample period (it meets none measured).

The sweep, its CPU cap (``common.cpu_limit``; the run goes to its stop time in ~10 ms
calls so that the interrupt lands) and ``beat`` are MuJoCo's (``generated_mujoco.ladder``
and ``each``). CPU: ``ExecuteSimulation`` and the last update; building and
``InitializeSimulation`` are outside the clock, as in ``basilisk_gg``.
"""
import math
from types import SimpleNamespace

import numpy as np

from . import basilisk_gg, generated_mujoco, peers
from .common import cpu

INTEGRATORS = (('bsk_rk4', 'rk4'), ('bsk_rkf78', 'rkf78'))
START_ROTATION = 0.5  # rad a step: the coarsest RK4 step tried
HALVINGS = 24
RTOLS = tuple(10.0 ** -k for k in range(3, 14))
# CPU s of one ExecuteSimulation call: it runs in C without the GIL's release, so a cap's
# interrupt lands between two (a whole RKF78 run in one call overran a 0.16 s cap by 0.4 s);
# the calls' Python adds ~1 % (0.1135 s against 0.1124 in one call: least of 7, interleaved)
CHUNK_CPU = 0.01


def available() -> bool:
    return basilisk_gg.installed() is not None


def _ns(seconds):
    return int(round(seconds * 1e9))


def divisors(period_ns):
    """The divisors of ``period_ns`` (a whole number of ns), ascending: RK4's possible
    steps a sample, whose task ticks land on the sample instants (a period in whole µs has
    at least those of 1000: 1, 2, 4, 5, 8, 10, …, 1000)."""
    low = np.arange(1, math.isqrt(period_ns) + 1, dtype=np.int64)
    low = low[period_ns % low == 0]
    return np.unique(np.r_[low, period_ns // low])


def steps_per_sample(period_ns, at_least):
    """The least divisor of ``period_ns`` that is ≥ ``at_least`` (None past the period)."""
    d = divisors(period_ns)
    i = int(np.searchsorted(d, max(1.0, at_least)))
    return int(d[i]) if i < len(d) else None


def _damping(scene, moments):
    """``extra`` for ``basilisk_gg.build``: the damping module and its effector, or None."""
    d = SimpleNamespace(active=scene.dissipative, model=scene.kind,
                        coefficient=scene.coefficient)
    damper = peers._damper(SimpleNamespace(dissipation=d, moments=moments))
    if damper is None:
        return None
    i1, i2, i3 = (float(v) for v in moments)

    def extra(sim, sc):
        from Basilisk.architecture import messaging, sysModel
        from Basilisk.simulation import extForceTorque

        class Damping(sysModel.SysModel):
            """The user's module: the torque of the body's own state, each task period."""

            def __init__(self):
                super().__init__()
                self.stateInMsg = messaging.SCStatesMsgReader()
                self.torqueOutMsg = messaging.CmdTorqueBodyMsg()
                self.payload = messaging.CmdTorqueBodyMsgPayload()

            def UpdateState(self, CurrentSimNanos):  # noqa: N802, N803 - Basilisk's names
                w1, w2, w3 = self.stateInMsg().omega_BN_B
                self.payload.torqueRequestBody = damper(i1 * w1, i2 * w2, i3 * w3)
                self.torqueOutMsg.write(self.payload, CurrentSimNanos, self.moduleID)

        ext = extForceTorque.ExtForceTorque()
        ext.ModelTag = 'damping_effector'
        sc.addDynamicEffector(ext)
        module = Damping()
        module.ModelTag = 'damping'
        module.stateInMsg.subscribeTo(sc.scStateOutMsg)
        ext.cmdTorqueInMsg.subscribeTo(module.torqueOutMsg)
        # higher priority runs first: the torque of the last state, then the hub's step
        sim.AddModelToTask('dyn', module, 300)
        sim.AddModelToTask('dyn', ext, 200)
        return module, ext
    return extra


def run(scene, param, integrator, times):
    """(CPU s, attitude (n, 4) (x, y, z, w) at ``times``) of one Basilisk run: integrator
    'rk4' (``param``: its steps per sample, an int dividing the period in ns) or 'rkf78'
    (``param``: relTol). ``times``: the grid from 0 at one period, and the end."""
    period_ns, end_ns = _ns(times[1] - times[0]), _ns(times[-1])
    if integrator == 'rk4' and period_ns % int(param):
        raise ValueError(f'RK4 at {param} steps a sample: not a divisor of {period_ns} ns')
    task_ns = period_ns // int(param) if integrator == 'rk4' else period_ns
    moments = np.asarray(scene.moments, float)
    setup = SimpleNamespace(moments=moments, mu=None, r0=np.zeros(3), v0=np.zeros(3),
                            attitude=np.asarray(scene.attitude, float),
                            angular_velocity=np.asarray(scene.omega, float),
                            sample_period=period_ns * 1e-9)
    sim, sc, _, rec = basilisk_gg.build(setup, integrator, task_ns * 1e-9 if integrator ==
                                        'rk4' else param, extra=_damping(scene, moments),
                                        gravity_gradient=False)
    # off the sample grid, the end is reached by one update after the last tick before it
    # (even one landing on the end: the recorder would not take it)
    off_grid = end_ns % period_ns != 0
    last_tick = ((end_ns - 1) // task_ns) * task_ns if off_grid else end_ns
    c0 = cpu()
    t, ticks = 0, 16
    while t < last_tick:  # in chunks of ~CHUNK_CPU: a cap's interrupt lands between two
        c = cpu()
        t = min(last_tick, t + ticks * task_ns)
        sim.ConfigureStopTime(t)
        sim.ExecuteSimulation()
        ticks = max(1, int(ticks * min(4.0, CHUNK_CPU / max(cpu() - c, 1e-6))))
    if off_grid:  # the last sample: one shorter update
        for model in (*(sim._bench_keep[2] or ()), sc):  # the damping module first
            model.UpdateState(end_ns)
    sigma_end = sc.scStateOutMsg.read().sigma_BN
    spent = cpu() - c0
    sigma = np.asarray(rec.sigma_BN, float)
    if len(sigma) != len(times) - off_grid:
        raise RuntimeError(f'{len(sigma)} recorded samples for {len(times)} instants')
    if off_grid:
        sigma = np.vstack((sigma, sigma_end))
    q = basilisk_gg.mrp_to_quat(sigma)
    if not np.all(np.isfinite(q)):
        raise RuntimeError('non-finite state')
    del sim
    return spent, q


def _params(scene, integrator, times):
    """The sweep's ladder coarse → fine: RK4's steps a sample, or RKF78's relTol."""
    if integrator == 'rkf78':
        return RTOLS
    period_ns = _ns(times[1] - times[0])
    rate = float(np.linalg.norm(scene.omega))
    d = divisors(period_ns)
    # the least with at most START_ROTATION a step, then each the least ≥ twice the last
    n = d[min(len(d) - 1, int(np.searchsorted(d, rate * period_ns * 1e-9 / START_ROTATION
                                               - 1e-9)))]
    out = []
    while n is not None and len(out) < HALVINGS:
        out.append(int(n))
        i = int(np.searchsorted(d, 2 * n))
        n = d[i] if i < len(d) else None
    return out


def load():
    """Imports every Basilisk module a run uses. Outside any CPU cap: a first import that a
    cap stops leaves the package half initialised, and every later run of the process then
    fails ("partially initialized module 'Basilisk'"), each counted as a diverged rung."""
    from Basilisk.architecture import bskLogging, messaging, sysModel  # noqa: F401
    from Basilisk.simulation import (GravityGradientEffector, extForceTorque,  # noqa: F401
                                     gravityEffector, spacecraft, svIntegrators)
    from Basilisk.utilities import SimulationBaseClass, macros  # noqa: F401


def sweep(scene, integrator, ref, times, cap, beat=math.inf):
    """(param, CPU s, error) of the first rung meeting the budget; else (None, bound, error
    of its last finished run): MuJoCo's sweep (``generated_mujoco.ladder``). ``param``:
    RK4's step in s, or RKF78's relTol."""
    load()
    out = generated_mujoco.ladder(scene, ref, _params(scene, integrator, times),
                                  lambda p: run(scene, p, integrator, times), cap, beat)
    if integrator == 'rk4' and out[0] is not None:
        return (_ns(times[1] - times[0]) * 1e-9 / out[0],) + out[1:]
    return out


def runs(scene, ref, times, cap, beat=math.inf, log=print):
    """[(peer name, step or relTol or None, CPU s or bound, error)] for each Basilisk
    integrator, each stopped where it can no longer set the row; [] without Basilisk.
    Each sweep runs in a child process (:func:`isolated`): a run can abort the process
    from C++ (``libc++abi: terminating``: generated scene 74 ended a 100-scene run so);
    a sweep whose child died is logged and sets nothing (bound inf)."""
    if not available():
        return []
    load()  # once in the parent: each child inherits the modules

    def one(integ, b):
        out, status = isolated(lambda: sweep(scene, integ, ref, times, cap, b))
        if out is None:
            log(f'  Basilisk {integ} on {getattr(scene, "name", "the scene")}: its process '
                f'ended without a result (wait status {status}); counted as no setting met')
            return None, math.inf, math.inf
        return out
    return generated_mujoco.each(INTEGRATORS, one, beat)


def isolated(call):
    """(``call()``'s picklable result computed in a forked child, or None if the child
    ended without one; the child's wait status). CPU figures measured inside are the
    child's own."""
    import os
    import pickle
    import sys
    sys.stdout.flush()
    sys.stderr.flush()
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: its result down the pipe, then out without cleanup
        code = 1
        try:
            os.close(read)
            with os.fdopen(write, 'wb') as f:
                f.write(pickle.dumps(call()))
            code = 0
        finally:
            os._exit(code)
    os.close(write)
    with os.fdopen(read, 'rb') as f:
        data = f.read()
    _, status = os.waitpid(pid, 0)
    return (pickle.loads(data) if data else None), status
