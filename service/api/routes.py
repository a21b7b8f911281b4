"""Thin routes under /api/v1: validate, call a CRUD function, raise HTTPException."""

from __future__ import annotations

import time
from datetime import datetime, timedelta, timezone
from typing import Annotated, Literal

import numpy as np
from fastapi import APIRouter, File, Form, Header, HTTPException, Path as PathParam, Query, Request, UploadFile
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import Response
from sqlalchemy.exc import IntegrityError

from drivers.capture import CaptureError
from service.errors import redact_paths
from service.jobs.upload import UploadRefused, further_operations, ingest_upload, parse_upload
from service.storage import crud
from service.storage.crud_alarms import annunciated, shelved_now
from service.storage.fit_curve import fit_curve
from service.storage.models import BreakerRow, utcnow

from . import schemas as s
from .refs import BreakerRef, IsoOnly, breaker_by_ref
from .deps import AdminDep, MonitorDep, OperatorDep, ReaderDep, SessionDep, SettingsDep, UploaderDep

router = APIRouter(prefix="/api/v1")

# Row ids are 32-bit on PostgreSQL: a larger id is a 422, not a database error.
MAX_ID = 2_147_483_647
BreakerId = BreakerRef  # the id, the name or the tag (service/api/refs.py)
OperationId = Annotated[int, PathParam(ge=1, le=MAX_ID, description="operation id")]
AlarmId = Annotated[int, PathParam(ge=1, le=MAX_ID, description="alarm id")]

NOT_FOUND = {404: {"model": s.Message}}
AUTH = {401: {"model": s.Message}, 403: {"model": s.Message}}


def _breaker_or_404(session, ref: str):
    return breaker_by_ref(session, ref)


def _utc(t: datetime | None) -> datetime | None:
    if t is None:
        return None
    return t.replace(tzinfo=timezone.utc) if t.tzinfo is None else t.astimezone(timezone.utc)


# -- breakers ----------------------------------------------------------------------------------
@router.get("/breakers", response_model=list[s.BreakerPublic], responses=AUTH, tags=["breakers"])
def list_breakers(session: SessionDep, _: ReaderDep):
    return crud.list_breakers(session)


@router.get("/breakers/{breaker_id}", response_model=s.BreakerDetail, responses={**AUTH, **NOT_FOUND},
            tags=["breakers"])
def get_breaker(breaker_id: BreakerId, session: SessionDep, _: ReaderDep):
    row = _breaker_or_404(session, breaker_id)
    design = crud.breaker_model(row).design_parameters()
    return s.BreakerDetail(**s.BreakerPublic.model_validate(row).model_dump(), breaker_file=row.breaker_file,
                           cam_file_name=row.cam_file_name, design_parameters={k: float(v) for k, v in design.items()})


@router.post("/breakers", response_model=s.BreakerPublic, status_code=201, responses={**AUTH, 409: {"model": s.Message},
             422: {"model": s.Message}}, tags=["breakers"])
def create_breaker(body: s.BreakerCreate, session: SessionDep, _: AdminDep):
    from service.breaker_file import BreakerFileError, breaker_from_text, parse_breaker_text

    try:
        breaker = breaker_from_text(body.breaker_file, body.cam_table, source="(sent)")
        cam = parse_breaker_text(body.breaker_file, source="(sent)").cam  # none for an unknown design
        cam_name = cam.profile if cam is not None else ""
    except BreakerFileError as exc:
        raise HTTPException(422, f"invalid breaker file: {exc}") from None
    if parse_breaker_text(body.breaker_file, source="(sent)").name is None:
        raise HTTPException(422, "invalid breaker file: give the breaker a `name`")
    if crud.get_breaker_by_name(session, name=breaker.name) is not None:
        raise HTTPException(409, f"a breaker named {breaker.name!r} exists")
    try:
        row = crud.upsert_breaker(session, name=breaker.name, tag=body.tag, breaker_file=body.breaker_file,
                                  cam_file_name=cam_name, cam_table=body.cam_table)
        session.commit()
    except IntegrityError:
        raise HTTPException(409, "a breaker with that name or tag exists") from None
    return row


@router.post("/breakers/{breaker_id}/baseline/reset", response_model=s.Message, responses={**AUTH, **NOT_FOUND},
             tags=["breakers"])
def reset_baseline(breaker_id: BreakerId, body: s.BaselineReset, session: SessionDep, settings: SettingsDep,
                   who: AdminDep):
    from service.jobs.fit import reset_baseline as reset

    breaker_id = _breaker_or_404(session, breaker_id).id
    cleared = reset(session, breaker_id=breaker_id, by=who.name, settings=settings.drift_settings)
    session.commit()
    return s.Message(detail=f"baseline reset ({body.reason}); the next {settings.drift_settings.baseline_n} "
                            f"good fits form the new baseline; {cleared} alarm(s) cleared")


def _latest(row, fit, kind: str) -> s.LatestFit | None:
    if fit is None or not fit.parameters:
        return None
    op = fit.operation
    names = s.OPENING if kind == "open" else s.CLOSING
    params = {}
    for name in names:
        if name in fit.parameters:
            ci = (fit.ci95 or {}).get(name)
            params[name] = s.ParameterEstimate(value=fit.parameters[name], unit=s.UNITS[name],
                                               ci95=list(ci) if ci else None, time=op.occurred_at,
                                               operation_id=op.id, identifiable=fit.identifiable is not False)
    return s.LatestFit(operation_id=op.id, time=op.occurred_at, rmse_rad=fit.rmse_rad, identifiable=fit.identifiable,
                       parameters=params, characteristics=fit.characteristics)


@router.get("/breakers/{breaker_id}/health", response_model=s.HealthPublic, responses={**AUTH, **NOT_FOUND},
            tags=["breakers"])
def breaker_health(breaker_id: BreakerId, session: SessionDep, settings: SettingsDep, _: ReaderDep):
    from service.jobs.fit import drift_status

    row = _breaker_or_404(session, breaker_id)
    breaker_id = row.id
    opening = _latest(row, crud.latest_fit(session, breaker_id=breaker_id, kind="open"), "open")
    closing = _latest(row, crud.latest_fit(session, breaker_id=breaker_id, kind="close"), "close")
    alarms = crud.list_alarms(session, state="active", breaker_id=breaker_id)
    status = drift_status(session, breaker_id=breaker_id, settings=settings.drift_settings)
    if opening is None and closing is None:
        status = "unknown" if not alarms else status
    chars = {}
    if opening and opening.characteristics:
        chars["opening"] = opening.characteristics
    if closing and closing.characteristics:
        chars["closing"] = closing.characteristics
    from service.jobs.alarm_actions import compensation

    comp = {p: c["status"] for p, c in compensation(session, breaker_id=breaker_id,
                                                    settings=settings.drift_settings).items()}
    return s.HealthPublic(breaker_id=breaker_id, status=status, opening=opening, closing=closing,
                          characteristics=chars, active_alarms=[s.AlarmPublic.model_validate(a) for a in alarms],
                          temperature_compensation=comp)


@router.get("/breakers/{breaker_id}/parameters", response_model=s.TrendPublic, responses={**AUTH, **NOT_FOUND},
            tags=["breakers"])
def parameter_trend(breaker_id: BreakerId, session: SessionDep, _: ReaderDep,
                    name: Annotated[s.ParameterName, Query(description="parameter, e.g. DO")],
                    since: Annotated[datetime | None, IsoOnly, Query(description="ISO-8601; UTC when no zone")] = None,
                    limit: Annotated[int, Query(ge=1, le=20000)] = 5000,
                    include_clock_suspect: Annotated[bool, Query(
                        description="also values of clock-suspect operations (left out by default)")] = False):
    breaker_id = _breaker_or_404(session, breaker_id).id
    rows = crud.parameter_trend(session, breaker_id=breaker_id, name=name, since=_utc(since), limit=limit,
                                clock_suspect=None if include_clock_suspect else False)
    points = [s.TrendPoint(time=r.occurred_at, value=r.value, operation_id=r.operation_id, identifiable=r.identifiable,
                           ci95=[r.ci_low, r.ci_high] if r.ci_low is not None and r.ci_high is not None else None)
              for r in rows]
    return s.TrendPublic(breaker_id=breaker_id, name=name, unit=s.UNITS[name], points=points)


@router.get("/breakers/{breaker_id}/operations", response_model=list[s.OperationPublic],
            responses={**AUTH, **NOT_FOUND}, tags=["operations"])
def list_operations(breaker_id: BreakerId, session: SessionDep, _: ReaderDep,
                    limit: Annotated[int, Query(ge=1, le=1000)] = 50,
                    clock_suspect: Annotated[bool | None, Query(
                        description="true: only clock-suspect operations; false: none of them; omitted: all")] = None):
    breaker_id = _breaker_or_404(session, breaker_id).id
    return crud.list_operations(session, breaker_id=breaker_id, limit=limit, clock_suspect=clock_suspect)


@router.get("/operations/{operation_id}", response_model=s.OperationPublic, responses={**AUTH, **NOT_FOUND},
            tags=["operations"])
def get_operation(operation_id: OperationId, session: SessionDep, _: ReaderDep):
    op = crud.get_operation(session, operation_id=operation_id)
    if op is None:
        raise HTTPException(404, f"no operation {operation_id}")
    from service.acquisition.comtrade_writer import stored_masked_spans

    out = s.OperationPublic.model_validate(op)
    out.masked_samples = [s.MaskedSpan(**{k: m[k] for k in ("channel", "first_s", "last_s", "count")})
                          for m in (stored_masked_spans(op.capture_path) if op.capture_path else [])]
    return out


@router.get("/operations/{operation_id}/diagnosis", response_model=s.DiagnosisPublic,
            responses={**AUTH, **NOT_FOUND, 202: {"model": s.DiagnosisPublic,
                                                  "description": "queued or running: ask again"}},
            tags=["operations"])
def get_diagnosis(operation_id: OperationId, request: Request, response: Response, session: SessionDep,
                  _: ReaderDep):
    """Sim-to-real gap diagnosis of the operation (`hvcb diagnose`), computed on demand as a job:
    the first request queues it and answers 202; ask again until the status is done or failed."""
    from sqlalchemy import select

    from service.storage.models import DiagnosisRow

    if crud.get_operation(session, operation_id=operation_id) is None:
        raise HTTPException(404, f"no operation {operation_id}")
    query = select(DiagnosisRow).where(DiagnosisRow.operation_id == operation_id)
    row = session.scalars(query).one_or_none()
    if row is None:
        try:
            session.add(DiagnosisRow(operation_id=operation_id, status="queued"))
            session.commit()
        except IntegrityError:  # a concurrent request queued it first
            session.rollback()
        row = session.scalars(query).one()
    if row.status in ("queued", "running"):
        request.app.state.diagnoses.ensure(operation_id)
        response.status_code = 202
    return s.DiagnosisPublic(operation_id=operation_id, status=row.status, requested_at=row.requested_at,
                             finished_at=row.finished_at, failure_reason=row.failure_reason, result=row.result)


@router.get("/operations/{operation_id}/curve", response_model=s.CurvePublic,
            responses={**AUTH, **NOT_FOUND, 410: {"model": s.Message}}, tags=["operations"])
def get_curve(operation_id: OperationId, session: SessionDep, _: ReaderDep,
              points: Annotated[int, Query(ge=10, le=5000, description="samples returned")] = 1000):
    from service.acquisition.capture_file import read_stored_capture

    op = crud.get_operation(session, operation_id=operation_id)
    if op is None:
        raise HTTPException(404, f"no operation {operation_id}")
    breaker = crud.breaker_model(crud.get_breaker(session, breaker_id=op.breaker_id))
    fit = op.fit
    session.close()  # the file is read and the answer built without holding a connection
    try:
        cap = read_stored_capture(op.capture_path, breaker)
    except CaptureError as exc:
        raise HTTPException(410, f"the capture file is no longer readable: {redact_paths(str(exc))}") from None
    if cap.aux:  # the recorded channels share the travel's time axis: one min/max decimation of all
        from service.acquisition.recorded_channels import channel_indices

        idx = channel_indices(cap, points)
    else:
        idx = np.unique(np.linspace(0, cap.travel.size - 1, min(points, cap.travel.size)).astype(int))
    t, measured = cap.t[idx], cap.travel[idx]
    fitted = residual = window = None
    curve = fit_curve(fit, cap.t, crud.breaker_model(session.get(BreakerRow, op.breaker_id))) if fit is not None else None
    if curve is not None:
        ft, fv = curve
        inside = (t >= ft[0]) & (t <= ft[-1])
        f = np.where(inside, np.interp(t, ft, fv), np.nan)
        fitted = [None if not np.isfinite(v) else round(float(v), 7) for v in f]
        residual = [None if not np.isfinite(v) else round(float(v), 7) for v in measured - f]
        if fit.window_start_s is not None:
            window = [fit.window_start_s, fit.window_end_s]
    from service.acquisition.recorded_channels import operation_events, recorded_channels

    return s.CurvePublic(operation_id=op.id, kind=op.kind, t_s=[round(float(v), 9) for v in t],
                         measured_rad=[round(float(v), 7) for v in measured], fitted_rad=fitted,
                         residual_rad=residual, window_s=window, channels=recorded_channels(cap, idx),
                         events=operation_events(cap, op.kind, breaker.stroke) if cap.aux else None)


# -- uploads -----------------------------------------------------------------------------------
def _duplicate(session, breaker_id: int, key: str) -> s.UploadAccepted | None:
    """The operation already stored under this idempotency key, or None."""
    op = crud.get_operation_by_key(session, capture_key=key)
    if op is None:
        return None
    if op.breaker_id != breaker_id:
        raise HTTPException(409, f"this capture (Idempotency-Key {key[:12]}...) is stored under breaker "
                                 f"{op.breaker_id}, not {breaker_id}")
    ops = [op, *further_operations(session, key)]
    return s.UploadAccepted(operation_id=op.id, capture_key=key, operation=op.kind, status="duplicate",
                            operations=[s.UploadedOperation(operation_id=o.id, capture_key=o.capture_key, operation=o.kind)
                                        for o in ops])


def _upload_context(session, ref: str, idempotency_key: str | None):
    row = _breaker_or_404(session, ref)
    dup = _duplicate(session, row.id, idempotency_key, ) if idempotency_key is not None else None
    return row, dup


@router.post("/breakers/{breaker_id}/captures", response_model=s.UploadAccepted, status_code=202,
             responses={**AUTH, **NOT_FOUND, 200: {"model": s.UploadAccepted,
                                                   "description": "stored before under this Idempotency-Key"},
                        409: {"model": s.Message}, 413: {"model": s.Message}, 422: {"model": s.Message}},
             tags=["operations"])
async def upload_capture(breaker_id: BreakerId, request: Request, response: Response,
                         settings: SettingsDep, monitor: MonitorDep, who: UploaderDep,
                         files: Annotated[list[UploadFile], File(
                             min_length=1, description="a .cfg and its .dat, one .cff, or one .zip")],
                         # no `| None`: a form field cannot be null, only left out
                         operation: Annotated[Literal["open", "close"],
                                              Form(description="inferred from the travel when omitted")] = None,
                         temperature_c: Annotated[float, Form(
                             ge=-60, le=100, allow_inf_nan=False,
                             description="ambient or mechanism temperature of the operation [C] "
                                         "(docs/alarms.md); else the capture's temperature channel, "
                                         "else the latest SCADA value")] = None,
                         # no `| None` either: a header cannot be null, only left out (a nullable
                         # schema makes clients send "null", which the pattern refuses)
                         idempotency_key: Annotated[str, Header(
                             alias="Idempotency-Key", pattern=r"^[0-9a-f]{64}$",
                             description="the capture's content hash (SHA-256 of the hex SHA-256 of the .cfg "
                                         "then the .dat): a retry answers with the stored operation")] = None):
    """Upload one capture (operator, admin or agent key). With ``Idempotency-Key`` a capture is
    stored once however often it is sent: a repeat answers 200 with the existing operation.
    The key is checked from the headers before the body is read, and the body is cut at
    ``max_upload_bytes`` (docs/security.md). The files are stored byte for byte as sent."""
    def context():
        with request.app.state.Session() as session:
            return _upload_context(session, breaker_id, idempotency_key)

    row, dup = await run_in_threadpool(context)
    if dup is not None:
        response.status_code = 200
        return dup
    try:
        upload = await parse_upload(request.app.state, files, row, operation, idempotency_key)
    except UploadRefused as exc:
        raise HTTPException(exc.status_code, exc.detail) from None
    source = "agent" if who.role == "agent" else "upload"
    if temperature_c is not None:  # given with the upload: it beats the capture's channel
        upload.capture.meta["temperature_c"], upload.capture.meta["temperature_source"] = temperature_c, source
    result = await run_in_threadpool(ingest_upload, monitor, settings, upload, breaker_id=row.id, source=source,
                                     capture_key=idempotency_key)
    done = [result, *result.more]
    return s.UploadAccepted(operation_id=result.operation_id, capture_key=result.capture_key, operation=upload.kind,
                            status="spooled" if result.spooled else "queued",
                            operations=[s.UploadedOperation(operation_id=r.operation_id, capture_key=r.capture_key,
                                                            operation=kind) for r, (_, kind) in zip(done, upload.operations)])


# -- alarms ------------------------------------------------------------------------------------
@router.get("/alarms", response_model=list[s.AlarmPublic], responses=AUTH, tags=["alarms"])
def list_alarms(session: SessionDep, _: ReaderDep,
                state: Annotated[Literal["active", "raised", "acknowledged", "cleared", "all"], Query()] = "active",
                breaker_id: Annotated[int | None, Query(ge=1, le=MAX_ID)] = None):
    return crud.list_alarms(session, state=state, breaker_id=breaker_id)


@router.post("/alarms/{alarm_id}/ack", response_model=s.AlarmPublic, responses={**AUTH, **NOT_FOUND,
             409: {"model": s.Message}}, tags=["alarms"])
def acknowledge_alarm(alarm_id: AlarmId, session: SessionDep, settings: SettingsDep, who: OperatorDep,
                      body: s.AlarmAck | None = None):
    from service.jobs.fit import acknowledge_drift

    alarm = crud.get_alarm(session, alarm_id=alarm_id)
    if alarm is None:
        raise HTTPException(404, f"no alarm {alarm_id}")
    if alarm.state == "cleared":
        raise HTTPException(409, f"alarm {alarm_id} is already cleared")
    if alarm.state == "raised":
        crud.acknowledge_alarm(session, alarm=alarm, by=who.name, comment=body.comment if body else None)
        acknowledge_drift(session, alarm=alarm, by=who.name, settings=settings.drift_settings)
        from service.jobs.alarm_actions import audit_acknowledge

        audit_acknowledge(session, alarm=alarm, by=who.name, comment=body.comment if body else None)
        session.commit()
    return alarm


# -- SCADA -------------------------------------------------------------------------------------
SCADA_CACHE_S = 1.0  # pollers ask every few seconds; fits land every few minutes


@router.get("/scada/points", response_model=list[s.ScadaPoint], responses=AUTH, tags=["scada"])
async def scada_points(request: Request, settings: SettingsDep, _: ReaderDep):
    """Flat point list for SCADA pollers (computed at most once per second)."""
    cached = getattr(request.app.state, "scada_cache", None)
    now_m = time.monotonic()
    if cached is None or cached[0] < now_m:
        body = await run_in_threadpool(_scada_body, request, settings)
        cached = (now_m + SCADA_CACHE_S, body)
        request.app.state.scada_cache = cached
    return Response(cached[1], media_type="application/json")


def _scada_body(request: Request, settings) -> bytes:
    with request.app.state.Session() as session:
        points = _scada_points(session, settings)
    return s.ScadaPointList(points).model_dump_json().encode()


def _scada_points(session, settings) -> list[s.ScadaPoint]:
    now = utcnow()
    daq = {d.breaker_id: d for d in crud.daq_statuses(session)}
    stale = timedelta(seconds=settings.stale_after_s)
    daq_timeout = timedelta(seconds=settings.daq_timeout_s)
    points: list[s.ScadaPoint] = []
    from service.jobs.prognosis import soonest_by_breaker

    soonest = soonest_by_breaker(session)
    for row in crud.list_breakers(session):
        d = daq.get(row.id)
        daq_down = d is not None and (not d.connected or d.last_seen is None or now - d.last_seen > daq_timeout)
        active = crud.list_alarms(session, state="active", breaker_id=row.id)
        alarms = annunciated(active, now)
        shelves = {a.parameter: a for a in active if shelved_now(a, now)}
        level = 2 if any(a.level == "alarm" for a in alarms) else 1 if alarms else 0
        for kind, section, names in (("open", "opening", s.OPENING), ("close", "closing", s.CLOSING)):
            fit = crud.latest_fit(session, breaker_id=row.id, kind=kind)
            for name in names:
                value = ts = None
                quality = "bad"
                if fit is not None and fit.parameters and name in fit.parameters:
                    value, ts = float(fit.parameters[name]), fit.operation.occurred_at
                    if daq_down or now - ts > stale:
                        quality = "bad"
                    elif fit.identifiable is False:
                        quality = "uncertain"
                    else:
                        quality = "good"
                shelf = shelves.get(name)
                points.append(s.ScadaPoint(point=f"{row.tag}.{section}.{name}", value=value, unit=s.UNITS[name],
                                           timestamp=ts, quality=quality,
                                           shelved_until=shelf.shelved_until if shelf else None,
                                           shelved_by=shelf.shelved_by if shelf else None))
            if kind == "open":  # the vibration's trip-latch time (service.vibration), from the same fit
                latch = (fit.characteristics or {}).get("latch_time_s") if fit is not None else None
                ts = fit.operation.occurred_at if fit is not None else None
                good = isinstance(latch, (int, float)) and not daq_down and ts is not None and now - ts <= stale
                shelf = shelves.get("latch_time_s")
                points.append(s.ScadaPoint(point=f"{row.tag}.opening.latch_time_s",
                                           value=float(latch) if isinstance(latch, (int, float)) else None, unit="s",
                                           timestamp=ts, quality="good" if good else "bad",
                                           shelved_until=shelf.shelved_until if shelf else None,
                                           shelved_by=shelf.shelved_by if shelf else None))
        points.append(s.ScadaPoint(point=f"{row.tag}.alarm_level", value=float(level), unit="1", timestamp=now,
                                   quality="good"))
        if row.id in soonest:  # median openings to the soonest limit; null: none within the horizon
            _, median, at = soonest[row.id]
            points.append(s.ScadaPoint(point=f"{row.tag}.prognosis.operations_to_limit", value=median, unit="1",
                                       timestamp=at, quality="good"))
        if d is not None:
            points.append(s.ScadaPoint(point=f"{row.tag}.daq.connected", value=0.0 if daq_down else 1.0, unit="1",
                                       timestamp=d.last_seen, quality="good"))
    return points


# Refits (hvcb refit through the API, admins only): their routes are in refits.py.
from .refits import router as _refit_router  # noqa: E402

router.include_router(_refit_router)

