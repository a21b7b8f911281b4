"""Webhook signatures: HMAC-SHA256 over ``"<timestamp>." + body`` (stdlib ``hmac``).

The timestamp is in the signed text, so a captured request cannot be replayed later with a new
timestamp; a receiver refuses one whose timestamp is older than its tolerance.
"""

from __future__ import annotations

import hashlib
import hmac

SIGNATURE_HEADER = "X-Hvcb-Signature"
TIMESTAMP_HEADER = "X-Hvcb-Timestamp"
IDEMPOTENCY_HEADER = "Idempotency-Key"
PREFIX = "v1="
# Five minutes: longer than any clock skew NTP leaves, shorter than a replay is useful.
DEFAULT_TOLERANCE_S = 300


def sign(secret: str, timestamp: int, body: bytes) -> str:
    """The signature header's value: ``v1=<hex HMAC-SHA256(secret, "<timestamp>." + body)>``."""
    mac = hmac.new(secret.encode(), str(int(timestamp)).encode() + b"." + body, hashlib.sha256)
    return PREFIX + mac.hexdigest()


def verify(secret: str, *, timestamp: str, signature: str, body: bytes, now: float,
           tolerance_s: float = DEFAULT_TOLERANCE_S) -> bool:
    """True when ``signature`` is this body's signature with ``secret`` and the timestamp lies
    within ``tolerance_s`` of ``now`` [s since the epoch]. Constant-time comparison."""
    try:
        ts = int(timestamp)
    except (TypeError, ValueError):
        return False
    if abs(now - ts) > tolerance_s:
        return False
    return hmac.compare_digest(sign(secret, ts, body), signature or "")
