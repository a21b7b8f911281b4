"""The breaker page's "Diagnose the last N operations" (issue 20): the form's POST, and what the
page shows of the breaker's diagnoses. The request goes through the same queue and bound as the
API's (service/jobs/breaker_diagnosis.py)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Form, HTTPException, Request
from fastapi.responses import RedirectResponse

from service.errors import UserError
from service.jobs.breaker_diagnosis import MAX_LAST, MIN_LAST, QueueFull, queue_diagnosis, summary
from service.storage import crud, crud_diagnoses

from .diagnosis_view import view
from .render import page, security_headers
from .handlers import Id, ReaderPost

router = APIRouter(include_in_schema=False)


def breaker_diagnosis_context(request: Request, session, breaker) -> dict:
    """The breaker page's diagnosis part: the one named by ``?diagnosis=ID`` or the latest, and
    the recent ones. A pending one left by a restart is submitted again."""
    wanted = request.query_params.get("diagnosis", "")
    row = None
    if wanted.isdigit() and len(wanted) < 10:
        row = crud_diagnoses.get(session, breaker_id=breaker.id, diagnosis_id=int(wanted))
    if row is None:
        row = crud_diagnoses.latest(session, breaker_id=breaker.id)
    if row is not None and row.status in ("queued", "running"):
        request.app.state.breaker_diagnoses.ensure(row.id)
    return {"bdiag": row, "bdiag_summary": summary(row) if row is not None else "",
            "bdiag_view": view(row.result) if row is not None and row.status == "done" else None,
            "bdiag_recent": crud_diagnoses.recent(session, breaker_id=breaker.id, limit=8),
            "DIAG_MIN": MIN_LAST, "DIAG_MAX": MAX_LAST}


@router.post("/breakers/{breaker_id}/diagnoses")
def request_breaker_diagnosis(request: Request, breaker_id: Id, user: ReaderPost,
                              operation: Annotated[str, Form(pattern="^(open|close)$")],
                              last: Annotated[int, Form(ge=MIN_LAST, le=MAX_LAST)] = 10):
    """Queue the diagnosis of the last ``last`` operations; the page then shows it as it runs."""
    with request.app.state.Session() as session:
        b = crud.get_breaker(session, breaker_id=breaker_id)
        if b is None:
            raise HTTPException(404, f"no breaker {breaker_id}")
        try:
            row, created = queue_diagnosis(session, breaker=b, kind=operation, last=last, who=user)
        except QueueFull as exc:
            resp = page(request, "error.html", {"status": 429, "message": str(exc)}, status_code=429)
            resp.headers["Retry-After"] = str(exc.retry_after_s)
            return resp
        except UserError as exc:
            return page(request, "error.html", {"status": 422, "message": str(exc)}, status_code=422)
        if created:
            request.app.state.breaker_diagnoses.submit(row.id)
        elif row.status in ("queued", "running"):
            request.app.state.breaker_diagnoses.ensure(row.id)
        target = f"/breakers/{breaker_id}?diagnosis={row.id}#breaker-diagnosis"
    return security_headers(RedirectResponse(target, status_code=303))
