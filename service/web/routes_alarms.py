"""The breaker's alarm page: compensation state, out of service, alarm history with first-out,
shelving, and the evidence plot (trend with the baseline band, temperature, CUSUM and its
thresholds). Thin handlers over service.jobs.alarm_actions; the SVG paths are computed here."""

from __future__ import annotations

import math
from typing import Annotated

from fastapi import APIRouter, Form, HTTPException, Request

from service.alarms.lifecycle import MAX_SHELVE, LifecycleError
from service.jobs import alarm_actions as actions
from service.storage import crud

from .render import page
from .alarm_values import alarm_values
from .handlers import AdminPost, Id, OperatorPost, Reader, back, db_session

router = APIRouter(include_in_schema=False)
W, H, PAD = 640.0, 150.0, 6.0


def _scale(values, lo=None, hi=None):
    got = [v for v in values if v is not None and math.isfinite(v)]
    lo = min(got) if lo is None and got else (lo if lo is not None else 0.0)
    hi = max(got) if hi is None and got else (hi if hi is not None else 1.0)
    span = (hi - lo) or abs(hi) * 1e-3 or 1.0
    return lambda v: PAD + (H - 2 * PAD) * (1 - (v - lo) / span)


def _path(xs, ys, fy) -> str:
    """SVG polyline points, broken where a value is missing."""
    parts, cur = [], []
    for x, y in zip(xs, ys):
        if y is None:
            if cur:
                parts.append(" ".join(cur))
            cur = []
        else:
            cur.append(f"{x:.1f},{fy(y):.1f}")
    if cur:
        parts.append(" ".join(cur))
    return parts


def plot(ev: dict) -> dict:
    """Polylines of the evidence series in a W x H box: value, band, temperature, CUSUM."""
    s = ev["series"]
    n = len(s["value"])
    if n == 0:
        return {}
    xs = [PAD + (W - 2 * PAD) * (i / max(n - 1, 1)) for i in range(n)]
    fv = _scale(s["value"] + [v for v in s["band_low"] + s["band_high"] if v is not None])
    th = ev["thresholds"]
    fs = _scale(s["statistic"], 0.0, max([th["alarm"] * 1.2] + [v for v in s["statistic"] if v is not None]))
    ft = _scale(s["temperature_c"])
    return {"w": W, "h": H, "value": _path(xs, s["value"], fv), "expected": _path(xs, s["expected"], fv),
            "band_low": _path(xs, s["band_low"], fv), "band_high": _path(xs, s["band_high"], fv),
            "temperature": _path(xs, s["temperature_c"], ft), "statistic": _path(xs, s["statistic"], fs),
            "warning_y": fs(th["warning"]), "alarm_y": fs(th["alarm"]), "n": n,
            "has_temperature": any(t is not None for t in s["temperature_c"])}


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
        evidence = {p: actions.evidence(session, breaker_id=b.id, parameter=p, settings=settings, limit=400)
                    for p in settings.watched}
        history = list(reversed(actions.history(session, breaker_id=b.id)))
        ctx = {"b": b, "nav": "alarms", "history": history,
               "alarm_values": alarm_values(session, [h["alarm"] for h in history]),
               "compensation": actions.compensation(session, breaker_id=b.id, settings=settings),
               "evidence": evidence, "plots": {p: plot(e) for p, e in evidence.items()},
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
