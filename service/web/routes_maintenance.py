"""The breaker page's maintenance log: the entries, and an operator's form to log one
(service/storage/maintenance.py restarts what it touches)."""

from __future__ import annotations

from datetime import datetime, timezone
from typing import Annotated

from fastapi import APIRouter, Form, HTTPException, Request

from service.alarms.maintenance import KINDS, MaintenanceError
from service.storage import crud
from service.jobs.maintenance import record_event
from service.storage.maintenance import list_events

from .handlers import Id, OperatorPost, back, db_session, not_found

router = APIRouter(include_in_schema=False)


def maintenance_context(session, breaker) -> dict:
    """What the breaker page's "Maintenance log" card shows."""
    return {"maintenance": list_events(session, breaker.id), "MAINTENANCE_KINDS": list(KINDS)}


def _when(text: str) -> datetime | None:
    """The form's time (a datetime-local field, read as UTC); None when empty (now)."""
    if not text.strip():
        return None
    try:
        t = datetime.fromisoformat(text.strip())
    except ValueError:
        raise HTTPException(422, f"the time {text!r} is not a date and time (YYYY-MM-DDTHH:MM, UTC)") from None
    return t if t.tzinfo else t.replace(tzinfo=timezone.utc)


@router.post("/breakers/{breaker_id}/maintenance")
def log_maintenance(request: Request, breaker_id: Id, user: OperatorPost,
                    kind: Annotated[str, Form(max_length=64)], done_by: Annotated[str, Form(max_length=200)],
                    done_at: Annotated[str, Form(max_length=40)] = "",
                    note: Annotated[str, Form(max_length=500)] = ""):
    with db_session(request) as session:
        b = crud.get_breaker(session, breaker_id=breaker_id) or not_found(f"breaker {breaker_id}")
        try:
            record_event(session, breaker_id=b.id, kind=kind, done_at=_when(done_at), done_by=done_by, note=note,
                         recorded_by=f"{user.name} (web)", settings=request.app.state.settings.drift_settings)
        except MaintenanceError as exc:
            raise HTTPException(422, str(exc)) from None
        session.commit()
    return back(request, f"/breakers/{breaker_id}#maintenance-log")
