"""The per-run function (pure: spec + run id → row) and the Dask driver around it.

Run k draws its values from ``numpy.random.default_rng(SeedSequence(S, spawn_key=(k,)))``
— the k-th child of ``SeedSequence(S).spawn(n)`` for any n > k — and its scene's ``seed``
parameter (sensor noise) from that sequence's first child, so it depends only on the
campaign seed S and k, whichever worker runs it, in whichever order, alone or in a chunk.
It runs on the same engine as ``rigid-body-sim run`` (:func:`rigid_body_sim.offline.simulate`).

The driver sends chunks of run ids to Dask (a local cluster it starts, or a scheduler's
address), keeps a bounded number of chunks in flight (memory does not grow with the
number of runs), and hands each finished chunk's rows to the store as they arrive. A chunk
whose worker dies is retried by Dask on another worker; its rows arrive once.
"""
import logging
import math
import os
import signal
import time
from dataclasses import dataclass, field, replace
from typing import Callable, Iterable, List, Optional, Sequence, Tuple

import numpy as np

from ..scene import SceneFile
from . import dispersions as disp
from .metrics import MetricsSink, empty

MAX_CHUNK = 32         # runs per task at most (a 15 s detumble is ~15 ms: 32 ≈ 0.5 s)
CHUNKS_PER_THREAD = 4  # target chunks per worker thread, for balance at the end
IN_FLIGHT_PER_THREAD = 3
WINDOW_REFRESH = 2.0    # s between looks at the cluster's size
# A local cluster's housekeeping, slowed down: the workers' statistical profiler (every 10 ms)
# off, event-loop health checks every 200 ms (20 ms), system monitor every 2 s (0.5 s). This
# halves Dask's own CPU while runs are in flight; a campaign needs none of them. Each worker
# process runs campaign/worker_setup.py at its start (its shutdown logs no false alarm).
LOCAL_CONFIG = {'distributed.worker.profile.enabled': False,
                'distributed.admin.tick.interval': '200ms',
                'distributed.admin.system-monitor.interval': '2s',
                'distributed.worker.preload': ['rigid_body_sim.campaign.worker_setup']}


class _InterruptedSyncCancel(logging.Filter):
    """Drops one log record: distributed 2026.8's ``sync()`` declares its ``future`` without
    a value, so an interrupt (Ctrl-C, SIGTERM) landing before its coroutine has started
    makes the ``cancel`` callback it schedules raise NameError on the event-loop thread —
    there was nothing to cancel — and tornado logs that with a traceback (1 interrupt in
    12 under load). Any other callback error still gets through."""

    def filter(self, record):
        exc = record.exc_info[1] if record.exc_info else None
        return not (isinstance(exc, NameError) and "'future'" in str(exc)
                    and 'sync.<locals>.cancel' in record.getMessage())


INTERRUPTED_SYNC_CANCEL = _InterruptedSyncCancel()


@dataclass(frozen=True)
class CampaignSpec:
    """Everything a run needs; picklable, sent once to every worker."""
    scene: SceneFile
    dispersions: Tuple[disp.Dispersion, ...]
    seed: int
    runs: int
    policy: str = 'redraw'
    pointing_tolerance: float = 0.01
    rate_tolerance: float = 0.01
    columns: Tuple[str, ...] = field(default=())

    @classmethod
    def create(cls, scene, dispersions, seed, runs, **kw) -> 'CampaignSpec':
        return cls(scene, tuple(dispersions), int(seed), int(runs),
                   columns=tuple(disp.columns(scene, dispersions)), **kw)

    def identity(self) -> dict:
        """What defines the runs' results (not how many runs): a resumed campaign must
        match it."""
        return {'scene': self.scene.name, 'simulator': self.scene.simulator,
                'controller': self.scene.controller,
                'dispersions': [d.text for d in self.dispersions], 'seed': self.seed,
                'policy': self.policy, 'pointing_tolerance': self.pointing_tolerance,
                'rate_tolerance': self.rate_tolerance}


def rng_for(seed: int, k: int) -> np.random.Generator:
    """Run k's generator: depends on (seed, k) only."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(k,)))


def noise_seed(seed: int, k: int) -> int:
    """Run k's ``seed`` parameter (the scene's random processes, e.g. sensor noise): from
    the first child of run k's SeedSequence, so it too depends on (seed, k) only."""
    return int(np.random.SeedSequence(seed, spawn_key=(k, 0)).generate_state(1, np.uint64)[0]
               >> np.uint64(1))  # within the parameter's range [0, 2^63 - 1]


def run_one(spec: CampaignSpec, k: int) -> dict:
    """Run k of the campaign → its row. Never raises for a bad run: a refused draw, an
    integrator error or any other failure is the row's ``status`` and ``error``."""
    from ..offline import simulate
    from ..physics import IntegrationError
    # the thread's CPU time: a Dask worker's other threads (its event loop) are not the run's
    cpu0 = time.thread_time()
    row = {'run_id': k, 'seed': spec.seed, 'status': 'ok', 'error': '', 'redraws': 0,
           'noise_seed': None}
    values, metrics = None, empty()
    integrator = str(spec.scene.simulator.get('integrator', ''))
    base = spec.scene
    if 'seed' in base.simulator and 'seed' not in {d.key for d in spec.dispersions}:
        row['noise_seed'] = noise_seed(spec.seed, k)
        base = replace(base, simulator={**base.simulator, 'seed': row['noise_seed']})
    try:
        values, scene, row['redraws'] = disp.draw(base, spec.dispersions,
                                                  rng_for(spec.seed, k), spec.policy)
    except disp.DrawRejected as exc:
        row.update(status='bad_draw', error=str(exc), redraws=exc.attempts)
    else:
        sink = MetricsSink(scene, spec.pointing_tolerance, spec.rate_tolerance)
        try:
            result = simulate(scene, sinks=[sink], keep='none')
            metrics, integrator = sink.result(), result.integrator
        except IntegrationError as exc:
            row.update(status='integration_error', error=str(exc))
        except Exception as exc:  # noqa: BLE001 — a run's failure is its row; the campaign goes on
            row.update(status='error', error=f'{type(exc).__name__}: {exc}')
    row.update(disp.flatten(spec.scene, spec.dispersions, values))
    row.update(metrics)
    row['integrator'] = integrator
    row['cpu_time'] = time.thread_time() - cpu0
    return row


def run_chunk(spec: CampaignSpec, ids: Sequence[int]) -> List[dict]:
    """Rows of the runs ``ids`` (one Dask task)."""
    return [run_one(spec, k) for k in ids]


def lost_rows(spec: CampaignSpec, ids, reason: str) -> List[dict]:
    """Rows for runs whose task failed outside the run function: it killed every worker
    it ran on (KilledWorker), or a worker could not load it (rigid_body_sim missing)."""
    rows = []
    for k in ids:
        row = {'run_id': k, 'seed': spec.seed, 'status': 'task_failed', 'error': reason,
               'redraws': 0, 'noise_seed': None, 'integrator': '', 'cpu_time': math.nan}
        row.update(disp.flatten(spec.scene, spec.dispersions, None))
        row.update(empty())
        rows.append(row)
    return rows


def chunk_size(n_runs: int, threads: int) -> int:
    return max(1, min(MAX_CHUNK, math.ceil(n_runs / (max(1, threads) * CHUNKS_PER_THREAD))))


def chunks(ids: Sequence[int], size: int) -> Iterable[List[int]]:
    ids = list(ids)
    for i in range(0, len(ids), size):
        yield ids[i:i + size]


def cores() -> int:
    """Cores this process may run on (its affinity), at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


class Cluster:
    """A Dask client: on ``scheduler`` (an address) if given, else on a local cluster of
    ``workers`` processes (one thread each) started here and shut down on close."""

    def __init__(self, scheduler: Optional[str] = None, workers: Optional[int] = None,
                 timeout: float = 30.0):
        import dask
        from distributed import Client, LocalCluster
        logging.getLogger('distributed').setLevel(logging.ERROR)
        tornado_log = logging.getLogger('tornado.application')
        if INTERRUPTED_SYNC_CANCEL not in tornado_log.filters:
            tornado_log.addFilter(INTERRUPTED_SYNC_CANCEL)
        self.local = None
        if scheduler:
            self.client = Client(scheduler, timeout=timeout)
            return
        # Worker processes ignore SIGINT (they inherit the ignored disposition): Ctrl-C in a
        # terminal reaches the whole process group, and only this process should handle it.
        old = signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            # LOCAL_CONFIG reaches the worker processes through their nannies
            with dask.config.set(LOCAL_CONFIG):
                self.local = LocalCluster(n_workers=workers or cores(),
                                          threads_per_worker=1, processes=True,
                                          dashboard_address=None,
                                          silence_logs=logging.ERROR)
            self.client = Client(self.local, timeout=timeout)
        except BaseException:
            if self.local is not None:
                self.local.close()
            raise
        finally:
            signal.signal(signal.SIGINT, old)

    @property
    def threads(self) -> int:
        info = self.client.scheduler_info(n_workers=-1)['workers']
        return sum(w.get('nthreads', 1) for w in info.values())

    def close(self):
        try:
            self.client.close()
        finally:
            if self.local is not None:
                self.local.close()


def execute(cluster: Cluster, spec: CampaignSpec, ids: Sequence[int],
            on_rows: Callable[[List[dict]], None], chunk: Optional[int] = None) -> None:
    """Run ``ids`` on ``cluster``; ``on_rows(rows)`` is called in this process with each
    finished chunk's rows, as they finish. At most a few chunks per worker thread are in
    flight, so this process's memory does not grow with the number of runs."""
    from distributed import as_completed
    threads = max(1, cluster.threads)
    size = chunk or chunk_size(len(ids), threads)
    client = cluster.client
    spec_future = client.scatter(spec, broadcast=True)
    todo = iter(chunks(ids, size))
    pending = {}

    def submit():
        part = next(todo, None)
        if part is None:
            return None
        fut = client.submit(run_chunk, spec_future, part, pure=False,
                            key=f'campaign-run-{part[0]}-{part[-1]}-{os.urandom(4).hex()}')
        pending[fut.key] = part
        return fut

    # the window follows the cluster's size (workers may join late: dask-jobqueue)
    refreshed = time.monotonic()
    done = as_completed([f for f in (submit() for _ in range(threads * IN_FLIGHT_PER_THREAD))
                         if f])
    for fut in done:
        part = pending.pop(fut.key)
        try:
            rows = fut.result()
        except Exception as exc:  # noqa: BLE001 — e.g. KilledWorker after its retries
            rows = lost_rows(spec, part, f'{type(exc).__name__}: {exc}')
        fut.release()
        on_rows(rows)
        if time.monotonic() - refreshed > WINDOW_REFRESH:
            threads, refreshed = max(1, cluster.threads), time.monotonic()
        while len(pending) < threads * IN_FLIGHT_PER_THREAD:
            nxt = submit()
            if nxt is None:
                break
            done.add(nxt)
