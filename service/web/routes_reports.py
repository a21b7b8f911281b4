"""The breaker page's buttons: its condition report (PDF) and CSV exports, for a signed-in
engineer. The same report and files as the API (service/api/routes_reports.py)."""

from __future__ import annotations

from datetime import date, datetime, time, timezone
from typing import Annotated

from fastapi import APIRouter, HTTPException, Query, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import Response, StreamingResponse

from service.reports.exports import alarm_chunks, file_name, operation_chunks
from service.reports.window import Window
from service.storage import crud

from .handlers import Id, Reader, db_session, not_found
from .render import security_headers

router = APIRouter(include_in_schema=False)
CSV = "text/csv; charset=utf-8"
From = Annotated[str, Query(alias="from", max_length=40)]
To = Annotated[str, Query(alias="to", max_length=40)]


def _when(text: str, field: str, *, end: bool) -> datetime | None:
    """A form's date (2026-01-31: the whole day) or time (ISO 8601, UTC when no zone); empty: none."""
    text = (text or "").strip()
    if not text:
        return None
    try:
        if len(text) == 10:
            day = date.fromisoformat(text)
            t = datetime.combine(day, time.max if end else time.min, tzinfo=timezone.utc)
            return t
        t = datetime.fromisoformat(text)
    except ValueError:
        raise HTTPException(422, f"{field} {text!r} is not a date (use 2026-01-31 or 2026-01-31T12:00)") from None
    return t if t.tzinfo else t.replace(tzinfo=timezone.utc)


def _window(start: str, end: str) -> Window:
    try:
        return Window(_when(start, "from", end=False), _when(end, "to", end=True))
    except ValueError as exc:
        raise HTTPException(422, str(exc)) from None


def _breaker(request: Request, breaker_id: int):
    with db_session(request) as session:
        b = crud.get_breaker(session, breaker_id=breaker_id) or not_found(f"breaker {breaker_id}")
        return b.id, b.name


def _download(body, name: str, media: str):
    headers = {"Content-Disposition": f'attachment; filename="{name}"', "Cache-Control": "no-store"}
    if isinstance(body, bytes):
        return security_headers(Response(body, media_type=media, headers=headers))
    return security_headers(StreamingResponse(body, media_type=media, headers=headers))


@router.get("/breakers/{breaker_id}/report.pdf")
async def report_pdf(request: Request, breaker_id: Id, user: Reader, start: From = "", end: To = ""):
    """Drawn by a worker process (service/workers/reports.py), awaited without holding a thread."""
    import asyncio

    from service.workers.reports import ReportFailed

    window = _window(start, end)
    bid, bname = await run_in_threadpool(_breaker, request, breaker_id)
    job = request.app.state.reports.submit(breaker_id=bid, breaker_name=bname, start=window.start, end=window.end)
    try:
        body, name = await asyncio.shield(asyncio.wrap_future(job.future))
    except ReportFailed as exc:
        raise HTTPException(404, str(exc)) from None
    except Exception:
        raise HTTPException(503, job.error()) from None
    return _download(body, file_name(name, "condition-report", "pdf"), "application/pdf")


@router.get("/breakers/{breaker_id}/operations.csv")
def operations_csv(request: Request, breaker_id: Id, user: Reader, start: From = "", end: To = ""):
    window = _window(start, end)
    bid, name = _breaker(request, breaker_id)
    return _download(operation_chunks(request.app.state.Session, breaker_id=bid, window=window),
                     file_name(name, "operations", "csv"), CSV)


@router.get("/breakers/{breaker_id}/alarms.csv")
def alarms_csv(request: Request, breaker_id: Id, user: Reader, start: From = "", end: To = ""):
    window = _window(start, end)
    bid, name = _breaker(request, breaker_id)
    return _download(alarm_chunks(request.app.state.Session, breaker_id=bid, window=window),
                     file_name(name, "alarms", "csv"), CSV)
