"""The breaker's alarm page: compensation state, out of service, alarm history with first-out,
shelving, and the evidence charts (service/web/evidence_plot.py). Thin handlers over
service.jobs.alarm_actions."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Form, HTTPException, Request

from service.alarms.lifecycle import MAX_SHELVE, LifecycleError
from service.display import unit
from service.jobs import alarm_actions as actions
from service.storage import crud

from .evidence_plot import evidence_charts
from .render import page
from .alarm_values import alarm_values
from .handlers import AdminPost, Id, OperatorPost, Reader, back, db_session

router = APIRouter(include_in_schema=False)
def _alarm(session, alarm_id: int):
    a = crud.get_alarm(session, alarm_id=alarm_id)
    if a is None:
        raise HTTPException(404, f"no alarm {alarm_id}")
    return a


def _breaker(session, breaker_id: int):
    b = crud.get_breaker(session, breaker_id=breaker_id)
    if b is None:
        raise HTTPException(404, f"no breaker {breaker_id}")
    return b


@router.get("/breakers/{breaker_id}/alarms")
def breaker_alarms_page(request: Request, breaker_id: Id, user: Reader):
    settings = request.app.state.settings.drift_settings
    with db_session(request) as session:
        b = _breaker(session, breaker_id)
        settings = settings.for_breaker(b.name)
        evidence = {p: actions.evidence(session, breaker_id=b.id, parameter=p, settings=settings, limit=400)
                    for p in settings.watched}
        history = list(reversed(actions.history(session, breaker_id=b.id)))
        from service.storage.crud_vibration import WATCHABLE

        ctx = {"b": b, "nav": "alarms", "history": history, "vibration_read": WATCHABLE,
               "alarm_values": alarm_values(session, [h["alarm"] for h in history]),
               "compensation": actions.compensation(session, breaker_id=b.id, settings=settings),
               "evidence": evidence, "plots": {p: evidence_charts(e, unit(p)) for p, e in evidence.items()},
               "max_shelve_h": int(MAX_SHELVE.total_seconds() // 3600)}
        return page(request, "breaker_alarms.html", ctx)


def _done(request: Request, breaker_id: int, call):
    try:
        call()
    except LifecycleError as exc:
        raise HTTPException(409, str(exc)) from None
    return back(request, f"/breakers/{breaker_id}/alarms")


@router.post("/alarms/{alarm_id}/shelve")
def shelve(request: Request, alarm_id: Id, user: OperatorPost,
           hours: Annotated[float, Form(gt=0, le=MAX_SHELVE.total_seconds() / 3600)],
           reason: Annotated[str, Form(min_length=3, max_length=500)]):
    with db_session(request) as session:
        a = _alarm(session, alarm_id)
        resp = _done(request, a.breaker_id, lambda: actions.shelve(session, alarm=a, by=user.name,
                                                                    minutes=hours * 60, reason=reason))
        session.commit()
        return resp


@router.post("/alarms/{alarm_id}/unshelve")
def unshelve(request: Request, alarm_id: Id, user: OperatorPost,
             reason: Annotated[str, Form(max_length=500)] = ""):
    with db_session(request) as session:
        a = _alarm(session, alarm_id)
        resp = _done(request, a.breaker_id, lambda: actions.unshelve(session, alarm=a, by=user.name, reason=reason))
        session.commit()
        return resp


@router.post("/breakers/{breaker_id}/out-of-service")
def out_of_service(request: Request, breaker_id: Id, user: OperatorPost,
                   reason: Annotated[str, Form(min_length=3, max_length=500)]):
    with db_session(request) as session:
        b = _breaker(session, breaker_id)
        resp = _done(request, b.id, lambda: actions.take_out_of_service(session, breaker=b, by=user.name,
                                                                         reason=reason))
        session.commit()
        return resp


@router.post("/breakers/{breaker_id}/return-to-service")
def return_to_service(request: Request, breaker_id: Id, user: AdminPost,
                      reason: Annotated[str, Form(max_length=500)] = ""):
    settings = request.app.state.settings.drift_settings
    with db_session(request) as session:
        b = _breaker(session, breaker_id)
        resp = _done(request, b.id, lambda: actions.return_to_service(session, breaker=b, by=user.name,
                                                                       reason=reason, settings=settings))
        session.commit()
        return resp
