"""Outbox writes: every stored alarm transition adds its event rows in the same transaction.

Hooked on the alarm table's mapper (after insert, after update), so every path that changes an
alarm (the detector's raise, escalation and clear, an operator's acknowledge, shelve and
unshelve, a baseline reset) records its event without knowing of notifications, and the event
exists exactly when the transition is committed: nothing is lost, and nothing is sent for a
transition that was rolled back. Writing a row is all it does; sending is the notifier's.
"""

from __future__ import annotations

import uuid
from typing import Any

from sqlalchemy import event, insert, inspect, select

from service.notifications.events import alarm_payload, alarm_transitions, silenced_reason
from service.notifications.rows import NotificationEventRow
from service.storage.models import AlarmRow, BreakerRow, utcnow

_WATCHED = ("state", "level", "shelved_until")
_FIELDS = ("id", "parameter", "level", "state", "episode", "message", "raised_at", "first_out", "shelved_until",
           "shelved_by", "shelve_reason", "acknowledged_by", "ack_comment", "evidence", "operation_id")


def install() -> None:
    """Hook the alarm table (idempotent; every process that stores alarms calls it)."""
    if not event.contains(AlarmRow, "after_insert", _after_insert):
        event.listen(AlarmRow, "after_insert", _after_insert)
        event.listen(AlarmRow, "after_update", _after_update)


def uninstall() -> None:
    """For tests that need a database without the hook."""
    if event.contains(AlarmRow, "after_insert", _after_insert):
        event.remove(AlarmRow, "after_insert", _after_insert)
        event.remove(AlarmRow, "after_update", _after_update)


def _after_insert(mapper, connection, target: AlarmRow) -> None:
    _record(connection, target, inserted=True, old={})


def _after_update(mapper, connection, target: AlarmRow) -> None:
    state = inspect(target)
    old = {}
    for name in _WATCHED:
        hist = state.attrs[name].history
        if hist.added or hist.deleted:
            old[name] = hist.deleted[0] if hist.deleted else None
    if old:
        _record(connection, target, inserted=False, old=old)


def _record(connection, alarm: AlarmRow, *, inserted: bool, old: dict[str, Any]) -> None:
    now = utcnow()
    values = {f: getattr(alarm, f) for f in _FIELDS}
    kinds = alarm_transitions(inserted=inserted, old=old, new=values, now=now)
    if not kinds:
        return
    b = connection.execute(select(BreakerRow.id, BreakerRow.name, BreakerRow.tag, BreakerRow.out_of_service_since)
                           .where(BreakerRow.id == alarm.breaker_id)).one()
    breaker = {"id": b.id, "name": b.name, "tag": b.tag}
    rows = []
    for kind in kinds:
        key = uuid.uuid4().hex
        rows.append({"key": key, "kind": kind, "breaker_id": b.id, "alarm_id": alarm.id,
                     "parameter": alarm.parameter, "severity": alarm.level, "created_at": now,
                     "silenced": silenced_reason(kind, shelved_until=alarm.shelved_until,
                                                 out_of_service_since=b.out_of_service_since, now=now),
                     "payload": alarm_payload(kind, key=key, alarm=values, breaker=breaker, now=now)})
    for row in rows:  # one by one: ids in the order of the kinds
        connection.execute(insert(NotificationEventRow).values(**row))
