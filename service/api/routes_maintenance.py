"""The engineer's maintenance log (issue 50, docs/alarms.md "Maintenance log"): ``GET`` and
``POST /api/v1/breakers/{name}/maintenance``. An entry restarts the baseline, the alarms and
the prognosis of the parameters it touches at the time the work was done."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Literal

from fastapi import APIRouter, HTTPException
from fastapi import Path as PathParam
from pydantic import BaseModel, ConfigDict, Field

from service.alarms.maintenance import KINDS, MaintenanceError
from service.jobs.maintenance import record_event
from service.storage.maintenance import event_dict, list_events

from . import schemas as s
from .deps import OperatorDep, ReaderDep, SessionDep, SettingsDep
from .refs import IsoOnly
from .routes_alarms import _breaker_ref

router = APIRouter(prefix="/api/v1", tags=["maintenance log"])
BreakerRef = Annotated[str, PathParam(min_length=1, max_length=120, description="breaker name, tag or id")]
ERRORS = {401: {"model": s.Message, "description": "no or unknown API key"},
          403: {"model": s.Message, "description": "the key's role may not do this"},
          404: {"model": s.Message, "description": "no such breaker"}}
Kind = Literal[tuple(KINDS)]  # type: ignore[valid-type]


class MaintenanceEvent(BaseModel):
    id: int
    breaker_id: int
    kind: str = Field(description="what was done: " + ", ".join(f'"{k}"' for k in KINDS))
    done_at: s.UtcTime = Field(description="when the work was done")
    done_by: str = Field(description="who did it")
    note: str
    parameters: list[str] = Field(description='the parameters it touches ("*": every one); their baseline, '
                                              'alarms and prognosis restart at done_at')
    recorded_by: str
    recorded_at: s.UtcTime


class MaintenanceRequest(BaseModel):
    # unknown fields are refused, and the schema says so (additionalProperties: false)
    model_config = ConfigDict(extra="forbid")

    kind: Kind = Field(description="what was done")
    done_at: Annotated[datetime | None, IsoOnly] = Field(
        None, description="when it was done: ISO 8601 with a time zone (default: now)")
    done_by: str = Field(min_length=1, max_length=200, description="who did it")
    note: str = Field("", max_length=500)


@router.get("/breakers/{name}/maintenance", response_model=list[MaintenanceEvent], responses=ERRORS)
def get_maintenance(name: BreakerRef, session: SessionDep, _: ReaderDep):
    """The breaker's maintenance log, newest first."""
    b = _breaker_ref(session, name)
    return [event_dict(r) for r in list_events(session, b.id)]


@router.post("/breakers/{name}/maintenance", response_model=MaintenanceEvent, status_code=201,
             responses={**ERRORS, 422: {"model": s.Message, "description": "an unknown kind, a time without a "
                                                                             "zone or in the future, no name"}})
def post_maintenance(name: BreakerRef, body: MaintenanceRequest, session: SessionDep, settings: SettingsDep,
                     who: OperatorDep):
    """Log maintenance work: the parameters it touches restart their baseline, alarms and
    prognosis at ``done_at`` (the fits after it form a new baseline; an active alarm of them is
    cleared)."""
    b = _breaker_ref(session, name)
    try:
        row = record_event(session, breaker_id=b.id, kind=body.kind, done_at=body.done_at, done_by=body.done_by,
                           note=body.note, recorded_by=f"{who.name} (api)", settings=settings.drift_settings)
    except MaintenanceError as exc:
        raise HTTPException(422, str(exc)) from None
    session.commit()
    return event_dict(row)
