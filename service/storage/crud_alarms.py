"""Storage of the alarm lifecycle and of temperatures: SCADA temperature, shelving, out of
service, the audit trail, alarm history with first-out, and the evidence series of a parameter."""

from __future__ import annotations

from datetime import datetime, timedelta

from sqlalchemy import select
from sqlalchemy.orm import Session

from service.storage.models import (AlarmActionRow, AlarmRow, BreakerRow, OperationRow,
                                    ParameterValueRow, utcnow)

# A SCADA temperature applies to an operation up to this long after it was written: ambient
# follows a daily swing of about +-6 K, at most 6 K * 2 pi / 24 h = 1.6 K/h, so within 1 h it is
# off by < 1.6 K (0.6 % of DO at -0.4 %/K, below the 1-2 % run-to-run spread).
SCADA_TEMPERATURE_MAX_AGE = timedelta(hours=1)


def operation_temperature(session: Session, *, breaker_id: int, occurred_at: datetime,
                          temperature_c: float | None, source: str | None) -> tuple[float | None, str | None]:
    """(temperature [C], source) for a new operation: its own, else the breaker's latest SCADA
    value if written at most SCADA_TEMPERATURE_MAX_AGE before (or any time after) the operation."""
    if temperature_c is not None:
        return float(temperature_c), source or "upload"
    row = session.get(BreakerRow, breaker_id)
    if row is None or row.scada_temperature_c is None or row.scada_temperature_at is None:
        return None, None
    if occurred_at.tzinfo is None:
        from datetime import timezone

        occurred_at = occurred_at.replace(tzinfo=timezone.utc)
    if row.scada_temperature_at < occurred_at - SCADA_TEMPERATURE_MAX_AGE:
        return None, None
    return float(row.scada_temperature_c), "scada"


def set_scada_temperature(session: Session, *, breaker: BreakerRow, temperature_c: float,
                          at: datetime | None = None) -> None:
    breaker.scada_temperature_c = float(temperature_c)
    breaker.scada_temperature_at = at or utcnow()
    # Operations already stored without a temperature whose fit has not been fed to the
    # detector yet are left alone: the value is applied forwards only, never to the past.


def operation_temperatures(session: Session, operation_ids) -> dict[int, float | None]:
    ids = list(operation_ids)
    if not ids:
        return {}
    rows = session.execute(select(OperationRow.id, OperationRow.temperature_c)
                           .where(OperationRow.id.in_(ids)))
    return {i: t for i, t in rows}


def shelved_now(alarm: AlarmRow, now: datetime) -> bool:
    """An active alarm inside its shelve (``service.alarms.lifecycle.AlarmView.shelved``)."""
    return (alarm.state in ("raised", "acknowledged") and alarm.shelved_until is not None
            and now < alarm.shelved_until)


def annunciated(alarms, now: datetime) -> list[AlarmRow]:
    """The alarms an operator is told of: the active ones not shelved (ISA-18.2 shelving
    suppresses the annunciation, not the record; history and the alarm list still show them)."""
    return [a for a in alarms if not shelved_now(a, now)]


def shelved_parameters(session: Session, *, breaker_id: int, now: datetime) -> set[str]:
    """The watched parameters of the breaker whose active alarm is shelved at ``now``."""
    q = select(AlarmRow).where(AlarmRow.breaker_id == breaker_id, AlarmRow.state.in_(("raised", "acknowledged")),
                               AlarmRow.shelved_until.is_not(None))
    return {a.parameter for a in session.scalars(q) if shelved_now(a, now)}


def add_action(session: Session, *, breaker_id: int, action, alarm_id: int | None = None) -> AlarmActionRow:
    """Store one audited ``service.alarms.lifecycle.Action``."""
    row = AlarmActionRow(breaker_id=breaker_id, alarm_id=alarm_id if alarm_id is not None else action.alarm_id,
                         action=action.action, by=action.by, at=action.at, reason=action.reason or "",
                         until=action.until)
    session.add(row)
    session.flush()
    return row


def list_actions(session: Session, *, breaker_id: int | None = None, alarm_id: int | None = None,
                 limit: int = 200) -> list[AlarmActionRow]:
    q = select(AlarmActionRow)
    if breaker_id is not None:
        q = q.where(AlarmActionRow.breaker_id == breaker_id)
    if alarm_id is not None:
        q = q.where(AlarmActionRow.alarm_id == alarm_id)
    return list(session.scalars(q.order_by(AlarmActionRow.at.desc(), AlarmActionRow.id.desc()).limit(limit)))


def alarm_history(session: Session, *, breaker_id: int, limit: int = 200) -> list[AlarmRow]:
    """The breaker's alarms in the order they were raised (oldest first), first-out marked."""
    q = (select(AlarmRow).where(AlarmRow.breaker_id == breaker_id)
         .order_by(AlarmRow.raised_at, AlarmRow.id).limit(limit))
    return list(session.scalars(q))


def first_out_now(session: Session, *, breaker_id: int, exclude_id: int | None = None) -> bool:
    """True when no alarm of the breaker is active now: a new one would be first-out."""
    q = select(AlarmRow.id).where(AlarmRow.breaker_id == breaker_id,
                                  AlarmRow.state.in_(("raised", "acknowledged")))
    if exclude_id is not None:
        q = q.where(AlarmRow.id != exclude_id)
    return session.scalar(q.limit(1)) is None


def parameter_series(session: Session, *, breaker_id: int, name: str, since: datetime | None = None):
    """(operation id, time, value, ci_low, ci_high, temperature) of the identifiable fits of one
    parameter, oldest first: the detector's input, for the evidence plot."""
    q = (select(ParameterValueRow.operation_id, ParameterValueRow.occurred_at, ParameterValueRow.value,
                ParameterValueRow.ci_low, ParameterValueRow.ci_high, OperationRow.temperature_c)
         .join(OperationRow, OperationRow.id == ParameterValueRow.operation_id)
         .where(ParameterValueRow.breaker_id == breaker_id, ParameterValueRow.name == name,
                ParameterValueRow.identifiable.is_(True)))
    if since is not None:
        q = q.where(ParameterValueRow.occurred_at >= since)
    return list(session.execute(q.order_by(ParameterValueRow.occurred_at, ParameterValueRow.id)))
