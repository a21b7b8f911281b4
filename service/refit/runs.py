"""Refit runs: choose the stored operations, hand batches to the workers, track progress, resume.

A run is a row in ``refit_runs``. An operation counts as refitted by a run when its fits row
carries the run's id, which the batch's write sets in the same transaction as the new result;
so whatever stops a run (Ctrl-C, a killed process, a crash), starting it again re-fits exactly
the operations it had not landed. When every batch has landed, the drift detector of each
breaker is replayed on the newest results, so alarms and trends follow the newest version.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from datetime import datetime

from sqlalchemy import delete, func, or_, select

from service.errors import UserError
from service.storage import crud
from service.storage.models import AlarmRow, DriftStateRow, FitRow, OperationRow, RefitRunRow, utcnow

UNFINISHED = ("queued", "running", "interrupted")
BATCH_SIZE = 25


def _selection(breaker_id: int | None, since: datetime | None):
    """Operations with a finished fit, optionally of one breaker and from a time on."""
    q = (select(OperationRow.id).join(FitRow, FitRow.operation_id == OperationRow.id)
         .where(FitRow.status.in_(("done", "failed"))))
    if breaker_id is not None:
        q = q.where(OperationRow.breaker_id == breaker_id)
    if since is not None:
        q = q.where(OperationRow.occurred_at >= since)
    return q


def start_run(session, *, breaker: str | None = None, since: datetime | None = None,
              requested_by: str | None = None) -> tuple[RefitRunRow, bool]:
    """The unfinished run with the same selection (resumed), else a new one.

    Returns ``(run, resumed)``. Raises ``UserError`` for an unknown breaker name.
    """
    breaker_id = None
    if breaker is not None:
        row = crud.get_breaker_by_name(session, name=breaker)
        if row is None:
            known = ", ".join(b.name for b in crud.list_breakers(session)) or "none registered"
            raise UserError(f"no breaker named {breaker!r} (known: {known})")
        breaker_id = row.id
    q = select(RefitRunRow).where(RefitRunRow.status.in_(UNFINISHED))
    q = q.where(RefitRunRow.breaker_id.is_(None) if breaker_id is None else RefitRunRow.breaker_id == breaker_id)
    q = q.where(RefitRunRow.since.is_(None) if since is None else RefitRunRow.since == since)
    run = session.scalar(q.order_by(RefitRunRow.id.desc()).limit(1))
    if run is not None:
        return run, True
    total = session.scalar(select(func.count()).select_from(_selection(breaker_id, since).subquery()))
    run = RefitRunRow(breaker_id=breaker_id, since=since, status="queued", total=int(total or 0),
                      done=0, failed=0, requested_by=requested_by, created_at=utcnow())
    session.add(run)
    session.flush()
    return run, False


def pending_batches(session, run: RefitRunRow, batch_size: int = BATCH_SIZE) -> list[list[int]]:
    """Operation ids the run has not landed yet: per breaker, in time order, in batches."""
    q = (_selection(run.breaker_id, run.since)
         .where(or_(FitRow.refit_run_id.is_(None), FitRow.refit_run_id != run.id))
         .add_columns(OperationRow.breaker_id)
         .order_by(OperationRow.breaker_id, OperationRow.occurred_at, OperationRow.id))
    batches, current, current_breaker = [], [], None
    for op_id, breaker_id in session.execute(q):
        if current and (breaker_id != current_breaker or len(current) >= batch_size):
            batches.append(current)
            current = []
        current.append(op_id)
        current_breaker = breaker_id
    if current:
        batches.append(current)
    return batches


def rebuild_drift(session, *, breaker_ids, options=None) -> None:
    """Replay each breaker's drift detector on its newest results.

    The detector's state and the active alarms came from the superseded results: the active
    alarms are cleared (saying so) and the replay raises whatever the newest results warrant.
    """
    from service.jobs.fit import update_drift

    now = utcnow()
    for breaker_id in sorted(set(breaker_ids)):
        session.execute(delete(DriftStateRow).where(DriftStateRow.breaker_id == breaker_id))
        for alarm in session.scalars(select(AlarmRow).where(AlarmRow.breaker_id == breaker_id,
                                                            AlarmRow.state != "cleared")):
            alarm.state, alarm.cleared_at, alarm.updated_at = "cleared", now, now
            alarm.evidence = {**(alarm.evidence or {}), "cleared": {"reason": "refit: superseded results"}}
        session.flush()
        update_drift(session, breaker_id=breaker_id, options=options)


def run_refit(Session, run_id: int, *, submit_batches: Callable, options=None,
              on_progress: Callable[[int, int], None] | None = None,
              batch_size: int = BATCH_SIZE) -> RefitRunRow:
    """Drive one run to its end (or to an interruption) and return its final row.

    ``submit_batches(run_id, batches, report)`` runs the batches on the workers and calls
    ``report(n)`` as each batch lands ``n`` operations. KeyboardInterrupt marks the run
    ``interrupted`` (the landed batches stay) and is re-raised.
    """
    with Session() as session, session.begin():
        run = session.get(RefitRunRow, run_id)
        run.status, run.started_at = "running", run.started_at or utcnow()
        batches = pending_batches(session, run, batch_size)
        landed = run.done + run.failed
        total = run.total
    if on_progress:
        on_progress(landed, total)
    try:
        submit_batches(run_id, batches, lambda n: on_progress and on_progress(n, total))
    except KeyboardInterrupt:
        with Session() as session, session.begin():
            session.get(RefitRunRow, run_id).status = "interrupted"
        raise
    with Session() as session, session.begin():
        run = session.get(RefitRunRow, run_id)
        touched = session.scalars(select(FitRow.breaker_id).where(FitRow.refit_run_id == run_id).distinct())
        rebuild_drift(session, breaker_ids=list(touched), options=options)
        run.status, run.finished_at = "done", utcnow()
        session.flush()
        session.expunge(run)
    return run


def wait_for(Session, run_id: int, *, expected: int, report, poll_s: float = 0.2,
             timeout_s: float | None = None) -> None:
    """Follow a run landed by remote workers (Celery) until ``expected`` more operations landed."""
    with Session() as session:
        start = _landed(session, run_id)
    seen, deadline = start, None if timeout_s is None else time.monotonic() + timeout_s
    while seen - start < expected:
        time.sleep(poll_s)
        with Session() as session:
            now = _landed(session, run_id)
        if now > seen:
            report(now - seen)
            seen = now
        if deadline is not None and time.monotonic() > deadline:
            raise UserError(f"refit run {run_id}: the workers landed {seen - start} of {expected} "
                            f"operations in {timeout_s:.0f} s; are Celery workers running?")


def _landed(session, run_id: int) -> int:
    return int(session.scalar(select(func.count()).select_from(FitRow)
                              .where(FitRow.refit_run_id == run_id)) or 0)
