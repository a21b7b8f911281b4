"""The engineer's maintenance log in the database: record an entry, restart what it touches.

Recording an entry (``service.jobs.maintenance.record_event``, which drives the drift jobs) stores it, restarts the drift detector of each watched
parameter it touches at the time the work was done (service.alarms.maintenance.restart: a new
baseline from the fits after it, an active alarm cleared), feeds the fits since then again and
recomputes the prognoses, which read their history from the latest entry touching each
parameter (``restart_times``). API: ``GET``/``POST /api/v1/breakers/{name}/maintenance``; the
breaker page's "Maintenance log" card; the report's block.
"""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import select
from sqlalchemy.orm import Session

from service.alarms.maintenance import EVERY, KINDS, MaintenanceError
from .models import MaintenanceEventRow

NOTE_MAX = 500


def list_events(session: Session, breaker_id: int) -> list[MaintenanceEventRow]:
    """The breaker's log, newest first."""
    return list(session.scalars(select(MaintenanceEventRow).where(MaintenanceEventRow.breaker_id == breaker_id)
                                .order_by(MaintenanceEventRow.done_at.desc(), MaintenanceEventRow.id.desc())))


def restart_times(session: Session, breaker_id: int) -> dict[str, datetime]:
    """parameter (or "*": every one) -> when the latest entry touching it was done."""
    out: dict[str, datetime] = {}
    for row in list_events(session, breaker_id):
        for p in row.parameters or []:
            if p not in out or row.done_at > out[p]:
                out[p] = row.done_at
    return out


def restart_time(session: Session, breaker_id: int, parameter: str) -> datetime | None:
    """When ``parameter``'s baseline, alarms and prognosis last restarted by a logged entry."""
    times = restart_times(session, breaker_id)
    found = [t for t in (times.get(parameter), times.get(EVERY)) if t is not None]
    return max(found) if found else None


def event_dict(row: MaintenanceEventRow) -> dict:
    return {"id": row.id, "breaker_id": row.breaker_id, "kind": row.kind, "done_at": row.done_at,
            "done_by": row.done_by, "note": row.note, "parameters": list(row.parameters or []),
            "recorded_by": row.recorded_by, "recorded_at": row.recorded_at}


__all__ = ["KINDS", "MaintenanceError", "event_dict", "list_events", "restart_time", "restart_times"]
