"""Run in each worker process of a campaign's local cluster at its start (Dask's
``distributed.worker.preload``, set in ``runner.LOCAL_CONFIG``)."""
import logging
import weakref

HEARTBEAT_FAILED = 'Failed to communicate with scheduler during heartbeat.'


class ClosingWorkerHeartbeat(logging.Filter):
    """Drops one record, of a worker that is closing: distributed 2026.8's ``Worker.close``
    closes the worker's connection pool while a heartbeat to the scheduler may still await
    its reply, so that read fails (CommClosedError, "Stream is closed") and
    ``Worker.heartbeat`` logs it at ERROR with a traceback. The worker's stderr is the
    campaign's terminal: 1 interrupt in ~10 under load showed it after "interrupted".
    Nothing failed: the worker was told to close. The same failure while the worker runs
    (a scheduler really lost) and every other record still get through."""

    def __init__(self, worker):
        super().__init__()
        self._worker = weakref.ref(worker)

    def filter(self, record):
        if record.getMessage() != HEARTBEAT_FAILED:
            return True
        from distributed.core import Status
        worker = self._worker()
        exc = record.exc_info[1] if record.exc_info else None
        return not (isinstance(exc, OSError) and worker is not None and worker.status in (
            Status.closing, Status.closing_gracefully, Status.closed))


def dask_setup(worker):
    logging.getLogger('distributed.worker').addFilter(ClosingWorkerHeartbeat(worker))
