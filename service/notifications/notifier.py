"""The notifier: one thread per route sends its messages, one thread watches the stored state
(shelves that ran out, prognosis windows). Started and stopped with the service (service.api.app).

It only reads the outbox and writes its own bookkeeping, in short transactions; a receiver that
is slow or gone costs this route's thread its time and nothing else. Any error of the database
or a receiver is logged and the round is tried again: the thread never dies of it.
"""

from __future__ import annotations

import logging
import os
import socket
import threading

from service.notifications import chat, outbox, smtp, watch, webhook
from service.notifications.delivery_error import DeliveryError
from service.notifications.message import body
from service.storage.models import utcnow

log = logging.getLogger("hvcb.notifications")

TRANSPORTS = {"webhook": webhook.send, "email": smtp.send, "apprise": chat.send}


class Notifier:
    """``start()`` / ``stop()`` the notifier for ``settings`` (a NotificationSettings) on ``Session``."""

    def __init__(self, settings, Session, *, owner: str | None = None):
        self.settings, self.Session = settings, Session
        self.owner = owner or f"{socket.gethostname()}:{os.getpid()}"
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self.sent = 0  # messages accepted by receivers since start (all routes)

    @property
    def enabled(self) -> bool:
        return bool(self.settings.routes)

    def start(self) -> None:
        if not self.enabled or self._threads:
            return
        self._stop.clear()
        # Each route's progress exists before the service takes a request: a new route starts at
        # the newest event, and no event written after the start can slip past its cursor.
        with self.Session() as session, session.begin():
            for r in self.settings.routes:
                outbox.route_row(session, r.name)
        self._threads = [threading.Thread(target=self._watch_loop, name="hvcb-notify-watch", daemon=True)]
        self._threads += [threading.Thread(target=self._route_loop, args=(r,), name=f"hvcb-notify-{r.name}",
                                           daemon=True) for r in self.settings.routes]
        for t in self._threads:
            t.start()
        log.info("notifier started: %d route(s)", len(self.settings.routes))

    def stop(self) -> None:
        self._stop.set()
        for t in self._threads:
            t.join(timeout=max(r.timeout_s for r in self.settings.routes) + 5 if self.settings.routes else 5)
        self._threads = []
        webhook.close_clients()
        if self.enabled:
            try:
                with self.Session() as session, session.begin():
                    for r in self.settings.routes:
                        outbox.release(session, r.name, owner=self.owner)
            except Exception:  # the lease runs out by itself
                log.warning("notifier: could not release its route leases", exc_info=True)

    # -- one round of each thread (tests call these directly) ----------------------------------
    def watch_once(self) -> int:
        now = utcnow()
        with self.Session() as session, session.begin():
            return (watch.shelve_expiries(session, now=now)
                    + watch.prognosis_windows(session, weeks=self.settings.prognosis_weeks, now=now))

    def route_once(self, route) -> float:
        """One round of a route: take in new events and send its next due message. Returns how
        long to wait before the next round [s]: 0 after an accepted message (more may be due),
        the time left of the backoff after a failure (nothing can go before the failed message,
        so the route does not touch the database until then), else ``poll_s``."""
        s = self.settings
        lease_s = max(60.0, 3 * route.timeout_s)
        with self.Session() as session, session.begin():
            now = utcnow()
            if not outbox.claim(session, route.name, owner=self.owner, now=now, lease_s=lease_s):
                return s.poll_s
            retry_at = outbox.route_row(session, route.name).next_attempt_at
            if retry_at is not None and retry_at > now:
                return min((retry_at - now).total_seconds(), lease_s / 2)
            outbox.take_in(session, route, now=now)
            msg = outbox.next_message(session, route, now=now, group_interval_s=s.group_interval_s,
                                      max_events=s.max_events_per_message)
        if msg is None:
            return s.poll_s
        key, events = msg
        try:  # outside any transaction
            TRANSPORTS[route.kind](route, body(key, events, s.page_url))
        except DeliveryError as exc:
            with self.Session() as session, session.begin():
                when = outbox.mark_failed(session, route.name, key, now=utcnow(), error=str(exc),
                                          retry_min_s=s.retry_min_s, retry_max_s=s.retry_max_s)
            log.warning("notification route %s: %s; %d event(s) kept, next attempt at %s",
                        route.name, exc, len(events), when.isoformat())
            return max((when - utcnow()).total_seconds(), 0.0)
        with self.Session() as session, session.begin():
            outbox.mark_sent(session, route.name, key, now=utcnow())
        self.sent += 1
        return 0.0

    # -- the threads -----------------------------------------------------------------------------
    def _watch_loop(self) -> None:
        while not self._stop.is_set():
            try:
                self.watch_once()
            except Exception:
                log.warning("notifier: watching shelves and prognoses failed; trying again", exc_info=True)
            self._stop.wait(self.settings.poll_s)

    def _route_loop(self, route) -> None:
        while not self._stop.is_set():
            try:
                wait = self.route_once(route)  # 0: a backlog drains without waiting
            except Exception:
                log.warning("notification route %s: round failed; trying again", route.name, exc_info=True)
                wait = self.settings.poll_s
            if wait > 0:
                self._stop.wait(wait)
