"""Where a refit's batches run: the local process pool, in this process, or Celery workers."""

from __future__ import annotations

from concurrent.futures import FIRST_COMPLETED, wait

from service.jobs.fit import JobOptions

from service.jobs.refit import refit_batch
from service.processes import process_pool

BATCH_TASK = "hvcb.refit_batch"


def _warm() -> None:
    try:
        import service.estimation.fit  # noqa: F401  (compile before the first batch)
    except Exception:
        pass


def local_pool(options: JobOptions, workers: int, on_batch=None):
    """Batches on a spawned process pool, at most ``2 × workers`` in flight.

    ``on_batch(result)`` sees each batch's result dict (benchmarks read its ``cpu_s``).
    """
    def submit(run_id, batches, report):
        opts = options.to_dict()
        pool = process_pool(workers, initializer=_warm)
        pending, queue = set(), list(batches)
        try:
            while queue or pending:
                while queue and len(pending) < 2 * workers:
                    pending.add(pool.submit(refit_batch, run_id, queue.pop(0), opts))
                finished, pending = wait(pending, return_when=FIRST_COMPLETED)
                for fut in finished:
                    res = fut.result()
                    if on_batch is not None:
                        on_batch(res)
                    report(res["done"] + res["failed"])
        except BaseException:
            pool.shutdown(wait=False, cancel_futures=True)
            raise
        pool.shutdown(wait=True)
    return submit


def inline(options: JobOptions):
    """Batches one after another in this process (tests, debugging)."""
    def submit(run_id, batches, report):
        for batch in batches:
            res = refit_batch(run_id, batch, options)
            report(res["done"] + res["failed"])
    return submit


def celery(settings, Session, *, timeout_s: float | None = None):
    """Batches as ``hvcb.refit_batch`` tasks; progress is read from the database."""
    from service.workers.celery_backend import make_celery_from_settings

    from .runs import wait_for

    app = make_celery_from_settings(settings, with_options=False)

    def submit(run_id, batches, report):
        for batch in batches:
            app.send_task(BATCH_TASK, args=[int(run_id), [int(i) for i in batch]])
        wait_for(Session, run_id, expected=sum(len(b) for b in batches), report=report,
                 timeout_s=timeout_s)
    return submit
