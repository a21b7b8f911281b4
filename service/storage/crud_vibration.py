"""Storage reads of the vibration channel's results: they live in the fits' JSON
``characteristics`` column (``latch_time_s``, ``vibration_events``, ``vibration_envelope``), so no
table of their own. The breaker's fingerprint rows and the latch time's history for the drift
detector."""

from __future__ import annotations

from datetime import datetime
from types import SimpleNamespace

from sqlalchemy import select
from sqlalchemy.orm import Session

from .models import BreakerRow, FitRow, OperationRow

FINGERPRINT_OPERATIONS = 10
"""The breaker's first healthy operations of a kind its fingerprint is learnt from."""


def _done_fits(breaker_id: int, kind: str, since: datetime | None):
    q = (select(FitRow.operation_id, OperationRow.occurred_at, FitRow.characteristics)
         .join(OperationRow, OperationRow.id == FitRow.operation_id)
         .where(FitRow.breaker_id == breaker_id, FitRow.kind == kind, FitRow.status == "done",
                OperationRow.clock_suspect.is_(False)))
    if since is not None:
        q = q.where(OperationRow.occurred_at >= since)
    return q.order_by(OperationRow.occurred_at, OperationRow.id)


def fingerprint_rows(session: Session, *, breaker_id: int, kind: str,
                     count: int = FINGERPRINT_OPERATIONS) -> list[tuple[int, dict]]:
    """(operation id, characteristics) of the breaker's first ``count`` done fits of ``kind`` with a
    read vibration since its last baseline reset (a maintenance starts a new fingerprint)."""
    since = session.scalar(select(BreakerRow.baseline_reset_at).where(BreakerRow.id == breaker_id))
    out = []
    for op_id, _, ch in session.execute(_done_fits(breaker_id, kind, since)):
        if ch and ch.get("vibration_events"):
            out.append((op_id, ch))
            if len(out) >= count:
                break
    return out


def breaker_fingerprint(session: Session, *, breaker_id: int, kind: str):
    """The breaker's learnt ``service.vibration.Fingerprint`` of ``kind``, or None (too few yet)."""
    from service.vibration import Fingerprint

    rows = fingerprint_rows(session, breaker_id=breaker_id, kind=kind)
    fp = Fingerprint(kind)
    if len(rows) < fp.min_operations:
        return None
    return fp.fit([ch for _, ch in rows], operation_ids=[i for i, _ in rows])


WATCHABLE = ("latch_time_s", "buffer_ratio")
"""The vibration's characteristics the drift detector may watch (``[alarms.watched]``)."""


def characteristic_history(session: Session, *, breaker_id: int, name: str, since: datetime | None = None) -> list:
    """The openings' values of characteristic ``name`` (``WATCHABLE``), oldest first, shaped like
    parameter rows; the latch time through :func:`latch_history` (a missed strike left out)."""
    if name == "latch_time_s":
        return latch_history(session, breaker_id=breaker_id, since=since)
    return [SimpleNamespace(operation_id=op_id, occurred_at=t, value=float(ch[name]), ci_low=None, ci_high=None)
            for op_id, t, ch in session.execute(_done_fits(breaker_id, "open", since))
            if ch and isinstance(ch.get(name), (int, float))]


def latch_history(session: Session, *, breaker_id: int, since: datetime | None = None) -> list:
    """The openings' read latch times [s], oldest first, shaped like parameter rows for the drift
    detector (``operation_id``, ``occurred_at``, ``value``; no interval). An opening whose first
    shock sits where the breaker's fingerprint has its latch release (the strike missed) is left out."""
    fp = breaker_fingerprint(session, breaker_id=breaker_id, kind="open")
    return [SimpleNamespace(operation_id=op_id, occurred_at=t, value=float(ch["latch_time_s"]),
                            ci_low=None, ci_high=None)
            for op_id, t, ch in session.execute(_done_fits(breaker_id, "open", since))
            if ch and isinstance(ch.get("latch_time_s"), (int, float))
            and (fp is None or not fp.shift(ch)["strike_not_seen"])]
