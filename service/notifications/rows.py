"""The outbox's tables (migration 0013): the events, each route's progress, and the deliveries.

``notification_events`` is written in the same transaction as the alarm transition it records
(service.notifications.capture), so an event exists exactly when its transition does.
``notification_routes`` keeps each route's cursor (the last event it has taken in) and its
retry state; ``notification_deliveries`` holds one row per (event, route) until it is sent.
"""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import ForeignKey, Index, Integer, String, Text, UniqueConstraint
from sqlalchemy.orm import Mapped, mapped_column

from service.storage.models import Base, utcnow


class NotificationEventRow(Base):
    """One event for the notifiers; ``id`` orders them (per breaker too), ``key`` is the
    idempotency key receivers see. ``silenced`` says why no route gets it (shelved, out of
    service), None when it is routed."""

    __tablename__ = "notification_events"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    key: Mapped[str] = mapped_column(String(64), unique=True)
    kind: Mapped[str] = mapped_column(String(24))
    breaker_id: Mapped[int] = mapped_column(ForeignKey("breakers.id", ondelete="CASCADE"))
    alarm_id: Mapped[int | None] = mapped_column(ForeignKey("alarms.id", ondelete="SET NULL"))
    parameter: Mapped[str | None] = mapped_column(String(16))
    severity: Mapped[str] = mapped_column(String(10))
    silenced: Mapped[str | None] = mapped_column(Text)
    payload: Mapped[dict] = mapped_column(default=dict)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)

    __table_args__ = (Index("ix_notification_events_alarm", "alarm_id", "id"),)


class NotificationRouteRow(Base):
    """A configured route's progress: every event up to ``cursor`` has been taken in (a new route
    starts at the newest event: it is not sent the past), and its retry state."""

    __tablename__ = "notification_routes"
    name: Mapped[str] = mapped_column(String(60), primary_key=True)
    cursor: Mapped[int] = mapped_column(Integer, default=0)
    failures: Mapped[int] = mapped_column(Integer, default=0)  # consecutive failed attempts
    next_attempt_at: Mapped[datetime | None]
    last_error: Mapped[str | None] = mapped_column(Text)
    last_sent_at: Mapped[datetime | None]
    lease_owner: Mapped[str | None] = mapped_column(String(120))
    lease_until: Mapped[datetime | None]
    created_at: Mapped[datetime] = mapped_column(default=utcnow)


class NotificationDeliveryRow(Base):
    """One event for one route: ``status`` is "pending" until the receiver accepted it ("sent"),
    or "skipped" when the route does not take it (filters, silenced). Every event gets a row per
    route, so an event committed late (PostgreSQL may commit a lower id after a higher one) is
    still found. ``message_key`` is set when the event is put in a message (so a retried message
    is the same message)."""

    __tablename__ = "notification_deliveries"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    event_id: Mapped[int] = mapped_column(ForeignKey("notification_events.id", ondelete="CASCADE"))
    route: Mapped[str] = mapped_column(String(60))
    message_key: Mapped[str | None] = mapped_column(String(64))
    status: Mapped[str] = mapped_column(String(8), default="pending")
    attempts: Mapped[int] = mapped_column(Integer, default=0)
    sent_at: Mapped[datetime | None]

    __table_args__ = (UniqueConstraint("event_id", "route", name="uq_notification_deliveries_event_route"),
                      Index("ix_notification_deliveries_pending", "route", "status", "event_id"))
