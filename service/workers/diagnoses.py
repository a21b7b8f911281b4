"""Runs diagnosis jobs on demand in a process of their own, one at a time."""

from __future__ import annotations

import threading
from concurrent.futures import Future, ProcessPoolExecutor

from service.processes import process_pool

from .priority import lower_priority


class DiagnosisRunner:
    """Submits ``run_diagnosis_job`` for an operation once per process lifetime of the request.

    The database row is the job's state: a row left ``queued`` or ``running`` by a restart is
    submitted again by the next request for it.
    """

    def __init__(self, database_url: str):
        self.database_url = database_url
        self._pool: ProcessPoolExecutor | None = None
        self._futures: dict[int, Future] = {}
        self._lock = threading.Lock()

    def ensure(self, operation_id: int) -> None:
        from service.jobs.diagnosis import run_diagnosis_job

        with self._lock:
            fut = self._futures.get(operation_id)
            if fut is not None and not fut.done():
                return
            if self._pool is None:
                # spawn: the API process runs threads, which fork would copy mid-lock.
                self._pool = process_pool(1, initializer=lower_priority)
            self._futures[operation_id] = self._pool.submit(run_diagnosis_job, operation_id, self.database_url)

    def shutdown(self) -> None:
        with self._lock:
            if self._pool is not None:
                self._pool.terminate_workers()  # a running diagnosis is ended, not awaited
                self._pool = None
