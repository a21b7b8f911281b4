"""Recording an entry of the engineer's maintenance log: store it, restart the drift detectors of
the parameters it touches at the time the work was done, feed the fits since then again and
recompute the prognoses (the log's storage: service/storage/maintenance.py)."""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import select
from sqlalchemy.orm import Session

from service.alarms.maintenance import MaintenanceError, restart, touched
from service.storage.maintenance import NOTE_MAX
from service.storage.models import BreakerRow, MaintenanceEventRow, utcnow

from .fit import _drift_state, _save_state, apply_alarm_event, breaker_settings, update_drift


def record_event(session: Session, *, breaker_id: int, kind: str, done_at: datetime | None, done_by: str,
                 note: str = "", recorded_by: str, settings) -> MaintenanceEventRow:
    """Log ``kind`` done at ``done_at`` (now when None) by ``done_by`` and restart what it touches.
    MaintenanceError in words for an unknown kind, a time in the future, or an empty name."""
    params = list(touched(kind))
    now = utcnow()
    done_at = now if done_at is None else done_at
    if done_at.tzinfo is None:
        raise MaintenanceError("the time the work was done needs a time zone (e.g. 2026-03-01T09:00:00Z)")
    if done_at.year < 1970:  # before any breaker's monitoring: a typing slip, not a date
        raise MaintenanceError(f"the work cannot be logged as done in {done_at.year}: give the date it was done")
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
    settings = breaker_settings(session, breaker_id, settings)
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
