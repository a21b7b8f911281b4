"""Events no stored transition makes, found by looking at the stored state each round:

- a shelve that ended by itself (its time is up): ``unshelved``;
- a breaker's prognosis entering (``prognosis_entered``) or leaving (``prognosis_left``) its last
  N weeks before a limit, from the prognoses the worker stores as each fit lands.

Each is decided against the events already in the outbox, so it is written once however often
it is looked at, and after a restart too.
"""

from __future__ import annotations

import uuid
from datetime import datetime, timedelta, timezone

from sqlalchemy import select

from service.notifications.events import alarm_payload, prognosis_payload, silenced_reason
from service.notifications.rows import NotificationEventRow
from service.storage.models import AlarmRow, BreakerRow, PrognosisRow

_ALARM_FIELDS = ("id", "parameter", "level", "state", "episode", "message", "raised_at", "first_out",
                 "shelved_until", "shelved_by", "shelve_reason", "acknowledged_by", "ack_comment", "evidence",
                 "operation_id")


def _breaker(b: BreakerRow) -> dict:
    return {"id": b.id, "name": b.name, "tag": b.tag}


def _last_kind(session, where, kinds) -> str | None:
    return session.scalar(select(NotificationEventRow.kind).where(*where, NotificationEventRow.kind.in_(kinds))
                          .order_by(NotificationEventRow.id.desc()).limit(1))


def _add(session, *, kind: str, breaker: BreakerRow, alarm_id, parameter, severity, payload, now) -> None:
    session.add(NotificationEventRow(key=payload["id"], kind=kind, breaker_id=breaker.id, alarm_id=alarm_id,
                                     parameter=parameter, severity=severity, payload=payload, created_at=now,
                                     silenced=silenced_reason(kind, shelved_until=None, now=now,
                                                              out_of_service_since=breaker.out_of_service_since)))


def shelve_expiries(session, *, now: datetime) -> int:
    """``unshelved`` for each active alarm whose shelve ran out since its ``shelved`` event."""
    q = select(AlarmRow).where(AlarmRow.state.in_(("raised", "acknowledged")), AlarmRow.shelved_until.is_not(None),
                               AlarmRow.shelved_until <= now)
    n = 0
    for alarm in session.scalars(q):
        if _last_kind(session, (NotificationEventRow.alarm_id == alarm.id,), ("shelved", "unshelved")) != "shelved":
            continue
        breaker = session.get(BreakerRow, alarm.breaker_id)
        values = {f: getattr(alarm, f) for f in _ALARM_FIELDS}
        payload = alarm_payload("unshelved", key=uuid.uuid4().hex, alarm=values, breaker=_breaker(breaker), now=now)
        payload["reason"] = "the shelving time ended"
        _add(session, kind="unshelved", breaker=breaker, alarm_id=alarm.id, parameter=alarm.parameter,
             severity=alarm.level, payload=payload, now=now)
        n += 1
    session.flush()
    return n


def within(result: dict, *, weeks: float, now: datetime) -> bool:
    """Is the limit expected within ``weeks`` (median date), or already crossed?"""
    if result.get("status") == "crossed":
        return True
    median = (result.get("date_to_limit") or {}).get("median")
    if not median:
        return False
    when = datetime.fromisoformat(median.replace("Z", "+00:00"))
    if when.tzinfo is None:
        when = when.replace(tzinfo=timezone.utc)
    return when - now <= timedelta(weeks=weeks)


def prognosis_windows(session, *, weeks: float, now: datetime) -> int:
    """``prognosis_entered`` / ``prognosis_left`` where a stored prognosis crossed the window."""
    n = 0
    for p in session.scalars(select(PrognosisRow)):
        inside = within(p.result or {}, weeks=weeks, now=now)
        last = _last_kind(session, (NotificationEventRow.breaker_id == p.breaker_id,
                                    NotificationEventRow.parameter == p.parameter),
                          ("prognosis_entered", "prognosis_left"))
        was = last == "prognosis_entered"
        if inside == was:
            continue
        kind = "prognosis_entered" if inside else "prognosis_left"
        breaker = session.get(BreakerRow, p.breaker_id)
        payload = prognosis_payload(kind, key=uuid.uuid4().hex, breaker=_breaker(breaker), parameter=p.parameter,
                                    weeks=weeks, result=p.result or {}, now=now)
        _add(session, kind=kind, breaker=breaker, alarm_id=None, parameter=p.parameter, severity="warning",
             payload=payload, now=now)
        n += 1
    session.flush()
    return n
