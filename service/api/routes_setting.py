"""The spring setting of a close–open pair and the breaker's commissioning pair (issue 39,
docs/pairs.md): ``GET /operations/{id}/setting``, ``GET`` and ``POST
/breakers/{name}/commissioning``."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, HTTPException
from fastapi import Path as PathParam
from pydantic import BaseModel, Field

from service.storage import crud
from service.storage.spring_references import (
    NoPair,
    current_reference,
    record_reference,
    reference_dict,
    setting_of,
)

from . import schemas as s
from .refs import NumberOnly
from .deps import OperatorDep, ReaderDep, SessionDep
from .routes_alarms import _breaker_ref

router = APIRouter(prefix="/api/v1", tags=["spring setting"])
BreakerRef = Annotated[str, PathParam(min_length=1, max_length=120, description="breaker name, tag or id")]
OperationId = Annotated[int, PathParam(ge=1, le=2**31 - 1, description="operation id")]
ERRORS = {401: {"model": s.Message, "description": "no or unknown API key"},
          403: {"model": s.Message, "description": "the key's role may not do this"},
          404: {"model": s.Message, "description": "no such breaker or operation"}}


class PairReading(BaseModel):
    steps: float = Field(description="nut steps from the design seat, for the design's spring rate")
    friction: float = Field(description="friction factor (1 = the design's TOf and TCf)")
    sd_steps: float | None = None
    sd_friction: float | None = None


class Commissioning(BaseModel):
    id: int
    breaker_id: int
    opening_id: int
    closing_id: int
    known_steps: float = Field(description="the nut setting the pair was recorded at [steps from the design seat]")
    reading: PairReading = Field(description="the pair's own reading from the design seat")
    recorded_by: str
    recorded_at: s.UtcTime


class CommissionRequest(BaseModel):
    # a JSON number only (false is not 0 steps, "3" is not 3; the schema says number)
    operation_id: Annotated[int, NumberOnly] = Field(ge=1, le=2**31 - 1, description="either half of the close–open pair")
    known_steps: Annotated[float, NumberOnly] = Field(ge=-50, le=50, allow_inf_nan=False,
                                                      description="its nut setting [steps from the design seat]")


class SettingPublic(BaseModel):
    status: str = Field(description='"ok", or "none" (no fitted close–open pair: why in reason)')
    reason: str | None = None
    steps: float | None = Field(None, description="nut setting [steps from the design seat]")
    sd_steps: float | None = None
    ci95: list[float] | None = Field(None, description="95 % interval [steps]")
    nearest: int | None = None
    friction: float | None = None
    sd_friction: float | None = None
    kO_sd_steps: float | None = Field(None, description="the part of sd_steps from the unit's unknown spring "
                                                       "rate (0 with a commissioning pair)")
    basis: str | None = None
    opening_id: int | None = None
    closing_id: int | None = None
    reference: Commissioning | None = None


@router.get("/operations/{operation_id}/setting", response_model=SettingPublic, responses=ERRORS)
def operation_setting(operation_id: OperationId, session: SessionDep, _: ReaderDep):
    """The opening spring's nut setting and the friction from the operation's close–open pair
    (the breaker's nearest operation of the other kind within 15 minutes)."""
    op = crud.get_operation(session, operation_id=operation_id)
    if op is None:
        raise HTTPException(404, f"no operation {operation_id}")
    out = setting_of(session, op, crud.breaker_model(crud.get_breaker(session, breaker_id=op.breaker_id)))
    if out.get("ci95") is not None:
        out["ci95"] = list(out["ci95"])
    return SettingPublic(**{k: v for k, v in out.items() if k in SettingPublic.model_fields})


@router.get("/breakers/{name}/commissioning", response_model=Commissioning, responses=ERRORS)
def get_commissioning(name: BreakerRef, session: SessionDep, _: ReaderDep):
    """The breaker's commissioning pair: the reference its pairs' settings are read against."""
    b = _breaker_ref(session, name)
    row = current_reference(session, b.id)
    if row is None:
        raise HTTPException(404, f"{b.name} has no commissioning pair: record one with POST "
                                 f"/api/v1/breakers/{b.name}/commissioning or `hvcb commission`")
    return reference_dict(row)


@router.post("/breakers/{name}/commissioning", response_model=Commissioning, status_code=201,
             responses={**ERRORS, 409: {"model": s.Message, "description": "the operation has no fitted close–open "
                                                                             "partner, or is another breaker's"}})
def post_commissioning(name: BreakerRef, body: CommissionRequest, session: SessionDep, who: OperatorDep):
    """Record a close–open pair, recorded at a known nut setting, as the breaker's commissioning
    pair: its spring rate's offset is then removed from every later pair's setting."""
    b = _breaker_ref(session, name)
    op = crud.get_operation(session, operation_id=body.operation_id)
    if op is None:
        raise HTTPException(404, f"no operation {body.operation_id}")
    if op.breaker_id != b.id:
        raise HTTPException(409, f"operation {op.id} is not {b.name}'s")
    try:
        row = record_reference(session, op, crud.breaker_model(b), known_steps=body.known_steps,
                               by=f"{who.name} (api)")
    except NoPair as exc:
        raise HTTPException(409, str(exc)) from None
    session.commit()
    return reference_dict(row)
