"""The breaker page's prognosis (fan chart) data: the same prognosis the API answers
(service/jobs/prognosis.py), for a signed-in engineer."""

from __future__ import annotations

import json

from fastapi import APIRouter, Request
from fastapi.responses import Response

from service.jobs.prognosis import HOW_TO_ADD, as_json, breaker_prognoses
from service.storage import crud

from .render import security_headers
from .handlers import Id, Reader, db_session, not_found

router = APIRouter(include_in_schema=False)


@router.get("/ui/breakers/{breaker_id}/prognosis.json")
def breaker_prognosis(request: Request, breaker_id: Id, user: Reader):
    with db_session(request) as session:
        b = crud.get_breaker(session, breaker_id=breaker_id) or not_found(f"breaker {breaker_id}")
        progs = breaker_prognoses(session, breaker=b, settings=request.app.state.settings.drift_settings)
    body = {"breaker": b.name, "parameters": [as_json(p) for p in progs],
            "message": "" if progs else f"{b.name} has no maintenance limits: {HOW_TO_ADD}"}
    return security_headers(Response(json.dumps(body), media_type="application/json"))
