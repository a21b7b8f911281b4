"""Queries of the web page (service/web/): sessions, the fleet summary, trends and paging.

Like ``crud``: session first, keyword-only arguments. Bulk reads select plain columns (no ORM
objects) so a breaker with 10,000 operations renders quickly.
"""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import Integer, cast, func, select, update
from sqlalchemy.orm import Session

from .crud import _suspect_ids

from .models import (AlarmRow, ApiKeyRow, BreakerRow, DaqStatusRow, DiagnosisRow, FitRow, OperationRow,
                     ParameterValueRow, WebSessionRow, utcnow)


# -- sessions ----------------------------------------------------------------------------------
def create_web_session(session: Session, *, token_hash: str, key_id: int, expires_at: datetime) -> WebSessionRow:
    row = WebSessionRow(token_hash=token_hash, key_id=key_id, expires_at=expires_at)
    session.add(row)
    session.flush()
    return row


def find_web_session(session: Session, *, token_hash: str) -> tuple[WebSessionRow, ApiKeyRow] | None:
    """The live session with this token and its key: None when ended, expired or the key revoked."""
    now = utcnow()
    row = session.execute(select(WebSessionRow, ApiKeyRow).join(ApiKeyRow, ApiKeyRow.id == WebSessionRow.key_id)
                          .where(WebSessionRow.token_hash == token_hash, WebSessionRow.ended_at.is_(None),
                                 WebSessionRow.expires_at > now, ApiKeyRow.revoked_at.is_(None))).first()
    return None if row is None else (row[0], row[1])


def end_web_session(session: Session, *, token_hash: str) -> bool:
    res = session.execute(update(WebSessionRow).where(WebSessionRow.token_hash == token_hash,
                                                      WebSessionRow.ended_at.is_(None)).values(ended_at=utcnow()))
    return res.rowcount == 1


def purge_web_sessions(session: Session, *, before: datetime) -> int:
    """Forget sessions that expired or ended before ``before``."""
    from sqlalchemy import delete, or_

    res = session.execute(delete(WebSessionRow).where(or_(WebSessionRow.expires_at < before,
                                                          WebSessionRow.ended_at < before)))
    return res.rowcount or 0


# -- fleet -------------------------------------------------------------------------------------
def last_operation_times(session: Session, *, breaker_id: int) -> dict[str, datetime | None]:
    """{"open": time, "close": time} of the breaker's latest opening and closing."""
    q = (select(OperationRow.kind, func.max(OperationRow.occurred_at))
         .where(OperationRow.breaker_id == breaker_id, OperationRow.clock_suspect.is_(False))
         .group_by(OperationRow.kind))
    out = {"open": None, "close": None}
    for kind, t in session.execute(q):
        if isinstance(t, str):  # SQLite returns the aggregate of a DateTime as text
            t = datetime.fromisoformat(t)
        if t is not None and t.tzinfo is None:
            from datetime import timezone
            t = t.replace(tzinfo=timezone.utc)
        out[kind] = t
    return out


def recent_values(session: Session, *, breaker_id: int, name: str, limit: int = 30) -> list[tuple]:
    """The parameter's latest ``limit`` values as (occurred_at, value, ci_low, ci_high), oldest first."""
    q = (select(ParameterValueRow.occurred_at, ParameterValueRow.value, ParameterValueRow.ci_low,
                ParameterValueRow.ci_high)
         .where(ParameterValueRow.breaker_id == breaker_id, ParameterValueRow.name == name,
                ParameterValueRow.operation_id.not_in(_suspect_ids(breaker_id)))
         .order_by(ParameterValueRow.occurred_at.desc(), ParameterValueRow.id.desc()).limit(limit))
    return list(reversed([tuple(r) for r in session.execute(q)]))


def has_done_fit(session: Session, *, breaker_id: int) -> bool:
    return session.scalar(select(FitRow.id).where(FitRow.breaker_id == breaker_id, FitRow.status == "done")
                          .limit(1)) is not None


# -- breaker page ------------------------------------------------------------------------------
def characteristics_rows(session: Session, *, breaker_id: int, operation_ids: list[int] | None = None) -> list[tuple]:
    """(occurred_at, kind, characteristics dict) of the breaker's done fits (or of those
    operations), oldest first."""
    q = (select(OperationRow.occurred_at, FitRow.kind, FitRow.characteristics)
         .join(OperationRow, OperationRow.id == FitRow.operation_id)
         .where(FitRow.breaker_id == breaker_id, FitRow.status == "done"))
    if operation_ids is not None:
        q = q.where(FitRow.operation_id.in_(operation_ids))
    return [tuple(r) for r in session.execute(q.order_by(OperationRow.occurred_at, OperationRow.id))]


def parameter_rows_after(session: Session, *, breaker_id: int, after_id: int) -> list[tuple]:
    """(id, name, occurred_at, operation_id, value, ci_low, ci_high, identifiable) of the breaker's
    parameter values stored after row ``after_id``, oldest first: the trend cache's increment."""
    q = (select(ParameterValueRow.id, ParameterValueRow.name, ParameterValueRow.occurred_at,
                ParameterValueRow.operation_id, ParameterValueRow.value, ParameterValueRow.ci_low,
                ParameterValueRow.ci_high, ParameterValueRow.identifiable)
         .where(ParameterValueRow.breaker_id == breaker_id, ParameterValueRow.id > after_id,
                ParameterValueRow.operation_id.not_in(_suspect_ids(breaker_id)))
         .order_by(ParameterValueRow.occurred_at, ParameterValueRow.id))
    return [tuple(r) for r in session.execute(q)]


def trend_version(session: Session, *, breaker_id: int) -> tuple:
    """Changes whenever the breaker page's trends change: parameter rows, alarms, baseline reset."""
    pv = session.execute(select(func.count(), func.max(ParameterValueRow.id))
                         .where(ParameterValueRow.breaker_id == breaker_id)).one()
    al = session.execute(select(func.count(), func.max(AlarmRow.updated_at))
                         .where(AlarmRow.breaker_id == breaker_id)).one()
    reset = session.scalar(select(BreakerRow.baseline_reset_at).where(BreakerRow.id == breaker_id))
    return (int(pv[0] or 0), int(pv[1] or 0), int(al[0] or 0), str(al[1]), str(reset))


def operations_page(session: Session, *, breaker_id: int, page: int, per_page: int) -> tuple[list[OperationRow], int]:
    """One page (1-based, newest first) of the breaker's operations with their fits, and the total."""
    total = int(session.scalar(select(func.count()).select_from(OperationRow)
                               .where(OperationRow.breaker_id == breaker_id)) or 0)
    q = (select(OperationRow).where(OperationRow.breaker_id == breaker_id)
         .order_by(OperationRow.occurred_at.desc(), OperationRow.id.desc())
         .offset((page - 1) * per_page).limit(per_page))
    return list(session.scalars(q)), total


def alarms_with_breakers(session: Session, *, state: str = "active", breaker_id: int | None = None,
                         limit: int = 500) -> list[tuple[AlarmRow, BreakerRow]]:
    q = select(AlarmRow, BreakerRow).join(BreakerRow, BreakerRow.id == AlarmRow.breaker_id)
    if state == "active":
        q = q.where(AlarmRow.state.in_(("raised", "acknowledged")))
    elif state != "all":
        q = q.where(AlarmRow.state == state)
    if breaker_id is not None:
        q = q.where(AlarmRow.breaker_id == breaker_id)
    q = q.order_by(AlarmRow.raised_at.desc(), AlarmRow.id.desc()).limit(limit)
    return [(a, b) for a, b in session.execute(q)]


def get_diagnosis(session: Session, *, operation_id: int) -> DiagnosisRow | None:
    return session.scalar(select(DiagnosisRow).where(DiagnosisRow.operation_id == operation_id))


def get_api_key(session: Session, *, key_id: int) -> ApiKeyRow | None:
    return session.get(ApiKeyRow, key_id)


# -- live updates ------------------------------------------------------------------------------
def change_marker(session: Session) -> str:
    """A short text that changes whenever an operation, a fit, an alarm or a diagnosis changes."""
    ops = session.execute(select(func.count(), func.max(OperationRow.id)).select_from(OperationRow)).one()
    fits = session.execute(select(func.count(), func.max(FitRow.finished_at))
                           .where(FitRow.status.in_(("done", "failed")))).one()
    alarms = session.execute(select(func.count(), func.max(AlarmRow.updated_at))).one()
    diag = session.execute(select(func.count(), func.max(DiagnosisRow.finished_at))
                           .where(DiagnosisRow.status.in_(("done", "failed")))).one()
    from .models import BreakerDiagnosisRow

    bdiag = session.execute(select(func.count(), func.max(BreakerDiagnosisRow.id),
                                   func.max(BreakerDiagnosisRow.finished_at))).one()
    brk = session.execute(select(func.count(), func.max(BreakerRow.baseline_reset_at))).one()
    # the DAQ links: connection state and error counters (not the heartbeat, which ticks every second)
    daq = session.execute(select(func.count(), func.sum(cast(DaqStatusRow.connected, Integer)),
                                 func.sum(DaqStatusRow.frames_dropped), func.sum(DaqStatusRow.crc_errors))).one()
    return "|".join(str(v) for row in (ops, fits, alarms, diag, bdiag, brk, daq) for v in row)
