"""Where breaker diagnoses run: the backend the fits use (``[service] executor``).

- ``local``: a spawned process pool of one process (a diagnosis uses both cores itself);
- ``celery``: an ``hvcb.breaker_diagnosis`` task on the fit queue, run by any ``hvcb worker``;
- ``inline``: a thread of this process, one at a time (tests, debugging).

The database row is the job's state. Locally, a row left queued or running by a restart is
submitted again by the next request that reads it (:meth:`ensure`); Celery redelivers by itself.
"""

from __future__ import annotations

import threading
from concurrent.futures import Future, ThreadPoolExecutor

from service.processes import process_pool

from .priority import lower_priority

TASK_NAME = "hvcb.breaker_diagnosis"


class BreakerDiagnosisRunner:
    def __init__(self, settings):
        self.settings = settings
        self.kind = settings.executor_kind
        self._pool = None
        self._celery = None
        self._futures: dict[int, Future] = {}
        self._lock = threading.Lock()

    def submit(self, diagnosis_id: int) -> None:
        """Queue the job of a committed row (a no-op when this process already runs it)."""
        from service.jobs.breaker_diagnosis import run_breaker_diagnosis_job

        with self._lock:
            if self.kind == "celery":
                if self._celery is None:
                    from .celery_backend import make_celery_from_settings

                    self._celery = make_celery_from_settings(self.settings, with_options=False)
                self._celery.send_task(TASK_NAME, args=[int(diagnosis_id)])
                return
            fut = self._futures.get(diagnosis_id)
            if fut is not None and not fut.done():
                return
            if self._pool is None:
                if self.kind == "inline":
                    self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="ThreadPoolExecutor-diagnosis")
                else:  # spawn: the API process runs threads, which fork would copy mid-lock
                    self._pool = process_pool(1, initializer=lower_priority)
            self._futures = {k: f for k, f in self._futures.items() if not f.done()}
            self._futures[diagnosis_id] = self._pool.submit(run_breaker_diagnosis_job, int(diagnosis_id),
                                                            self.settings.sqlalchemy_url)

    def ensure(self, diagnosis_id: int) -> None:
        """Submit a pending row again unless this process is running it (local backends only)."""
        if self.kind != "celery":
            self.submit(diagnosis_id)

    def shutdown(self) -> None:
        with self._lock:
            if self._pool is not None:
                if self.kind == "inline":
                    self._pool.shutdown(wait=True, cancel_futures=True)
                else:  # a running diagnosis is ended, not awaited: a GET submits it again (ensure)
                    self._pool.terminate_workers()
                self._pool = None
            if self._celery is not None:
                self._celery.close()
                self._celery = None
