"""MuJoCo on the generated scenes, run as its users run it: the state read at each sample.

The generalisation suite's peers (``generated_peers``) are scipy's solve_ivp and, where it
is installed (``rigid-body-sim bench --peers`` says how), MuJoCo. A MuJoCo user with a free
body calls ``mj_step`` in a loop and reads ``qpos``/``qvel`` at the instants they record:
here ``mj_step(model, data, nstep=k)`` between samples, the last step shortened to end at a
sample off the step grid (a duration that is not a multiple of the sample period). MuJoCo
has no internal-dissipation model, so a dissipative scene adds the damping torque from
Python in MuJoCo's passive-force callback (``peers.mujoco_damping``), as its users do.

Its step goes down by halves from ~0.5 rad of rotation a step to the first that meets the
scene's budget against its reference, within a CPU cap; that run's CPU is the peer's. The
free joint's angular velocity and applied torque are in the body frame (principal here:
the generated inertia is diagonal), the quaternion is (w, x, y, z) in ``qpos[3:7]``.
"""
import contextlib
import importlib.util
import math
from types import SimpleNamespace

import numpy as np

from ..physics import rotation
from . import peers
from .common import CpuCapReached, cpu, cpu_limit

INTEGRATORS = (('mujoco_rk4', 'RK4'), ('mujoco_euler', 'Euler'))
START_ROTATION = 0.5  # rad a step: the coarsest step tried
HALVINGS = 24


def available() -> bool:
    return importlib.util.find_spec('mujoco') is not None


@contextlib.contextmanager
def _warnings_counted():
    import mujoco
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(lambda message: None)
    try:
        yield
    finally:
        mujoco.set_mju_user_warning(previous)


def run(scene, h, integrator, times):
    """(CPU s, attitude (n, 4) (x, y, z, w) at ``times``) of one MuJoCo run at step ``h``."""
    import mujoco
    model = peers.mujoco_model(scene.moments, h, integrator)
    data = mujoco.MjData(model)
    moments = np.asarray(scene.moments, float)
    q0 = np.asarray(scene.attitude, float)
    data.qpos[3:7] = (q0[3], q0[0], q0[1], q0[2])
    data.qvel[3:6] = np.asarray(scene.omega, float)
    d = SimpleNamespace(active=scene.dissipative, model=scene.kind,
                        coefficient=scene.coefficient)
    damper = peers._damper(SimpleNamespace(dissipation=d, moments=moments))
    out = np.empty((len(times), 4))
    # MuJoCo prints a warning for an unstable run and resets it; the run is judged failed
    # below from its warning counter, so the message goes to the bench's log, not stderr.
    with _warnings_counted(), \
            peers.mujoco_damping(damper, moments) if damper else contextlib.nullcontext():
        c0 = cpu()
        t = 0.0
        for k, t_sample in enumerate(times):
            n = int(math.floor((t_sample - t) / h + 1e-9))
            rest = (t_sample - t) - n * h
            if n:
                mujoco.mj_step(model, data, nstep=n)
            if rest > 1e-12 * max(1.0, t_sample):  # off the grid: one shorter step
                model.opt.timestep = rest
                mujoco.mj_step(model, data)
                model.opt.timestep = h
            t = t_sample
            out[k] = (data.qpos[4], data.qpos[5], data.qpos[6], data.qpos[3])
    spent = cpu() - c0
    # MuJoCo resets an unstable simulation and carries on: that is a failed run.
    if data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number > 0:
        raise RuntimeError('MuJoCo reported an unstable simulation (bad qacc) and reset it')
    if not np.all(np.isfinite(out)):
        raise RuntimeError('non-finite state')
    return spent, out / np.linalg.norm(out, axis=1, keepdims=True)


def sweep(scene, integrator, ref, times, cap, beat=math.inf):
    """(h, CPU s, error) of the first step meeting the budget; else (None, bound, error of
    its last finished run), as ``generated_peers.peer_sweep``: ``cap`` (CPU s of the
    sweep) held by an interrupt, ``beat`` the least CPU a peer already run needs."""
    rate = float(np.linalg.norm(scene.omega))
    h = min(float(times[1] - times[0]) if len(times) > 1 else float(times[-1]),
            START_ROTATION / max(rate, 1e-12))
    return ladder(scene, ref, [h / 2.0 ** k for k in range(HALVINGS)],
                  lambda step: run(scene, step, integrator, times), cap, beat)


def ladder(scene, ref, rungs, run_rung, cap, beat=math.inf):
    """(rung, CPU s, error) of the first of ``rungs`` (coarse → fine, each run costing
    about twice the last) whose ``run_rung(rung)`` → (CPU s, attitude at the samples)
    meets the budget; else (None, bound, error of its last finished run). A run that
    raises is one more rung down. Basilisk's sweep is this one too."""
    spent, last_cost, bound, err_last = 0.0, 0.0, 0.0, math.inf
    for rung in rungs:
        left = cap - spent
        if 2.5 * last_cost > left:
            break  # the next run, at half the step, costs about twice the last
        limit = min(left, beat)
        c0 = cpu()
        try:
            with cpu_limit(limit):
                c, q = run_rung(rung)
        except CpuCapReached:
            spent += cpu() - c0
            return None, max(bound, cpu() - c0, beat if beat <= left else 0.0), err_last
        except Exception:  # noqa: BLE001 - a run that blows up is one more rung down
            last_cost = cpu() - c0
            spent += last_cost
            bound = max(bound, last_cost)
            continue
        err = float(np.max(rotation.angle_between(q, ref.attitude)))
        last_cost, err_last = c, err
        spent += cpu() - c0
        if err + ref.error <= scene.budget:
            return rung, c, err
        bound = max(bound, c)
    else:  # every rung ran and missed: no bound holds (generated_peers._row_of)
        return None, math.inf, err_last
    return None, bound, err_last


def runs(scene, ref, times, cap, beat=math.inf):
    """[(peer name, h or None, CPU s or bound, error)] for each MuJoCo integrator, each
    stopped where it can no longer set the row (``beat``, or the other's); [] without it."""
    if not available():
        return []
    # imported before any run's CPU cap: its first import (~0.1 CPU-s) inside a run's
    # cap was stopped by it and failed ("initialization failed"), a peer's every rung
    # then counted as a diverged run (a scene measured alone lost MuJoCo)
    import mujoco  # noqa: F401
    return each(INTEGRATORS, lambda integ, b: sweep(scene, integ, ref, times, cap, b), beat)


def each(integrators, sweep_one, beat=math.inf):
    """[(name,) + sweep_one(integrator, beat)] for each (name, integrator), each one's
    ``beat`` the least CPU of those before it (met, or bounded)."""
    out = []
    for name, integrator in integrators:
        out.append((name,) + sweep_one(integrator, beat))
        beat = min(beat, out[-1][2])
    return out
