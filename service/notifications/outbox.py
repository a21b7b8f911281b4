"""The outbox's bookkeeping: a route takes in new events, forms its next message, and marks it
sent or failed. Each step is one short transaction; the sending happens between them, outside
any transaction, so a slow or unreachable receiver never holds a lock a fit or an alarm needs.

Exactly once per route: an event becomes one delivery row per route (unique), is put in one
message (its ``message_key``), and the message is retried unchanged until it is accepted; then
its deliveries are marked sent. Order per breaker: a route sends its messages in event order and
the next message is formed only after the previous one was accepted.
"""

from __future__ import annotations

from datetime import datetime, timedelta

from sqlalchemy import exists, func, or_, select, update

from service.notifications.message import message_key
from service.notifications.retry import backoff_s
from service.notifications.rows import NotificationDeliveryRow, NotificationEventRow, NotificationRouteRow

TAKE_IN_BATCH = 1000  # events examined per step (a backlog is taken in over several steps)
# An event older than this is committed or rolled back: every transaction that writes events is a
# fit's or an operator's, seconds long. Below the cursor nothing new can appear any more.
SETTLE = timedelta(minutes=10)

E, D = NotificationEventRow, NotificationDeliveryRow


def route_row(session, name: str) -> NotificationRouteRow:
    """The route's progress; a new route starts after the newest event (it is not sent the past)."""
    row = session.get(NotificationRouteRow, name)
    if row is None:
        newest = session.scalar(select(func.max(NotificationEventRow.id))) or 0
        row = NotificationRouteRow(name=name, cursor=newest, failures=0)
        session.add(row)
        session.flush()
    return row


def claim(session, name: str, *, owner: str, now: datetime, lease_s: float) -> bool:
    """Take (or renew) the route's lease, so one notifier at a time sends it (several API processes).
    A lease more than half left is kept as it is: no write at every idle round (SQLite has one writer)."""
    row = route_row(session, name)
    half = now + timedelta(seconds=lease_s / 2)
    if row.lease_owner == owner and row.lease_until is not None and row.lease_until > half:
        return True
    res = session.execute(update(NotificationRouteRow)
                          .where(NotificationRouteRow.name == name,
                                 or_(NotificationRouteRow.lease_owner.is_(None),
                                     NotificationRouteRow.lease_owner == owner,
                                     NotificationRouteRow.lease_until < now))
                          .values(lease_owner=owner, lease_until=now + timedelta(seconds=lease_s)))
    return res.rowcount == 1


def release(session, name: str, *, owner: str) -> None:
    session.execute(update(NotificationRouteRow).where(NotificationRouteRow.name == name,
                                                       NotificationRouteRow.lease_owner == owner)
                    .values(lease_owner=None, lease_until=None))


def _unconsidered(name: str):
    return ~exists().where(D.event_id == E.id, D.route == name)


def take_in(session, route, *, now: datetime) -> int:
    """Give each new event a delivery row for this route: pending when the route takes it,
    skipped when its filters or a silence (shelved, out of service) say no. Returns how many
    are pending. Events are found by the missing row, not by id alone: on PostgreSQL a
    transaction may commit a lower id after a higher one."""
    row = route_row(session, route.name)
    events = list(session.scalars(select(E).where(E.id > row.cursor, _unconsidered(route.name))
                                  .order_by(E.id).limit(TAKE_IN_BATCH)))
    added = 0
    for ev in events:
        take = ev.silenced is None and route.matches(kind=ev.kind, severity=ev.severity, parameter=ev.parameter,
                                                     breaker=ev.payload.get("breaker", {}))
        session.add(D(event_id=ev.id, route=route.name, status="pending" if take else "skipped", attempts=0))
        added += take
    session.flush()
    settled = session.scalar(select(func.max(E.id)).where(E.id > row.cursor, E.created_at < now - SETTLE))
    if settled is not None and session.scalar(select(func.count()).select_from(E).where(
            E.id > row.cursor, E.id <= settled, _unconsidered(route.name))) == 0:
        row.cursor = settled
    return added


def unconsidered(session, name: str) -> int:
    """Events the route has not taken in yet (it takes them in at its next round)."""
    row = route_row(session, name)
    return session.scalar(select(func.count()).select_from(E).where(E.id > row.cursor, _unconsidered(name)))


def _payload(ev: NotificationEventRow) -> dict:
    return {**ev.payload, "sequence": ev.id}


def next_message(session, route, *, now: datetime, group_interval_s: float,
                 max_events: int) -> tuple[str, list[dict]] | None:
    """``(key, events)`` of the route's next message, or None (nothing due: no events, backing
    off, or within the group interval of the last message)."""
    row = route_row(session, route.name)
    if row.next_attempt_at is not None and now < row.next_attempt_at:
        return None
    base = (select(NotificationDeliveryRow, NotificationEventRow)
            .join(NotificationEventRow, NotificationEventRow.id == NotificationDeliveryRow.event_id)
            .where(NotificationDeliveryRow.route == route.name, NotificationDeliveryRow.status == "pending"))
    formed = session.execute(base.where(NotificationDeliveryRow.message_key.is_not(None))
                             .order_by(NotificationDeliveryRow.event_id)).all()
    if formed:  # a message that failed before: the same events under the same key
        key = formed[0][0].message_key
        return key, [_payload(ev) for d, ev in formed if d.message_key == key]
    if row.last_sent_at is not None and now < row.last_sent_at + timedelta(seconds=group_interval_s):
        return None
    pending = session.execute(base.where(NotificationDeliveryRow.message_key.is_(None))
                              .order_by(NotificationDeliveryRow.event_id).limit(max_events)).all()
    if not pending:
        return None
    key = message_key([ev.key for _, ev in pending])
    for d, _ in pending:
        d.message_key = key
    session.flush()
    return key, [_payload(ev) for _, ev in pending]


def mark_sent(session, name: str, key: str, *, now: datetime) -> int:
    """The receiver accepted message ``key``: its deliveries are done (with the number of
    attempts it took); the route is healthy again."""
    row = route_row(session, name)
    res = session.execute(update(NotificationDeliveryRow)
                          .where(NotificationDeliveryRow.route == name, NotificationDeliveryRow.message_key == key,
                                 NotificationDeliveryRow.status == "pending")
                          .values(status="sent", sent_at=now, attempts=row.failures + 1))
    row.failures, row.next_attempt_at, row.last_error, row.last_sent_at = 0, None, None, now
    return res.rowcount


def mark_failed(session, name: str, key: str, *, now: datetime, error: str, retry_min_s: float,
                retry_max_s: float) -> datetime:
    """Message ``key`` was not accepted: it waits (exponential backoff) and is sent again as it is.
    Only the route's row is written (one small write per attempt, however large the message)."""
    row = route_row(session, name)
    row.failures += 1
    row.last_error = error[:2000]
    row.next_attempt_at = now + timedelta(seconds=backoff_s(row.failures, first_s=retry_min_s, max_s=retry_max_s))
    return row.next_attempt_at


def backlog(session) -> dict[str, int]:
    """Route name -> events taken in and not yet accepted by its receiver."""
    q = (select(NotificationDeliveryRow.route, func.count()).where(NotificationDeliveryRow.status == "pending")
         .group_by(NotificationDeliveryRow.route))
    return dict(session.execute(q).all())
