"""Basilisk 2.12 (PyPI ``bsk``) on the gravity-gradient scenes, against ours at equal error.

    python -m rigid_body_sim.bench.basilisk_gg [--quick] [--out DIR]

Scenes: ``config/gravity_gradient.yaml`` (circular orbit at 7,000 km, libration about
LVLH) and an eccentric, tumbling variant of it (``TUMBLE``). Both simulators run the same
physics, checked term by term (test/test_bench_basilisk.py: the torques agree to 1e-12):

* the body: Basilisk's spacecraft hub with ``IHubPntBc_B`` = diag(I), its centre of mass at
  B; the scenes give I as a diagonal, so our principal frame is the body frame;
* the torque: its ``GravityGradientEffector``, τ = 3μ/r³ r̂ × (I r̂), as ours
  (physics/orbit/kernel.py);
* μ: Basilisk's Earth has 3.98600436e14 m³/s² (astroConstants.h ``MU_EARTH``), ours
  3.986004418e14 (physics/orbit/constants.py), 4.5e-9 apart: its Earth is given ours;
* the orbit, as each user gets it. Ours is the Kepler orbit in closed form. Basilisk
  integrates the hub's translation under a point-mass Earth (``GravBodyData``, central)
  with the attitude's integrator and step, from our orbit's r, v at t = 0. Its orbit error
  is therefore part of its attitude error; every row gives it (``orbit_error``: the largest
  angle between its position and ours at the samples), to show what that costs.

Each runs as its user runs it, the state recorded at the scene's sample rate (0.1 Hz):
Basilisk's dynamics task at the step (RK4) or at the sample period (RKF78, adaptive within
each task period; ``absTol`` = 1e-3·``relTol``), a recorder on ``scStateOutMsg`` every
sample period; ours through ``offline.simulate``, every sample kept. CPU: process seconds of
``ExecuteSimulation`` (``InitializeSimulation`` outside the clock, as in peers.py) and of
our run (its ``cpu_seconds``, auto's selection included), the least of a few runs.

Error: the largest attitude angle at the samples against one reference, our dop853 down the
oracle's rtol ladder (bench/oracle.reference) with its bound on its own error. The target
row at each error level is Basilisk's least CPU to reach it over ours (targets.cpu_to_reach).

Not here yet: the magnetorquer comparison (``MtbEffector`` with a centred dipole), which
needs our magnetorquers.
"""
import math
import os
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from ..engine import EngineConfig
from ..offline import effective_parameters
from ..physics import rotation
from ..scene import load
from . import oracle, targets
from .common import cpu, write_csv

FIELDS = ('scene', 'method', 'family', 'kind', 'param', 'cpu_s', 'attitude_error',
          'orbit_error', 'samples', 'reference_error', 'status')
TARGET = 'Basilisk CPU / ours at equal attitude error (gravity gradient)'
REQUIRED = 10.0
TUMBLE = ('orbit.semi_major_axis=9.0e6', 'orbit.eccentricity=0.25',
          'orbit.argument_of_periapsis=0.5', 'orbit.true_anomaly=2.0',
          'initial_angular_velocity=[0.003, -0.002, 0.004]')
QUICK_DURATION = 4000.0  # s: --quick runs the circular scene over this horizon only
REF_BUDGET = 1e-11  # the reference ladder refines until its bound is under a quarter of it
BUDGET = {True: 0.5, False: 12.0}   # CPU s per method's sweep (quick, full)
STEPS = tuple(10.0 / 2 ** k for k in range(12))     # s: the sample period halved
TOLS = tuple(10.0 ** -k for k in range(4, 14))
# our dop853 stops short of the reference's rtol (1e-13 or finer): it would be its own judge
OUR_TOLS = TOLS[:-1]
ACCURACIES = tuple(10.0 ** -k for k in range(2, 12))
OURS = (('auto', 'accuracy', ACCURACIES), ('splitting4', 'h', STEPS),
        ('splitting6', 'h', STEPS), ('rk4', 'h', STEPS), ('dop853', 'rtol', OUR_TOLS))
PEERS = (('bsk_rk4', 'h', STEPS), ('bsk_rkf78', 'rtol', TOLS))
FLOOR = 1e-13


@dataclass(frozen=True)
class GgScene:
    name: str
    overrides: tuple

    def scene_file(self, quick=False):
        extra = (f'duration={QUICK_DURATION!r}',) if quick else ()
        return load('gravity_gradient', self.overrides + extra)


SCENES = (GgScene('gravity_gradient', ()), GgScene('gravity_gradient_tumble', TUMBLE))


@dataclass(frozen=True)
class Setup:
    """The initial state both simulators start from (inertial frame, SI)."""
    moments: np.ndarray
    mu: float
    r0: np.ndarray
    v0: np.ndarray
    attitude: np.ndarray          # body → inertial, (x, y, z, w)
    angular_velocity: np.ndarray  # body frame, rad/s
    sample_period: float
    duration: float
    orbit: object

    @classmethod
    def of(cls, scene_file):
        config = EngineConfig.from_parameters(effective_parameters(scene_file))
        body, env = config.body, config.environment
        if not np.allclose(body.principal_to_body, (0.0, 0.0, 0.0, 1.0), atol=0.0):
            raise ValueError(f'{scene_file.path}: the Basilisk harness needs the inertia as '
                             'its diagonal (principal frame = body frame)')
        if env is None or not env.gravity_gradient:
            raise ValueError(f'{scene_file.path}: no orbit with the gravity gradient')
        r0, v0 = env.orbit.state(0.0)
        return cls(np.asarray(body.principal_moments, float), env.orbit.mu, r0, v0,
                   np.asarray(config.attitude, float),
                   np.asarray(config.angular_velocity, float), config.sample_period,
                   config.duration, env.orbit)


def installed():
    """bsk's version, or None when it is not installed."""
    import importlib.util
    if importlib.util.find_spec('Basilisk') is None:
        return None
    from importlib.metadata import version
    return version('bsk')


def mrp_to_quat(sigma):
    """MRPs σ_BN (..., 3) → our attitude body → inertial (x, y, z, w): the same rotation
    (axis ê, angle Φ from N to B), so q = (2σ, 1 − σ²)/(1 + σ²)."""
    sigma = np.asarray(sigma, float)
    s2 = np.sum(sigma * sigma, axis=-1, keepdims=True)
    return np.concatenate((2.0 * sigma, 1.0 - s2), axis=-1) / (1.0 + s2)


def quat_to_mrp(q):
    """Our attitude (x, y, z, w) → σ_BN, the short set (|σ| ≤ 1)."""
    q = np.asarray(q, float) / np.linalg.norm(q)
    if q[3] < 0.0:
        q = -q
    return q[:3] / (1.0 + q[3])


def _column(v):
    return [[float(x)] for x in v]


def build(setup, integrator='rk4', param=10.0, attitude=None, position=None, extra=None,
          gravity_gradient=True):
    """(sim, spacecraft, effector, recorder) of a Basilisk simulation of ``setup``,
    initialised: integrator 'rk4' (``param`` = step = task period) or 'rkf78' (``param`` =
    relTol, task = sample period). ``attitude``/``position`` replace the initial ones;
    ``extra(sim, spacecraft)`` adds further modules before the initialisation (its result is
    kept alive with sim); ``gravity_gradient`` False leaves the effector out (None), and
    ``setup.mu`` None the gravity field too."""
    from Basilisk.architecture import bskLogging
    from Basilisk.simulation import (GravityGradientEffector, gravityEffector, spacecraft,
                                     svIntegrators)
    from Basilisk.utilities import SimulationBaseClass, macros
    bskLogging.setDefaultLogLevel(bskLogging.BSK_WARNING)
    task = param if integrator == 'rk4' else setup.sample_period
    sim = SimulationBaseClass.SimBaseClass()
    sim.CreateNewProcess('dynamics').addTask(sim.CreateNewTask('dyn', macros.sec2nano(task)))
    sc = spacecraft.Spacecraft()
    sc.ModelTag = 'spacecraft'
    sc.hub.mHub = 1.0  # kg: the torque does not depend on it
    sc.hub.r_BcB_B = [[0.0], [0.0], [0.0]]
    sc.hub.IHubPntBc_B = np.diag(setup.moments).tolist()
    earth = None
    if setup.mu is not None:  # None: a free body, no gravity field (nor its translation cost)
        earth = gravityEffector.GravBodyData()  # point mass (its default model)
        earth.planetName = 'earth_planet_data'
        earth.mu = setup.mu
        earth.isCentralBody = True
        sc.gravField.setGravBodies(gravityEffector.GravBodyVector([earth]))
    sc.hub.r_CN_NInit = _column(setup.r0 if position is None else position)
    sc.hub.v_CN_NInit = _column(setup.v0)
    sc.hub.sigma_BNInit = _column(quat_to_mrp(setup.attitude if attitude is None
                                              else attitude))
    sc.hub.omega_BN_BInit = _column(setup.angular_velocity)
    gg = None
    if gravity_gradient:
        gg = GravityGradientEffector.GravityGradientEffector()
        gg.ModelTag = 'gravity_gradient'
        gg.addPlanetName(earth.planetName)
        sc.addDynamicEffector(gg)
    if integrator == 'rk4':
        integ = svIntegrators.svIntegratorRK4(sc)
    elif integrator == 'rkf78':
        integ = svIntegrators.svIntegratorRKF78(sc)
        integ.relTol, integ.absTol = param, param * 1e-3
    else:
        raise ValueError(f'Basilisk integrator {integrator!r}: rk4 or rkf78')
    sc.setIntegrator(integ)
    sim.AddModelToTask('dyn', sc)
    if gg is not None:
        sim.AddModelToTask('dyn', gg)
    rec = sc.scStateOutMsg.recorder(macros.sec2nano(setup.sample_period))
    sim.AddModelToTask('dyn', rec)
    # keep Python references to everything Basilisk holds by pointer
    sim._bench_keep = [earth, integ, extra(sim, sc) if extra else None]
    sim.InitializeSimulation()
    return sim, sc, gg, rec


def torque(setup, attitude, position):
    """Basilisk's gravity-gradient torque (body frame, N·m) at an attitude and position."""
    sim, _, gg, _ = build(setup, attitude=attitude, position=position)
    gg.computeForceTorque(0.0, 0.0)  # the hub's states it reads live as long as sim does
    out = np.array(gg.torqueExternalPntB_B, float).ravel()
    del sim
    return out


def run_basilisk(setup, integrator, param):
    """(CPU s of ExecuteSimulation, sample times s, attitude (n, 4), position (n, 3))."""
    from Basilisk.utilities import macros
    sim, _, _, rec = build(setup, integrator, param)
    sim.ConfigureStopTime(macros.sec2nano(setup.duration))
    t0 = cpu()
    sim.ExecuteSimulation()
    elapsed = cpu() - t0
    return (elapsed, np.asarray(rec.times(), float) / 1e9, mrp_to_quat(rec.sigma_BN),
            np.asarray(rec.r_BN_N, float))


def orbit_error(setup, t, r):
    """Largest angle (rad) between Basilisk's positions r at times t and our orbit's."""
    ours = np.array([setup.orbit.state(float(x))[0] for x in t])
    # atan2 of |a × b| and a · b: arccos of the cosine loses half the digits near 0
    return float(np.max(np.arctan2(np.linalg.norm(np.cross(ours, r), axis=1),
                                   np.sum(ours * r, axis=1))))


def _least(run, spent_cap=0.3, repeats=3):
    """The least CPU of up to ``repeats`` runs while they total under ``spent_cap`` s."""
    best, total, out = math.inf, 0.0, None
    for _ in range(repeats):
        out = run()
        best, total = min(best, out[0]), total + out[0]
        if total > spent_cap:
            break
    return best, out


def _row(scene, method, family, kind, param, cpu_s, err, orbit_err, n, status='ok'):
    return {'scene': scene, 'method': method, 'family': family, 'kind': kind, 'param': param,
            'cpu_s': cpu_s, 'attitude_error': err, 'orbit_error': orbit_err, 'samples': n,
            'status': status}


def ours_kw(method, kind, p):
    """``simulate``'s arguments for one point of a sweep: auto at an accuracy, a fixed
    method at a step, or an adaptive one at an rtol (atol 1e-3·rtol)."""
    return ({'integrator': 'auto', 'accuracy': p} if kind == 'accuracy' else
            {'integrator': method, 'step': p} if kind == 'h' else
            {'integrator': method, 'integrator_options': {'rtol': p, 'atol': p * 1e-3}})


def _ours_once(f, method, kind, p, **extra):
    result, best = oracle.timed(f, **(extra | ours_kw(method, kind, p)))
    return best, result


def _sweep(name, kind, params, budget, once, log):
    """Rows of one method coarse → fine until its budget, the floor or no progress."""
    rows, spent, last, best_err, stale = [], 0.0, None, math.inf, 0
    for p in params:
        if last is not None and spent + last * (2.0 if kind == 'h' else 1.5) > budget:
            log(f'    {name} {kind}={p:.3g} not run (predicted past its {budget:g} s budget)')
            break
        try:
            row = once(p)
        except Exception as exc:  # noqa: BLE001 - a method's failure is a data point
            rows.append({'param': p, 'status': f'failed: {type(exc).__name__}: {exc}'[:200]})
            continue
        spent += row['cpu_s']
        last = row['cpu_s']
        rows.append(row)
        e = row['attitude_error']
        if e <= FLOOR:
            break
        stale = stale + 1 if e > 0.5 * best_err else 0
        best_err = min(best_err, e)
        if stale >= 2 and e < 1e-6:  # round-off floor (or the orbit's error) reached
            break
    return rows


def sweep_scene(scene, quick, log=print):
    """(rows, reference) of one scene: ours and Basilisk's sweeps."""
    f = scene.scene_file(quick)
    setup = Setup.of(f)
    c0 = cpu()
    ref = oracle.reference(SimpleNamespace(scene_file=lambda: f, kind='gravity_gradient',
                                           budget=REF_BUDGET))
    log(f'  {scene.name}: reference {ref.what}, own error ≤ {ref.error:.2g} rad '
        f'[{cpu() - c0:.1f} s]')
    rows, budget = [], BUDGET[quick]
    for method, kind, params in OURS:  # kernels loaded (or compiled) before any clock
        _ours_once(f, method, kind, params[0], duration=4 * setup.sample_period)

    def ours(method, kind):
        def once(p):
            c, result = _ours_once(f, method, kind, p)
            err = oracle.error(result, ref.attitude)
            return _row(scene.name, method, 'ours', kind, p, c, err, math.nan,
                        len(result.samples))
        return once

    def peer(method, kind):
        def once(p):
            c, (_, t, q, r) = _least(lambda: run_basilisk(setup, method[4:], p))
            if len(q) != len(ref.attitude):
                raise RuntimeError(f'{len(q)} samples, the reference has {len(ref.attitude)}')
            err = float(np.max(rotation.angle_between(q, ref.attitude)))
            return _row(scene.name, method, 'peer', kind, p, c, err, orbit_error(setup, t, r),
                        len(q))
        return once

    for family, methods, make in (('ours', OURS, ours), ('peer', PEERS, peer)):
        for method, kind, params in methods:
            params = params[::2] if quick else params
            for r in _sweep(method, kind, params, budget, make(method, kind), log):
                if 'scene' not in r:
                    r = _row(scene.name, method, family, kind, r['param'], math.nan,
                             math.nan, math.nan, 0, r['status'])
                rows.append(dict(r, reference_error=ref.error))
            _log_best(rows, scene.name, method, log)
    return rows, ref


def _log_best(rows, scene, method, log):
    ok = [r for r in rows if r['scene'] == scene and r['method'] == method
          and r['status'] == 'ok']
    if not ok:
        log(f'    {method:12s} no successful run')
        return
    b = min(ok, key=lambda r: (r['attitude_error'], r['cpu_s']))
    c = min(ok, key=lambda r: r['cpu_s'])
    orbit = '' if math.isnan(b['orbit_error']) else f'; orbit {b["orbit_error"]:.2g} rad'
    log(f'    {method:12s} best {b["attitude_error"]:.2e} rad in {b["cpu_s"]:.3g} s '
        f'({b["kind"]} {b["param"]:.3g}{orbit}); cheapest {c["cpu_s"]:.3g} s → '
        f'{c["attitude_error"]:.2e} rad')


def target_rows(rows):
    """One row per scene and error level: Basilisk's least CPU to reach it / ours."""
    scenes = [SimpleNamespace(name=n) for n in dict.fromkeys(r['scene'] for r in rows)]
    return [dict(r, target=TARGET) for r in targets.work_precision(rows, scenes)]


def run(quick, log=print):
    """(rows, target rows, notes): both scenes (--quick: the circular one, shortened)."""
    version = installed()
    if version is None:
        note = ('Basilisk (bsk) not installed: .venv/bin/pip install --no-deps -r '
                'requirements-peers.txt (make venv does)')
        log(f'  {note}')
        return [], [targets.simple(TARGET, math.nan, REQUIRED, None, note)], note
    log(f'  bsk {version}; RK4 and RKF78 against ours (auto, fixed methods, dop853)')
    rows = []
    for scene in SCENES[:1] if quick else SCENES:
        rows += sweep_scene(scene, quick, log)[0]
    t_rows = target_rows(rows)
    for r in t_rows:
        log(f'  {r["verdict"]:5s} {r["scene"]:24s} {r["level"]:.0e} rad: '
            f'{r["peer_method"] or "—"} {r["peer_cpu_s"]:.3g} s / {r["ours_method"] or "—"} '
            f'{r["ours_cpu_s"]:.3g} s = {r["measured"]:.3g}× {r["note"]}')
    return rows, t_rows, f'bsk {version}'


def main(argv=None):
    """Run this section alone; write basilisk.csv into DIR and its rows into DIR's
    targets.csv / targets.md (replacing this section's previous rows), then summary.md."""
    import argparse
    from . import report
    parser = argparse.ArgumentParser(prog='python -m rigid_body_sim.bench.basilisk_gg',
                                     description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true',
                        help=f'the circular scene over {QUICK_DURATION:g} s, fewer points')
    parser.add_argument('--out', default='out/bench', metavar='DIR',
                        help='output directory (default out/bench)')
    args = parser.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    with np.errstate(over='ignore', invalid='ignore'):
        rows, t_rows, _ = run(args.quick)
    write_csv(os.path.join(args.out, 'basilisk.csv'), FIELDS, rows)
    report.replace_targets(args.out, TARGET, t_rows)
    print(report.write(args.out))
    return 0


if __name__ == '__main__':
    import sys
    sys.exit(main())
