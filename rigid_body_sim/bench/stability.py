"""Stability where methods fail: a fixed number of steps at growing step sizes.

Torque-free tumble: x = h·|ω|max. Stiff double-bracket dissipation: x = h·α|L|²(1/I_min −
1/I_max), the linearised decay rate times h (explicit RK4's real-axis limit is x ≈ 2.785).
Per run: max |L| and T drift over the run (relative to the start for the torque-free scene;
for dissipation |L| is the Casimir, and T is compared with a dense DOP853 reference at each
step), the attitude error at the end (torque-free: against the exact solution), the number
of steps on which |L| grew, and failure ("blown up at h = …": non-finite or Newton failure).
"""
import numpy as np

from ..physics import INTEGRATORS, IntegrationError, create, rotation
from .common import cpu
from .peers import _rhs_factory
from .scenes import SCENE_BY_NAME

FIELDS = ('scene', 'method', 'x', 'x_name', 'h', 'steps', 'steps_done', 'momentum_growth_steps',
          'max_momentum_drift', 'max_energy_drift', 'attitude_error', 'status', 'verdict')
GRID_FULL = (0.01, 0.03, 0.1, 0.3, 1.0, 2.0, 2.5, 2.7, 2.9, 3.0, 5.0, 10.0, 30.0, 100.0)
GRID_QUICK = (0.01, 0.1, 1.0, 2.0, 2.5, 3.0, 5.0, 10.0, 30.0, 100.0)
LIMIT = 0.01  # 1 % drift marks a method as failed


def _methods():
    return [n for n, c in INTEGRATORS.items() if not (c.adaptive or c.requires_actuators)]


def _sweep(scene, x_name, rate, steps, grid, budget, ref_fn, log):
    rows = []
    moments = np.asarray(scene.moments, float)
    dyn = scene.dynamics
    for name in _methods():
        spent, last = 0.0, None
        for x in grid:
            h = x / rate
            if last is not None:
                scale = (x / last[1] if (scene.dissipation.active
                                         and name.startswith(('splitting', 'exact'))) else 1.0)
                predicted = last[0] * max(scale, 1.0)
                if spent + predicted > budget:
                    log(f'  stability {scene.name}/{name}: x={x:g} skipped '
                        f'(predicted {predicted:.2g} s CPU > budget)')
                    break
            integ = create(name, dyn)
            q, m = scene.q0_array, scene.m0
            t0_T = 0.5 * float(np.sum(m * m / moments))
            g0 = float(np.linalg.norm(m))
            g_prev = g0
            growth, done, max_dg, max_dt = 0, 0, 0.0, 0.0
            status = 'ok'
            c0 = cpu()
            err_state = np.seterr(over='ignore', invalid='ignore')
            try:
                for k in range(steps):
                    q, m = integ.step(q, m, h, t=k * h)
                    done += 1
                    g = float(np.linalg.norm(m))
                    growth += g > g_prev
                    g_prev = g
                    max_dg = max(max_dg, abs(g - g0) / g0)
                    tk = 0.5 * float(np.sum(m * m / moments))
                    t_ref = ref_fn((k + 1) * h, t0_T)
                    max_dt = max(max_dt, abs(tk - t_ref) / t_ref)
                    if max_dg > 1e6 or max_dt > 1e6:
                        raise IntegrationError(name, h, k * h, 'drift > 1e6 (diverged)')
            except IntegrationError as exc:
                status = f'blown up at h={h:.4g}: {exc.reason}'
            finally:
                np.seterr(**err_state)
            cost = cpu() - c0
            spent += cost
            last = (cost, x)
            att = float('nan')
            if status == 'ok' and scene.torque_free:
                from ..physics.exact import TorqueFreeSolution
                q_ref, _ = TorqueFreeSolution(moments, scene.q0_array, scene.m0).at(steps * h)
                att = float(rotation.angle_between(q, q_ref))
            failed = status != 'ok' or max_dg > LIMIT or max_dt > LIMIT
            verdict = ('blown up' if status != 'ok' else
                       f'drift > {LIMIT:.0%}' if failed else 'bounded')
            rows.append({'scene': scene.name, 'method': name, 'x': x, 'x_name': x_name, 'h': h,
                         'steps': steps, 'steps_done': done, 'momentum_growth_steps': growth,
                         'max_momentum_drift': max_dg,
                         'max_energy_drift': max_dt, 'attitude_error': att, 'status': status,
                         'verdict': verdict})
    return rows


def run(quick, log=print):
    grid = GRID_QUICK if quick else GRID_FULL
    steps = 100 if quick else 300
    budget = 0.8 if quick else 8.0
    rows = []
    tumble = SCENE_BY_NAME['tumble']
    rows += _sweep(tumble, 'h*|w|max', tumble.omega_max, steps, grid, budget, lambda t, t0: t0,
                   log)
    stiff = SCENE_BY_NAME['stiff_dissipation']
    rate = stiff.stiffness
    horizon = steps * max(grid) / rate
    from scipy.integrate import solve_ivp
    sol = solve_ivp(_rhs_factory(stiff), (0.0, horizon), np.r_[stiff.q0_array, stiff.m0],
                    method='DOP853', rtol=1e-11, atol=1e-13, dense_output=True)
    moments = np.asarray(stiff.moments, float)

    def t_ref(t, _t0):
        m = sol.sol(min(t, horizon))[4:]
        return 0.5 * float(np.sum(m * m / moments))
    rows += _sweep(stiff, 'h*alpha*|L|^2*(1/Imin-1/Imax)', rate, steps, grid, budget, t_ref, log)
    return rows


def summary(rows):
    """One line per (scene, method): where it fails."""
    out = []
    for scene in dict.fromkeys(r['scene'] for r in rows):
        for method in dict.fromkeys(r['method'] for r in rows if r['scene'] == scene):
            rs = [r for r in rows if r['scene'] == scene and r['method'] == method]
            bad = [r for r in rs if r['verdict'] != 'bounded']
            if not bad:
                text = f'bounded at every x tested (up to {max(r["x"] for r in rs):g})'
            else:
                first = min(bad, key=lambda r: r['x'])
                ok_below = [r['x'] for r in rs
                            if r['verdict'] == 'bounded' and r['x'] < first['x']]
                text = f'fails from x = {first["x"]:g} ({first["verdict"]}; {first["status"]})'
                if ok_below:
                    text += f', bounded up to {max(ok_below):g}'
                if len(bad) == len(rs):
                    text = f'fails at every x tested ({first["verdict"]} from x = {first["x"]:g})'
            out.append((scene, method, text))
    return out
