"""The executor interface: ``submit(operation_id)`` queues the fit job of a committed capture."""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

from service.jobs.fit import JobOptions

# Called with the job's return dict when a job finishes in this process (local backends).
ResultCallback = Callable[[dict], None]


class Executor(Protocol):
    kind: str

    def start(self) -> None: ...

    def submit(self, operation_id: int) -> None:
        """Queue the fit of ``operation_id``. The operation row must already be committed."""

    def in_flight(self) -> int:
        """Jobs submitted by this process and not finished (local backends; -1 if unknown)."""

    def shutdown(self, *, wait: bool = True) -> None: ...


def make_executor(settings, *, on_result: ResultCallback | None = None) -> Executor:
    options = JobOptions.from_settings(settings)
    kind = settings.executor_kind
    if kind == "celery":
        from .celery_backend import CeleryExecutor

        return CeleryExecutor(settings)
    if kind == "inline":
        from .local import InlineExecutor

        return InlineExecutor(options, on_result=on_result)
    from .local import LocalExecutor

    return LocalExecutor(options, max_workers=settings.workers, on_result=on_result)
