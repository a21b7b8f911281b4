"""Celery with Redis: workers on other machines sharing the PostgreSQL database.

Run a worker with ``hvcb worker`` (or ``celery -A service.workers.celery_backend:app worker``)
with the same ``DATABASE_URL`` and ``HVCB_BROKER_URL`` as the API.

A task is acknowledged only after it finishes (``acks_late``) and is put back in the queue when
its worker process dies (``reject_on_worker_lost``); since the job is idempotent, a redelivered
task either finishes the fit or finds it done.
"""

from __future__ import annotations

import os

from celery import Celery

from service.jobs import JobOptions, run_fit_job

TASK_NAME = "hvcb.fit"


def make_celery(broker_url: str, *, visibility_timeout_s: int = 600) -> Celery:
    app = Celery("hvcb", broker=broker_url)
    app.conf.update(
        task_acks_late=True,
        task_reject_on_worker_lost=True,
        task_acks_on_failure_or_timeout=True,
        worker_prefetch_multiplier=1,
        task_ignore_result=True,
        task_serializer="json",
        accept_content=["json"],
        broker_connection_retry_on_startup=True,
        broker_transport_options={"visibility_timeout": visibility_timeout_s},
        worker_hijack_root_logger=False,
    )

    @app.task(name=TASK_NAME, acks_late=True, reject_on_worker_lost=True, bind=True)
    def fit_task(self, operation_id: int, options: dict | None = None):
        if options is None:
            options = _worker_options()
        return run_fit_job(int(operation_id), options)

    return app


def _worker_options() -> dict:
    from service.settings import load_settings

    return JobOptions.from_settings(load_settings(os.environ.get("HVCB_CONFIG") or None)).to_dict()


class CeleryExecutor:
    kind = "celery"

    def __init__(self, broker_url: str, options: JobOptions, *, visibility_timeout_s: int = 600):
        self.app = make_celery(broker_url, visibility_timeout_s=visibility_timeout_s)
        self.options = options

    def start(self) -> None:
        pass

    def submit(self, operation_id: int) -> None:
        # Workers read their database URL from their own settings; the job key is the operation id.
        self.app.send_task(TASK_NAME, args=[int(operation_id)])

    def in_flight(self) -> int:
        return -1

    def shutdown(self, *, wait: bool = True) -> None:
        self.app.close()


def _default_app() -> Celery:
    url = os.environ.get("HVCB_BROKER_URL")
    if not url:
        from service.settings import load_settings

        url = load_settings(os.environ.get("HVCB_CONFIG") or None).broker_url or "redis://127.0.0.1:6379/0"
    return make_celery(url)


app = _default_app() if os.environ.get("HVCB_CELERY_APP", "1") == "1" and os.environ.get("HVCB_BROKER_URL") else None
