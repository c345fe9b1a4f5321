"""Campaigns on the real Dask paths: a local cluster, a scheduler and workers started as
processes on 127.0.0.1, a worker killed mid-campaign, SIGINT/SIGTERM then --resume, and
--rerun bit for bit. Every process started here is killed at the end."""
import json
import os
import signal
import socket
import subprocess
import sys
import time

import pyarrow.parquet as pq
import pytest

from campaign_helpers import CLI, SHORT, cli, rows_equal, spec_for
from cli_inprocess import run_cli
from rigid_body_sim.campaign import store
from rigid_body_sim.campaign.runner import run_one

DASK = os.path.join(os.path.dirname(sys.executable), 'dask')


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
    # the rest in this process (not about Dask: the rerun and the refusal start no cluster)
    again = run_cli('campaign', *args, '--rerun', '13')
    assert again.returncode == 0 and 'identical to the stored row' in again.stderr
    assert json.loads(again.stdout)['run_id'] == 13
    other = [('12' if a == '11' else a) for a in args]  # another seed: another campaign
    mismatch = run_cli('campaign', *other, '--rerun', '13')
    assert mismatch.returncode == 0 and 'differs from this command in: seed' in mismatch.stderr
    # a finished campaign is not silently overwritten
    assert run_cli('campaign', *args).returncode == 2


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
    assert set(table.column('status').to_pylist()) == {'ok'}, (
        set(table.column('error').to_pylist()), stderr[-3000:])


@pytest.mark.parametrize('how', ['SIGINT to the group', 'SIGTERM to the process'])
def test_interrupt_keeps_finished_runs_and_resume_runs_only_the_rest(tmp_path, how):
    out = tmp_path / 'r'
    n = 400  # seconds of work even on an idle machine: SIGINT lands mid-campaign
    args = ['detumble', '--disperse', 'initial_angular_velocity=normal:0.2', '--runs', str(n),
            '--workers', '2', '--chunk', '1', '--out', str(out), '--no-plots', '--set',
            'integrator=rk4', '--set', 'step=0.001']
    # a new session: SIGINT goes to the whole group, as Ctrl-C in a terminal does
    # SIGINT as in a terminal: a shell's background job (`make test &`) starts with SIGINT
    # ignored, which Python and its children inherit, and the campaign then rightly runs on
    camp = subprocess.Popen(CLI + args, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
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
    assert camp.returncode == 130, stderr + stdout[-2000:]
    assert 'Traceback' not in stderr and 'interrupted' in stderr, stderr[-3000:]
    kept = _read_rows(out)
    assert 0 < len(kept) < n
    # the rest in Dask's own chunks: --chunk 1 made the first rows land at once (for the
    # signal), but sent the resume's ~400 runs as ~400 tasks: 12 CPU-s of the test's 16
    # (6.6 CPU-s with the default chunks); which chunk runs a run does not change its row
    # and on one worker: the resume's assertions (only the rest run, the kept rows not run
    # again) do not depend on the worker count, and a worker less is a nanny and a worker
    # process less to start (issue 32)
    at = args.index('--chunk')
    rest = args[:at] + args[at + 2:]
    at = rest.index('--workers')
    rest[at + 1] = '1'
    # and from this process (its cluster's worker is still a process of its own): the
    # resume is about what it runs, not about a fresh CLI process, which imported dask,
    # pyarrow and the engine again (the interrupted run above is the real CLI process)
    res = run_cli('campaign', *rest, '--resume')
    assert res.returncode == 0, res.stderr
    assert f'{n - len(kept)} runs now, {n} in' in res.stdout
    final = store.read(str(out))
    ids = final.column('run_id').to_pylist()
    assert sorted(ids) == list(range(n))
    after = _read_rows(out)
    for k, row in kept.items():  # the runs kept were not run again
        assert row['cpu_time'] == after[k]['cpu_time']


# The race behind a traceback after Ctrl-C, made certain: the scheduler answers heartbeats
# 3 s late, so one is always in flight when the workers close their connections.
_HEARTBEAT_IN_FLIGHT = '''
import asyncio, time
from rigid_body_sim.campaign.runner import Cluster
cluster = Cluster(workers=2)
scheduler = cluster.local.scheduler
answer = scheduler.handlers['heartbeat_worker']

async def late(*args, **kwargs):
    await asyncio.sleep(3.0)
    return answer(*args, **kwargs)
scheduler.handlers['heartbeat_worker'] = late
time.sleep(2.5)  # each worker's heartbeat (every 0.5-1 s) now waits for its answer
cluster.close()
print('closed')
'''


def test_workers_closing_with_a_heartbeat_in_flight_print_no_traceback():
    """Worker.close closes the worker's connections while a heartbeat may still await the
    scheduler's answer; Worker.heartbeat logged that with a traceback at ERROR, on the
    campaign's terminal (1 SIGTERM in ~10 under load). A closing worker's failed heartbeat
    is no error (campaign/worker_setup.py); while the worker runs it still is."""
    res = subprocess.run([sys.executable, '-c', _HEARTBEAT_IN_FLIGHT], capture_output=True,
                         text=True, timeout=180)
    assert res.returncode == 0 and 'closed' in res.stdout, res.stderr[-3000:]
    assert 'Traceback' not in res.stderr, res.stderr[-3000:]


def test_a_running_workers_failed_heartbeat_is_still_logged():
    import logging
    from distributed.comm.core import CommClosedError
    from distributed.core import Status
    from rigid_body_sim.campaign.worker_setup import HEARTBEAT_FAILED, ClosingWorkerHeartbeat

    class Worker:
        status = Status.running
    worker = Worker()
    keep = ClosingWorkerHeartbeat(worker)
    try:
        raise CommClosedError('Stream is closed')
    except CommClosedError:
        record = logging.LogRecord('distributed.worker', logging.ERROR, __file__, 1,
                                   HEARTBEAT_FAILED, None, sys.exc_info())
    assert keep.filter(record)  # the scheduler lost while the worker runs: an error
    worker.status = Status.closing
    assert not keep.filter(record)  # the worker closing its own connections: none
    other = logging.LogRecord('distributed.worker', logging.ERROR, __file__, 1,
                              'Unexpected exception during heartbeat. Closing worker.', None,
                              record.exc_info)
    assert keep.filter(other)
