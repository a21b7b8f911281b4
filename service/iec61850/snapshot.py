"""Read what the IEC 61850 point map needs from the database (``points.BreakerView``).

Fits are stored by workers that may run on other machines, so the server polls the database
rather than hooking the worker: ``fingerprint`` is one cheap query set that changes whenever a
fit lands, an alarm changes or an operation is stored; the full read runs only then (or every
few seconds, for DAQ-down and staleness transitions).
"""

from __future__ import annotations

from datetime import datetime, timedelta

from sqlalchemy import func, select

from service.storage import crud
from service.storage.crud_alarms import annunciated
from service.storage.models import AlarmRow, BreakerRow, FitRow, OperationRow

from .points import BreakerView, FitView, operating_time_level


def fingerprint(session) -> tuple:
    """Changes whenever breakers, operations, finished fits or alarms change."""
    ops = session.execute(select(func.count(OperationRow.id), func.max(OperationRow.id))).one()
    fits = session.execute(select(func.count(FitRow.id), func.max(FitRow.finished_at))
                           .where(FitRow.status == "done")).one()
    alarms = session.execute(select(func.count(AlarmRow.id), func.max(AlarmRow.updated_at))).one()
    breakers = tuple(session.execute(select(BreakerRow.id, BreakerRow.name, BreakerRow.tag,
                                            BreakerRow.baseline_reset_at).order_by(BreakerRow.id)).all())
    return tuple(ops), tuple(fits), tuple(alarms), breakers


def breakers(session) -> list[tuple[int, str, str]]:
    """(id, name, tag) of every registered breaker."""
    return [(b.id, b.name, b.tag) for b in crud.list_breakers(session)]


def _fit_view(fit: FitRow | None) -> FitView | None:
    if fit is None:
        return None
    chars = fit.characteristics or (fit.result or {}).get("characteristics") or {}
    tm = chars.get("operating_time_s")
    latch = chars.get("latch_time_s")
    return FitView(parameters=dict(fit.parameters or {}), identifiable=fit.identifiable,
                   occurred_at=fit.operation.occurred_at,
                   operating_time_s=float(tm) if isinstance(tm, (int, float)) else None,
                   latch_time_s=float(latch) if isinstance(latch, (int, float)) else None)


class OperatingTimeCache:
    """Drift level of each breaker's operating times, recomputed only when its fits change."""

    def __init__(self):
        self._cache: dict = {}

    def level(self, session, *, breaker: BreakerRow, kind: str, settings) -> str:
        q = (select(FitRow.operation_id, OperationRow.occurred_at, FitRow.characteristics)
             .join(OperationRow, OperationRow.id == FitRow.operation_id)
             .where(FitRow.breaker_id == breaker.id, FitRow.kind == kind, FitRow.status == "done",
                    FitRow.identifiable.is_not(False), OperationRow.clock_suspect.is_(False)))
        if breaker.baseline_reset_at is not None:
            q = q.where(OperationRow.occurred_at >= breaker.baseline_reset_at)
        sub = q.subquery()
        key_q = select(func.count(), func.max(sub.c.operation_id))
        key = (breaker.id, kind, tuple(session.execute(key_q).one()), breaker.baseline_reset_at)
        if key in self._cache:
            return self._cache[key]
        history = []
        for op_id, t, chars in session.execute(q.order_by(OperationRow.occurred_at, FitRow.operation_id)):
            tm = (chars or {}).get("operating_time_s")
            if isinstance(tm, (int, float)) and tm == tm:
                history.append((op_id, t, float(tm)))
        level = operating_time_level(history, settings)
        self._cache = {k: v for k, v in self._cache.items() if k[:2] != key[:2]}
        self._cache[key] = level
        return level


def breaker_views(session, *, now: datetime, daq_timeout_s: float, drift_settings,
                  cache: OperatingTimeCache) -> dict[int, BreakerView]:
    """A ``BreakerView`` per breaker id."""
    from service.jobs.prognosis import soonest_by_breaker

    daq = {d.breaker_id: d for d in crud.daq_statuses(session)}
    soonest = soonest_by_breaker(session)
    timeout = timedelta(seconds=daq_timeout_s)
    out = {}
    for b in crud.list_breakers(session):
        n_ops = session.scalar(select(func.count(OperationRow.id)).where(OperationRow.breaker_id == b.id))
        last = session.execute(select(OperationRow.kind, OperationRow.occurred_at)
                               .where(OperationRow.breaker_id == b.id, OperationRow.clock_suspect.is_(False))
                               .order_by(OperationRow.occurred_at.desc(), OperationRow.id.desc()).limit(1)).first()
        alarms = {a.parameter: a.level
                  for a in annunciated(crud.list_alarms(session, state="active", breaker_id=b.id), now)}
        d = daq.get(b.id)
        daq_down = d is not None and (not d.connected or d.last_seen is None or now - d.last_seen > timeout)
        out[b.id] = BreakerView(
            name=b.name, tag=b.tag, operations=int(n_ops or 0),
            last_kind=last[0] if last else None, last_operation_at=last[1] if last else None,
            fits={k: _fit_view(crud.latest_fit(session, breaker_id=b.id, kind=k)) for k in ("open", "close")},
            alarms=alarms, daq_down=daq_down, soonest=soonest.get(b.id),
            operating_time_levels={k: cache.level(session, breaker=b, kind=k, settings=drift_settings)
                                   for k in ("open", "close")})
    return out
