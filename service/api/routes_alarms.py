"""Thin routes of the alarm lifecycle and temperature under /api/v1 (docs/alarms.md):
shelve / unshelve, out of service / return to service, alarm history with first-out, the
evidence series, the compensation state, and the temperature SCADA writes."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, HTTPException, Path as PathParam
from pydantic import BaseModel, Field

from service.alarms.lifecycle import MAX_SHELVE, LifecycleError
from service.jobs import alarm_actions as actions
from service.storage import crud
from service.storage.models import BreakerRow

from . import schemas as s
from .deps import AdminDep, OperatorDep, ReaderDep, SessionDep, SettingsDep
from .refs import BreakerRef, breaker_by_ref

router = APIRouter(prefix="/api/v1", tags=["alarms"])

MAX_ID = 2_147_483_647
AlarmId = Annotated[int, PathParam(ge=1, le=MAX_ID, description="alarm id")]
BreakerId = BreakerRef  # the id, the name or the tag (service/api/refs.py)
ERRORS = {401: {"model": s.Message}, 403: {"model": s.Message}, 404: {"model": s.Message},
          409: {"model": s.Message}}


class Shelve(BaseModel):
    # strict: a JSON number only (true is not 1 minute; the schema says number)
    minutes: float = Field(..., gt=0, le=MAX_SHELVE.total_seconds() / 60, strict=True,
                           description=f"how long [min], at most {MAX_SHELVE.days} days")
    reason: str = Field(..., min_length=3, max_length=2000, description="why (audited)")


class Reason(BaseModel):
    reason: str = Field("", max_length=2000)


class OutOfService(BaseModel):
    reason: str = Field(..., min_length=3, max_length=2000, description="e.g. the maintenance order")


class Temperature(BaseModel):
    temperature_c: float = Field(..., ge=-60, le=100, allow_inf_nan=False, strict=True,
                                 description="ambient or mechanism temperature now [C]")


class TemperatureState(BaseModel):
    breaker_id: int
    temperature_c: float | None
    written_at: s.UtcTime | None
    applies_for_s: float = Field(description="an operation takes it up to this long after it was written")


class ActionPublic(s.ORM):
    id: int
    breaker_id: int
    alarm_id: int | None = None
    action: str
    by: str
    at: s.UtcTime
    reason: str
    until: s.UtcTime | None = None


class AlarmLifecycle(s.AlarmPublic):
    first_out: bool = True
    shelved_until: s.UtcTime | None = None
    shelved_by: str | None = None
    shelve_reason: str | None = None


class HistoryEntry(BaseModel):
    order: int = Field(description="1 = the breaker's first alarm")
    first_out: bool = Field(description="raised while no other alarm of the breaker was active")
    shelved: bool
    alarm: AlarmLifecycle
    actions: list[ActionPublic]


class ServiceState(BaseModel):
    breaker_id: int
    in_service: bool
    out_of_service_since: s.UtcTime | None = None
    out_of_service_by: str | None = None
    out_of_service_reason: str | None = None
    alarms_cleared: int = 0


def _alarm(session, alarm_id: int):
    a = crud.get_alarm(session, alarm_id=alarm_id)
    if a is None:
        raise HTTPException(404, f"no alarm {alarm_id}")
    return a


def _breaker(session, ref: str) -> BreakerRow:
    return breaker_by_ref(session, ref)


def _breaker_ref(session, ref: str) -> BreakerRow:
    return breaker_by_ref(session, ref)


def _lifecycle(call):
    try:
        return call()
    except LifecycleError as exc:
        raise HTTPException(409, str(exc)) from None


def _service_state(b: BreakerRow, cleared: int = 0) -> ServiceState:
    return ServiceState(breaker_id=b.id, in_service=b.out_of_service_since is None,
                        out_of_service_since=b.out_of_service_since, out_of_service_by=b.out_of_service_by,
                        out_of_service_reason=b.out_of_service_reason, alarms_cleared=cleared)


@router.post("/alarms/{alarm_id}/shelve", response_model=AlarmLifecycle, responses=ERRORS)
def shelve_alarm(alarm_id: AlarmId, body: Shelve, session: SessionDep, who: OperatorDep):
    """Shelve an active alarm for a stated time with a reason (audited); it unshelves by itself."""
    a = _alarm(session, alarm_id)
    _lifecycle(lambda: actions.shelve(session, alarm=a, by=who.name, minutes=body.minutes, reason=body.reason))
    session.commit()
    return a


@router.post("/alarms/{alarm_id}/unshelve", response_model=AlarmLifecycle, responses=ERRORS)
def unshelve_alarm(alarm_id: AlarmId, session: SessionDep, who: OperatorDep, body: Reason | None = None):
    a = _alarm(session, alarm_id)
    _lifecycle(lambda: actions.unshelve(session, alarm=a, by=who.name, reason=body.reason if body else ""))
    session.commit()
    return a


@router.get("/alarms/{alarm_id}/actions", response_model=list[ActionPublic], responses=ERRORS)
def alarm_audit(alarm_id: AlarmId, session: SessionDep, _: ReaderDep):
    """Who did what to this alarm, when and why (newest first)."""
    from service.storage.crud_alarms import list_actions

    _alarm(session, alarm_id)
    return list_actions(session, alarm_id=alarm_id)


@router.get("/breakers/{breaker_id}/alarms/history", response_model=list[HistoryEntry], responses=ERRORS)
def alarm_history(breaker_id: BreakerId, session: SessionDep, _: ReaderDep):
    """Every alarm of the breaker in the order raised, first-out marked, with its audit trail."""
    breaker_id = _breaker(session, breaker_id).id
    return [HistoryEntry(order=h["order"], first_out=h["first_out"], shelved=h["shelved"],
                         alarm=AlarmLifecycle.model_validate(h["alarm"]),
                         actions=[ActionPublic.model_validate(a) for a in h["actions"]])
            for h in actions.history(session, breaker_id=breaker_id)]


@router.get("/breakers/{breaker_id}/alarms/evidence/{parameter}", responses=ERRORS)
def alarm_evidence(breaker_id: BreakerId, parameter: Annotated[str, PathParam(max_length=16)],
                   session: SessionDep, settings: SettingsDep, _: ReaderDep) -> dict:
    """The evidence plot's data: each good fit's value with the baseline's expected value and
    +-2 sigma band at its temperature, the temperature, the CUSUM and its thresholds."""
    b = _breaker(session, breaker_id)
    breaker_id, ds = b.id, settings.drift_settings.for_breaker(b.name)
    if parameter not in ds.watched:
        raise HTTPException(404, f"{parameter} is not watched for drift (watched: {', '.join(ds.watched)})")
    return actions.evidence(session, breaker_id=breaker_id, parameter=parameter, settings=ds)


@router.get("/breakers/{breaker_id}/compensation", responses=ERRORS)
def compensation(breaker_id: BreakerId, session: SessionDep, settings: SettingsDep, _: ReaderDep) -> dict:
    """Per watched parameter: "temperature-compensated" or "not temperature-compensated", and
    the temperature dependence the baseline has learnt."""
    b = _breaker(session, breaker_id)
    return {"breaker_id": b.id, "parameters": actions.compensation(session, breaker_id=b.id,
                                                                   settings=settings.drift_settings)}


@router.post("/breakers/{breaker_id}/out-of-service", response_model=ServiceState, responses=ERRORS)
def out_of_service(breaker_id: BreakerId, body: OutOfService, session: SessionDep, who: OperatorDep):
    """Maintenance starts: the breaker's fits are not watched until it returns to service."""
    b = _breaker(session, breaker_id)
    _lifecycle(lambda: actions.take_out_of_service(session, breaker=b, by=who.name, reason=body.reason))
    session.commit()
    return _service_state(b)


@router.post("/breakers/{breaker_id}/return-to-service", response_model=ServiceState, responses=ERRORS)
def return_to_service(breaker_id: BreakerId, session: SessionDep, settings: SettingsDep, who: AdminDep,
                      body: Reason | None = None):
    """Maintenance over: the breaker is watched again from a new baseline (admin: it resets it)."""
    b = _breaker(session, breaker_id)
    cleared = _lifecycle(lambda: actions.return_to_service(session, breaker=b, by=who.name,
                                                           reason=body.reason if body else "",
                                                           settings=settings.drift_settings))
    session.commit()
    return _service_state(b, cleared)


@router.put("/breakers/{breaker}/temperature", response_model=TemperatureState, responses=ERRORS)
def put_temperature(breaker: BreakerRef, body: Temperature, session: SessionDep, who: OperatorDep):
    """SCADA writes the breaker's temperature (operator key; an agent key uploads and nothing
    else: an agent sends the temperature with the capture). The latest value applies to
    operations that carry no temperature of their own, up to an hour after it was written."""
    from service.storage.crud_alarms import SCADA_TEMPERATURE_MAX_AGE

    b = _breaker_ref(session, breaker)
    try:
        actions.set_temperature(session, breaker=b, temperature_c=body.temperature_c, by=who.name)
    except ValueError as exc:
        raise HTTPException(422, str(exc)) from None
    session.commit()
    return TemperatureState(breaker_id=b.id, temperature_c=b.scada_temperature_c, written_at=b.scada_temperature_at,
                            applies_for_s=SCADA_TEMPERATURE_MAX_AGE.total_seconds())


@router.get("/breakers/{breaker}/temperature", response_model=TemperatureState, responses=ERRORS)
def get_temperature(breaker: BreakerRef, session: SessionDep, _: ReaderDep):
    from service.storage.crud_alarms import SCADA_TEMPERATURE_MAX_AGE

    b = _breaker_ref(session, breaker)
    return TemperatureState(breaker_id=b.id, temperature_c=b.scada_temperature_c, written_at=b.scada_temperature_at,
                            applies_for_s=SCADA_TEMPERATURE_MAX_AGE.total_seconds())
