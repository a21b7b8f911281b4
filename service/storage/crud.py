"""Queries and updates. Every function takes the session first and keyword-only arguments."""

from __future__ import annotations

import hashlib
import secrets
import threading
from datetime import datetime
from pathlib import Path

from sqlalchemy import func, select, update
from sqlalchemy.orm import Session

from .models import (AlarmRow, ApiKeyRow, BreakerRow, DaqStatusRow, FitRow, OperationRow,
                     ParameterValueRow, utcnow)

# ``agent`` (an edge agent) ranks below reader: it may only upload captures (``require(..., also=)``).
ROLE_RANK = {"agent": -1, "reader": 0, "operator": 1, "admin": 2}


# -- breakers ----------------------------------------------------------------------------------
def register_breaker_file(session: Session, *, path: Path, tag: str | None = None) -> BreakerRow:
    """Create or refresh the breaker described by the breaker file at ``path`` (and its cam table)."""
    from service.breaker_file import load_breaker, parse_breaker_text

    path = Path(path)
    breaker = load_breaker(path)  # validates before anything is stored
    text = path.read_text()
    cam = parse_breaker_text(text, source=str(path)).cam  # none for an unknown design
    cam_name = cam.profile if cam is not None else ""
    cam_text = (path.parent / cam_name).read_text() if cam_name else ""
    return upsert_breaker(session, name=breaker.name, tag=tag, breaker_file=text,
                          cam_file_name=cam_name, cam_table=cam_text)


def upsert_breaker(session: Session, *, name: str, breaker_file: str, cam_file_name: str,
                   cam_table: str, tag: str | None = None) -> BreakerRow:
    digest = hashlib.sha256((breaker_file + "\0" + cam_table).encode()).hexdigest()
    row = session.scalar(select(BreakerRow).where(BreakerRow.name == name))
    if row is None:
        row = BreakerRow(name=name, tag=tag or name, breaker_file=breaker_file, cam_file_name=cam_file_name,
                         cam_table=cam_table, content_sha256=digest)
        session.add(row)
    else:
        if row.content_sha256 != digest:
            row.breaker_file, row.cam_file_name, row.cam_table = breaker_file, cam_file_name, cam_table
            row.content_sha256 = digest
            row.updated_at = utcnow()
        if tag and row.tag != tag:
            row.tag = tag
    session.flush()
    return row


def list_breakers(session: Session) -> list[BreakerRow]:
    return list(session.scalars(select(BreakerRow).order_by(BreakerRow.id)))


def get_breaker(session: Session, *, breaker_id: int) -> BreakerRow | None:
    return session.get(BreakerRow, breaker_id)


def get_breaker_by_name(session: Session, *, name: str) -> BreakerRow | None:
    return session.scalar(select(BreakerRow).where(BreakerRow.name == name))


_breaker_cache: dict[str, object] = {}
_breaker_lock = threading.Lock()


def breaker_model(row: BreakerRow):
    """The ``Breaker`` stored in ``row`` (materialised once per content hash and process)."""
    from service.breaker_file import breaker_from_text

    with _breaker_lock:
        hit = _breaker_cache.get(row.content_sha256)
        if hit is not None:
            return hit
        breaker = breaker_from_text(row.breaker_file, row.cam_table, source=f"of breaker {row.name!r}",
                                    default_name=row.name)
        _breaker_cache[row.content_sha256] = breaker
        return breaker


# -- operations and fits -----------------------------------------------------------------------
def create_operation(session: Session, *, capture_key: str, breaker_id: int, kind: str,
                     occurred_at: datetime, source: str, capture_path: str, capture_sha256: str,
                     flags: list, sample_rate: float, n_samples: int, clock_suspect: bool = False,
                     temperature_c: float | None = None,
                     temperature_source: str | None = None) -> tuple[OperationRow, bool]:
    """Store an operation and queue its fit. Idempotent on ``capture_key``: returns (row, created).

    ``temperature_c`` [C]: the operation's own (upload field, agent, capture channel); without
    it the breaker's latest SCADA temperature applies (service/storage/crud_alarms.py)."""
    existing = session.scalar(select(OperationRow).where(OperationRow.capture_key == capture_key))
    if existing is not None:
        return existing, False
    op = OperationRow(capture_key=capture_key, breaker_id=breaker_id, kind=kind, occurred_at=occurred_at,
                      source=source, capture_path=capture_path, capture_sha256=capture_sha256,
                      flags=list(flags), sample_rate=float(sample_rate), n_samples=int(n_samples),
                      clock_suspect=bool(clock_suspect))
    from service.storage.crud_alarms import operation_temperature

    op.temperature_c, op.temperature_source = operation_temperature(
        session, breaker_id=breaker_id, occurred_at=occurred_at, temperature_c=temperature_c,
        source=temperature_source)
    session.add(op)
    session.flush()
    session.add(FitRow(operation_id=op.id, breaker_id=breaker_id, kind=kind, status="queued"))
    session.flush()
    return op, True


def get_operation_by_key(session: Session, *, capture_key: str) -> OperationRow | None:
    return session.scalar(select(OperationRow).where(OperationRow.capture_key == capture_key))


def get_operation(session: Session, *, operation_id: int) -> OperationRow | None:
    return session.get(OperationRow, operation_id)


def list_operations(session: Session, *, breaker_id: int, limit: int = 50,
                    clock_suspect: bool | None = None) -> list[OperationRow]:
    q = select(OperationRow).where(OperationRow.breaker_id == breaker_id)
    if clock_suspect is not None:
        q = q.where(OperationRow.clock_suspect.is_(clock_suspect))
    q = (q
         .order_by(OperationRow.occurred_at.desc(), OperationRow.id.desc()).limit(limit))
    return list(session.scalars(q))


def count_operations(session: Session) -> int:
    return int(session.scalar(select(func.count()).select_from(OperationRow)) or 0)


def pending_operation_ids(session: Session) -> list[int]:
    """Operations whose fit is queued or was running when the service stopped."""
    q = select(FitRow.operation_id).where(FitRow.status.in_(("queued", "running"))).order_by(FitRow.operation_id)
    return list(session.scalars(q))


def queue_depth(session: Session) -> int:
    return int(session.scalar(select(func.count()).select_from(FitRow)
                              .where(FitRow.status.in_(("queued", "running")))) or 0)


def requeue_stale_fits(session: Session, *, older_than) -> list[int]:
    """Fits still `running` since before ``older_than``: their worker died without a word (a lost
    machine, a task that exhausted its retries). They go back to `queued`; returns their operations."""
    stale = list(session.scalars(select(FitRow.operation_id)
                                 .where(FitRow.status == "running", FitRow.started_at < older_than)))
    if stale:
        session.execute(update(FitRow).where(FitRow.operation_id.in_(stale), FitRow.status == "running",
                                             FitRow.started_at < older_than)
                        .values(status="queued", queued_at=utcnow()))
    return stale


def claim_fit(session: Session, *, operation_id: int, worker: str) -> FitRow | None:
    """Mark the fit running (one more attempt). None when it is already done or failed."""
    res = session.execute(update(FitRow)
                          .where(FitRow.operation_id == operation_id, FitRow.status.in_(("queued", "running")))
                          .values(status="running", attempts=FitRow.attempts + 1, started_at=utcnow(),
                                  worker=worker))
    if res.rowcount != 1:
        return None
    session.flush()
    return session.scalar(select(FitRow).where(FitRow.operation_id == operation_id)
                          .execution_options(populate_existing=True))


def fit_result_values(result: dict, curve: dict | None, finished_at) -> dict:
    """The fits row's columns for a finished fit (a new fit and a refit write the same ones)."""
    window = result.get("window_s") or (None, None)
    return dict(status="done", failure_reason=None, parameters=result.get("parameters"),
                ci95=result.get("ci95"), stderr=result.get("stderr"), rmse_rad=result.get("rmse_rad"),
                fitness=result.get("fitness"), window_start_s=window[0], window_end_s=window[1],
                onset_delay_s=result.get("onset_delay_s"), noise_rad=result.get("noise_rad"),
                evaluations=result.get("evaluations"), runtime_s=result.get("runtime_s"),
                identifiable=result.get("identifiable"), condition_number=result.get("condition_number"),
                dc_used=result.get("dc_used"), dc_source=result.get("dc_source"),
                warnings=list(result.get("warnings") or []), characteristics=result.get("characteristics"),
                curve=curve, result=result, finished_at=finished_at)


def store_fit_result(session: Session, *, operation_id: int, result: dict, curve: dict | None) -> bool:
    """Store a finished fit exactly once. False when another attempt already stored one."""
    values = dict(fit_result_values(result, curve, utcnow()), results_stored=FitRow.results_stored + 1)
    res = session.execute(update(FitRow).where(FitRow.operation_id == operation_id,
                                               FitRow.status.in_(("queued", "running"))).values(**values))
    if res.rowcount != 1:
        return False
    fit = session.scalar(select(FitRow).where(FitRow.operation_id == operation_id))
    op = session.get(OperationRow, operation_id)
    ci = result.get("ci95") or {}
    for name, value in (result.get("parameters") or {}).items():
        lo, hi = (ci.get(name) or (None, None))[:2]
        session.add(ParameterValueRow(fit_id=fit.id, operation_id=operation_id, breaker_id=op.breaker_id,
                                      kind=op.kind, name=name, value=float(value),
                                      ci_low=None if lo is None else float(lo),
                                      ci_high=None if hi is None else float(hi),
                                      identifiable=bool(result.get("identifiable", True)),
                                      occurred_at=op.occurred_at))
    session.flush()
    return True


def store_fit_failure(session: Session, *, operation_id: int, reason: str) -> bool:
    res = session.execute(update(FitRow).where(FitRow.operation_id == operation_id,
                                               FitRow.status.in_(("queued", "running")))
                          .values(status="failed", failure_reason=reason[:4000], finished_at=utcnow()))
    return res.rowcount == 1


def get_fit(session: Session, *, operation_id: int) -> FitRow | None:
    return session.scalar(select(FitRow).where(FitRow.operation_id == operation_id))


def latest_opening_fit(session: Session, *, breaker_id: int, before: datetime | None = None) -> FitRow | None:
    """The breaker's latest good opening fit (done, with AO), optionally before a time."""
    q = (select(FitRow).join(OperationRow, OperationRow.id == FitRow.operation_id)
         .where(FitRow.breaker_id == breaker_id, FitRow.kind == "open", FitRow.status == "done",
                OperationRow.clock_suspect.is_(False)))
    if before is not None:
        q = q.where(OperationRow.occurred_at <= before)
    q = q.order_by(OperationRow.occurred_at.desc(), FitRow.id.desc()).limit(5)
    for fit in session.scalars(q):
        if fit.parameters and "AO" in fit.parameters and fit.identifiable is not False:
            return fit
    return None


def latest_good_fit(session: Session, *, breaker_id: int, kind: str,
                    before: datetime | None = None, exclude_operation: int | None = None) -> FitRow | None:
    """The breaker's latest identifiable finished fit of one kind (a warm-start prior)."""
    q = (select(FitRow).join(OperationRow, OperationRow.id == FitRow.operation_id)
         .where(FitRow.breaker_id == breaker_id, FitRow.kind == kind, FitRow.status == "done",
                FitRow.identifiable.is_not(False), OperationRow.clock_suspect.is_(False)))
    if before is not None:
        q = q.where(OperationRow.occurred_at <= before)
    if exclude_operation is not None:
        q = q.where(FitRow.operation_id != exclude_operation)
    return session.scalar(q.order_by(OperationRow.occurred_at.desc(), FitRow.id.desc()).limit(1))


def latest_fit(session: Session, *, breaker_id: int, kind: str) -> FitRow | None:
    """The breaker's latest finished fit of one kind; clock-suspect operations are never latest."""
    q = (select(FitRow).join(OperationRow, OperationRow.id == FitRow.operation_id)
         .where(FitRow.breaker_id == breaker_id, FitRow.kind == kind, FitRow.status == "done",
                OperationRow.clock_suspect.is_(False))
         .order_by(OperationRow.occurred_at.desc(), FitRow.id.desc()).limit(1))
    return session.scalar(q)


def parameter_trend(session: Session, *, breaker_id: int, name: str, since: datetime | None = None,
                    limit: int = 5000, clock_suspect: bool | None = False) -> list[ParameterValueRow]:
    """A parameter's values, oldest first; by default without clock-suspect operations
    (``clock_suspect``: True = only those, None = all)."""
    q = select(ParameterValueRow).where(ParameterValueRow.breaker_id == breaker_id, ParameterValueRow.name == name)
    if clock_suspect is not None:
        q = q.where(ParameterValueRow.operation_id.in_(select(OperationRow.id).where(
            OperationRow.breaker_id == breaker_id, OperationRow.clock_suspect.is_(clock_suspect))))
    if since is not None:
        q = q.where(ParameterValueRow.occurred_at >= since)
    q = q.order_by(ParameterValueRow.occurred_at, ParameterValueRow.id).limit(limit)
    return list(session.scalars(q))


def good_parameter_history(session: Session, *, breaker_id: int, name: str,
                           since: datetime | None = None, last: int | None = None) -> list[ParameterValueRow]:
    """Identifiable values of a parameter, oldest first, for the drift detector; with ``last``,
    only the newest ``last`` of them (still oldest first)."""
    q = select(ParameterValueRow).where(ParameterValueRow.breaker_id == breaker_id,
                                        ParameterValueRow.name == name, ParameterValueRow.identifiable.is_(True),
                                        ParameterValueRow.operation_id.not_in(_suspect_ids(breaker_id)))
    if since is not None:
        q = q.where(ParameterValueRow.occurred_at >= since)
    if last is not None:
        newest = q.order_by(ParameterValueRow.occurred_at.desc(), ParameterValueRow.id.desc()).limit(last)
        return list(reversed(list(session.scalars(newest))))
    return list(session.scalars(q.order_by(ParameterValueRow.occurred_at, ParameterValueRow.id)))


def _suspect_ids(breaker_id: int):
    """The breaker's clock-suspect operation ids (a subquery)."""
    return select(OperationRow.id).where(OperationRow.breaker_id == breaker_id, OperationRow.clock_suspect.is_(True))


# -- alarms ------------------------------------------------------------------------------------
def list_alarms(session: Session, *, state: str = "active", breaker_id: int | None = None) -> list[AlarmRow]:
    q = select(AlarmRow)
    if state == "active":
        q = q.where(AlarmRow.state.in_(("raised", "acknowledged")))
    elif state != "all":
        q = q.where(AlarmRow.state == state)
    if breaker_id is not None:
        q = q.where(AlarmRow.breaker_id == breaker_id)
    return list(session.scalars(q.order_by(AlarmRow.raised_at.desc(), AlarmRow.id.desc())))


def get_alarm(session: Session, *, alarm_id: int) -> AlarmRow | None:
    return session.get(AlarmRow, alarm_id)


def acknowledge_alarm(session: Session, *, alarm: AlarmRow, by: str, comment: str | None = None) -> AlarmRow:
    if alarm.state == "raised":
        alarm.state = "acknowledged"
        alarm.acknowledged_at = utcnow()
        alarm.acknowledged_by = by
        alarm.ack_comment = comment
        alarm.updated_at = utcnow()
        session.flush()
    return alarm


def active_alarm(session: Session, *, breaker_id: int, parameter: str) -> AlarmRow | None:
    q = (select(AlarmRow).where(AlarmRow.breaker_id == breaker_id, AlarmRow.parameter == parameter,
                                AlarmRow.state.in_(("raised", "acknowledged")))
         .order_by(AlarmRow.id.desc()).limit(1))
    return session.scalar(q)


# -- API keys ----------------------------------------------------------------------------------
def hash_key(key: str) -> str:
    return hashlib.sha256(key.encode()).hexdigest()


def create_api_key(session: Session, *, name: str, role: str, key: str | None = None) -> tuple[ApiKeyRow, str]:
    """Create a key; returns (row, plaintext). The plaintext is never stored."""
    if role not in ROLE_RANK:
        raise ValueError(f"role must be one of {', '.join(ROLE_RANK)}")
    key = key or "hvcb_" + secrets.token_urlsafe(32)
    row = ApiKeyRow(name=name, prefix=key[:12], key_hash=hash_key(key), role=role)
    session.add(row)
    session.flush()
    return row, key


def find_api_key(session: Session, *, key: str) -> ApiKeyRow | None:
    return session.scalar(select(ApiKeyRow).where(ApiKeyRow.key_hash == hash_key(key),
                                                  ApiKeyRow.revoked_at.is_(None)))


def list_api_keys(session: Session) -> list[ApiKeyRow]:
    return list(session.scalars(select(ApiKeyRow).order_by(ApiKeyRow.id)))


def count_api_keys(session: Session) -> int:
    return int(session.scalar(select(func.count()).select_from(ApiKeyRow)) or 0)


class LastAdminKey(Exception):
    """Revoking this key would leave no active admin key: nobody could manage keys any more."""


def revoke_api_key(session: Session, *, row: ApiKeyRow) -> ApiKeyRow:
    """Revoke ``row`` (already revoked: unchanged). Raises LastAdminKey instead of revoking the
    last active admin key. The active admin rows are locked first (``FOR UPDATE`` on
    PostgreSQL), so two admins revoking each other's key at once cannot both succeed."""
    if row.revoked_at is not None:
        return row
    if row.role == "admin":
        admins = session.scalars(select(ApiKeyRow.id).where(ApiKeyRow.role == "admin", ApiKeyRow.revoked_at.is_(None))
                                 .with_for_update()).all()
        if set(admins) <= {row.id}:
            raise LastAdminKey(row.id)
    row.revoked_at = utcnow()
    return row


# -- DAQ status --------------------------------------------------------------------------------
def report_daq(session: Session, *, breaker_id: int, connected: bool, frames: int = 0, frames_dropped: int = 0,
               crc_errors: int = 0, captures: int = 0, detail: str = "", seen_at: datetime | None = None) -> None:
    row = session.get(DaqStatusRow, breaker_id)
    if row is None:
        row = DaqStatusRow(breaker_id=breaker_id)
        session.add(row)
    row.connected, row.frames, row.frames_dropped = connected, frames, frames_dropped
    row.crc_errors, row.captures, row.detail = crc_errors, captures, detail
    row.last_seen = seen_at or utcnow()
    session.flush()


def daq_statuses(session: Session) -> list[DaqStatusRow]:
    return list(session.scalars(select(DaqStatusRow)))


def forget_daqs_except(session: Session, *, breaker_ids: list[int]) -> int:
    """Delete the stored DAQ status of every breaker not in ``breaker_ids`` (a DAQ removed from
    the settings), so its breaker is not shown with a dead DAQ forever. Returns rows deleted."""
    from sqlalchemy import delete

    res = session.execute(delete(DaqStatusRow).where(DaqStatusRow.breaker_id.not_in(breaker_ids)))
    return res.rowcount or 0
