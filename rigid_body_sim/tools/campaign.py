"""Campaign throughput: Dask against a plain multiprocessing.Pool, scaling, memory.

    python -m rigid_body_sim.tools.campaign [--runs 1000] [--workers N] [--repeats 2]

Runs of the detumble scene (15 s; inertia ±5 % uniform, ω0 + N(0, 0.2²) per component)
through the campaign's per-run function (:func:`rigid_body_sim.campaign.runner.run_one`):

* ``pool``: ``multiprocessing.Pool(N).imap_unordered`` over the run ids (spawned
  processes, the same chunk size as the campaign), rows collected in this process;
* ``dask``: the campaign driver on a local Dask cluster of N worker processes, rows
  written to the Parquet dataset as in ``rigid-body-sim campaign``;
* ``dask_1``: the same with one worker (scaling 1 → N).

Workers are warmed (compiled kernels loaded) before timing; cluster start-up is reported
apart, and so is the CPU time per run inside the run function (the same work in both, so
a gap in wall time is scheduling, not the runs). The two are timed alternately
``--repeats`` times and the best of each compared, in the same run. Memory: this
process's RSS when 10 %, 50 % and 100 % of the runs are in, and each worker's RSS before
and after. On a shared machine wall time depends on what else runs; the CPU that all the
processes of each set-up spend beyond the runs' own (this process — with a local
cluster's scheduler and nannies — and the workers) does not, and is printed too. Prints
a table and one JSON line.
"""
from . import argument_parser
import json
import multiprocessing
import os
import sys
import tempfile
import time
from functools import partial

DISPERSIONS = ('inertia=uniform:5%', 'initial_angular_velocity=normal:0.2')


def spec(runs, duration):
    from ..campaign import dispersions as disp
    from ..campaign.runner import CampaignSpec
    from ..scene import load
    scene = load('detumble', [f'duration={duration}'])
    return CampaignSpec.create(scene, [disp.parse(t) for t in DISPERSIONS], 0, runs)


def _rss_mb() -> float:
    import psutil
    return psutil.Process().memory_info().rss / 2 ** 20


def _cpu_s() -> float:
    """CPU seconds (user + system) of this whole process, every thread."""
    import psutil
    t = psutil.Process().cpu_times()
    return t.user + t.system


def _warm(s, _i):
    from ..campaign.runner import run_one
    run_one(s, 0)
    time.sleep(0.5)  # hold this process so every worker gets one warm-up
    return os.getpid()


def time_pool(s, workers, chunk):
    from ..campaign.runner import run_one
    ctx = multiprocessing.get_context('spawn')
    with ctx.Pool(workers) as pool:
        import psutil
        procs = [psutil.Process(p) for p in
                 set(pool.map(partial(_warm, s), range(workers), chunksize=1))]
        cpu0 = _cpu_s() + sum(sum(p.cpu_times()[:2]) for p in procs)
        t0 = time.perf_counter()
        rows = list(pool.imap_unordered(partial(run_one, s), range(s.runs), chunksize=chunk))
        elapsed = time.perf_counter() - t0
        total = _cpu_s() + sum(sum(p.cpu_times()[:2]) for p in procs) - cpu0
    assert len(rows) == s.runs and all(r['status'] == 'ok' for r in rows)
    runs_cpu = sum(r['cpu_time'] for r in rows)
    return elapsed, runs_cpu / len(rows), total / runs_cpu - 1.0


def time_dask(s, workers, chunk):
    import pyarrow.parquet  # noqa: F401 — imported before the clock starts
    from ..campaign import store
    from ..campaign.runner import Cluster, execute
    t0 = time.perf_counter()
    cluster = Cluster(None, workers)
    startup = time.perf_counter() - t0
    try:
        cluster.client.wait_for_workers(workers)
        cluster.client.run(_warm, s, 0)
        before = cluster.client.run(_rss_mb)
        with tempfile.TemporaryDirectory() as out:
            rows = store.RunStore(out, s.columns, {'bench': True})
            rss, seen, cpu = {}, [0], [0.0]

            def on_rows(new):
                rows.add(new)
                seen[0] += len(new)
                cpu[0] += sum(r['cpu_time'] for r in new)
                for pct in (10, 50):
                    if seen[0] >= s.runs * pct // 100 and f'at_{pct}pct' not in rss:
                        rss[f'at_{pct}pct'] = _rss_mb()
            cpu0 = _cpu_s() + sum(cluster.client.run(_cpu_s).values())
            t0 = time.perf_counter()
            execute(cluster, s, range(s.runs), on_rows, chunk)
            rows.close()
            elapsed = time.perf_counter() - t0
            # the client process holds the scheduler and the nannies of a local cluster
            total = _cpu_s() + sum(cluster.client.run(_cpu_s).values()) - cpu0
            rss['at_end'] = _rss_mb()
            assert len(store.existing_ids(out)) == s.runs
        after = cluster.client.run(_rss_mb)
    finally:
        cluster.close()
    workers_rss = {'before': sorted(before.values()), 'after': sorted(after.values())}
    return elapsed, startup, rss, workers_rss, cpu[0] / s.runs, total / cpu[0] - 1.0


def main(argv=None) -> int:
    from ..campaign.runner import chunk_size
    parser = argument_parser(__spec__, __doc__)
    parser.add_argument('--runs', type=int, default=1000)
    parser.add_argument('--workers', type=int, default=os.cpu_count() or 1)
    parser.add_argument('--duration', type=float, default=15.0, help='simulated s per run')
    parser.add_argument('--repeats', type=int, default=2)
    args = parser.parse_args(argv)
    s = spec(args.runs, args.duration)
    chunk = chunk_size(args.runs, args.workers)
    pool, dask, startup, pool_cpu, dask_cpu, pool_extra, dask_extra = [], [], [], [], [], [], []
    mem = workers_rss = None
    try:
        for _ in range(args.repeats):
            t, c, x = time_pool(s, args.workers, chunk)
            pool.append(t)
            pool_cpu.append(c)
            pool_extra.append(x)
            d, up, mem, workers_rss, c, x = time_dask(s, args.workers, chunk)
            dask.append(d)
            startup.append(up)
            dask_cpu.append(c)
            dask_extra.append(x)
        one, *_ = time_dask(s, 1, chunk_size(args.runs, 1))
    except KeyboardInterrupt:
        print('interrupted', file=sys.stderr)
        return 130
    best_pool, best_dask = min(pool), min(dask)
    result = {
        'runs': args.runs, 'workers': args.workers, 'duration': args.duration, 'chunk': chunk,
        'pool_seconds': pool, 'dask_seconds': dask, 'dask_startup_seconds': startup,
        'pool_runs_per_s': args.runs / best_pool, 'dask_runs_per_s': args.runs / best_dask,
        'dask_overhead': best_dask / best_pool - 1.0,
        'dask_1_worker_runs_per_s': args.runs / one,
        'scaling_1_to_n': one / best_dask,
        'cpu_per_run_pool': pool_cpu, 'cpu_per_run_dask': dask_cpu,
        'cpu_beyond_runs_pool': pool_extra, 'cpu_beyond_runs_dask': dask_extra,
        'client_rss_mb': mem, 'worker_rss_mb': workers_rss,
        'client_rss_growth_second_half_mb': mem['at_end'] - mem['at_50pct'],
    }
    print(f'{args.runs} detumbles of {args.duration:g} s on {args.workers} workers '
          f'(chunks of {chunk}):')
    print(f'  multiprocessing.Pool  {result["pool_runs_per_s"]:8.1f} runs/s  (best of '
          f'{", ".join(f"{t:.2f}" for t in pool)} s)')
    print(f'  Dask local cluster    {result["dask_runs_per_s"]:8.1f} runs/s  (best of '
          f'{", ".join(f"{t:.2f}" for t in dask)} s; start-up '
          f'{min(startup):.2f} s apart)')
    print(f'  Dask overhead vs Pool {100 * result["dask_overhead"]:+.1f} % (target <= 10 %)')
    print(f'  Dask, 1 worker        {result["dask_1_worker_runs_per_s"]:8.1f} runs/s; '
          f'1 -> {args.workers} workers: x{result["scaling_1_to_n"]:.2f}')
    print(f'  CPU per run (the run function\'s thread): Pool {1e3 * min(pool_cpu):.1f} ms, '
          f'Dask {1e3 * min(dask_cpu):.1f} ms')
    print(f'  CPU of every process beyond the runs\' own: Pool '
          f'{100 * min(pool_extra):+.1f} %, Dask {100 * min(dask_extra):+.1f} % (load-proof)')
    w = {k: [round(x, 1) for x in v] for k, v in workers_rss.items()}
    print(f'  client RSS {mem["at_10pct"]:.1f} / {mem["at_50pct"]:.1f} / {mem["at_end"]:.1f} '
          f'MB at 10 / 50 / 100 % of the runs; workers {w["before"]} -> {w["after"]} MB')
    print(json.dumps(result))
    return 0


if __name__ == '__main__':
    sys.exit(main())
