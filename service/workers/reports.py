"""The condition report (PDF) drawn in a worker process, never in the API's threads (issue 44
item 2). The API and the web page's button submit a job here and answer with it at once (202 and
its URL) or await it without holding a thread; the job gathers the report's content from the
database and draws it in the worker, which runs at a lower CPU priority than the API so that the
light routes keep answering while reports are drawn.

``local`` and ``celery`` installations draw in a spawned process pool of ``REPORT_WORKERS``; the
tests' ``inline`` executor in a thread (no process to start)."""

from __future__ import annotations

import threading
import time
import uuid
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from datetime import datetime

from service.processes import process_pool

from .priority import lower_priority

REPORT_WORKERS = 1      # one report at a time: it is one core's work, and the machine has few
KEEP_S = 600.0          # a finished report can be fetched this long [s]
MAX_JOBS = 64           # at most this many jobs remembered (oldest finished ones forgotten first)
MAX_PENDING = 16        # reports queued or being drawn at once; beyond: refused (busy), not queued


class ReportFailed(Exception):
    """The report could not be drawn; the message says why, in words."""


class ReportsBusy(Exception):
    """``MAX_PENDING`` reports are already queued or being drawn; the message says so."""


def draw_report(database_url: str, alarms: dict, breaker_id: int, start: datetime | None,
                end: datetime | None) -> tuple[bytes, str]:
    """The condition report of breaker ``breaker_id`` over [start, end], as (PDF bytes, breaker
    name). Runs in the worker: its own engine, the drift settings of the ``[alarms]`` section."""
    from service.reports.content import gather
    from service.reports.pdf import render
    from service.reports.window import Window
    from service.settings import drift_settings_for
    from service.storage.db import cached_engine, session_factory
    from service.storage.models import BreakerRow

    settings = drift_settings_for(alarms)
    with session_factory(cached_engine(database_url))() as session:
        b = session.get(BreakerRow, breaker_id)
        if b is None:
            raise ReportFailed(f"breaker {breaker_id} no longer exists")
        content = gather(session, breaker=b, settings=settings, window=Window(start, end))
        name = b.name
    return render(content), name


def _lower_priority() -> None:
    lower_priority()
    try:  # the report's modules loaded once per worker, before its first report
        import service.reports.content  # noqa: F401
        import service.reports.pdf  # noqa: F401
    except Exception:  # the job reports it
        pass


@dataclass
class ReportJob:
    id: str
    breaker_id: int
    breaker_name: str
    start: datetime | None
    end: datetime | None
    future: Future
    requested: float = field(default_factory=time.monotonic)

    @property
    def status(self) -> str:
        if not self.future.done():
            return "running" if self.future.running() else "queued"
        return "failed" if self.future.exception() is not None else "done"

    def error(self) -> str:
        exc = self.future.exception()
        from service.errors import in_words

        return str(exc) if isinstance(exc, ReportFailed) else f"the report could not be drawn: {in_words(exc)}"


class ReportRunner:
    """Report jobs of one service, remembered for ``KEEP_S`` after they finish. The same report
    (breaker and window) asked for while one is being drawn is that job."""

    def __init__(self, settings):
        self.database_url = settings.sqlalchemy_url
        self.alarms = dict(settings.alarms)
        self.kind = settings.executor_kind
        self._pool = None
        self._jobs: dict[str, ReportJob] = {}
        self._lock = threading.Lock()

    def submit(self, *, breaker_id: int, breaker_name: str, start: datetime | None = None,
               end: datetime | None = None) -> ReportJob:
        with self._lock:
            self._forget()
            for job in self._jobs.values():
                if (job.breaker_id, job.start, job.end) == (breaker_id, start, end) and not job.future.done():
                    return job
            pending = sum(not j.future.done() for j in self._jobs.values())
            if pending >= MAX_PENDING:
                raise ReportsBusy(f"{pending} condition reports are being drawn or wait their turn: "
                                  "ask again in a minute")
            if self._pool is None:
                if self.kind == "inline":
                    self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="ThreadPoolExecutor-report")
                else:  # spawn: the API process runs threads, which fork would copy mid-lock
                    self._pool = process_pool(REPORT_WORKERS, initializer=_lower_priority)
            fut = self._pool.submit(draw_report, self.database_url, self.alarms, breaker_id, start, end)
            job = ReportJob(uuid.uuid4().hex, breaker_id, breaker_name, start, end, fut)
            self._jobs[job.id] = job
            return job

    def get(self, job_id: str) -> ReportJob | None:
        with self._lock:
            self._forget()
            return self._jobs.get(job_id)

    def _forget(self) -> None:
        now = time.monotonic()
        done = [j for j in self._jobs.values() if j.future.done()]
        for j in done:
            if now - j.requested > KEEP_S:
                del self._jobs[j.id]
        for j in sorted(done, key=lambda j: j.requested)[:max(0, len(self._jobs) - MAX_JOBS)]:
            self._jobs.pop(j.id, None)

    def shutdown(self) -> None:
        with self._lock:
            if self._pool is not None:
                if isinstance(self._pool, ThreadPoolExecutor):
                    self._pool.shutdown(wait=True, cancel_futures=True)
                else:
                    self._pool.terminate_workers()
                self._pool = None
