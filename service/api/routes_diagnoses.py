"""/api/v1/breakers/{breaker}/diagnoses: the gap diagnosis of a breaker's stored history (issue 20).

Any reader may ask (as for the per-operation diagnosis); the job runs in the worker pool and the
request is bounded per caller (service/jobs/breaker_diagnosis.py says the numbers and why).
"""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import APIRouter, HTTPException, Path as PathParam, Query, Request
from fastapi.responses import JSONResponse
from pydantic import BaseModel, ConfigDict, Field

from service.errors import UserError
from service.jobs.breaker_diagnosis import (MAX_LAST, MIN_LAST, NothingToDiagnose, QueueFull, queue_diagnosis,
                                            summary)
from service.storage import crud, crud_diagnoses

from .deps import ReaderDep, SessionDep
from .refs import NumberOnly
from .schemas import Message, UtcTime

router = APIRouter(prefix="/api/v1", tags=["diagnoses"])

BreakerRef = Annotated[str, PathParam(min_length=1, max_length=120,
                                      description="breaker name (or its numeric id)")]
DiagnosisId = Annotated[int, PathParam(ge=1, le=2_147_483_647, description="diagnosis id")]
AUTH = {401: {"model": Message}, 403: {"model": Message}}
NOT_FOUND = {404: {"model": Message}}


class BreakerDiagnosisCreate(BaseModel):
    operation: Literal["open", "close"] = Field(description="which stored operations: openings or closings")
    last: Annotated[int, NumberOnly] = Field(10, description=f"how many of the newest usable ones, {MIN_LAST} to {MAX_LAST}",
                      json_schema_extra={"minimum": MIN_LAST, "maximum": MAX_LAST})


class SkippedOperation(BaseModel):
    operation_id: int
    reason: str


class BreakerDiagnosisBrief(BaseModel):
    id: int
    breaker_id: int
    operation: Literal["open", "close"]
    last: int = Field(description="N asked for")
    used: int = Field(description="operations diagnosed together (fewer than N when some were left out)")
    operation_ids: list[int]
    skipped: list[SkippedOperation] = Field(description="newer operations left out, with the reason")
    summary: str
    status: Literal["queued", "running", "done", "failed"]
    diagnosis_status: str | None = Field(None, description="the answer when done: none, named, ambiguous, "
                                                           "unexplained (or what the diagnosis said)")
    effects: list[str] = Field(default_factory=list, description="named effects when done")
    failure_reason: str | None = None
    requested_by: str | None = None
    requested_at: UtcTime
    started_at: UtcTime | None = None
    finished_at: UtcTime | None = None
    url: str


class DiagnosisResult(BaseModel):
    """service.diagnosis.diagnose's answer (docs/diagnosis.md); the keys the card reads are typed,
    the rest (where, gap, parameters, ...) pass through."""

    model_config = ConfigDict(extra="allow")
    status: Literal["none", "named", "ambiguous", "unexplained"]
    answer: str = Field(description="the most probable hypothesis: effects joined by '+', 'none' or "
                                    "'outside_catalogue'")
    answer_probability: float = Field(description="the learnt scorer's probability; equals probabilities[answer]")
    raw_probability: float | None = Field(None, description="the same (kept for older readers)")
    probabilities: dict[str, float] = Field(description="every hypothesis, by the learnt scorer "
                                                        "(service/diagnosis/scorer.json); 'none' is P(no effect)")
    set: list[str] = Field(default_factory=list, description="the 90 % set: hypotheses ('none', effect names, "
                                                             "pairs as 'a+b', 'unexplained'), most probable first; "
                                                             "conformal on simulated groups (calibration_note)")
    set_members: list[dict] = Field(default_factory=list, description="[{hypothesis, probability, shrink}] per "
                                                                      "member of the set")
    effects: list[str] = Field(default_factory=list, description="the named effects (status named)")
    rivals: list[dict] = Field(default_factory=list, description="[{effect, probability}]: the set's members")
    absorbed: list[dict] = Field(default_factory=list, description="[{effect, strength, bias: {parameter: "
                                                                   "relative bias}}]")
    materiality: dict | None = Field(None, description="gap size and the fitted effects' strengths, intervals "
                                                       "and parameter biases")
    discrepancy: dict | None = Field(None, description="where the unexplained part lies (phases, peak, shape)")


class BreakerDiagnosisPublic(BreakerDiagnosisBrief):
    reused: bool = Field(False, description="an identical earlier request's diagnosis, not a new one")
    result: DiagnosisResult | dict | None = Field(None, description="service.diagnosis.diagnose's answer "
                                                                    "(docs/diagnosis.md)")


def _breaker(session, ref: str):
    row = crud.get_breaker_by_name(session, name=ref)
    if row is None and ref.isdigit() and int(ref) <= 2_147_483_647:
        row = crud.get_breaker(session, breaker_id=int(ref))
    if row is None:
        raise HTTPException(404, f"no breaker named {ref!r}")
    return row


def _url(row) -> str:
    return f"/api/v1/breakers/{row.breaker_id}/diagnoses/{row.id}"


def _brief(row) -> dict:
    result = row.result or {}
    effects = result.get("effects")
    if not isinstance(effects, list):
        verdict = result.get("verdict")
        effects = [verdict] if isinstance(verdict, str) and verdict not in ("none", "unexplained") else []
    return dict(id=row.id, breaker_id=row.breaker_id, operation=row.operation, last=row.last_n,
                used=len(row.operation_ids or []), operation_ids=list(row.operation_ids or []),
                skipped=list(row.skipped or []), summary=summary(row), status=row.status,
                diagnosis_status=result.get("status") if row.status == "done" else None,
                effects=[str(e) for e in effects] if row.status == "done" else [],
                failure_reason=row.failure_reason, requested_by=row.requested_by, requested_at=row.requested_at,
                started_at=row.started_at, finished_at=row.finished_at, url=_url(row))


def public(row, *, reused: bool = False) -> BreakerDiagnosisPublic:
    return BreakerDiagnosisPublic(**_brief(row), reused=reused, result=row.result if row.status == "done" else None)


@router.post("/breakers/{breaker}/diagnoses", response_model=BreakerDiagnosisPublic, status_code=202,
             responses={**AUTH, **NOT_FOUND,
                        200: {"model": BreakerDiagnosisPublic,
                              "description": "an identical request (same operations) was queued or done before"},
                        422: {"model": Message}, 429: {"model": Message, "description": "queue bound reached"}})
def request_breaker_diagnosis(breaker: BreakerRef, body: BreakerDiagnosisCreate, request: Request,
                              session: SessionDep, who: ReaderDep):
    """Diagnose the sim-to-real gap of the breaker's last ``last`` stored ``operation``s together
    (any reader). Answers 202 with the diagnosis and its ``Location``; follow it until ``status``
    is done or failed. Operations flagged ``clock suspect`` and those whose raw capture was pruned
    are left out (``skipped`` says which and why)."""
    row = _breaker(session, breaker)
    try:
        diag, created = queue_diagnosis(session, breaker=row, kind=body.operation, last=body.last, who=who)
    except QueueFull as exc:
        return JSONResponse({"detail": str(exc)}, status_code=429,
                            headers={"Retry-After": str(exc.retry_after_s)})
    except (NothingToDiagnose, UserError) as exc:
        raise HTTPException(422, str(exc)) from None
    out = public(diag, reused=not created)
    if created:
        request.app.state.breaker_diagnoses.submit(diag.id)
    elif diag.status in ("queued", "running"):
        request.app.state.breaker_diagnoses.ensure(diag.id)
    return JSONResponse(out.model_dump(mode="json"), status_code=202 if created else 200,
                        headers={"Location": out.url})


@router.get("/breakers/{breaker}/diagnoses", response_model=list[BreakerDiagnosisBrief],
            responses={**AUTH, **NOT_FOUND})
def list_breaker_diagnoses(breaker: BreakerRef, session: SessionDep, _: ReaderDep,
                           limit: Annotated[int, Query(ge=1, le=100)] = 20):
    """The breaker's recent diagnoses, newest first (without their results)."""
    row = _breaker(session, breaker)
    return [BreakerDiagnosisBrief(**_brief(d)) for d in crud_diagnoses.recent(session, breaker_id=row.id, limit=limit)]


@router.get("/breakers/{breaker}/diagnoses/{diagnosis_id}", response_model=BreakerDiagnosisPublic,
            responses={**AUTH, **NOT_FOUND})
def get_breaker_diagnosis(breaker: BreakerRef, diagnosis_id: DiagnosisId, request: Request, session: SessionDep,
                          _: ReaderDep):
    """One diagnosis: ``status`` queued, running, done (with ``result``) or failed (with
    ``failure_reason`` in words)."""
    row = _breaker(session, breaker)
    diag = crud_diagnoses.get(session, breaker_id=row.id, diagnosis_id=diagnosis_id)
    if diag is None:
        raise HTTPException(404, f"breaker {row.name!r} has no diagnosis {diagnosis_id}")
    if diag.status in ("queued", "running"):
        request.app.state.breaker_diagnoses.ensure(diag.id)  # after a restart of a local pool
    return public(diag)
