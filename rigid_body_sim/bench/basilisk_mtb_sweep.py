"""Basilisk 2.12's magnetorquers against ours at equal attitude error (issue 30).

    python -m rigid_body_sim.bench.basilisk_mtb_sweep [--quick] [--out DIR]

The scenes (``SCENES``): the gravity-gradient scenes of ``basilisk_gg`` with the Earth's
field as a tilted dipole (``environment.magnetic_field: dipole``, IGRF-14's degree 1 at
``EPOCH``) and three rods holding a dipole (A·m², body frame) for the whole run: a small
residual one on the libration, and one whose m × B is as large as the gravity gradient's
(~1e-5 N·m) on the eccentric tumble. Basilisk runs the same physics (``basilisk_mtb``; its
field and torque agree with the closed forms to 1e-12 in test/test_bench_basilisk_mtb.py):
the coefficients and the Earth's turn (GMST at the epoch, our sidereal rate) are ours.

What each side pays, as its user runs it:

* ours: ``offline.simulate`` on an engine holding the command (``Engine.apply_dipole_command``,
  what the controller node's dipole does), every sample kept, auto's selection included;
* Basilisk: ``ExecuteSimulation`` once per update of its field module, with the Earth's
  orientation written in between (a SPICE user's spice module does that inside the run;
  here the Python write is left off the clock, the calls' own overhead stays on it).
  ``MtbEffector`` holds the field of the last update while the attitude moves: a zero-order
  hold, first order in the update period whatever the integrator. RK4 updates the field at
  each step (period = step); RKF78 at each sample (its task period), which is where its
  error stops falling.

Error: the largest attitude angle at the samples against our dop853 with the held dipole,
refined down an rtol ladder until two rungs agree (that difference bounds its error).
"""
import math
import os
from dataclasses import dataclass, replace

import numpy as np

from ..offline import engine_for, simulate
from ..physics import rotation
from ..physics.environment import earth, magnetic_field
from ..scene import load
from . import basilisk_gg as gg, basilisk_mtb as mtb_harness, targets
from .common import cpu, write_csv

TARGET = 'Basilisk CPU / ours at equal attitude error (magnetorquers)'
REQUIRED = 10.0
EPOCH = '2026-03-20T12:00:00Z'
MAGNETIC = (f'epoch={EPOCH}', 'environment.magnetic_field=dipole',
            'magnetorquer.max_dipole=[1.0, 1.0, 1.0]', 'command_timeout=1.0e6')
QUICK_DURATION = 2000.0  # s: --quick's horizon (the bench's quick run in the tests)
REF_LADDER = tuple(10.0 ** -k for k in range(9, 14))
BUDGET = {True: 0.25, False: 12.0}  # CPU s per method's sweep (quick, full)
OURS = (('auto', 'accuracy', gg.ACCURACIES), ('splitting4', 'h', gg.STEPS),
        ('splitting6', 'h', gg.STEPS), ('rk4', 'h', gg.STEPS),
        ('dop853', 'rtol', gg.OUR_TOLS))
PEERS = (('bsk_rk4', 'h', gg.STEPS), ('bsk_rkf78', 'rtol', gg.TOLS))


@dataclass(frozen=True)
class MtbScene:
    """A gravity-gradient scene with the dipole field and rods holding ``dipole`` (A·m²,
    body frame) from t = 0; ``duration`` (s) replaces the scene's where given."""
    name: str
    overrides: tuple
    dipole: tuple
    duration: float = None

    def scene_file(self, quick=False):
        duration = QUICK_DURATION if quick else self.duration
        extra = () if duration is None else (f'duration={duration!r}',)
        return load('gravity_gradient', self.overrides + MAGNETIC + extra)


# a residual dipole on the libration (the torque a tenth of the gravity gradient's: the
# body librates about a shifted equilibrium), and rods turning the eccentric tumble (m × B
# as large as the gravity gradient; chaotic: errors grow fast, so a shorter horizon)
SCENES = (MtbScene('magnetorquers_libration', (), (0.002, -0.001, 0.003)),
          MtbScene('magnetorquers_tumble', gg.TUMBLE, (0.3, -0.2, 0.5), 4000.0))


def basilisk_setup(f, dipole):
    """The harness's setup for scene file ``f``: our orbit and state, our field's degree-1
    coefficients (T) and the Earth's angle at t = 0."""
    m = magnetic_field.dipole_moment(EPOCH) * magnetic_field.MU0_OVER_4PI \
        / magnetic_field.IGRF_RADIUS ** 3  # (g11, h11, g10), T
    return mtb_harness.MtbSetup(gg.Setup.of(f), (m[2], m[0], m[1]), dipole,
                                theta0=float(earth.gmst(EPOCH)),
                                earth_rate=earth.EARTH_ROTATION_RATE,
                                radius=magnetic_field.IGRF_RADIUS, field_period=1.0)


def ours(f, dipole, **kw):
    """(result, CPU s): one run of ours holding ``dipole``, selection included."""
    engine = engine_for(f, **kw)
    engine.apply_dipole_command(np.array(dipole))
    result = simulate(f, engine=engine)
    return result, result.cpu_seconds + result.selection_cpu_seconds


def reference(f, dipole, log=print):
    """(attitude at the samples, bound on its error, what): dop853 down REF_LADDER until two
    rungs agree to within 0.7 of the last difference (round-off) or the ladder ends."""
    best, coarse = None, None
    for rtol in REF_LADDER:
        fine = ours(f, dipole, **gg.ours_kw('dop853', 'rtol', rtol))[0].samples['attitude']
        if coarse is not None:
            bound = float(np.max(rotation.angle_between(coarse, fine)))
            if best is not None and bound >= 0.7 * best[0]:
                break
            best = (bound, fine, rtol)
        coarse = fine
    log(f'  reference: dop853 rtol {best[2]:g}, own error ≤ {best[0]:.2g} rad')
    return best[1], best[0], f'dop853 rtol {best[2]:g}'


def basilisk_run(setup, integrator, param):
    """(CPU s of the ExecuteSimulation calls, t, attitude, position): field updates at the
    step (rk4) or at each sample (rkf78)."""
    period = param if integrator == 'rk4' else setup.base.sample_period
    from Basilisk.utilities import macros
    s = replace(setup, field_period=period)
    sim, modules, rec = mtb_harness.build(s, integrator, param)
    n = int(round(s.base.duration / period))
    spent = 0.0
    for k in range(n + 1):
        modules.write_planet(k * period)  # a spice module's work: off the clock
        sim.ConfigureStopTime(macros.sec2nano(k * period))
        t0 = cpu()
        sim.ExecuteSimulation()
        spent += cpu() - t0
    return (spent, np.asarray(rec.times(), float) / 1e9,
            gg.mrp_to_quat(rec.sigma_BN), np.asarray(rec.r_BN_N, float))


def sweep(scene, quick, log=print):
    """Rows of ours and Basilisk's sweeps on ``scene`` (``basilisk_gg.FIELDS``)."""
    f, name, dipole = scene.scene_file(quick), scene.name, scene.dipole
    setup = basilisk_setup(f, dipole)
    c0 = cpu()
    log(f'  {name}:')
    ref, ref_error, _ = reference(f, dipole, log)
    log(f'  [{cpu() - c0:.1f} s]')
    for method, kind, params in OURS:  # kernels loaded (or compiled) before any clock
        ours(f, dipole, duration=4 * setup.base.sample_period,
             **gg.ours_kw(method, kind, params[0]))

    def mine(method, kind):
        def once(p):
            kw = gg.ours_kw(method, kind, p)
            c, (_, result) = gg._least(lambda: ours(f, dipole, **kw)[::-1])
            err = float(np.max(rotation.angle_between(result.samples['attitude'], ref)))
            return gg._row(name, method, 'ours', kind, p, c, err, math.nan,
                           len(result.samples))
        return once

    def peer(method, kind):
        def once(p):
            c, (_, t, q, r) = gg._least(lambda: basilisk_run(setup, method[4:], p))
            if len(q) != len(ref):
                raise RuntimeError(f'{len(q)} samples, the reference has {len(ref)}')
            err = float(np.max(rotation.angle_between(q, ref)))
            return gg._row(name, method, 'peer', kind, p, c, err,
                           gg.orbit_error(setup.base, t, r), len(q))
        return once

    rows = []
    for family, methods, make in (('ours', OURS, mine), ('peer', PEERS, peer)):
        for method, kind, params in methods:
            params = params[::2] if quick else params
            for r in gg._sweep(method, kind, params, BUDGET[quick], make(method, kind), log):
                if 'scene' not in r:
                    r = gg._row(name, method, family, kind, r['param'], math.nan, math.nan,
                                math.nan, 0, r['status'])
                rows.append(dict(r, reference_error=ref_error))
            gg._log_best(rows, name, method, log)
    return rows


def run(quick, log=print):
    """(rows, target rows, note), as ``basilisk_gg.run``."""
    version = gg.installed()
    if version is None:
        note = ('Basilisk (bsk) not installed: .venv/bin/pip install --no-deps -r '
                'requirements-peers.txt (make venv does)')
        log(f'  {note}')
        return [], [targets.simple(TARGET, math.nan, REQUIRED, None, note)], note
    log(f'  bsk {version}: MtbEffector (centred dipole) against our magnetorquers')
    rows = []
    for scene in SCENES[:1] if quick else SCENES:
        rows += sweep(scene, quick, log)
    t_rows = [dict(r, target=TARGET) for r in targets.work_precision(rows, SCENES[:1] if quick
                                                                     else SCENES)]
    for r in t_rows:
        log(f'  {r["verdict"]:5s} {r["scene"]:24s} {r["level"]:.0e} rad: '
            f'{r["peer_method"] or "—"} '
            f'{r["peer_cpu_s"]:.3g} s / {r["ours_method"] or "—"} {r["ours_cpu_s"]:.3g} s '
            f'= {r["measured"]:.3g}× {r["note"]}')
    return rows, t_rows, f'bsk {version}'


def main(argv=None):
    """Run this comparison alone; write basilisk_mtb.csv into DIR and its rows into DIR's
    targets.csv / targets.md (replacing its previous rows), then summary.md."""
    import argparse
    from . import report
    parser = argparse.ArgumentParser(prog='python -m rigid_body_sim.bench.basilisk_mtb_sweep',
                                     description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true',
                        help=f'the scene over {QUICK_DURATION:g} s, fewer points')
    parser.add_argument('--out', default='out/bench', metavar='DIR',
                        help='output directory (default out/bench)')
    args = parser.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    with np.errstate(over='ignore', invalid='ignore'):
        rows, t_rows, _ = run(args.quick)
    write_csv(os.path.join(args.out, 'basilisk_mtb.csv'), gg.FIELDS, rows)
    report.replace_targets(args.out, TARGET, t_rows, command='python -m rigid_body_sim.bench.'
                           'basilisk_mtb_sweep --out {out}')
    print(report.write(args.out))
    return 0


if __name__ == '__main__':
    import sys
    sys.exit(main())
