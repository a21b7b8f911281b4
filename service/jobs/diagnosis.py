"""The diagnosis job: run ``hvcb diagnose`` on one stored operation and keep the answer.

Diagnoses are requested through the API and computed on demand in a process of their own (a
whole-catalogue diagnosis takes seconds and must not stall the API or the fit queue).
"""

from __future__ import annotations

import json

from sqlalchemy import select

from service.jobs.fit import failure_reason
from service.storage import crud
from service.storage.db import cached_engine, session_factory
from service.storage.models import BreakerRow, DiagnosisRow, OperationRow, utcnow
from service.storage.spool import capture_digest, capture_files


def run_diagnosis_job(operation_id: int, database_url: str) -> str:
    """Diagnose one operation's capture and store the result or the reason it failed.

    Returns the final status (``done``, ``failed`` or ``skipped`` when another run finished it).
    """
    from drivers.capture import CaptureError
    from service.acquisition.capture_file import read_stored_capture
    from service.diagnosis import diagnose

    Session = session_factory(cached_engine(database_url))
    with Session() as session, session.begin():
        row = session.scalars(select(DiagnosisRow).where(DiagnosisRow.operation_id == operation_id)
                              .with_for_update()).one_or_none()
        if row is None or row.status in ("done", "failed"):
            return "skipped"
        row.status = "running"
        op = session.get(OperationRow, operation_id)
        breaker = crud.breaker_model(session.get(BreakerRow, op.breaker_id))
        path, sha, kind = op.capture_path, op.capture_sha256, op.kind
    try:
        files = capture_files(path)
        if any(not p.exists() for p in files) or capture_digest(files) != sha:
            raise CaptureError("capture file missing or changed since it was recorded")
        capture = read_stored_capture(path, breaker)
        result = json.loads(json.dumps(diagnose([capture], breaker, kind), default=_plain))
        status, reason = "done", None
    except Exception as exc:  # stored with its reason; a later request may retry by deleting it
        result, status, reason = None, "failed", failure_reason(exc)
    with Session() as session, session.begin():
        row = session.scalars(select(DiagnosisRow).where(DiagnosisRow.operation_id == operation_id)).one()
        row.status, row.result, row.failure_reason, row.finished_at = status, result, reason, utcnow()
    return status


def _plain(obj):
    try:
        return float(obj)
    except (TypeError, ValueError):
        return str(obj)
