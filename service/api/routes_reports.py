"""A breaker's condition report (PDF) and CSV exports (docs/reports.md): thin routes over
service.reports. The report is drawn by a worker process (service/workers/reports.py), never in
the API's threads; the CSV answers stream: rows are read and sent a chunk at a time."""

from __future__ import annotations

import asyncio
from datetime import datetime
from typing import Annotated, Literal

from fastapi import APIRouter, HTTPException, Path as PathParam, Query, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import JSONResponse, Response, StreamingResponse
from pydantic import BaseModel, Field

from service.reports.exports import alarm_chunks, file_name, operation_chunks
from service.reports.window import Window

from . import schemas as s
from .deps import ReaderDep, SessionDep
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


class ReportJobPublic(BaseModel):
    """A condition report being drawn by the workers (issue 44: never in the API's threads)."""

    id: str = Field(description="the job's id")
    status: Literal["queued", "running", "done", "failed"]
    breaker: str = Field(description="the breaker's name")
    url: str = Field(description="GET it: 202 with this body while it is drawn, then 200 with the PDF")
    error: str | None = Field(None, description="why it failed, in words")


PDF = {"content": {"application/pdf": {"schema": {"type": "string", "format": "binary"}}},
       "description": "the condition report as PDF"}
JOB = {"model": ReportJobPublic, "description": "the report is being drawn: fetch `url` (Location) later",
       "headers": {"Location": {"schema": {"type": "string"}, "description": "the job's URL"},
                   "Retry-After": {"schema": {"type": "integer"}, "description": "seconds"}}}
FAILED = {"model": s.Message, "description": "the report could not be drawn, or too many wait (why, in words)"}
JobId = Annotated[str, PathParam(pattern=r"^[0-9a-f]{32}$", description="report job id")]


def _public(job) -> ReportJobPublic:
    return ReportJobPublic(id=job.id, status=job.status, breaker=job.breaker_name,
                           url=f"/api/v1/reports/{job.id}", error=job.error() if job.status == "failed" else None)


def _pending(job) -> JSONResponse:
    body = _public(job)
    return JSONResponse(body.model_dump(), status_code=202, headers={"Location": body.url, "Retry-After": "1"})


def _finished(job) -> Response:
    if job.status == "failed":
        raise HTTPException(503, job.error())
    data, name = job.future.result()
    return Response(data, media_type="application/pdf",
                    headers=_attachment(file_name(name, "condition-report", "pdf")))


async def _submit_job(request: Request, name: str, window: Window):
    def find():
        with request.app.state.Session() as session:
            b = _breaker_ref(session, name)
            return b.id, b.name

    from service.workers.reports import ReportsBusy

    breaker_id, breaker_name = await run_in_threadpool(find)
    try:
        return request.app.state.reports.submit(breaker_id=breaker_id, breaker_name=breaker_name,
                                                start=window.start, end=window.end)
    except ReportsBusy as exc:
        raise HTTPException(503, str(exc), headers={"Retry-After": "60"}) from None


@router.get("/breakers/{name}/report", response_class=Response, responses={
    **ERRORS, 200: PDF, 202: JOB, 503: FAILED})
async def breaker_report(name: BreakerRef, request: Request, _: ReaderDep, start: From = None, end: To = None):
    """The breaker's condition report: identity and file, the latest opening and closing against the
    breaker file's limits, the parameter trends, the alarms, the prognosis, the last diagnosis, the
    method. Drawn by a worker process, never in the API's threads: when it is ready within
    ``[server] report_wait_s`` (a few seconds for 10,000 operations, bench/report_speed.py) the
    answer is the PDF; else 202 with the job, whose URL gives the PDF when it is done."""
    window = _window(start, end)
    job = await _submit_job(request, name, window)
    try:
        await asyncio.wait_for(asyncio.shield(asyncio.wrap_future(job.future)),
                               timeout=request.app.state.settings.server.report_wait_s)
    except asyncio.TimeoutError:
        return _pending(job)
    except Exception:  # the job's own failure: answered in words below
        pass
    return _finished(job)


@router.post("/breakers/{name}/reports", response_model=ReportJobPublic, status_code=202,
             responses={**ERRORS, 202: JOB, 503: {"model": s.Message, "description": "too many reports waiting"}})
async def request_report(name: BreakerRef, request: Request, _: ReaderDep, start: From = None, end: To = None):
    """Ask for the breaker's condition report; the answer comes at once with the job. GET its
    ``url`` for the PDF (202 while it is drawn)."""
    window = _window(start, end)
    return _pending(await _submit_job(request, name, window))


@router.get("/reports/{job_id}", response_class=Response, responses={
    401: {"model": s.Message}, 403: {"model": s.Message},
    404: {"model": s.Message, "description": "no such report job (or it finished more than 10 minutes ago)"},
    200: PDF, 202: JOB, 503: FAILED})
async def get_report(job_id: JobId, request: Request, _: ReaderDep):
    """A report job: 202 with its state while it is drawn, then the PDF."""
    job = request.app.state.reports.get(job_id)
    if job is None:
        raise HTTPException(404, f"no report job {job_id} (a finished report is kept 10 minutes)")
    if not job.future.done():
        return _pending(job)
    return _finished(job)


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
