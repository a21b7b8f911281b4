"""Queries of breaker-level diagnoses (issue 20): which stored operations a diagnosis uses, the
rows themselves, and the counts the per-caller queue bound reads."""

from __future__ import annotations

import hashlib
from pathlib import Path

from sqlalchemy import func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from .models import BreakerDiagnosisRow, CapturePreviewRow, OperationRow, utcnow
from .spool import capture_files

PENDING = ("queued", "running")
# A capture whose clock the acquisition side doubts (its time order among the others is not to be
# trusted) is left out; both spellings, as a flag may come from a file or a driver.
EXCLUDED_FLAGS = {"clock_suspect": "its clock is suspect", "clock suspect": "its clock is suspect"}
# At most this many stored operations are looked at to find N usable ones (a bound on the query).
LOOK_BACK = 200


def select_operations(session: Session, *, breaker_id: int, kind: str, last: int
                      ) -> tuple[list[OperationRow], list[dict]]:
    """The newest ``last`` usable operations of ``kind`` (oldest first), and the newer ones that
    were left out, each ``{"operation_id", "reason"}``: a suspect clock, or a raw capture that is
    gone (pruned by the retention policy, or missing from disk)."""
    rows = session.scalars(select(OperationRow)
                           .where(OperationRow.breaker_id == breaker_id, OperationRow.kind == kind)
                           .order_by(OperationRow.occurred_at.desc(), OperationRow.id.desc())
                           .limit(LOOK_BACK))
    pruned = set(session.scalars(select(CapturePreviewRow.operation_id)
                                 .join(OperationRow, OperationRow.id == CapturePreviewRow.operation_id)
                                 .where(OperationRow.breaker_id == breaker_id)))
    used, skipped = [], []
    for op in rows:
        if len(used) == last:
            break
        reason = _excluded(op, pruned)
        if reason:
            skipped.append({"operation_id": op.id, "reason": reason})
        else:
            used.append(op)
    used.reverse()
    return used, skipped


def _excluded(op: OperationRow, pruned: set[int]) -> str | None:
    for flag in op.flags or []:
        if str(flag).lower() in EXCLUDED_FLAGS:
            return EXCLUDED_FLAGS[str(flag).lower()]
    if op.id in pruned:
        return "its raw capture was pruned by the retention policy"
    if any(not Path(p).is_file() for p in capture_files(op.capture_path)):
        return "its capture file is missing"
    return None


def selection_key(*, breaker_id: int, kind: str, operation_ids: list[int]) -> str:
    """The identity of a request: the same breaker, operation and operations is the same diagnosis."""
    text = f"{breaker_id}|{kind}|" + ",".join(str(i) for i in operation_ids)
    return hashlib.sha256(text.encode()).hexdigest()


def find_active(session: Session, *, key: str) -> BreakerDiagnosisRow | None:
    """The queued, running or done diagnosis of this selection (failed ones do not count)."""
    return session.scalar(select(BreakerDiagnosisRow).where(BreakerDiagnosisRow.dedupe_key == key))


def insert(session: Session, *, breaker_id: int, kind: str, last: int, operation_ids: list[int],
           skipped: list[dict], key: str, requested_by: str | None, key_id: int | None, role: str
           ) -> tuple[BreakerDiagnosisRow, bool]:
    """Store a queued diagnosis and commit, or return the active one of the same selection.

    Returns ``(row, created)``. Committed before it is acknowledged; a concurrent identical
    request loses on the unique ``dedupe_key`` and gets the winner's row.
    """
    row = BreakerDiagnosisRow(breaker_id=breaker_id, operation=kind, last_n=last, operation_ids=list(operation_ids),
                              skipped=list(skipped), selection_key=key, dedupe_key=key, status="queued",
                              requested_by=requested_by, requested_key_id=key_id, requested_role=role)
    session.add(row)
    try:
        session.commit()
    except IntegrityError:
        session.rollback()
        existing = find_active(session, key=key)
        if existing is None:  # it failed in between: a retry of the caller queues it anew
            raise
        return existing, False
    return row, True


def pending_counts(session: Session, *, key_id: int | None, role: str) -> tuple[int, int]:
    """(queued + running diagnoses asked with this key, the same asked by every key of ``role``)."""
    base = select(func.count()).select_from(BreakerDiagnosisRow).where(BreakerDiagnosisRow.status.in_(PENDING))
    mine = session.scalar(base.where(BreakerDiagnosisRow.requested_key_id == key_id)) if key_id is not None else 0
    theirs = session.scalar(base.where(BreakerDiagnosisRow.requested_role == role))
    return int(mine or 0), int(theirs or 0)


def get(session: Session, *, breaker_id: int, diagnosis_id: int) -> BreakerDiagnosisRow | None:
    row = session.get(BreakerDiagnosisRow, diagnosis_id)
    return row if row is not None and row.breaker_id == breaker_id else None


def latest(session: Session, *, breaker_id: int) -> BreakerDiagnosisRow | None:
    return session.scalar(select(BreakerDiagnosisRow).where(BreakerDiagnosisRow.breaker_id == breaker_id)
                          .order_by(BreakerDiagnosisRow.id.desc()).limit(1))


def recent(session: Session, *, breaker_id: int, limit: int = 20) -> list[BreakerDiagnosisRow]:
    return list(session.scalars(select(BreakerDiagnosisRow).where(BreakerDiagnosisRow.breaker_id == breaker_id)
                                .order_by(BreakerDiagnosisRow.id.desc()).limit(limit)))


def claim(session: Session, *, diagnosis_id: int) -> BreakerDiagnosisRow | None:
    """Mark a queued (or interrupted running) diagnosis running; None when it is finished or gone."""
    row = session.scalar(select(BreakerDiagnosisRow).where(BreakerDiagnosisRow.id == diagnosis_id)
                         .with_for_update())
    if row is None or row.status not in PENDING:
        return None
    row.status, row.started_at = "running", utcnow()
    return row


def finish(session: Session, *, diagnosis_id: int, result: dict | None, reason: str | None) -> None:
    """Store the result (done) or the reason (failed: the selection may then be asked again)."""
    row = session.get(BreakerDiagnosisRow, diagnosis_id)
    if row is None:
        return
    row.status = "done" if reason is None else "failed"
    row.result, row.failure_reason, row.finished_at = result, reason, utcnow()
    if reason is not None:
        row.dedupe_key = None


def pending_ids(session: Session) -> list[int]:
    return list(session.scalars(select(BreakerDiagnosisRow.id).where(BreakerDiagnosisRow.status.in_(PENDING))
                                .order_by(BreakerDiagnosisRow.id)))
