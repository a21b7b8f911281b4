"""A breaker's condition report (PDF) and CSV exports (docs/reports.md): thin routes over
service.reports. The CSV answers stream: rows are read and sent a chunk at a time."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated

from fastapi import APIRouter, HTTPException, Path as PathParam, Query, Request
from fastapi.responses import Response, StreamingResponse

from service.reports.exports import alarm_chunks, file_name, operation_chunks
from service.reports.window import Window

from . import schemas as s
from .deps import ReaderDep, SessionDep, SettingsDep
from .refs import IsoOnly
from .routes_alarms import _breaker_ref

router = APIRouter(prefix="/api/v1", tags=["reports"])
BreakerRef = Annotated[str, PathParam(min_length=1, max_length=120, description="breaker name, tag or id")]


From = Annotated[datetime | None, IsoOnly,
                 Query(alias="from", description="operations at or after (ISO 8601; UTC when no zone)")]
To = Annotated[datetime | None, IsoOnly,
               Query(alias="to", description="operations at or before (ISO 8601; UTC when no zone)")]
ERRORS = {401: {"model": s.Message}, 403: {"model": s.Message}, 404: {"model": s.Message},
          422: {"model": s.Message, "description": "`from` is after `to`"}}
CSV = "text/csv; charset=utf-8"


def _window(start, end) -> Window:
    try:
        return Window(start, end)
    except ValueError as exc:
        raise HTTPException(422, str(exc)) from None


def _attachment(name: str) -> dict:
    return {"Content-Disposition": f'attachment; filename="{name}"', "Cache-Control": "no-store"}


@router.get("/breakers/{name}/report", response_class=Response, responses={
    **ERRORS, 200: {"content": {"application/pdf": {"schema": {"type": "string", "format": "binary"}}},
                    "description": "the condition report as PDF"}})
def breaker_report(name: BreakerRef, session: SessionDep, settings: SettingsDep, _: ReaderDep,
                   start: From = None, end: To = None):
    """The breaker's condition report: identity and file, the latest opening and closing against the
    breaker file's limits, the parameter trends, the alarms, the prognosis, the last diagnosis, the
    method. Renders in a few seconds for 10,000 operations (bench/report_speed.py)."""
    from service.reports.content import gather
    from service.reports.pdf import render

    window = _window(start, end)
    b = _breaker_ref(session, name)
    content = gather(session, breaker=b, settings=settings.drift_settings, window=window)
    session.close()  # the PDF is drawn without holding a connection
    return Response(render(content), media_type="application/pdf",
                    headers=_attachment(file_name(b.name, "condition-report", "pdf")))


@router.get("/breakers/{name}/operations.csv", response_class=StreamingResponse, responses={
    **ERRORS, 200: {"content": {CSV: {"schema": {"type": "string"}}},
                    "description": "one row per operation: every fitted parameter with its 95 % interval and "
                                   "the travel characteristics; units in the header, times ISO 8601 UTC"}})
def operations_csv(name: BreakerRef, request: Request, session: SessionDep, _: ReaderDep,
                   start: From = None, end: To = None):
    """The breaker's operations as CSV, oldest first, streamed a chunk of rows at a time."""
    window = _window(start, end)
    b = _breaker_ref(session, name)
    breaker_id, breaker_name = b.id, b.name
    session.close()
    return StreamingResponse(operation_chunks(request.app.state.Session, breaker_id=breaker_id, window=window),
                             media_type=CSV, headers=_attachment(file_name(breaker_name, "operations", "csv")))


@router.get("/breakers/{name}/alarms.csv", response_class=StreamingResponse, responses={
    **ERRORS, 200: {"content": {CSV: {"schema": {"type": "string"}}},
                    "description": "the breaker's alarms raised in the window with their lifecycle and evidence"}})
def alarms_csv(name: BreakerRef, request: Request, session: SessionDep, _: ReaderDep,
               start: From = None, end: To = None):
    """The breaker's alarm history as CSV, oldest first, streamed."""
    window = _window(start, end)
    b = _breaker_ref(session, name)
    breaker_id, breaker_name = b.id, b.name
    session.close()
    return StreamingResponse(alarm_chunks(request.app.state.Session, breaker_id=breaker_id, window=window),
                             media_type=CSV, headers=_attachment(file_name(breaker_name, "alarms", "csv")))
