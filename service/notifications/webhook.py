"""Webhook transport: POST the message's JSON, signed (signature.py), with its idempotency key.

httpx (already the service's HTTP client). Any 2xx is accepted; anything else, a timeout or a
refused connection is a failure and the message is retried unchanged (same bytes, same key).
"""

from __future__ import annotations

import threading
import time

import httpx

from service.errors import in_words
from service.notifications.delivery_error import DeliveryError
from service.notifications.message import body_bytes
from service.notifications.signature import IDEMPOTENCY_HEADER, SIGNATURE_HEADER, TIMESTAMP_HEADER, sign


_clients: dict[tuple[str, str], httpx.Client] = {}
_lock = threading.Lock()


def _client(route) -> httpx.Client:
    """One client per route, kept: its connection pool and TLS context are made once, not at
    every attempt (loading the CA bundle costs milliseconds of CPU, a retried route pays it often)."""
    key = (route.name, route.url)
    with _lock:
        if key not in _clients:
            _clients[key] = httpx.Client(timeout=route.timeout_s)
        return _clients[key]


def close_clients() -> None:
    with _lock:
        for c in _clients.values():
            c.close()
        _clients.clear()


def send(route, message: dict, *, now: float | None = None) -> None:
    data = body_bytes(message)
    ts = int(now if now is not None else time.time())
    headers = {"Content-Type": "application/json", "User-Agent": "hvcb-notifier/1",
               TIMESTAMP_HEADER: str(ts), SIGNATURE_HEADER: sign(route.secret, ts, data),
               IDEMPOTENCY_HEADER: message["message_id"]}
    try:
        r = _client(route).post(route.url, content=data, headers=headers)
    except httpx.HTTPError as exc:
        raise DeliveryError(f"webhook {route.url} not reached: {in_words(exc)}") from None
    if not 200 <= r.status_code < 300:
        raise DeliveryError(f"webhook {route.url} answered {r.status_code}: {r.text[:200]}")
