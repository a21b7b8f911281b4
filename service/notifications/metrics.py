"""The notifier's state for /metrics: per route, events waiting for their receiver and the
consecutive failed attempts (a receiver that has been unreachable for a while)."""

from __future__ import annotations

from prometheus_client.core import GaugeMetricFamily
from sqlalchemy import select

from service.notifications.outbox import backlog
from service.notifications.rows import NotificationRouteRow


def notification_metrics(session, route_names) -> list:
    """Metric families for the configured routes ``route_names`` (read in the scrape's session)."""
    waiting = backlog(session)
    failures = dict(session.execute(select(NotificationRouteRow.name, NotificationRouteRow.failures)).all())
    pending = GaugeMetricFamily("hvcb_notification_backlog", "events waiting for their route's receiver",
                                labels=["route"])
    failing = GaugeMetricFamily("hvcb_notification_failures", "consecutive failed attempts of a route "
                                "(0: its last message was accepted)", labels=["route"])
    for name in route_names:
        pending.add_metric([name], waiting.get(name, 0))
        failing.add_metric([name], failures.get(name) or 0)
    return [pending, failing]
