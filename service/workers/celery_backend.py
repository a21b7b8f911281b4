"""Celery with Redis: workers on other machines sharing the PostgreSQL database.

Run a worker with ``hvcb worker`` or ``celery -A service.workers.celery_app worker`` with the
same ``DATABASE_URL``, ``HVCB_BROKER_URL`` and ``HVCB_DATA_DIR`` as the API.

A task is acknowledged only after it finishes (``acks_late``) and is put back in the queue when
its worker process dies (``reject_on_worker_lost``); when a whole worker machine vanishes, Redis
redelivers the unacknowledged task after ``celery_visibility_timeout_s``. Since the job is
idempotent, a redelivered task either finishes the fit or finds it done.

The task carries only the operation id: each worker reads its database URL and fit options from
its own settings, so no credentials travel through the broker.
"""

from __future__ import annotations

import os
from functools import lru_cache

from celery import Celery
from sqlalchemy.exc import InterfaceError, OperationalError

from service.jobs.fit import JobOptions, run_fit_job

TASK_NAME = "hvcb.fit"

# A database that drops out for a moment (failover, restart, network) fails the task with one of
# these. The job is idempotent (claim and store only touch an unfinished fit), so it is retried:
# delays doubling from 2 s to at most 60 s with full jitter, 8 times (~5 minutes in all). A longer
# outage leaves the fit `running`; the service's stale-fit sweep queues it again after the lease.
TRANSIENT_RETRY = dict(autoretry_for=(OperationalError, InterfaceError), retry_backoff=2,
                       retry_backoff_max=60, retry_jitter=True, max_retries=8)


def make_celery(broker_url: str, *, queue: str = "hvcb", key_prefix: str = "",
                visibility_timeout_s: int = 600, options: JobOptions | None = None) -> Celery:
    """A Celery app whose ``hvcb.fit`` task runs :func:`service.jobs.run_fit_job`.

    ``options`` are the worker's job options; when None they are read from the worker's
    settings at the first task.
    """
    app = Celery("hvcb", broker=broker_url, set_as_current=False)
    transport = {"visibility_timeout": visibility_timeout_s}
    if key_prefix:
        transport["global_keyprefix"] = key_prefix
    app.conf.update(
        task_default_queue=queue,
        task_acks_late=True,
        task_reject_on_worker_lost=True,
        task_acks_on_failure_or_timeout=True,
        worker_prefetch_multiplier=1,
        task_ignore_result=True,
        task_serializer="json",
        accept_content=["json"],
        broker_connection_retry_on_startup=True,
        broker_transport_options=transport,
        worker_hijack_root_logger=False,
        worker_cancel_long_running_tasks_on_connection_loss=False,
    )
    fixed = options.to_dict() if options is not None else None

    @app.task(name=TASK_NAME, acks_late=True, reject_on_worker_lost=True, **TRANSIENT_RETRY)
    def fit_task(operation_id: int):
        return run_fit_job(int(operation_id), fixed if fixed is not None else worker_options())

    @app.task(name="hvcb.refit_batch", acks_late=True, reject_on_worker_lost=True, **TRANSIENT_RETRY)
    def refit_batch_task(run_id: int, operation_ids: list):
        # A batch of one breaker's stored operations (``hvcb refit``); idempotent like the fit.
        from service.jobs.refit import refit_batch

        return refit_batch(int(run_id), [int(i) for i in operation_ids],
                           fixed if fixed is not None else worker_options())

    @app.task(name="hvcb.breaker_diagnosis", acks_late=True, reject_on_worker_lost=True, **TRANSIENT_RETRY)
    def breaker_diagnosis_task(diagnosis_id: int):
        # A breaker-level gap diagnosis (issue 20); idempotent: a finished row is left alone.
        from service.jobs.breaker_diagnosis import run_breaker_diagnosis_job

        url = fixed["database_url"] if fixed is not None else worker_options()["database_url"]
        return run_breaker_diagnosis_job(int(diagnosis_id), url)

    return app


def make_celery_from_settings(settings, *, with_options: bool = True) -> Celery:
    if not settings.broker_url:
        raise ValueError("Celery needs a broker: set HVCB_BROKER_URL (e.g. redis://127.0.0.1:6379/0)")
    return make_celery(settings.broker_url, queue=settings.celery_queue, key_prefix=settings.celery_key_prefix,
                       visibility_timeout_s=settings.celery_visibility_timeout_s,
                       options=JobOptions.from_settings(settings) if with_options else None)


@lru_cache(maxsize=1)
def worker_options() -> dict:
    """The job options of this worker process, from its settings (environment, HVCB_CONFIG)."""
    from service.settings import load_settings

    return JobOptions.from_settings(load_settings(os.environ.get("HVCB_CONFIG") or None)).to_dict()


class CeleryExecutor:
    kind = "celery"

    def __init__(self, settings):
        # The API side never runs tasks; its options are not sent (workers use their own).
        self.app = make_celery_from_settings(settings, with_options=False)

    def start(self) -> None:
        pass

    def submit(self, operation_id: int) -> None:
        # The job key is the operation id; a duplicate delivery finds the fit claimed or done.
        self.app.send_task(TASK_NAME, args=[int(operation_id)])

    def in_flight(self) -> int:
        return -1

    def shutdown(self, *, wait: bool = True) -> None:
        self.app.close()
