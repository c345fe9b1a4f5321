"""Monte Carlo campaigns: dispersions, seeds, metrics against analytic results, and the
real Dask paths (a local cluster; a scheduler and workers started as processes; a worker
killed mid-campaign; SIGINT and --resume; --rerun bit for bit)."""
import json
import math
import os
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import pyarrow.parquet as pq
import pytest

from rigid_body_sim.campaign import dispersions as disp
from rigid_body_sim.campaign import store
from rigid_body_sim.campaign.cli import _same
from rigid_body_sim.campaign.runner import CampaignSpec, rng_for, run_one
from rigid_body_sim.physics import RigidBody
from rigid_body_sim.physics.exact import TorqueFreeSolution
from rigid_body_sim.scene import SceneError, load

CLI = [sys.executable, '-m', 'rigid_body_sim.cli', 'campaign']
DASK = os.path.join(os.path.dirname(sys.executable), 'dask')
SHORT = ['--set', 'duration=8.0']  # detumbled (to 0.01 rad/s) by ~6 s


def cli(*args, timeout=300, **kw):
    return subprocess.run(CLI + list(args), capture_output=True, text=True, timeout=timeout,
                          **kw)


def spec_for(scene, sets=(), dispersions=(), seed=0, runs=10, **kw):
    s = load(scene, list(sets))
    return CampaignSpec.create(s, [disp.parse(t) for t in dispersions], seed, runs, **kw)


def rows_equal(a, b):
    """Rows identical bit for bit, CPU time aside; the differing keys otherwise."""
    return [k for k in a if k != 'cpu_time' and not _same(a[k], b.get(k))]


# ------------------------------------------------------------------ dispersions, seeds
def test_dispersion_texts_parse_and_bad_ones_name_the_problem():
    d = disp.parse('inertia=uniform:5%')
    assert (d.key, d.distribution, d.spread, d.relative) == ('inertia', 'uniform', 0.05, True)
    d = disp.parse('initial_angular_velocity=normal:0.2')
    assert (d.distribution, d.spread, d.relative) == ('normal', 0.2, False)
    for bad, words in (('inertia', 'KEY=DIST:SPREAD'), ('inertia=gauss:1', 'normal, uniform'),
                       ('inertia=normal:x', 'must be a number'),
                       ('inertia=normal:-1', '>= 0'), ('inertia=uniform:nan%', 'finite')):
        with pytest.raises(ValueError, match=words):
            disp.parse(bad)


def test_unknown_key_is_rejected_naming_the_closest(tmp_path):
    out = cli('detumble', '--disperse', 'inerta=uniform:5%', '--runs', '2', '--out',
              str(tmp_path))
    assert out.returncode == 2
    assert '--disperse inerta=uniform:5%' in out.stderr and 'did you mean inertia?' in out.stderr
    assert 'Traceback' not in out.stderr
    s = load('detumble')
    with pytest.raises(SceneError, match='given twice'):
        disp.check_keys(s, [disp.parse('inertia=normal:1'), disp.parse('inertia=normal:2')])
    with pytest.raises(SceneError, match='not numeric'):
        disp.check_keys(s, [disp.parse('mode=normal:1')])


def test_yaml_file_gives_dispersions_runs_and_seed(tmp_path):
    f = tmp_path / 'd.yaml'
    f.write_text('runs: 7\nseed: 42\ndispersions:\n  inertia: uniform:5%\n'
                 '  natural_frequency: normal:0.05\n')
    found, extra = disp.load_file(str(f))
    assert [d.text for d in found] == ['inertia=uniform:5%', 'natural_frequency=normal:0.05']
    assert extra == {'runs': 7, 'seed': 42}
    f.write_text('dispersions:\n  inertia: lognormal:1\n')
    with pytest.raises(ValueError, match='d.yaml: dispersions: inertia'):
        disp.load_file(str(f))
    f.write_text('runs: 0\ndispersions:\n  inertia: normal:1\n')
    with pytest.raises(ValueError, match=r'runs must be an integer in \[1, '):
        disp.load_file(str(f))
    f.write_text('seed: 9223372036854775808\ndispersions:\n  inertia: normal:1\n')
    with pytest.raises(ValueError, match='seed must be an integer'):
        disp.load_file(str(f))
    f.write_text('runs: 3\ndispersion:\n  inertia: normal:1\n')
    with pytest.raises(ValueError, match='"dispersions:" mapping'):
        disp.load_file(str(f))


def test_run_k_depends_only_on_seed_and_k():
    for k in (0, 3, 17):
        a = rng_for(123, k).random(4)
        for n in (k + 1, 50):  # the k-th spawned child, whatever the number of runs
            b = np.random.default_rng(np.random.SeedSequence(123).spawn(n)[k]).random(4)
            assert np.array_equal(a, b)
    spec = spec_for('detumble', ['duration=2.0'], ['inertia=uniform:5%',
                                        'initial_angular_velocity=normal:0.2'], seed=5)
    first = run_one(spec, 4)
    run_one(spec, 3)  # another run in between changes nothing
    assert rows_equal(first, run_one(spec, 4)) == []
    other = run_one(spec_for('detumble', ['duration=2.0'], ['inertia=uniform:5%',
                                                 'initial_angular_velocity=normal:0.2'],
                             seed=6), 4)
    assert other['inertia[0]'] != first['inertia[0]']


def test_draws_follow_their_distributions():
    s = load('detumble')
    ds = [disp.parse('inertia=uniform:5%'), disp.parse('initial_angular_velocity=normal:0.2')]
    n = 4000
    inertia, w = np.empty((n, 3)), np.empty((n, 3))
    for k in range(n):
        values, _, redraws = disp.draw(s, ds, rng_for(1, k))
        assert redraws == 0  # ±5 % of (1, 2, 2.5) never breaks the triangle inequality
        inertia[k], w[k] = values['inertia'], values['initial_angular_velocity']
    nominal_i, nominal_w = np.array([1.0, 2.0, 2.5]), np.array([1.0, -2.0, 1.5])
    rel = inertia / nominal_i - 1
    assert np.all(np.abs(rel) <= 0.05) and np.all(rel.max(axis=0) > 0.049)
    # uniform on ±5 %: σ = 0.05/√3; the sample σ within 5 % of it (n = 4000: ~1.1 % s.e.)
    assert np.allclose(rel.std(axis=0), 0.05 / math.sqrt(3), rtol=0.05)
    dw = w - nominal_w
    assert np.allclose(dw.std(axis=0), 0.2, rtol=0.05)
    assert np.all(np.abs(dw.mean(axis=0)) < 4 * 0.2 / math.sqrt(n))
    # per component, independent: correlations near zero
    assert abs(np.corrcoef(dw[:, 0], dw[:, 1])[0, 1]) < 0.06


def test_a_tensor_inertia_stays_symmetric(tmp_path):
    f = tmp_path / 'tensor.yaml'
    f.write_text('/**:\n  ros__parameters:\n    inertia: [2.0, 0.1, 0.0, 0.1, 3.0, 0.2, 0.0, '
                 '0.2, 4.0]\n/**/attitude_simulator:\n  ros__parameters:\n    duration: 1.0\n')
    s = load(str(f))
    for k in range(20):
        values, _, _ = disp.draw(s, [disp.parse('inertia=normal:0.05')], rng_for(0, k))
        m = np.reshape(values['inertia'], (3, 3))
        assert np.array_equal(m, m.T) and not np.allclose(m, np.reshape(s.simulator['inertia'],
                                                                        (3, 3)))


# ------------------------------------------------------------------ unphysical inertia
def _triangle_ok(i):
    i = np.asarray(i)
    return bool(np.all(i > 0) and i[0] + i[1] >= i[2] and i[1] + i[2] >= i[0]
                and i[0] + i[2] >= i[1])


def test_unphysical_inertia_is_redrawn_with_a_count_or_rejected():
    # (1, 1, 1.8) ± 20 %: about a third of the draws violate I1 + I2 >= I3
    sets = ['duration=2.0', 'inertia=[1.0, 1.0, 1.8]']
    ds = ['inertia=uniform:20%']
    n = 40
    nominal = np.array([1.0, 1.0, 1.8])
    # the first draw of run k, from its generator directly: nominal ± 20 % per component
    first = [nominal * (1 + 0.2 * rng_for(9, k).uniform(-1.0, 1.0, 3)) for k in range(n)]
    bad = {k for k in range(n) if not _triangle_ok(first[k])}
    assert 5 < len(bad) < n - 5

    rejected = [run_one(spec_for('detumble', sets, ds, seed=9, policy='reject'), k)
                for k in range(n)]
    assert {r['run_id'] for r in rejected if r['status'] == 'bad_draw'} == bad
    for r in rejected:
        if r['status'] == 'bad_draw':
            assert 'triangle inequality' in r['error'] and r['redraws'] == 1
            assert math.isnan(r['inertia[0]']) and math.isnan(r['detumble_time'])
        else:
            assert r['status'] == 'ok'
            assert r['inertia[2]'] == pytest.approx(first[r['run_id']][2], rel=1e-15)

    redrawn = [run_one(spec_for('detumble', sets, ds, seed=9), k) for k in range(n)]
    assert all(r['status'] == 'ok' for r in redrawn)
    assert {r['run_id'] for r in redrawn if r['redraws'] > 0} == bad
    for r in redrawn:
        i = [r[f'inertia[{j}]'] for j in range(3)]
        assert _triangle_ok(i)
        assert all(abs(v / c - 1) <= 0.2 for v, c in zip(i, (1.0, 1.0, 1.8)))
    # never clipped: no accepted draw sits on the boundary I1 + I2 = I3
    margin = [r['inertia[0]'] + r['inertia[1]'] - r['inertia[2]'] for r in redrawn]
    assert min(margin) > 1e-6

    # negative moments from a wide normal: redrawn too
    wide = spec_for('detumble', sets, ['inertia=normal:100%'], seed=2)
    rows = [run_one(wide, k) for k in range(10)]
    assert all(r['status'] == 'ok' and _triangle_ok([r[f'inertia[{j}]'] for j in range(3)])
               for r in rows)
    assert sum(r['redraws'] for r in rows) > 0


# ------------------------------------------------------------------ metrics, analytic
def test_detumble_decay_matches_the_held_law_for_every_draw():
    # τ = −2ζω_n I ω held over each control period h: |L| shrinks by (1 − 2ζω_n h) per
    # period (to first order in the gyroscopic term), whatever the inertia and ω0 — and the
    # controller's model moves with the dispersed inertia.
    spec = spec_for('detumble', [], ['inertia=uniform:5%', 'initial_angular_velocity=normal:0.2'],
                    seed=3)
    h, periods = 1 / 50, 750
    for k in range(6):
        r = run_one(spec, k)
        i = np.array([r[f'inertia[{j}]'] for j in range(3)])
        w = np.array([r[f'initial_angular_velocity[{j}]'] for j in range(3)])
        L0 = np.linalg.norm(i * w)
        assert r['final_angular_momentum'] / L0 == pytest.approx((1 - h) ** periods, rel=2e-3)
        assert r['status'] == 'ok' and not r['saturated'] and r['flip_count'] is None
        assert r['energy_dissipated'] == pytest.approx(0.5 * np.sum(i * w * w), rel=1e-9)
        # |ω| ≈ |ω0|·e^{−t} (|L| decays so; ω scales alike when I is near isotropic):
        # detumbled to 0.01 rad/s within ±0.8 s of ln(|ω0|/0.01)
        assert abs(r['detumble_time'] - math.log(np.linalg.norm(w) / 0.01)) < 0.8


def test_slew_settles_as_critical_damping_predicts():
    # error ≈ θ0(1 + ω_n t)e^{−ω_n t} with θ0 = π/2, ω_n = 1: below 0.01 rad at t ≈ 7.3 s
    spec = spec_for('slew', [], ['natural_frequency=uniform:10%'], seed=1)
    for k in range(4):
        r = run_one(spec, k)
        wn = r['natural_frequency[0]']  # a one-value array parameter
        from scipy.optimize import brentq
        predicted = brentq(lambda t: math.pi / 2 * (1 + wn * t) * math.exp(-wn * t) - 0.01,
                           1.0, 30.0)
        assert r['settling_time'] == pytest.approx(predicted, abs=0.5)
        assert r['final_pointing_error'] < 0.01
        assert math.isfinite(r['detumble_time'])


def test_free_tumble_flips_at_the_elliptic_interval_and_keeps_invariants():
    spec = spec_for('tennis_racket', [], ['initial_angular_velocity=normal:0.02'], seed=4)
    for k in range(4):
        r = run_one(spec, k)
        w = np.array([r[f'initial_angular_velocity[{j}]'] for j in range(3)])
        body = RigidBody.from_inertia([0.0023, 0.0140, 0.0163])
        sol = TorqueFreeSolution(body.principal_moments, [0, 0, 0, 1],
                                 body.principal_moments * w)
        gaps = np.diff(r['flip_times'])
        assert r['flip_count'] == len(r['flip_times']) >= 4
        assert np.allclose(gaps, float(sol.flip_interval), rtol=1e-4)
        assert abs(r['angular_momentum_drift']) < 1e-12
        assert abs(r['kinetic_energy_drift']) < 1e-12
        assert r['integrator'] == 'exact' and r['peak_torque'] == 0.0
        assert math.isnan(r['final_pointing_error'])


def test_saturation_and_integrator_failures_are_rows():
    r = run_one(spec_for('detumble', ['max_torque=2.0']), 0)
    assert r['saturated'] and 2.0 <= r['peak_torque'] <= 2.0 * math.sqrt(3) + 1e-12
    # rk4 on a 10 rad/s spin: stable for small steps, diverges for large ones
    spec = CampaignSpec.create(load('tennis_racket', ['integrator=rk4', 'publish_rate=1.0',
                                                      'duration=200', 'step=0.25']),
                               [disp.parse('step=uniform:0.24')], 0, 20)
    rows = [run_one(spec, k) for k in range(20)]
    failed = [r for r in rows if r['status'] != 'ok']
    ok = [r for r in rows if r['status'] == 'ok']
    assert failed and ok
    for r in failed:
        assert r['status'] == 'integration_error' and 'diverged' in r['error']
    assert max(r['step'] for r in ok) < min(r['step'] for r in failed)


def test_report_of_saturated_runs_with_equal_peaks(tmp_path):
    import pyarrow as pa
    from rigid_body_sim.campaign import report
    # the torque norm bound (1.5 N·m, both nodes) is reached in every run: equal peaks
    # settling (≈ 7.3/ω_n s) falls on both sides of the 7.6 s end for ω_n = 1 ± 20 %
    spec = spec_for('slew', ['duration=7.6', 'max_torque=1.5'],
                    ['natural_frequency=uniform:20%'], runs=8)
    rows = [run_one(spec, k) for k in range(8)]
    table = pa.Table.from_pylist(rows, schema=store.schema(spec.columns))
    s = report.summary(table, spec.columns)
    assert s['saturated'] == 8 and s['stats']['peak_torque']['max'] == pytest.approx(1.5)
    assert 'peak_torque' not in s['worst']  # no run is worse than another
    settle = {r['run_id']: r['settling_time'] for r in rows}
    never = sorted(k for k, v in settle.items() if math.isnan(v))
    assert 0 < len(never) < 8, settle
    # the runs that never settled come first (worst), then the slowest
    settled = sorted((k for k in settle if k not in never), key=lambda k: -settle[k])
    assert s['worst']['settling_time'] == (never + settled)[:5]
    assert s['stats']['settling_time']['nan'] == len(never)
    paths = report.write_plots(table, spec.columns, str(tmp_path))
    assert [os.path.basename(p) for p in paths] == ['histograms.png',
                                                    'scatter_natural_frequency_0.png']
    assert all(os.path.getsize(p) > 5000 for p in paths)


# ------------------------------------------------------------------ the real Dask paths
def _read_rows(out):
    return {r['run_id']: r for r in store.read(str(out)).to_pylist()}


def test_local_cluster_campaign_writes_dataset_summary_plots_and_reruns(tmp_path):
    out = tmp_path / 'c'
    args = ['detumble', '--disperse', 'inertia=uniform:5%', '--disperse',
            'initial_angular_velocity=normal:0.2', '--runs', '24', '--seed', '11',
            '--workers', '2', '--chunk', '3', '--out', str(out)] + SHORT
    res = cli(*args)
    assert res.returncode == 0, res.stderr
    assert 'Traceback' not in res.stderr
    assert '24 runs: 24 ok, 0 failed' in res.stdout and 'worst detumble_time' in res.stdout
    table = pq.read_table(str(out / 'runs'))  # the dataset, read by pyarrow as a directory
    ids = table.column('run_id').to_pylist()
    assert sorted(ids) == list(range(24))
    meta = json.loads(pq.read_schema(store.part_files(str(out))[0]).metadata[store.META_KEY])
    assert meta['config']['seed'] == 11 and meta['runs'] == 24
    assert meta['config']['dispersions'] == ['inertia=uniform:5%',
                                             'initial_angular_velocity=normal:0.2']
    assert meta['versions']['dask'] and meta['versions']['pyarrow']
    for png in ('histograms.png', 'scatter_inertia_0.png',
                'scatter_initial_angular_velocity_2.png'):
        assert (out / 'plots' / png).stat().st_size > 5000
    # the workers' rows are exactly what the function gives in this process
    spec = spec_for('detumble', ['duration=8.0'], ['inertia=uniform:5%',
                                                   'initial_angular_velocity=normal:0.2'],
                    seed=11, runs=24)
    rows = _read_rows(out)
    for k in (0, 13, 23):
        assert rows_equal(run_one(spec, k), rows[k]) == []
    again = cli(*args, '--rerun', '13')
    assert again.returncode == 0 and 'identical to the stored row' in again.stderr
    assert json.loads(again.stdout)['run_id'] == 13
    other = [('12' if a == '11' else a) for a in args]  # another seed: another campaign
    mismatch = cli(*other, '--rerun', '13')
    assert mismatch.returncode == 0 and 'differs from this command in: seed' in mismatch.stderr
    # a finished campaign is not silently overwritten
    assert cli(*args).returncode == 2


def _free_port():
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


@pytest.fixture
def dask_processes(tmp_path):
    """A `dask scheduler` and `dask worker` processes on 127.0.0.1; always killed."""
    procs = []
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [os.path.dirname(os.path.dirname(os.path.abspath(__file__)))] +
        os.environ.get('PYTHONPATH', '').split(os.pathsep)))
    port = _free_port()
    address = f'tcp://127.0.0.1:{port}'

    def start(cmd, name):
        log = open(tmp_path / f'{name}.log', 'w')
        procs.append(subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env,
                                      start_new_session=True, cwd=tmp_path))
        return procs[-1]

    start([DASK, 'scheduler', '--host', '127.0.0.1', '--port', str(port),
           '--dashboard-address', ':0', '--no-show'], 'scheduler')

    def worker(name):
        return start([DASK, 'worker', address, '--nthreads', '1', '--no-nanny', '--name', name,
                      '--host', '127.0.0.1'], name)

    def wait_for(n):
        from distributed import Client
        with Client(address, timeout=60) as c:
            c.wait_for_workers(n, timeout=120)

    try:
        yield address, worker, wait_for
    finally:
        for p in procs:
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGKILL)
            p.wait(timeout=30)


def test_scheduler_and_two_worker_processes(tmp_path, dask_processes):
    address, worker, wait_for = dask_processes
    worker('w1')
    worker('w2')
    wait_for(2)
    out = tmp_path / 'd'
    # rk4 on a 10 rad/s spin with a dispersed step: the large steps diverge. Their runs are
    # rows with the reason; the campaign goes on.
    sets = ['integrator=rk4', 'publish_rate=1.0', 'duration=200', 'step=0.25']
    res = cli('tennis_racket', '--disperse', 'step=uniform:0.24', '--runs', '16',
              '--scheduler', address, '--chunk', '2', '--out', str(out), '--no-plots',
              *[a for kv in sets for a in ('--set', kv)])
    assert res.returncode == 0, res.stderr
    rows = _read_rows(out)
    assert sorted(rows) == list(range(16))
    failed = [k for k, r in rows.items() if r['status'] == 'integration_error']
    assert 0 < len(failed) < 16
    assert all('diverged' in rows[k]['error'] for k in failed)
    assert f'16 runs: {16 - len(failed)} ok, {len(failed)} failed' in res.stdout
    assert store.read_config(str(out))['scheduler'] == address
    spec = spec_for('tennis_racket', sets, ['step=uniform:0.24'], runs=16)
    for k in (failed[0], next(k for k in rows if k not in failed)):
        assert rows_equal(run_one(spec, k), rows[k]) == []


def test_worker_killed_mid_campaign_retried_elsewhere(tmp_path, dask_processes):
    address, worker, wait_for = dask_processes
    worker('w1')
    victim = worker('w2')
    wait_for(2)
    out = tmp_path / 'k'
    n = 40
    # rk4 at 1 ms over 15 s: ~0.1 s a run, so tasks are in flight when the worker dies
    sets = ['--set', 'integrator=rk4', '--set', 'step=0.001']
    camp = subprocess.Popen(CLI + ['detumble', '--disperse', 'inertia=uniform:5%', '--runs',
                                   str(n), '--scheduler', address, '--chunk', '1', '--out',
                                   str(out), '--no-plots'] + sets,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        from distributed import Client
        with Client(address, timeout=60) as c:
            deadline = time.monotonic() + 120
            while time.monotonic() < deadline:
                busy = {w: keys for w, keys in c.processing().items() if keys}
                on_victim = [w for w, info in c.scheduler_info(n_workers=-1)['workers'].items()
                             if info.get('name') == 'w2' and busy.get(w)]
                if on_victim and sum(len(v) for v in busy.values()) >= 2:
                    break
                time.sleep(0.05)
            else:
                pytest.fail('the victim never got a task')
            os.killpg(victim.pid, signal.SIGKILL)
        stdout, stderr = camp.communicate(timeout=300)
    finally:
        if camp.poll() is None:
            camp.kill()
            camp.wait()
    assert camp.returncode == 0, stderr
    table = store.read(str(out))
    ids = table.column('run_id').to_pylist()
    assert len(ids) == len(set(ids)) == n  # complete, and no run twice
    assert set(table.column('status').to_pylist()) == {'ok'}


@pytest.mark.parametrize('how', ['SIGINT to the group', 'SIGTERM to the process'])
def test_interrupt_keeps_finished_runs_and_resume_runs_only_the_rest(tmp_path, how):
    out = tmp_path / 'r'
    n = 400  # seconds of work even on an idle machine: SIGINT lands mid-campaign
    args = ['detumble', '--disperse', 'initial_angular_velocity=normal:0.2', '--runs', str(n),
            '--workers', '2', '--chunk', '1', '--out', str(out), '--no-plots', '--set',
            'integrator=rk4', '--set', 'step=0.001']
    # a new session: SIGINT goes to the whole group, as Ctrl-C in a terminal does
    camp = subprocess.Popen(CLI + args, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    try:
        deadline = time.monotonic() + 180
        while not store.part_files(str(out)) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert store.part_files(str(out)), 'no rows written'
        if how.startswith('SIGINT'):  # Ctrl-C in a terminal: every process of the group
            os.killpg(camp.pid, signal.SIGINT)
        else:
            camp.send_signal(signal.SIGTERM)
        stdout, stderr = camp.communicate(timeout=120)
    finally:
        if camp.poll() is None:
            os.killpg(camp.pid, signal.SIGKILL)
            camp.wait()
    assert camp.returncode == 130, stderr
    assert 'Traceback' not in stderr and 'interrupted' in stderr
    kept = _read_rows(out)
    assert 0 < len(kept) < n
    res = cli(*args, '--resume')
    assert res.returncode == 0, res.stderr
    assert f'{n - len(kept)} runs now, {n} in' in res.stdout
    final = store.read(str(out))
    ids = final.column('run_id').to_pylist()
    assert sorted(ids) == list(range(n))
    after = _read_rows(out)
    for k, row in kept.items():  # the runs kept were not run again
        assert row['cpu_time'] == after[k]['cpu_time']
