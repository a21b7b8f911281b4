"""Local backends: a process pool (the default) and an inline runner (tests, debugging)."""

from __future__ import annotations

import logging
import threading
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool

from service.jobs.fit import JobOptions, run_fit_job
from service.processes import process_pool

log = logging.getLogger("hvcb.workers")


def _warm() -> None:
    """Import the estimator in each worker at start, so the first fit is not slower."""
    try:
        import service.estimation.fit  # noqa: F401
    except Exception:  # reported by the job itself
        pass


class LocalExecutor:
    """Process pool. A job whose process dies (BrokenProcessPool) is resubmitted on a new pool;
    the job's attempt counter in the database stops a job that kills its worker every time."""

    kind = "local"

    def __init__(self, options: JobOptions, *, max_workers: int = 1, on_result=None):
        self.options = options
        self.max_workers = max_workers
        self.on_result = on_result
        self._lock = threading.RLock()
        self._pool: ProcessPoolExecutor | None = None
        self._generation = 0
        self._futures: dict[int, Future] = {}
        self._closed = False

    def start(self) -> None:
        with self._lock:
            if self._pool is None:
                self._pool = self._new_pool()

    def _new_pool(self) -> ProcessPoolExecutor:
        return process_pool(self.max_workers, initializer=_warm)

    def pids(self) -> list[int]:
        """Process ids of the pool's workers (tests kill one to check the retry)."""
        with self._lock:
            procs = getattr(self._pool, "_processes", None) or {}
            return list(procs)

    def submit(self, operation_id: int) -> None:
        with self._lock:
            if self._closed:
                raise RuntimeError("executor is shut down")
            if self._pool is None:
                self._pool = self._new_pool()
            current = self._futures.get(operation_id)
            if current is not None and not current.done():
                return  # already queued here; the job is idempotent anyway
            generation = self._generation
            try:
                fut = self._pool.submit(run_fit_job, operation_id, self.options.to_dict())
            except BrokenProcessPool:
                self._replace_pool(generation)
                fut = self._pool.submit(run_fit_job, operation_id, self.options.to_dict())
                generation = self._generation
            self._futures[operation_id] = fut
        fut.add_done_callback(lambda f, op=operation_id, g=generation: self._done(op, g, f))

    def _replace_pool(self, generation: int) -> None:
        with self._lock:
            if generation != self._generation or self._closed:
                return
            old = self._pool
            self._generation += 1
            self._pool = self._new_pool()
        if old is not None:
            old.shutdown(wait=False, cancel_futures=True)

    def _done(self, operation_id: int, generation: int, fut: Future) -> None:
        exc = fut.exception() if not fut.cancelled() else None
        if isinstance(exc, BrokenProcessPool) or fut.cancelled():
            with self._lock:
                if self._closed:
                    return
                if self._futures.get(operation_id) is not fut:
                    return
                del self._futures[operation_id]
            log.warning("worker process died during the fit of operation %s; resubmitting", operation_id)
            self._replace_pool(generation)
            try:
                self.submit(operation_id)
            except RuntimeError:
                pass
            return
        with self._lock:
            if self._futures.get(operation_id) is fut:
                del self._futures[operation_id]
        if exc is not None:
            log.error("fit job of operation %s raised: %s", operation_id, exc)
            result = {"operation_id": operation_id, "status": "error", "landed": False, "runtime_s": 0.0}
        else:
            result = fut.result()
        if self.on_result is not None:
            try:
                self.on_result(result)
            except Exception:  # metrics must never break the executor
                log.exception("result callback failed")

    def in_flight(self) -> int:
        with self._lock:
            return sum(1 for f in self._futures.values() if not f.done())

    def shutdown(self, *, wait: bool = True) -> None:
        """``wait``: let the running fits finish; else end them now (their rows stay queued or
        running, and ``Monitor.recover`` re-queues them at the next start)."""
        with self._lock:
            self._closed = True
            pool, self._pool = self._pool, None
        if pool is None:
            return
        if wait:
            pool.shutdown(wait=True, cancel_futures=True)
        else:
            pool.terminate_workers()


class InlineExecutor:
    """Runs each job in a background thread of this process, one at a time (tests, debugging)."""

    kind = "inline"

    def __init__(self, options: JobOptions, *, on_result=None):
        import queue

        self.options = options
        self.on_result = on_result
        self._queue: queue.Queue = queue.Queue()
        self._thread: threading.Thread | None = None
        self._busy = 0

    def start(self) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="hvcb-inline-executor", daemon=True)
            self._thread.start()

    def _run(self) -> None:
        while True:
            op = self._queue.get()
            if op is None:
                return
            self._busy = 1
            try:
                result = run_fit_job(op, self.options)
                if self.on_result is not None:
                    self.on_result(result)
            except Exception:
                log.exception("fit job of operation %s raised", op)
            finally:
                self._busy = 0
                self._queue.task_done()

    def submit(self, operation_id: int) -> None:
        self.start()
        self._queue.put(operation_id)

    def join(self) -> None:
        self._queue.join()

    def in_flight(self) -> int:
        return self._queue.qsize() + self._busy

    def shutdown(self, *, wait: bool = True) -> None:
        if self._thread is not None:
            self._queue.put(None)
            if wait:
                self._thread.join(timeout=30)
            self._thread = None
