"""The engineer's maintenance log in the database: record an entry, restart what it touches.

Recording an entry (``record_event``) stores it, restarts the drift detector of each watched
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

from service.alarms.maintenance import EVERY, KINDS, MaintenanceError, restart, touched
from .models import BreakerRow, MaintenanceEventRow, utcnow

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


def record_event(session: Session, *, breaker_id: int, kind: str, done_at: datetime | None, done_by: str,
                 note: str = "", recorded_by: str, settings) -> MaintenanceEventRow:
    """Log ``kind`` done at ``done_at`` (now when None) by ``done_by`` and restart what it touches.
    MaintenanceError in words for an unknown kind, a time in the future, or an empty name."""
    from service.jobs.fit import _drift_state, _save_state, apply_alarm_event, update_drift

    params = list(touched(kind))
    now = utcnow()
    done_at = now if done_at is None else done_at
    if done_at.tzinfo is None:
        raise MaintenanceError("the time the work was done needs a time zone (e.g. 2026-03-01T09:00:00Z)")
    if done_at > now:
        raise MaintenanceError(f"the work cannot be logged as done in the future ({done_at.isoformat()})")
    if not done_by or not done_by.strip():
        raise MaintenanceError("say who did the work (done_by)")
    if len(note) > NOTE_MAX:
        raise MaintenanceError(f"the note is {len(note)} characters; at most {NOTE_MAX}")
    session.execute(select(BreakerRow.id).where(BreakerRow.id == breaker_id).with_for_update())
    row = MaintenanceEventRow(breaker_id=breaker_id, kind=kind, done_at=done_at, done_by=done_by.strip()[:200],
                              note=note, parameters=params, recorded_by=recorded_by[:200], recorded_at=now)
    session.add(row)
    for parameter in settings.watched:
        state_row, state = _drift_state(session, breaker_id, parameter, settings)
        fresh, events = restart(state, kind=kind, done_at=done_at, by=row.done_by)
        if fresh is state:
            continue
        for ev in events:
            apply_alarm_event(session, breaker_id=breaker_id, event=ev)
        _save_state(session, state_row, breaker_id, fresh)
    session.flush()
    update_drift(session, breaker_id=breaker_id, settings=settings)  # the fits since then, and the prognoses
    return row


def event_dict(row: MaintenanceEventRow) -> dict:
    return {"id": row.id, "breaker_id": row.breaker_id, "kind": row.kind, "done_at": row.done_at,
            "done_by": row.done_by, "note": row.note, "parameters": list(row.parameters or []),
            "recorded_by": row.recorded_by, "recorded_at": row.recorded_at}


__all__ = ["KINDS", "MaintenanceError", "event_dict", "list_events", "record_event", "restart_time",
           "restart_times"]
