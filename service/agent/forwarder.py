"""Forwards the outbox to the central hvcb, oldest first, one capture at a time.

Each capture is POSTed to ``/api/v1/breakers/{id}/captures`` with its content hash as
``Idempotency-Key``: at-least-once delivery, stored exactly once (the server answers a repeat
with the operation it already has). A capture leaves the outbox only when the server has
answered 200/202. Unreachable server, 5xx, 401/403/404: wait (doubling from ``retry_min_s`` to
``retry_max_s``) and try the same capture again, so order is kept. 409/413/422: the server will
never take this capture: it is set aside in ``outbox/rejected`` and the next one goes.
"""

from __future__ import annotations

import logging
import threading
import time
from datetime import datetime, timezone
from pathlib import Path

import httpx

from drivers.backoff import Backoff
from service.errors import in_words

from .outbox import Outbox, OutboxEntry

log = logging.getLogger("hvcb.agent.forward")

REJECT = {409, 413, 422}


class Forwarder:
    """The forwarding thread. ``central`` is ``CentralSettings``."""

    def __init__(self, outbox: Outbox, central, *, transport: httpx.BaseTransport | None = None,
                 on_sent=None):
        self.outbox, self.central, self.on_sent = outbox, central, on_sent
        self.client = httpx.Client(base_url=central.url, headers={"X-API-Key": central.api_key},
                                   verify=central.verify, timeout=central.timeout_s, transport=transport)
        self.central_up = False
        self.last_error: str | None = None
        self.attempts = 0
        self.failures = 0
        self.duplicates = 0
        self.last_latency_s: float | None = None  # capture → accepted by the server [s]
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="hvcb-agent-forward", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self.outbox.changed.set()
        if self._thread is not None:
            self._thread.join(timeout=self.central.timeout_s + 5)
            self._thread = None
        self.client.close()

    # -- the loop ------------------------------------------------------------------------------
    def _run(self) -> None:
        backoff = Backoff(self.central.retry_min_s, self.central.retry_max_s)
        while not self._stop.is_set():
            entry = self.outbox.oldest()
            if entry is None:
                self.outbox.changed.wait(1.0)
                self.outbox.changed.clear()
                continue
            outcome = self.send(entry)
            if outcome == "retry":
                self._stop.wait(backoff.next())
            else:
                backoff.reset()

    def send(self, entry: OutboxEntry) -> str:
        """One attempt at ``entry``: "sent", "rejected" or "retry"."""
        breaker_id = self.central.breaker_ids.get(entry.breaker)
        if breaker_id is None:
            self._fail(f"breaker {entry.breaker!r} has no id in [central] breaker_ids")
            return "retry"
        cfg = Path(entry.cfg)
        try:
            files = [("files", (cfg.name, cfg.read_bytes(), "application/octet-stream")),
                     ("files", (cfg.with_suffix(".dat").name, cfg.with_suffix(".dat").read_bytes(),
                                "application/octet-stream"))]
        except FileNotFoundError:
            log.error("capture %s lost its files; dropping the entry", cfg.name)
            self.outbox.sent(entry)
            return "rejected"
        data = {"operation": entry.operation} if entry.operation else {}
        self.attempts += 1
        try:
            r = self.client.post(f"/api/v1/breakers/{breaker_id}/captures", files=files, data=data,
                                 headers={"Idempotency-Key": entry.key})
        except httpx.HTTPError as exc:
            self._fail(f"central server unreachable: {in_words(exc)}")
            return "retry"
        if r.status_code in (200, 202):
            if not self.central_up:
                log.info("central server answers; forwarding %d spooled capture(s)", len(self.outbox))
            self.central_up, self.last_error = True, None
            if r.status_code == 200:
                self.duplicates += 1
            self.last_latency_s = (datetime.now(timezone.utc) - entry.captured).total_seconds()
            self.outbox.sent(entry)
            if self.on_sent is not None:  # e.g. a benchmark following the operation to its fit
                self.on_sent(entry, r.json())
            return "sent"
        detail = _detail(r)
        if r.status_code in REJECT:
            self.central_up = True
            self.outbox.reject(entry, f"HTTP {r.status_code}: {detail}")
            return "rejected"
        self._fail(f"central server answered HTTP {r.status_code}: {detail}")
        return "retry"

    def _fail(self, error: str) -> None:
        self.failures += 1
        if error != self.last_error:
            log.warning("%s; %d capture(s) wait in the outbox", error, len(self.outbox))
        self.central_up, self.last_error = False, error

    def wait_idle(self, timeout: float) -> bool:
        """True once the outbox is empty (tests, shutdown)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if not len(self.outbox):
                return True
            time.sleep(0.05)
        return False


def _detail(r: httpx.Response) -> str:
    try:
        return str(r.json().get("detail"))[:300]
    except ValueError:
        return r.text[:300]
