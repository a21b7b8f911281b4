"""The pages: thin handlers that read through crud/crud_web and render a template.

Page URLs sit at the root (``/``, ``/breakers/1``, ...); the JSON the charts and the live
updates fetch sits under ``/ui/``. Both authenticate with the session cookie, never X-API-Key.
"""

from __future__ import annotations

import asyncio
import io
import zipfile
from datetime import timedelta
from typing import Annotated

from fastapi import APIRouter, Depends, File, Form, HTTPException, Query, Request, UploadFile
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import JSONResponse, RedirectResponse, Response
from sqlalchemy.exc import IntegrityError
from starlette.background import BackgroundTask

from drivers.capture import CaptureError
from service.mechanics.nomenclature import CLOSING, OPENING, UNITS
from service.storage import crud, crud_web
from service.storage.crud_alarms import annunciated
from service.storage.models import DiagnosisRow, utcnow

from . import auth
from .alarm_values import alarm_values
from .auth import WebAuthError, WebUser
from .handlers import (MAX_ID, AdminPost, Id, OperatorPost, Reader, ReaderPost, back, db_session,
                       form_temperature, not_found, safe_next)
from .render import page, security_headers
from .series import CHARACTERISTICS, operation_curves, spark_axis, sparkline


router = APIRouter(include_in_schema=False)

PER_PAGE = 50


# -- sign-in -----------------------------------------------------------------------------------
@router.get("/signin")
def signin_form(request: Request, next: str = "/"):
    return _signin_page(request, next=next)


def _signin_page(request: Request, *, next: str = "/", error: str | None = None, status: int = 200):
    cookie, csrf = request.app.state.web_signer.pre_cookie()
    resp = page(request, "signin.html", {"next": safe_next(next), "error": error, "signin_csrf": csrf},
                status_code=status)
    auth.set_cookie(resp, request, auth.PRE_COOKIE, cookie, max_age=auth.PRE_MAX_AGE_S, path="/signin")
    return resp


@router.post("/signin")
async def signin(request: Request, api_key: Annotated[str, Form(max_length=400)] = "",
                 csrf_token: Annotated[str, Form(max_length=200)] = "", next: Annotated[str, Form()] = "/"):
    if not request.app.state.web_signer.check_pre(request.cookies.get(auth.PRE_COOKIE), csrf_token):
        return _signin_page(request, next=next, error="the sign-in form expired: try again", status=403)
    if not api_key.strip():
        return _signin_page(request, next=next, error="enter your API key", status=401)
    from .auth import client_address

    throttle, address = request.app.state.auth_throttle, client_address(request.scope)
    wait = throttle.blocked_for(address)
    try:
        cookie, _ = await run_in_threadpool(auth.sign_in, request, api_key)
    except WebAuthError as exc:
        if wait > 0:  # a blocked address learns nothing more than "wait"; a right key still gets in
            resp = _signin_page(request, next=next, status=429,
                                error=f"too many wrong keys from this address: try again in {wait:.0f} s")
            resp.headers["Retry-After"] = str(max(1, round(wait)))
            return resp
        if exc.kind == "signin" and exc.message.startswith("unknown"):
            delay = throttle.failed(address, "sign-ins")
            if delay:
                await asyncio.sleep(delay)
        return _signin_page(request, next=next, error=exc.message, status=401)
    if wait == 0:  # a right key from a blocked address does not unblock the others behind it
        throttle.succeeded(address)
    # a new session on every sign-in; the one this browser carried before ends now (D15)
    await run_in_threadpool(auth.end_presented_session, request)
    resp = RedirectResponse(safe_next(next), status_code=303)
    auth.set_cookie(resp, request, auth.COOKIE, cookie, max_age=int(request.app.state.web_signer.lifetime_s))
    resp.delete_cookie(auth.PRE_COOKIE, path="/signin")
    security_headers(resp)
    return resp


@router.post("/signout")
async def signout(request: Request, user: ReaderPost):
    await run_in_threadpool(auth.sign_out, request, user)
    resp = RedirectResponse("/signin", status_code=303)
    resp.delete_cookie(auth.COOKIE, path="/")
    security_headers(resp)
    return resp


# -- fleet -------------------------------------------------------------------------------------
def breaker_status(session, breaker_id: int, settings, alarms) -> str:
    """ok / warning / alarm / unknown, as the API's health endpoint says."""
    from service.jobs.fit import drift_status

    status = drift_status(session, breaker_id=breaker_id, settings=settings.drift_settings)
    if not alarms and not crud_web.has_done_fit(session, breaker_id=breaker_id):
        return "unknown"
    return status


def daq_states(session, settings) -> dict[int, dict]:
    """breaker id -> DAQ link state, from the same table and freshness rule as /healthz."""
    now, timeout = utcnow(), timedelta(seconds=settings.daq_timeout_s)
    out = {}
    for d in crud.daq_statuses(session):
        fresh = d.last_seen is not None and now - d.last_seen <= timeout
        out[d.breaker_id] = {"connected": bool(d.connected and fresh), "last_seen": d.last_seen,
                             "frames_dropped": d.frames_dropped, "crc_errors": d.crc_errors,
                             "captures": d.captures, "detail": d.detail,
                             "stale": d.connected and not fresh}
    return out


def _fleet(session, settings) -> list[dict]:
    from service.jobs.prognosis import soonest_by_breaker, soonest_texts

    daq, now, soonest = daq_states(session, settings), utcnow(), soonest_by_breaker(session)
    soonest_words = soonest_texts(session)
    rows = []
    for b in crud.list_breakers(session):
        active = crud.list_alarms(session, state="active", breaker_id=b.id)
        alarms = annunciated(active, now)
        latest = {}
        for name in ("DO", "BO"):
            vals = crud_web.recent_values(session, breaker_id=b.id, name=name, limit=30)
            if vals:
                t, v, lo, hi = vals[-1]
                trend = [x[1] for x in vals]
                axis = spark_axis(trend)
                latest[name] = {"value": v, "lo": lo, "hi": hi, "time": t, "unit": UNITS[name],
                                "spark": sparkline(trend, axis=axis), "axis": axis, "n": len(trend)}
        rows.append({"breaker": b, "status": breaker_status(session, b.id, settings, alarms),
                     "last": crud_web.last_operation_times(session, breaker_id=b.id), "latest": latest,
                     "alarms": alarms, "shelved": [a for a in active if a not in alarms], "daq": daq.get(b.id),
                     "soonest": soonest.get(b.id), "soonest_text": soonest_words.get(b.id)})
    # the soonest expected crossing of a maintenance limit first (a stable sort keeps the rest's order)
    return sorted(rows, key=lambda r: (r["soonest"] is None or r["soonest"][1] is None,
                                       r["soonest"][1] if r["soonest"] and r["soonest"][1] is not None else 0.0))


@router.get("/")
def fleet(request: Request, user: Reader):
    settings = request.app.state.settings
    with db_session(request) as session:
        rows = _fleet(session, settings)
    resp = page(request, "fleet.html", {"rows": rows, "nav": "fleet"})  # rendered with the connection back
    # engineers go from here to a breaker: have its trends ready (a long history takes a moment)
    resp.background = BackgroundTask(request.app.state.web_trends.warm, request.app.state.Session,
                                     [r["breaker"].id for r in rows], settings)
    return resp


# -- breaker -----------------------------------------------------------------------------------
@router.get("/breakers/{breaker_id}")
def breaker_page(request: Request, breaker_id: Id, user: Reader,
                 page_no: Annotated[int, Query(alias="page", ge=1, le=10**6)] = 1):
    settings = request.app.state.settings
    with db_session(request) as session:
        b = crud.get_breaker(session, breaker_id=breaker_id) or not_found(f"breaker {breaker_id}")
        alarms = crud.list_alarms(session, state="active", breaker_id=b.id)
        ops, total = crud_web.operations_page(session, breaker_id=b.id, page=page_no, per_page=PER_PAGE)
        pages = max(1, -(-total // PER_PAGE))
        ctx = {"b": b, "status": breaker_status(session, b.id, settings, alarms), "alarms": alarms,
               "ops": ops, "total": total, "page_no": page_no, "pages": pages,
               "daq": daq_states(session, settings).get(b.id),
               "last": crud_web.last_operation_times(session, breaker_id=b.id),
               "watched": dict(settings.drift_settings.watched), "nav": "fleet",
               "OPENING": OPENING, "CLOSING": CLOSING, "CHARACTERISTICS": CHARACTERISTICS,
               "alarm_values": alarm_values(session, alarms),
               "shelved": [a for a in alarms if a not in annunciated(alarms, utcnow())]}
        from .routes_diagnoses import breaker_diagnosis_context

        ctx.update(breaker_diagnosis_context(request, session, b))
        from .routes_maintenance import maintenance_context  # issue 50: the maintenance log card

        ctx.update(maintenance_context(session, b))
    return page(request, "breaker.html", ctx)  # rendered with the connection back


@router.get("/ui/breakers/{breaker_id}/trends.json")
def breaker_trends(request: Request, breaker_id: Id, user: Reader):
    """Every parameter with its CI, the baseline, the drift statistic and alarm markers; the
    travel characteristics. One request for the whole breaker page (service/web/trends.py)."""
    with db_session(request) as session:
        b = crud.get_breaker(session, breaker_id=breaker_id) or not_found(f"breaker {breaker_id}")
        body = request.app.state.web_trends.body(session, b, request.app.state.settings)
    return security_headers(Response(body, media_type="application/json"))


@router.post("/breakers/{breaker_id}/baseline/reset")
def reset_baseline(request: Request, breaker_id: Id, user: AdminPost,
                   reason: Annotated[str, Form(min_length=1, max_length=500)],
                   confirm: Annotated[str, Form()] = ""):
    from service.jobs.fit import reset_baseline as reset

    settings = request.app.state.settings
    if confirm != "yes":
        raise HTTPException(400, "tick the confirmation box to reset the baseline")
    with db_session(request) as session:
        crud.get_breaker(session, breaker_id=breaker_id) or not_found(f"breaker {breaker_id}")
        reset(session, breaker_id=breaker_id, by=f"{user.name} (web: {reason})", settings=settings.drift_settings)
        session.commit()
    return back(request, f"/breakers/{breaker_id}")


# -- operation ---------------------------------------------------------------------------------
@router.get("/operations/{operation_id}")
def operation_page(request: Request, operation_id: Id, user: Reader):
    with db_session(request) as session:
        op = crud.get_operation(session, operation_id=operation_id) or not_found(f"operation {operation_id}")
        b = crud.get_breaker(session, breaker_id=op.breaker_id)
        diag = crud_web.get_diagnosis(session, operation_id=op.id)
        from service.storage.retention import get_preview

        pruned = get_preview(session, operation_id=op.id)
        names = OPENING if op.kind == "open" else CLOSING
        from service.acquisition.comtrade_writer import stored_analyser_results, stored_masked_spans

        from service.storage.spring_references import setting_of

        from .diagnosis_view import view as diagnosis_view

        analyser = stored_analyser_results(op.capture_path) if op.capture_path else None
        ctx = {"op": op, "b": b, "fit": op.fit, "diag": diag, "names": names, "units": UNITS,
               "CHARACTERISTICS": CHARACTERISTICS, "nav": "fleet", "pruned": pruned,
               "analyser": analyser_table(analyser),
               "masked": stored_masked_spans(op.capture_path) if op.capture_path else [],
               "setting": setting_of(session, op, crud.breaker_model(b)),
               "diag_view": diagnosis_view(diag.result) if diag is not None and diag.status == "done" else None}
    return page(request, "operation.html", ctx)  # rendered with the connection back


def analyser_table(analyser: dict | None) -> dict | None:
    """The analyser's own results as rows (result, unit, value per channel) for the page."""
    if not analyser or not analyser.get("results"):
        return None
    rows, channels = [], []
    for name, values in analyser["results"].items():
        values = values if isinstance(values, dict) else {"": values}
        shown = {k: v for k, v in values.items() if isinstance(v, (int, float)) and v != 0}
        for k in shown:
            if k not in channels:
                channels.append(k)
        base, _, unit = name.rpartition("_m_s") if name.endswith("_m_s") else name.rpartition("_")
        label, unit = (base, "m/s") if name.endswith("_m_s") else (base, unit)
        rows.append({"label": label.replace("_", " "), "unit": {"a": "A"}.get(unit, unit), "cells": shown})
    return {"profile": analyser.get("profile"), "rows": rows, "channels": channels,
            "station": (analyser.get("metadata") or {}).get("station"),
            "breaker_type": (analyser.get("metadata") or {}).get("breaker_type")}


@router.get("/ui/operations/{operation_id}/curves.json")
def operation_curves_json(request: Request, operation_id: Id, user: Reader):
    from service.acquisition.capture_file import read_stored_capture

    with db_session(request) as session:
        op = crud.get_operation(session, operation_id=operation_id) or not_found(f"operation {operation_id}")
        breaker = crud.breaker_model(crud.get_breaker(session, breaker_id=op.breaker_id))
        fit, path = op.fit, op.capture_path
    # the file is read and the curves computed with the connection back in the pool
    try:
        cap = read_stored_capture(path, breaker)
    except CaptureError as exc:
        with db_session(request) as session:
            cap = _pruned_preview(session, op.id)
        if cap is None:
            from service.errors import redact_paths

            return security_headers(JSONResponse({"detail": f"the capture file is not readable: "
                                                            f"{redact_paths(str(exc))}"}, status_code=410))
    body = operation_curves(cap, fit, breaker)
    if getattr(cap, "note", None):
        body["note"] = cap.note
    body.update(operation_id=operation_id, kind=op.kind, fit_status=fit.status if fit else None)
    from service.estimation.analyser_compare import record_view  # coil currents, DCRM, the analyser's figures

    body.update(record_view(cap, op.kind, breaker, fit))
    return security_headers(JSONResponse(body))


def _pruned_preview(session, operation_id: int):
    """The decimated preview of a raw capture the retention policy removed, shaped like a capture."""
    from types import SimpleNamespace

    import numpy as np

    from service.storage.retention import get_preview

    row = get_preview(session, operation_id=operation_id)
    if row is None or not row.preview.get("t"):
        return None
    p = row.preview
    return SimpleNamespace(t=np.asarray(p["t"], float), travel=np.asarray(p["travel"], float),
                           vibration=None if p.get("vibration") is None else np.asarray(p["vibration"], float),
                           sample_rate=p["sample_rate"],
                           note=f"raw capture pruned on {row.pruned_at:%Y-%m-%d} by the retention policy: "
                                f"a min/max preview of {len(p['t'])} of its {p['n_samples']} samples is shown")


@router.post("/operations/{operation_id}/diagnosis")
def request_diagnosis(request: Request, operation_id: Id, user: ReaderPost):
    """Queue the gap diagnosis (as the API's GET does for any reader); the page polls for it."""
    with db_session(request) as session:
        crud.get_operation(session, operation_id=operation_id) or not_found(f"operation {operation_id}")
        row = crud_web.get_diagnosis(session, operation_id=operation_id)
        if row is None:
            try:
                session.add(DiagnosisRow(operation_id=operation_id, status="queued"))
                session.commit()
            except IntegrityError:  # a concurrent request queued it first
                session.rollback()
            row = crud_web.get_diagnosis(session, operation_id=operation_id)
        if row.status in ("queued", "running"):
            request.app.state.diagnoses.ensure(operation_id)
    return back(request, f"/operations/{operation_id}#diagnosis")


@router.get("/operations/{operation_id}/capture.zip")
def download_capture(request: Request, operation_id: Id, user: Reader):
    from service.storage.spool import capture_files

    with db_session(request) as session:
        op = crud.get_operation(session, operation_id=operation_id) or not_found(f"operation {operation_id}")
        files = capture_files(op.capture_path)
    missing = [p.name for p in files if not p.is_file()]
    if missing:
        raise HTTPException(410, f"the capture file is no longer stored ({', '.join(missing)})")
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        for p in files:
            zf.write(p, arcname=f"operation-{operation_id}{p.suffix.lower()}")
    resp = Response(buf.getvalue(), media_type="application/zip",
                    headers={"Content-Disposition": f'attachment; filename="operation-{operation_id}.zip"'})
    return security_headers(resp)


# -- alarms ------------------------------------------------------------------------------------
@router.get("/alarms")
def alarms_page(request: Request, user: Reader, state: Annotated[str, Query(pattern="^(active|all)$")] = "active"):
    with db_session(request) as session:
        rows = crud_web.alarms_with_breakers(session, state=state)
        values = alarm_values(session, [a for a, _ in rows])
    return page(request, "alarms.html", {"rows": rows, "state": state, "nav": "alarms", "values": values})


@router.post("/alarms/{alarm_id}/ack")
def acknowledge(request: Request, alarm_id: Id, user: OperatorPost,
                comment: Annotated[str, Form(max_length=500)] = ""):
    from service.jobs.fit import acknowledge_drift

    settings = request.app.state.settings
    with db_session(request) as session:
        alarm = crud.get_alarm(session, alarm_id=alarm_id) or not_found(f"alarm {alarm_id}")
        if alarm.state == "cleared":
            raise HTTPException(409, f"alarm {alarm_id} is already cleared")
        if alarm.state == "raised":
            crud.acknowledge_alarm(session, alarm=alarm, by=user.name, comment=comment.strip() or None)
            acknowledge_drift(session, alarm=alarm, by=user.name, settings=settings.drift_settings)
            session.commit()
    return back(request, "/alarms")


# -- upload ------------------------------------------------------------------------------------
@router.get("/upload")
def upload_form(request: Request, user: Annotated[WebUser, Depends(auth.require_page("operator"))]):
    with db_session(request) as session:
        breakers = crud.list_breakers(session)
    return page(request, "upload.html", {"breakers": breakers, "nav": "upload"})


@router.post("/upload")
async def upload(request: Request, user: OperatorPost,
                 breaker_id: Annotated[int, Form(ge=1, le=MAX_ID)],
                 files: Annotated[list[UploadFile], File()],
                 operation: Annotated[str, Form(pattern="^(auto|open|close)$")] = "auto",
                 temperature_c: Annotated[str, Form(max_length=20)] = ""):
    from service.jobs.upload import UploadRefused, ingest_upload, parse_upload

    settings = request.app.state.settings

    def form_error(message: str, status: int):
        with db_session(request) as session:
            breakers = crud.list_breakers(session)
        return page(request, "upload.html", {"breakers": breakers, "nav": "upload", "error": message,
                                             "chosen": breaker_id}, status_code=status)

    def breaker_row():
        with db_session(request) as session:
            return crud.get_breaker(session, breaker_id=breaker_id)

    try:
        row = await run_in_threadpool(breaker_row)
        if row is None:
            return await run_in_threadpool(form_error, f"there is no breaker {breaker_id}", 422)
        temp = form_temperature(temperature_c)
        upload = await parse_upload(request.app.state, files, row, None if operation == "auto" else operation)
    except (UploadRefused, HTTPException) as exc:
        return await run_in_threadpool(form_error, str(exc.detail), exc.status_code)
    if temp is not None:
        upload.capture.meta["temperature_c"], upload.capture.meta["temperature_source"] = temp, "upload"
    result = await run_in_threadpool(ingest_upload, request.app.state.monitor, settings, upload,
                                     breaker_id=breaker_id, source="upload", capture_key=None)
    if result.operation_id is None:
        return await run_in_threadpool(form_error, "the database is unavailable: the capture is kept in the spool "
                                       "and will be stored and fitted when it answers again", 202)
    return security_headers(RedirectResponse(f"/operations/{result.operation_id}", status_code=303))


# -- live updates ------------------------------------------------------------------------------
@router.get("/ui/marker")
def marker(request: Request, user: Reader):
    """Changes whenever something a page shows changes; pages poll it and refresh their parts."""
    with db_session(request) as session:
        m = crud_web.change_marker(session)
    return security_headers(JSONResponse({"marker": m}))
