"""Webhook transport: POST the message's JSON, signed (signature.py), with its idempotency key.

httpx (already the service's HTTP client). Any 2xx is accepted; anything else, a timeout or a
refused connection is a failure and the message is retried unchanged (same bytes, same key).
"""

from __future__ import annotations

import time

import httpx

from service.errors import in_words
from service.notifications.delivery_error import DeliveryError
from service.notifications.message import body_bytes
from service.notifications.signature import IDEMPOTENCY_HEADER, SIGNATURE_HEADER, TIMESTAMP_HEADER, sign


def send(route, message: dict, *, now: float | None = None) -> None:
    data = body_bytes(message)
    ts = int(now if now is not None else time.time())
    headers = {"Content-Type": "application/json", "User-Agent": "hvcb-notifier/1",
               TIMESTAMP_HEADER: str(ts), SIGNATURE_HEADER: sign(route.secret, ts, data),
               IDEMPOTENCY_HEADER: message["message_id"]}
    try:
        r = httpx.post(route.url, content=data, headers=headers, timeout=route.timeout_s)
    except httpx.HTTPError as exc:
        raise DeliveryError(f"webhook {route.url} not reached: {in_words(exc)}") from None
    if not 200 <= r.status_code < 300:
        raise DeliveryError(f"webhook {route.url} answered {r.status_code}: {r.text[:200]}")
