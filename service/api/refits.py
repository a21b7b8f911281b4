"""/api/v1/refits: admins queue a refit; anyone with an admin key can follow it.

The run executes in a background thread of the API process, handing its batches to the same
kind of workers the fits use (the local pool, Celery, or inline).
"""

from __future__ import annotations

import logging
import threading
from concurrent.futures import ThreadPoolExecutor
from datetime import datetime

from fastapi import APIRouter, HTTPException, Path as PathParam, Request
from pydantic import BaseModel, Field
from sqlalchemy import select
from typing import Annotated

from .deps import AdminDep, SessionDep
from .schemas import ORM, Message, UtcTime
from service.errors import UserError
from service.storage.models import RefitRunRow

log = logging.getLogger("hvcb.refit")
router = APIRouter()
RunId = Annotated[int, PathParam(ge=1, le=2_147_483_647, description="refit run id")]


class RefitCreate(BaseModel):
    breaker: str | None = Field(None, max_length=120, description="breaker name; all breakers when absent")
    since: datetime | None = Field(None, description="only operations at or after this time")


class RefitPublic(ORM):
    id: int
    breaker_id: int | None
    since: UtcTime | None
    status: str = Field(description="queued | running | interrupted | done")
    total: int
    done: int
    failed: int
    reason: str | None = Field(None, description="why some operations kept their result")
    requested_by: str | None
    created_at: UtcTime
    started_at: UtcTime | None
    finished_at: UtcTime | None


class RefitRunner:
    """One background thread that runs queued refits one after another."""

    def __init__(self, settings, Session):
        self.settings, self.Session = settings, Session
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="ThreadPoolExecutor-refit")

    def submit(self, run_id: int):
        return self._pool.submit(self._run, run_id)

    def _run(self, run_id: int) -> None:
        from service.jobs.fit import JobOptions

        from service.refit import pool
        from service.refit.runs import run_refit

        options = JobOptions.from_settings(self.settings)
        kind = self.settings.executor_kind
        if kind == "celery":
            submit = pool.celery(self.settings, self.Session)
        elif kind == "inline":
            submit = pool.inline(options)
        else:
            submit = pool.local_pool(options, self.settings.workers)
        try:
            run_refit(self.Session, run_id, submit_batches=submit, options=options)
        except Exception:  # the run stays resumable; the next POST with its selection resumes it
            log.exception("refit run %s stopped", run_id)
            with self.Session() as session, session.begin():
                session.get(RefitRunRow, run_id).status = "interrupted"


_lock = threading.Lock()


def _runner(request: Request) -> RefitRunner:
    state = request.app.state
    with _lock:
        if getattr(state, "refits", None) is None:
            state.refits = RefitRunner(state.settings, state.Session)
        return state.refits


@router.post("/refits", response_model=RefitPublic, status_code=202, tags=["refits"],
             responses={401: {"model": Message}, 403: {"model": Message}, 404: {"model": Message}})
def queue_refit(body: RefitCreate, request: Request, session: SessionDep, who: AdminDep):
    """Queue a refit of the stored operations (admin). An unfinished run with the same selection
    is resumed instead of starting a second one."""
    from service.refit.runs import start_run

    try:
        run, _ = start_run(session, breaker=body.breaker, since=body.since, requested_by=who.name)
    except UserError as exc:
        raise HTTPException(404, str(exc)) from None
    session.commit()
    out = RefitPublic.model_validate(run)
    _runner(request).submit(run.id)
    return out


@router.get("/refits", response_model=list[RefitPublic], tags=["refits"],
            responses={401: {"model": Message}, 403: {"model": Message}})
def list_refits(session: SessionDep, _: AdminDep):
    return list(session.scalars(select(RefitRunRow).order_by(RefitRunRow.id.desc()).limit(100)))


@router.get("/refits/{run_id}", response_model=RefitPublic, tags=["refits"],
            responses={401: {"model": Message}, 403: {"model": Message}, 404: {"model": Message}})
def get_refit(run_id: RunId, session: SessionDep, _: AdminDep):
    run = session.get(RefitRunRow, run_id)
    if run is None:
        raise HTTPException(404, f"no refit run {run_id}")
    return run
