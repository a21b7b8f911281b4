"""A message: the events one route sends at once (one, or a storm grouped), as the webhook's JSON
body and as a person's text (e-mail, chat). Pure."""

from __future__ import annotations

import hashlib
import json
from collections import Counter
from typing import Any

from service.notifications.events import SCHEMA_VERSION, headline


def message_key(event_keys: list[str]) -> str:
    """The message's idempotency key: its event's key, or for a group a digest of its events'
    keys (so a retried group carries the same key)."""
    if len(event_keys) == 1:
        return event_keys[0]
    return hashlib.sha256("\n".join(event_keys).encode()).hexdigest()[:32]


def body(key: str, events: list[dict[str, Any]], page_url: str = "") -> dict[str, Any]:
    """The webhook body (schema.py): the events oldest first."""
    return {"schema_version": SCHEMA_VERSION, "message_id": key, "page_url": page_url or None,
            "events": events}


def body_bytes(message: dict[str, Any]) -> bytes:
    """The exact bytes sent and signed (compact, keys sorted: the same message, the same bytes)."""
    return json.dumps(message, sort_keys=True, separators=(",", ":"), ensure_ascii=False).encode()


def subject(events: list[dict[str, Any]]) -> str:
    if len(events) == 1:
        return "[hvcb] " + headline(events[0])
    breakers = {e["breaker"]["name"] for e in events}
    worst = "ALARM" if any(e["severity"] == "alarm" for e in events) else "WARNING"
    return f"[hvcb] {worst}: {len(events)} events on {len(breakers)} breaker{'s' if len(breakers) > 1 else ''}"


def text(events: list[dict[str, Any]], page_url: str = "") -> str:
    """Plain text for a person: one line per event, oldest first, and a count by kind for a storm."""
    lines = []
    if len(events) > 1:
        counts = Counter(e["kind"] for e in events)
        lines += [f"{len(events)} events grouped: " + ", ".join(f"{n} {k}" for k, n in sorted(counts.items())), ""]
    for e in events:
        lines.append(f"{e['occurred_at']}  {headline(e)}")
        if page_url:
            lines.append(f"    {page_url.rstrip('/')}/breakers/{e['breaker']['id']}")
    lines += ["", "-- ", "hvcb condition monitor. Event ids (idempotency keys): " + ", ".join(e["id"] for e in events)]
    return "\n".join(lines) + "\n"
